"""Contact angles of the foot: where on the foot the ground touches, from touchdown to liftoff.

Convention (ROS REP-103: x forward, y left, z up; pitch about +y). In the sagittal plane
the calf's absolute pitch is theta = body pitch + hip angle + knee angle, 0 with the calf
pointing straight down. The ground's normal, seen from the calf, then points at the angle
theta from the calf's -z axis towards its +x: that is the point of the foot in contact.
A positive pitch swings the foot backwards, so in forward running theta *increases* through
stance: negative at touchdown (foot ahead of the knee), positive at liftoff (foot behind).
The attack angle is theta at touchdown, the detach angle theta at liftoff; the foot must
cover every angle the stance sweeps through, so :func:`contact_angles` also reports the
extremes over each stance.

A gait log (CSV or Parquet) has ``pitch`` [rad] and per leg ``<leg>_HFE``, ``<leg>_KFE`` [rad]
and ``<leg>_contact`` (1 in stance, 0 in flight), one row per sample in time order (a ``time``
column may be there; it is not needed).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.errors import DynoDataError, SpecError

#: Largest angular coverage a spherical-cap foot can have [rad] (a hemisphere).
MAX_COVERAGE = math.pi


@dataclass(frozen=True)
class ContactAngles:
    """Contact angles over the strides of a gait, with the margin applied, radians."""

    attack: float
    """Mean contact angle at touchdown [rad]."""
    detach: float
    """Mean contact angle at liftoff [rad]."""
    attack_spread: float
    """Standard deviation of the touchdown angle over strides [rad] (0 for given angles)."""
    detach_spread: float
    """Standard deviation of the liftoff angle over strides [rad]."""
    low: float
    """Lowest angle the foot must cover: min over stances minus the margin [rad]."""
    high: float
    """Highest angle the foot must cover: max over stances plus the margin [rad]."""
    margin: float
    """Margin applied on both sides [rad]."""
    strides: int
    """Stances found (0 for given angles)."""
    source: str = "--angles"
    """Where the angles come from: ``--angles`` or the gait log's path."""

    @property
    def coverage(self) -> float:
        """Angular coverage the foot needs, high - low [rad]."""
        return self.high - self.low

    def to_dict(self) -> dict[str, Any]:
        out = {k: getattr(self, k) for k in self.__dataclass_fields__}
        out["coverage"] = self.coverage
        out["units"] = "rad (strides and source excepted)"
        return out


def _check_margin(margin_deg: float) -> None:
    if not (math.isfinite(margin_deg) and 0 <= margin_deg < 90):
        raise SpecError(f"--margin: found {margin_deg} deg, expected 0 to 90 deg (it widens the arc at both ends)")


def _checked(low: float, high: float, margin: float, source: str) -> None:
    if max(abs(low), abs(high)) > 2 * math.pi:
        raise SpecError(
            f"{source}: contact angles reach {math.degrees(max(abs(low), abs(high))):.0f} deg; the log looks like "
            "degrees, expected radians (pitch, <leg>_HFE and <leg>_KFE in rad)"
        )
    if not high - low < MAX_COVERAGE:
        raise SpecError(
            f"{source}: the foot would have to cover {math.degrees(high - low):.1f} deg "
            f"(from {math.degrees(low):.1f} to {math.degrees(high):.1f} deg with a {math.degrees(margin):.1f} deg "
            "margin); a spherical cap covers less than 180 deg: reduce the margin or check the angles"
        )


def given_angles(attack_deg: float, detach_deg: float, margin_deg: float = 5.0) -> ContactAngles:
    """Angles stated by the user (``--angles ATTACK,DETACH`` in degrees, touchdown before liftoff).

    The stance sweeps the contact angle from the attack angle up to the detach angle (see the
    module docstring), so the attack angle is the smaller: e.g. ``-30, 25``.
    """
    _check_margin(margin_deg)
    if not all(math.isfinite(a) for a in (attack_deg, detach_deg)):
        raise SpecError(f"--angles: found {attack_deg}, {detach_deg}; expected two finite angles in degrees")
    if not attack_deg < detach_deg:
        raise SpecError(
            f"--angles: attack {attack_deg:g} deg must come before detach {detach_deg:g} deg in the stance: "
            "the calf pitch (REP-103, 0 = calf vertical) rises from touchdown (foot ahead, negative) to "
            "liftoff (foot behind, positive), e.g. --angles -30,25; swap or re-sign them"
        )
    if max(abs(attack_deg), abs(detach_deg)) > 180:
        raise SpecError(
            f"--angles: found {attack_deg:g}, {detach_deg:g} deg; expected calf pitches within +-180 deg (0 = calf "
            "vertical), e.g. -30,25"
        )
    a, d, m = (math.radians(x) for x in (attack_deg, detach_deg, margin_deg))
    low, high = a - m, d + m
    _checked(low, high, m, "--angles")
    return ContactAngles(a, d, 0.0, 0.0, low, high, m, 0)


def contact_angles(
    columns: Mapping[str, Any], legs: Sequence[str], margin_deg: float = 5.0, source: str = "gait log"
) -> ContactAngles:
    """Contact angles over every stance of every leg in a gait log (see module docstring)."""

    def column(name: str) -> NDArray[np.float64]:
        if name not in columns:
            raise DynoDataError(
                f"{source}: column '{name}' missing; a gait log needs pitch and "
                "<leg>_HFE, <leg>_KFE, <leg>_contact for each leg",
                column=name,
            )
        raw = columns[name]
        try:
            values = np.asarray(raw, dtype=float)
        except (TypeError, ValueError):
            bad = next(i for i, v in enumerate(raw) if not _is_number(v))
            raise DynoDataError(
                f"{source}: column '{name}' data row {bad + 1} is {raw[bad]!r}, expected a number", column=name
            ) from None
        if not np.all(np.isfinite(values)):
            row = int(np.flatnonzero(~np.isfinite(values))[0]) + 1
            raise DynoDataError(f"{source}: column '{name}' data row {row} is not a finite number", column=name)
        return values

    _check_margin(margin_deg)
    pitch = column("pitch")
    touch, lift, lows, highs = [], [], [], []
    for leg in legs:
        theta = pitch + column(f"{leg}_HFE") + column(f"{leg}_KFE")
        flag = column(f"{leg}_contact")
        odd = np.flatnonzero((flag != 0.0) & (flag != 1.0))
        if odd.size:
            raise DynoDataError(
                f"{source}: column '{leg}_contact' data row {odd[0] + 1} is {flag[odd[0]]:g}, expected 1 (stance) "
                "or 0 (flight); threshold a contact force or probability into a flag first",
                column=f"{leg}_contact",
            )
        contact = flag > 0.5
        edges = np.diff(contact.astype(np.int8))
        starts = np.flatnonzero(edges == 1) + 1
        ends = np.flatnonzero(edges == -1) + 1
        for s in starts:
            later = ends[ends > s]
            if later.size == 0:
                break  # the log ends in stance: an incomplete stride
            e = int(later[0])
            touch.append(theta[s])
            lift.append(theta[e - 1])
            lows.append(theta[s:e].min())
            highs.append(theta[s:e].max())
    if not touch:
        raise DynoDataError(
            f"{source}: no complete stance found (a contact flag rising then falling) for legs {', '.join(legs)}"
        )
    if np.mean(touch) > np.mean(lift):
        raise DynoDataError(
            f"{source}: the contact angle falls through stance (touchdown {math.degrees(np.mean(touch)):.1f} deg, "
            f"liftoff {math.degrees(np.mean(lift)):.1f} deg); in forward running it rises (REP-103: pitch about +y, "
            "a positive pitch swings the foot back): negate pitch, HFE and KFE if the log uses the opposite sign"
        )
    m = math.radians(margin_deg)
    low, high = float(min(lows)) - m, float(max(highs)) + m
    _checked(low, high, m, source)
    return ContactAngles(
        float(np.mean(touch)),
        float(np.mean(lift)),
        float(np.std(touch)),
        float(np.std(lift)),
        low,
        high,
        m,
        len(touch),
        source,
    )


def _is_number(value: Any) -> bool:
    try:
        float(value)
    except (TypeError, ValueError):
        return False
    return True


def gait_angles(path: str | Path, legs: Sequence[str] | None = None, margin_deg: float = 5.0) -> ContactAngles:
    """Contact angles from a gait log file (CSV or Parquet); legs default to every ``<leg>_contact`` column."""
    from hound_id.tables import read_table

    frame = read_table(path)
    if legs is not None and not legs:
        raise SpecError("--legs: no leg named; give e.g. RR,RL or leave --legs out for every leg")
    if legs is None:  # every leg any of its three columns names: one missing is an error, not a leg left out
        suffixes = ("_HFE", "_KFE", "_contact")
        legs = sorted({str(c)[: -len(x)] for c in frame.columns for x in suffixes if str(c).endswith(x)})
        if not legs:
            raise DynoDataError(
                f"{path}: no '<leg>_contact' column; a gait log needs time, pitch and <leg>_HFE, <leg>_KFE, "
                "<leg>_contact for each leg"
            )
    return contact_angles({str(c): frame[c].to_numpy() for c in frame.columns}, legs, margin_deg, source=str(path))
