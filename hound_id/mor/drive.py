"""The field-oriented drive's voltage and current limits at speed: the dq model behind the region's edges.

A surface-mounted PMSM (L_d = L_q = L) under field-oriented control, in the rotor's dq frame, steady state,
per phase (peak amplitudes, amplitude-invariant Park transform):

    v_d = R_ph i_d - w_e L i_q,      v_q = R_ph i_q + w_e L i_d + w_e psi,      tau = 1.5 p psi i_q

with w_e = p omega the electrical speed. Space-vector modulation limits the voltage vector to the circle
|v| <= V_bus / sqrt(3); the driver limits the current (i_d = 0 and |i_q| <= I without field weakening;
|i_dq| <= I_max with it).

hound-id's model (:mod:`hound_id.mor.spec`) works in DC-equivalent quantities: ``V = R i + omega / Kv`` with
R = sqrt(3) R_ph, 1/Kv = sqrt(3) p psi, V = V_bus and i = i_q. Multiplying the phase equations by sqrt(3) keeps
that form and adds one term, the reactance X = l omega with l = sqrt(3) p L [ohm s/rad]:

    (R i_d - X i_q)^2 + (R i_q + X i_d + omega/Kv)^2 <= V_bus^2.

With X = 0 and i_d = 0 this is the paper's eq. 2 exactly. In the linear-equivalent torque x = Kt i (the
coordinates of :func:`hound_id.mor.region.torque_interval`), with u = D omega (D = Kt / (R Kv), the back-EMF
damping), S = Kt V_bus / R (the stall torque) and rho = X / R, the reachable currents form a disk:

    centre (x_d, x_q) = (-u rho, -u) / (1 + rho^2),     radius S / sqrt(1 + rho^2).

* **Without field weakening** (i_d = 0) the window is the disk's chord on the q axis,
  x = (-u +- sqrt(S^2 (1 + rho^2) - u^2 rho^2)) / (1 + rho^2), cut to +-X_lim (X_lim = Kt I). The no-load speed
  is unchanged (zero current drops no voltage); the corner speed falls with the reactance.
* **With field weakening** the window is the q-extent of the disk intersected with the current circle
  |x_dq| <= Kt I_max (then cut to +-X_lim): the circle's top while the disk holds it (MTPA, i_d = 0, for this
  motor), then the circles' upper crossing (field weakening), then the disk's top (the voltage-limited maximum).
* **Past control** (the window empty: even the full opposing voltage cannot hold the current within the
  limit) the drive's switches are off and the back-EMF drives current through the inverter's diodes into the
  bus. The voltage vector then opposes the current with amplitude V_bus (the same modulation circle), so
  (R m + V)^2 + (X m)^2 = (omega/Kv)^2 for the current amplitude m, and the torque is Kt times its q part,
  x_q = -(m + S) m / sqrt((m + S)^2 + (rho m)^2) in x units (m in x units too). With X = 0 this is today's
  (V - omega/Kv)/R; with reactance the braking is smaller and, at high speed, falls again (the current turns
  into the d axis: the short-circuit limit). A six-pulse rectifier's fundamental is 2/pi V_bus per phase, 10 %
  above V_bus/sqrt(3): this model's diode braking is then slightly high, never low.

The torque follows the q current through the motor's current-torque curve (the d current is taken not to change
it: no cross-saturation, as for a surface-magnet rotor). Everything here is symmetric: the window at -omega is the
negative of the window at omega.

:func:`dq_window` works on numpy arrays and torch tensors alike (elementwise, differentiable where the window is
smooth); the clip (:mod:`hound_id.mor.saturation`) and the region (:mod:`hound_id.mor.region`) both call it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Inductance conventions a spec sheet may state (``inductance_convention``): ``line_to_line`` (what a meter across
#: two terminals reads, and what Maxon, CubeMars and most drive datasheets print: twice the phase inductance of a
#: wye winding) or ``phase``.
INDUCTANCE_CONVENTIONS = ("line_to_line", "phase")
#: The convention taken (with a warning) when a spec gives an inductance without one.
DEFAULT_INDUCTANCE_CONVENTION = "line_to_line"
#: The window is held at its value at this many no-load speeds (u = D omega = this x S, or x X_lim if larger: a bus
#: at 0 V) and beyond: the braking has
#: long faded to the short-circuit current's few N m there, no motor survives it, and every square taken stays within
#: float32's range for any finite speed.
SPEED_CAP = 1e4
#: Phase inductance over the stated inductance, per convention (a wye winding: L_ll = 2 L_ph).
PHASE_FACTOR = {"line_to_line": 0.5, "phase": 1.0}


@dataclass(frozen=True)
class Drive:
    """What the field-oriented drive adds to the DC-equivalent model: the winding's reactance and, optionally, field
    weakening (module docstring)."""

    reactance: float
    """l = sqrt(3) p L_phase [ohm s/rad]: the DC-equivalent reactance per motor rad/s (X = l omega); 0 without an
    inductance."""
    k_rho: float
    """l / (R D) = l Kv / Kt [1/(N m)]: rho = X / R = k_rho D |omega| (:func:`dq_window`)."""
    circle_x: float
    """Kt I_max [N m]: the phase-current circle in linear-equivalent torque (field weakening)."""
    field_weakening: bool
    """Whether the drive injects negative d current past base speed (else i_d = 0)."""
    phase_current_limit: float
    """The drive's phase-current amplitude limit |i_dq| <= I_max [A] (with field weakening; else the q limit)."""
    inductance_phase: float | None = None
    """Phase inductance [H] the reactance came from (None: none given)."""
    convention: str | None = None
    """How the spec stated its inductance (``phase`` or ``line_to_line``)."""
    pole_pairs: int | None = None
    """Pole pairs the reactance used."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (SI)."""
        return {
            "reactance_per_speed": self.reactance,
            "inductance_phase": self.inductance_phase,
            "inductance_convention": self.convention,
            "pole_pairs": self.pole_pairs,
            "field_weakening": self.field_weakening,
            "phase_current_limit": self.phase_current_limit,
            "units": {"reactance_per_speed": "ohm s/rad", "inductance_phase": "H", "phase_current_limit": "A"},
        }


def reactance_per_speed(inductance: float, convention: str, pole_pairs: int) -> float:
    """l = sqrt(3) p L_phase [ohm s/rad] for a stated inductance [H] and its convention."""
    return math.sqrt(3.0) * pole_pairs * inductance * PHASE_FACTOR[convention]


class _Ops:
    """The few elementwise operations :func:`dq_window` needs, for numpy arrays or torch tensors."""

    where: Any
    sqrt: Any
    relu: Any
    torch: bool

    def __init__(self, like: Any) -> None:
        self.torch = type(like).__module__.startswith("torch")
        if self.torch:
            import torch

            self.where, self.sqrt = torch.where, torch.sqrt
            self.relu = lambda x: torch.clamp(x, min=0.0)
        else:
            self.where, self.sqrt = np.where, np.sqrt
            self.relu = lambda x: np.maximum(x, 0.0)


def dq_window(u: Any, stall: Any, k_rho: Any, limit_x: Any, circle_x: Any, field_weakening: Any) -> tuple[Any, Any]:
    """(lo, hi) linear-equivalent torque window x = Kt i_q [N m] at u = D omega (module docstring).

    Args:
        u: Back-EMF damping times motor speed, D omega [N m] (signed).
        stall: S = Kt V_bus / R [N m] (may vary per environment: it scales with the bus voltage).
        k_rho: l / (R D) [1/(N m)]: rho = X / R = k_rho |u|.
        limit_x: X_lim = Kt I [N m], I the current the torque limit needs.
        circle_x: Kt I_max [N m], the phase-current circle with field weakening (unused without).
        field_weakening: bool, or a boolean array broadcast against ``u``.

    Returns the window inside control, and the diode-bridge torque (lo = hi) past it. Broadcasts like numpy.
    """
    if not type(u).__module__.startswith("torch"):
        with np.errstate(all="ignore"):  # far past control the unused branches overflow; the selected ones do not
            return _window(_Ops(u), u, stall, k_rho, limit_x, circle_x, field_weakening)
    return _window(_Ops(u), u, stall, k_rho, limit_x, circle_x, field_weakening)


def _window(
    ops: _Ops, u: Any, stall: Any, k_rho: Any, limit_x: Any, circle_x: Any, field_weakening: Any
) -> tuple[Any, Any]:
    where, sqrt, relu = ops.where, ops.sqrt, ops.relu
    eager = ops.torch  # torch computes every branch (a test of the data would cost a device sync on a GPU)
    w = abs(u)
    # every square below float32's range (NaN stays NaN); against the larger of S and X, so a bus at 0 V still brakes
    cap = SPEED_CAP * where(stall > limit_x, stall, limit_x)
    w = where(w > cap, cap, w)
    rho = k_rho * w
    n = 1.0 + rho * rho
    cq = -w / n
    # i_d = 0: the chord of the voltage disk on the q axis
    disc = stall * stall * n - (w * rho) ** 2
    h = sqrt(relu(disc)) / n
    top, bot = cq + h, cq - h
    ok = (disc >= 0) & (top >= -limit_x)
    if eager or np.any(field_weakening):  # the q extent of the disk within the current circle
        sn = sqrt(n)
        cd = -w * rho / n
        r, d, M = stall / sn, w / sn, circle_x
        top_circle = cd * cd + (M - cq) ** 2 <= r * r
        top_disk = cd * cd + (cq + r) ** 2 <= M * M
        bot_circle = cd * cd + (M + cq) ** 2 <= r * r
        bot_disk = cd * cd + (cq - r) ** 2 <= M * M
        a = (M * M - r * r + d * d) / (2.0 * where(d > 0, d, 1.0))  # along the centre line, from the origin
        hh = sqrt(relu(M * M - a * a))  # half the common chord
        up, down = (-a + hh * rho) / sn, (-a - hh * rho) / sn  # the crossings' q parts (the centre's direction is
        top1 = where(top_circle, M + 0.0 * w, where(top_disk, cq + r, up))  # (-rho, -1)/sqrt(n), its normal (-1, rho))
        bot1 = where(bot_circle, -M + 0.0 * w, where(bot_disk, cq - r, down))
        ok1 = (d <= M + r) & (top1 >= -limit_x)
        top, bot = where(field_weakening, top1, top), where(field_weakening, bot1, bot)
        ok = where(field_weakening, ok1, ok)
    # the whole window where the bus drives the full current: (X + |u|)^2 + (rho X)^2 <= S^2 (decided so, without
    # roots, here and in the fused loop alike; the roots agree to rounding)
    full = (limit_x + w) ** 2 + (rho * limit_x) ** 2 <= stall * stall
    hi = where(full | (top >= limit_x), limit_x + 0.0 * w, top)
    lo = where(full | (bot <= -limit_x), -limit_x + 0.0 * w, bot)
    ok = full | ok
    if eager or not np.all(ok):  # past control: the diode bridge's current, its q part
        m = relu((-stall + sqrt(relu(w * w * n - (stall * rho) ** 2))) / n)
        xq = -(m + stall) * m / sqrt((m + stall) ** 2 + (rho * m) ** 2)
        hi, lo = where(ok, hi, xq), where(ok, lo, xq)
    neg = u < 0
    return where(neg, -hi, lo), where(neg, -lo, hi)
