"""How far the coupled motor-space clip turns the joint-torque vector of each coupled joint group.

The clip of :mod:`hound_id.mor.saturation` (the paper's method) maps joint torques to motor torques
(tau_m = A^T tau_j), clips each motor to its own interval and maps back (tau_j = A^-T tau_m). In a
coupled group (the hollow-shaft hip/knee: tau_HFE = G_h tau_m,HFE + tau_m,KFE, tau_KFE = G_k tau_m,KFE)
a clip of one motor moves every joint of the group: the saturated joint-torque vector of the group
points in another direction than the command, and a joint whose own motor did not clip can even grow in
magnitude (|tau_HFE| rises on a knee-only clip when the knee motor's share of the hip torque opposes the
hip motor's). A per-joint clip to an interval that holds zero never makes a joint torque larger.

Everything here is a pure function of the commanded and saturated joint torques and the transmission
matrix A (its coupled groups, :func:`hound_id.mor.saturation.coupled_groups`); it does not import the clip.
``hound-id saturate`` adds it up over a log (streamed), :meth:`hound_id.runtime.Runtime.clip_turn` over a
training batch (numpy, or torch on its device: the per-row work stays there, one small array comes back).

Measures, per coupled group (two or more joints) and over the rows in which a motor of the group clipped:

* the **turn**: the angle between the commanded and the saturated joint-torque vector of the group [deg],
  measured only where both vectors are at least :data:`ANGLE_FLOOR` long (below it a direction is rounding
  or does not matter; those clips are counted as ``below_floor``);
* **growth**: rows in which a joint's |tau| grew by more than :data:`ANGLE_FLOOR`, and by how much [N m];
* the same by **which motors clipped** (the knee motor alone, the hip motor alone, both);
* given a **per-joint reference** (the same command clipped joint by joint, e.g. by
  :func:`hound_id.mor.saturation.per_joint_clip`): how far that clip turns the vector, how far its torques
  are from the coupled clip's, and (given its motor-space violation) in how many rows the motors cannot
  make them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Shortest joint-torque vector [N m, joint side] whose direction is measured, and smallest growth of a
#: joint's |tau| [N m] that is counted. Below it a direction is rounding, or too small to matter: float32
#: rounds the sample robot's joint torques (up to about 100 N m) to about 1e-5 N m, which turns a 0.01 N m
#: vector by at most 0.06 deg; float64 by 1e-12 deg.
ANGLE_FLOOR = 0.01
#: A motor torque counts as clipped when it moved by more than this times max(1 N m, |command|) (float64;
#: :data:`CLIP_ULPS` roundings of the dtype when that is more, as in float32).
CLIP_TOLERANCE = 1e-9
#: In float32 the saturated torques mapped back to motor space differ from the clip's by a few roundings
#: of the motor torques; this many roundings (3e-5 relative in float32) is clearly above that.
CLIP_ULPS = 256
#: Angles kept exactly per tally; beyond, they are binned (:data:`ANGLE_BIN`), so a log of any length
#: takes bounded memory. Ordinary logs and training batches stay exact.
EXACT_ANGLES = 65_536
#: Bin width of the angle histogram past :data:`EXACT_ANGLES` [deg]: quantiles then come to within half of it.
ANGLE_BIN = 0.01
#: Quantile of the "p95" statistic.
P95 = 0.95


def _is_torch(x: Any) -> bool:
    return type(x).__module__.startswith("torch")


def joint_groups(groups: NDArray[np.float64]) -> tuple[tuple[tuple[int, ...], tuple[int, ...]], ...]:
    """(joint indices, motor indices) of every coupled group with two or more joints, in joint order.

    Args:
        groups: The 0/1 motors x joints matrix of :func:`hound_id.mor.saturation.coupled_groups`.
    """
    g = np.asarray(groups) != 0
    seen: set[tuple[int, ...]] = set()
    out = []
    for m in range(g.shape[0]):
        joints = tuple(int(j) for j in np.flatnonzero(g[m]))
        if len(joints) > 1 and joints not in seen:
            seen.add(joints)
            motors = tuple(int(k) for k in np.flatnonzero(g[:, joints[0]]))
            out.append((joints, motors))
    return tuple(sorted(out))


@dataclass(frozen=True)
class Angles:
    """Quantiles of turn angles [deg] (all 0 when ``count`` is 0)."""

    count: int
    """Angles measured (clipped rows whose vectors are both at least the floor long)."""
    median: float
    """Median [deg] (linear interpolation between ranks)."""
    p95: float
    """95th percentile [deg]."""
    max: float
    """Largest [deg]."""

    def to_dict(self) -> dict[str, Any]:
        return {"count": self.count, "median": self.median, "p95": self.p95, "max": self.max}


@dataclass(frozen=True)
class Growth:
    """Rows in which some joint's |tau| grew under a clip by more than the floor."""

    rows: int
    """Number of such rows."""
    max: float
    """Largest growth |tau_sat| - |tau_cmd| of a joint [N m] (0 when none grew by more than the floor)."""
    joints: tuple[int, ...]
    """Per joint of the group, the rows in which it grew."""


@dataclass(frozen=True)
class PatternTurn:
    """The clips of one group in which exactly these motors clipped."""

    motors: tuple[str, ...]
    """The motors that clipped."""
    rows: int
    """Rows."""
    angle: Angles
    """The turn."""
    grew: Growth
    """Joints whose |tau| grew."""


@dataclass(frozen=True)
class Reference:
    """The group under the per-joint reference clip of the same command."""

    clipped: int
    """Rows in which the per-joint clip changed a joint of the group."""
    angle: Angles
    """Its turn, over those rows [deg]."""
    rows: int
    """Rows in which either clip acted."""
    differs: int
    """Of those, rows whose torques differ by more than the floor (norm over the group)."""
    difference_mean: float
    """Mean |tau_sat - tau_ref| over the group's joints (vector norm) [N m], over :attr:`rows`."""
    difference_max: float
    """Largest |tau_sat - tau_ref| [N m]."""
    outside: int | None
    """Rows in which the per-joint result lies outside some motor's region (None: not given)."""
    outside_max: float | None
    """Largest motor torque past its interval there [N m, motor side]."""


@dataclass(frozen=True)
class GroupTurn:
    """The turn of one coupled group."""

    joints: tuple[str, ...]
    """Joints of the group."""
    motors: tuple[str, ...]
    """Motors of the group."""
    rows: int
    """Rows seen."""
    clipped: int
    """Rows in which a motor of the group clipped."""
    angle: Angles
    """Angle between the commanded and the saturated joint-torque vector of the group, over the clips."""
    below_floor: int
    """Clips whose commanded or saturated vector is shorter than the floor (no angle measured)."""
    grew: Growth
    """Clips in which a joint's |tau| grew (a per-joint clip never does that)."""
    patterns: tuple[PatternTurn, ...]
    """The same by which motors clipped, most frequent first."""
    reference: Reference | None
    """Against the per-joint reference clip (None: not given)."""

    @property
    def name(self) -> str:
        """The joints joined by '+', e.g. ``FL_HFE+FL_KFE``."""
        return "+".join(self.joints)

    def to_dict(self) -> dict[str, Any]:
        def growth(g: Growth, rows: int) -> dict[str, Any]:
            return {
                "rows": g.rows,
                "fraction": g.rows / rows if rows else 0.0,
                "max": g.max,
                "by_joint": {j: g.joints[i] for i, j in enumerate(self.joints)},
            }

        ref = self.reference
        return {
            "group": self.name,
            "joints": list(self.joints),
            "motors": list(self.motors),
            "clipped_rows": self.clipped,
            "clipped_fraction": self.clipped / self.rows if self.rows else 0.0,
            "angle": self.angle.to_dict(),
            "below_floor": self.below_floor,
            "grew": growth(self.grew, self.clipped),
            "by_motors": [
                {"motors": list(p.motors), "rows": p.rows, "angle": p.angle.to_dict(), "grew": growth(p.grew, p.rows)}
                for p in self.patterns
            ],
            "per_joint": None
            if ref is None
            else {
                "clipped_rows": ref.clipped,
                "angle": ref.angle.to_dict(),
                "rows": ref.rows,
                "differs_rows": ref.differs,
                "difference_mean": ref.difference_mean,
                "difference_max": ref.difference_max,
                "outside_rows": ref.outside,
                "outside_max": ref.outside_max,
            },
        }


@dataclass(frozen=True)
class ClipTurn:
    """The turn of every coupled group (:func:`clip_turn`, ``hound-id saturate``)."""

    floor: float
    """The floor [N m] (:data:`ANGLE_FLOOR`)."""
    groups: tuple[GroupTurn, ...]
    """Per coupled group, in joint order (empty when no joints are coupled)."""
    reference: str | None = None
    """What the per-joint reference is (None: none given)."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "floor": self.floor,
            "reference": self.reference,
            "units": {"angle": "deg", "torque": "N m (joint side)", "outside_max": "N m (motor side)"},
            "groups": [g.to_dict() for g in self.groups],
        }

    def scalars(self, prefix: str = "clip_turn") -> dict[str, float]:
        """Flat ``{prefix/group/statistic: value}`` floats, for a training logger (TensorBoard, wandb)."""
        out: dict[str, float] = {}
        for g in self.groups:
            key = f"{prefix}/{g.name}"
            out[f"{key}/clipped_fraction"] = g.clipped / g.rows if g.rows else 0.0
            out[f"{key}/angle_median_deg"] = g.angle.median
            out[f"{key}/angle_p95_deg"] = g.angle.p95
            out[f"{key}/angle_max_deg"] = g.angle.max
            out[f"{key}/grew_fraction"] = g.grew.rows / g.clipped if g.clipped else 0.0
            out[f"{key}/grew_max"] = g.grew.max
            if g.reference is not None:
                out[f"{key}/per_joint_angle_median_deg"] = g.reference.angle.median
                out[f"{key}/per_joint_difference_max"] = g.reference.difference_max
        return out


# --- per-row measures (numpy or torch) -------------------------------------------------------------------------------


def _unit(v: Any, xp: Any) -> tuple[Any, Any]:
    """(unit vectors, lengths) of the rows of v, without overflow for any finite v (zero rows: zero, 0)."""
    scale = xp.amax(xp.abs(v), -1, keepdims=True) if xp is np else v.abs().amax(-1, keepdim=True)
    safe = xp.where(scale > 0, scale, xp.ones_like(scale))
    w = v / safe
    n = xp.sqrt((w * w).sum(-1, keepdims=True) if xp is np else (w * w).sum(-1, keepdim=True))
    u = w / xp.where(n > 0, n, xp.ones_like(n))
    if xp is np:
        with np.errstate(over="ignore"):  # a length past the float range is inf: longer than any floor
            return u, (n * scale)[..., 0]
    return u, (n * scale)[..., 0]


def _angle(a: Any, b: Any, xp: Any) -> tuple[Any, Any, Any]:
    """(angle between the rows of a and b [deg], |a|, |b|); 2 atan2(|u - w|, |u + w|) is exact near 0 and 180."""
    u, na = _unit(a, xp)
    w, nb = _unit(b, xp)
    d, s = u - w, u + w
    angle = 2.0 * xp.arctan2(xp.sqrt((d * d).sum(-1)), xp.sqrt((s * s).sum(-1))) * (180.0 / math.pi)
    return angle, na, nb


def _row_measures(
    tau_cmd: Any,
    tau_sat: Any,
    A: NDArray[np.float64],
    group: tuple[tuple[int, ...], tuple[int, ...]],
    floor: float,
    motor_cmd: Any = None,
    motor_sat: Any = None,
    tau_ref: Any = None,
    ref_violation: Any = None,
) -> NDArray[np.float64]:
    """Per row of a group, as one float64 numpy array (rows, columns): the pattern code (bit i: the group's
    i-th motor clipped), the angle [deg] (NaN: not measured), below-floor flag, the growth of each joint
    [N m] (0 unless clipped); with a reference: its changed flag, its angle (NaN: not measured), the
    difference norm [N m], and with its violation the largest one over the group's motors [N m] (-1: within).

    Works on numpy arrays or torch tensors (rows, n); torch is worked on its device and copied once.
    """
    motors = group[1]
    torch_like = _is_torch(tau_cmd)
    xp, A_m, eps, J, M = _on_backend(tau_cmd, A, group)
    tol = max(CLIP_TOLERANCE, CLIP_ULPS * eps)
    tm = tau_cmd @ A_m if motor_cmd is None else _cols(motor_cmd, M)
    tms = tau_sat @ A_m if motor_sat is None else _cols(motor_sat, M)
    # NaN counts as moved (not <=); a finite command whose motor torque is beyond the float range moved too
    ones = xp.ones_like(tm)
    within = xp.abs(tms - tm) <= tol * xp.maximum(ones, xp.abs(tm))
    moved = ~within | xp.isinf(tm)
    bits = [2.0**i for i in range(len(motors))]
    if torch_like:
        import torch

        code = moved.to(tau_cmd.dtype) @ torch.tensor(bits, dtype=tau_cmd.dtype, device=tau_cmd.device)
    else:
        code = moved.astype(tau_cmd.dtype) @ np.array(bits, dtype=tau_cmd.dtype)
    clipped = code > 0
    a, b = _cols(tau_cmd, J), _cols(tau_sat, J)
    angle, na, nb = _angle(a, b, xp)
    measured = clipped & (na >= floor) & (nb >= floor)
    below = clipped & ~measured
    angle = xp.where(measured, angle, _nan_like(angle))
    growth = xp.where(clipped[..., None], xp.abs(b) - xp.abs(a), xp.zeros_like(a))
    columns = [code, angle, _as_float(below, a), growth]
    if tau_ref is not None:
        columns += _reference_columns(a, b, _cols(tau_ref, J), na, floor, xp)
        if ref_violation is not None:
            v = _cols(ref_violation, M)
            v = xp.where(v > tol * xp.maximum(ones, xp.abs(tm)), v, -ones)
            columns.append(v.amax(-1) if torch_like else v.max(-1))
    if torch_like:
        import torch

        stacked = torch.cat([c if c.ndim == 2 else c[..., None] for c in columns], -1)
        return stacked.detach().to("cpu", torch.float64).numpy()  # the one copy (and sync) of the batch
    return np.column_stack([c if c.ndim == 2 else c[:, None] for c in columns]).astype(np.float64, copy=False)


def _on_backend(
    like: Any, A: NDArray[np.float64], group: tuple[tuple[int, ...], tuple[int, ...]]
) -> tuple[Any, Any, float, Any, Any]:
    """(array module, A's columns of the group's motors, eps, joint indices, motor indices) in ``like``'s library."""
    joints, motors = group
    A_m: Any
    if _is_torch(like):
        import torch

        A_m = torch.tensor(np.ascontiguousarray(A[:, list(motors)]), dtype=like.dtype, device=like.device)
        eps = float(torch.finfo(like.dtype).eps)
        return torch, A_m, eps, torch.tensor(joints, device=like.device), torch.tensor(motors, device=like.device)
    A_m = A[:, list(motors)].astype(like.dtype, copy=False)
    return np, A_m, float(np.finfo(like.dtype).eps), list(joints), list(motors)


def _cols(x: Any, idx: Any) -> Any:
    """The columns ``idx`` of a (rows, n) numpy array or torch tensor."""
    return x.index_select(-1, idx) if _is_torch(x) else x[:, idx]


def _nan_like(x: Any) -> Any:
    """NaN shaped like ``x``, in its library and dtype."""
    if _is_torch(x):
        import torch

        return torch.full_like(x, math.nan)
    return np.full_like(x, np.nan)


def _as_float(mask: Any, like: Any) -> Any:
    """A boolean mask as 0.0 and 1.0 in ``like``'s dtype."""
    return mask.to(like.dtype) if _is_torch(mask) else mask.astype(like.dtype)


def _reference_columns(a: Any, b: Any, r: Any, na: Any, floor: float, xp: Any) -> list[Any]:
    """Against the reference joint torques ``r``: (whether it changed the command, its angle [deg], |b - r| [N m])."""
    changed = (r != a).any(-1)
    ref_angle, nr, _ = _angle(a, r, xp)
    ref_measured = changed & (na >= floor) & (nr >= floor)
    _, diff = _unit(b - r, xp)
    return [_as_float(changed, a), xp.where(ref_measured, ref_angle, _nan_like(ref_angle)), diff]


# --- tallies (a log in batches, or one batch) ------------------------------------------------------------------------


class _AngleStore:
    """Angles [deg], exact up to :data:`EXACT_ANGLES`, binned beyond (bounded memory)."""

    def __init__(self) -> None:
        self.exact: list[NDArray[np.float64]] = []
        self.count = 0
        self.hist: NDArray[np.int64] | None = None
        self.max = 0.0

    def add(self, angles: NDArray[np.float64]) -> None:
        if not angles.size:
            return
        self.count += int(angles.size)
        self.max = max(self.max, float(angles.max()))
        if self.hist is None:
            self.exact.append(angles)
            if self.count <= EXACT_ANGLES:
                return
            angles, self.exact = np.concatenate(self.exact), []
            self.hist = np.zeros(int(round(180.0 / ANGLE_BIN)) + 1, dtype=np.int64)
        np.add.at(self.hist, np.minimum(np.floor(angles / ANGLE_BIN).astype(np.int64), self.hist.size - 1), 1)

    def result(self) -> Angles:
        if self.count == 0:
            return Angles(0, 0.0, 0.0, 0.0)
        if self.hist is None:
            values = np.concatenate(self.exact)
            return Angles(self.count, float(np.quantile(values, 0.5)), float(np.quantile(values, P95)), self.max)
        cumulative = np.cumsum(self.hist)

        def quantile(q: float) -> float:
            rank = int(math.floor(q * (self.count - 1)))  # 0-based rank of the lower neighbour
            k = int(np.searchsorted(cumulative, rank + 1))
            return min((k + 0.5) * ANGLE_BIN, self.max)

        return Angles(self.count, quantile(0.5), quantile(P95), self.max)


class _GrowthTally:
    def __init__(self, k: int) -> None:
        self.rows, self.max, self.joints = 0, 0.0, [0] * k

    def add(self, growth: NDArray[np.float64], floor: float) -> None:
        if not len(growth):
            return
        grew = growth > floor
        self.rows += int(grew.any(axis=1).sum())
        self.joints = [c + int(n) for c, n in zip(self.joints, grew.sum(axis=0), strict=True)]
        if grew.any():
            self.max = max(self.max, float(growth[grew].max()))

    def result(self) -> Growth:
        return Growth(self.rows, self.max, tuple(self.joints))


class _GroupTally:
    """One coupled group, batch by batch."""

    def __init__(self, joints: tuple[int, ...], motors: tuple[int, ...], floor: float) -> None:
        self.joint_index, self.motor_index, self.floor = joints, motors, floor
        k = len(joints)
        self.rows = self.clipped = self.below = 0
        self.angles = _AngleStore()
        self.grew = _GrowthTally(k)
        self.patterns: dict[int, tuple[list[int], _AngleStore, _GrowthTally]] = {}
        self.has_ref = self.has_violation = False
        self.ref_clipped = self.ref_rows = self.ref_differs = self.outside = 0
        self.ref_angles = _AngleStore()
        self.diff_sum: list[float] = []
        self.diff_max = self.outside_max = 0.0

    def add(self, m: NDArray[np.float64], has_ref: bool, has_violation: bool) -> None:
        k = len(self.joint_index)
        code, angle, below, growth = m[:, 0], m[:, 1], m[:, 2], m[:, 3 : 3 + k]
        clipped = code > 0
        self.rows += len(m)
        self.clipped += int(clipped.sum())
        self.below += int(below.sum())
        self.angles.add(angle[np.isfinite(angle)])
        self.grew.add(growth[clipped], self.floor)
        for c in np.unique(code[clipped]).astype(int):
            rows = code == c
            entry = self.patterns.setdefault(int(c), ([0], _AngleStore(), _GrowthTally(k)))
            entry[0][0] += int(rows.sum())
            entry[1].add(angle[rows & np.isfinite(angle)])
            entry[2].add(growth[rows], self.floor)
        if has_ref:
            self.has_ref = True
            changed, ref_angle, diff = m[:, 3 + k] > 0, m[:, 4 + k], m[:, 5 + k]
            acted = changed | clipped
            self.ref_clipped += int(changed.sum())
            self.ref_angles.add(ref_angle[np.isfinite(ref_angle)])
            self.ref_rows += int(acted.sum())
            self.ref_differs += int((acted & (diff > self.floor)).sum())
            if acted.any():
                self.diff_sum.append(float(diff[acted].sum()))
                self.diff_max = max(self.diff_max, float(diff[acted].max()))
            if has_violation:
                self.has_violation = True
                v = m[:, 6 + k]
                self.outside += int((v >= 0).sum())
                if (v >= 0).any():
                    self.outside_max = max(self.outside_max, float(v.max()))

    def result(self, joints: tuple[str, ...], motors: tuple[str, ...]) -> GroupTurn:
        names = tuple(joints[j] for j in self.joint_index)
        motor_names = tuple(motors[m] for m in self.motor_index)
        patterns = sorted(self.patterns.items(), key=lambda kv: (-kv[1][0][0], kv[0]))
        reference = None
        if self.has_ref:
            reference = Reference(
                clipped=self.ref_clipped,
                angle=self.ref_angles.result(),
                rows=self.ref_rows,
                differs=self.ref_differs,
                difference_mean=math.fsum(self.diff_sum) / self.ref_rows if self.ref_rows else 0.0,
                difference_max=self.diff_max,
                outside=self.outside if self.has_violation else None,
                outside_max=self.outside_max if self.has_violation else None,
            )
        return GroupTurn(
            joints=names,
            motors=motor_names,
            rows=self.rows,
            clipped=self.clipped,
            angle=self.angles.result(),
            below_floor=self.below,
            grew=self.grew.result(),
            patterns=tuple(
                PatternTurn(
                    motors=tuple(name for i, name in enumerate(motor_names) if code >> i & 1),
                    rows=entry[0][0],
                    angle=entry[1].result(),
                    grew=entry[2].result(),
                )
                for code, entry in patterns
            ),
            reference=reference,
        )


class TurnTally:
    """:class:`ClipTurn` of a log, added up batch by batch (memory bounded whatever the length).

    Args:
        A: The transmission matrix qd = A thetad_m (joints x motors).
        groups: :func:`hound_id.mor.saturation.coupled_groups` of A.
        joints: Joint names (rows of A).
        motors: Motor names (columns of A).
        floor: :data:`ANGLE_FLOOR` [N m].
        reference: What a given per-joint reference is, for the report.
    """

    def __init__(
        self,
        A: NDArray[np.float64],
        groups: NDArray[np.float64],
        joints: tuple[str, ...],
        motors: tuple[str, ...],
        floor: float = ANGLE_FLOOR,
        reference: str | None = None,
    ) -> None:
        if not (floor >= 0.0 and math.isfinite(floor)):
            from hound_id.errors import SaturationError

            raise SaturationError(f"clip turn: floor {floor} N m; expected a finite length >= 0")
        self.A, self.joints, self.motors, self.floor = np.asarray(A, dtype=float), joints, motors, floor
        self.reference = reference
        self.index = joint_groups(groups)
        self.tallies = [_GroupTally(j, m, floor) for j, m in self.index]

    def add(
        self,
        tau_cmd: Any,
        tau_sat: Any,
        motor_cmd: Any = None,
        motor_sat: Any = None,
        tau_ref: Any = None,
        ref_violation: Any = None,
    ) -> None:
        """Add rows (rows, n): numpy arrays or torch tensors (on any device).

        ``motor_cmd``/``motor_sat``: the motor torques, when already computed (else tau @ A); ``tau_ref``: the
        per-joint reference's joint torques; ``ref_violation``: how far its motor torques are outside their
        intervals [N m] (:meth:`hound_id.mor.saturation.Saturation.violation`).
        """
        if ref_violation is not None and tau_ref is None:
            from hound_id.errors import SaturationError

            raise SaturationError("clip turn: ref_violation needs tau_ref (the per-joint clip's torques)")
        for group, tally in zip(self.index, self.tallies, strict=True):
            m = _row_measures(tau_cmd, tau_sat, self.A, group, self.floor, motor_cmd, motor_sat, tau_ref, ref_violation)
            tally.add(m, tau_ref is not None, ref_violation is not None)

    def result(self) -> ClipTurn:
        return ClipTurn(
            floor=self.floor,
            groups=tuple(t.result(self.joints, self.motors) for t in self.tallies),
            reference=self.reference,
        )


def clip_turn(
    tau_cmd: Any,
    tau_sat: Any,
    A: NDArray[np.float64],
    groups: NDArray[np.float64],
    joints: tuple[str, ...],
    motors: tuple[str, ...],
    floor: float = ANGLE_FLOOR,
    tau_ref: Any = None,
    ref_violation: Any = None,
    reference: str | None = None,
) -> ClipTurn:
    """The turn of each coupled group over a batch of commands (..., n) and their saturated torques [N m].

    See the module docstring for the measures and :class:`TurnTally` for the arguments.
    """
    n = len(joints)
    shape = tuple(tau_cmd.shape)
    if shape[-1:] != (n,) or tuple(tau_sat.shape) != shape:
        from hound_id.errors import SaturationError

        raise SaturationError(
            f"clip turn: tau_cmd has shape {shape} and tau_sat {tuple(tau_sat.shape)}; expected both (..., {n})"
        )
    tally = TurnTally(A, groups, joints, motors, floor, reference)

    def rows(x: Any) -> Any:
        return None if x is None else x.reshape(-1, n)

    tally.add(rows(tau_cmd), rows(tau_sat), tau_ref=rows(tau_ref), ref_violation=rows(ref_violation))
    return tally.result()


__all__ = [
    "ANGLE_FLOOR",
    "Angles",
    "ClipTurn",
    "GroupTurn",
    "Growth",
    "PatternTurn",
    "Reference",
    "TurnTally",
    "clip_turn",
    "joint_groups",
]
