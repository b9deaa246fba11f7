"""The motor friction a trainer feels: each fitted friction term, the torque it makes, and where an export can put it.

Motor side, opposing the rotor's motion, with sgn(w) = tanh(w / :data:`EPS_SPEED`) as in the fit
(:mod:`hound_id.dyno.current.effects`, same names and signs):

==============  ===========================================  ================================================
term            motor-side friction torque [N m]             parameters
==============  ===========================================  ================================================
coulomb         -f_c sgn(w)                                  f_c [N m]
viscous         -b w                                         b [N m s/rad]
stribeck        -f_s sgn(w) exp(-(w / w_s)^2)                f_s [N m], w_s [rad/s]
gear_friction   -c |i| sgn(w)                                c [N m/A]; i the motor's current [A]
==============  ===========================================  ================================================

The current of ``gear_friction`` is the load: the current the motor's curve needs for the torque it makes, so
the runtime asks for the joint torques (:meth:`hound_id.runtime.Runtime.friction_torque`).

Each term is a :class:`FrictionTerm` in :data:`TERMS` (sorted by name): its parameters with their units and the
value a motor without a fit takes, its torque (numpy or torch: only arithmetic, with ``sgn`` and ``exp`` given),
and ``homes``, the export formats that hold it and where. A format not in ``homes`` cannot hold the term; the
export states the largest torque it loses (:meth:`FrictionTerm.largest`). A fit effect that trainers should feel
names its term (``Effect.friction`` in :mod:`hound_id.dyno.current.effects`); a new term is one entry here, or, from
your own effects file, one :func:`register` call beside the effect's (a trainer that loads the bundle registers the
same term before :func:`hound_id.runtime.load`).
No import but the standard library and :mod:`hound_id.errors`: the runtime loads this module.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from hound_id.errors import SpecError

__all__ = ["EPS_SPEED", "TERMS", "FrictionTerm", "parameters", "register"]

#: Smoothing speed of the friction sign, tanh(omega / EPS_SPEED) [rad/s], as in the fit.
EPS_SPEED = 0.01


@dataclass(frozen=True)
class FrictionTerm:
    """One friction term of a motor (motor side, SI)."""

    name: str
    """The fit effect's name."""
    label: str
    """What a sentence calls it (e.g. "load-dependent friction")."""
    parameters: tuple[tuple[str, str, float], ...]
    """(name, unit, value for a motor without it) per parameter, as the fit names them."""
    physics: str
    """What it is, in a few words."""
    torque: Callable[..., Any]
    """f(p, w, sgn, load, exp) -> the term's friction torque [N m] (opposes w); p maps parameter -> array, w the
    motor speed [rad/s], sgn tanh(w / EPS_SPEED), load |i| [A] (None when the term does not need it), exp the array
    library's exp."""
    homes: Mapping[str, str]
    """Export format -> the field that holds the term there (formats not listed cannot hold it)."""
    needs_load: bool = False
    """Whether the torque depends on the motor's current (then the runtime needs the joint torques)."""
    size: Callable[[Mapping[str, float], float, float], float] | None = None
    """(p, the current at the torque limit [A], the top speed [rad/s]) -> the largest torque the term makes [N m]
    (default: its first parameter, a torque)."""

    def largest(self, p: Mapping[str, float], limit_current: float, top_speed: float) -> float:
        """The largest friction torque this term makes on a motor [N m], at the torque limit's current and up to
        ``top_speed``: what an export that cannot hold the term loses."""
        return float(self.size(p, limit_current, top_speed)) if self.size else abs(float(p[self.parameters[0][0]]))


def parameters() -> tuple[tuple[str, str, float], ...]:
    """Every parameter of every term, (name, unit, value without a fit), in :data:`TERMS` order."""
    return tuple(p for term in TERMS.values() for p in term.parameters)


_MOTOR_SIDE = {"bundle": "friction (hound_id.runtime.Runtime.friction_torque)"}


def _tendons_and_urdfs(tendon: str, urdf: str) -> dict[str, str]:
    """The homes of a term on the motor tendons (MuJoCo and the trainers built on its MJCF) and in the URDFs' joint
    ``<dynamics>``."""
    return {
        **{fmt: f"tendon {tendon}" for fmt in ("mujoco", "mjlab", "newton")},
        **{fmt: f"dynamics {urdf}" for fmt in ("urdf", "urdf-open")},
    }


#: The friction terms, sorted by name.
TERMS: dict[str, FrictionTerm] = {
    term.name: term
    for term in sorted(
        (
            FrictionTerm(
                "coulomb",
                "Coulomb friction",
                (("coulomb", "N m", 0.0),),
                "a constant torque against the motion",
                lambda p, w, sgn, load, exp: -p["coulomb"] * sgn,
                {
                    **_MOTOR_SIDE,
                    **_tendons_and_urdfs("frictionloss", "friction"),
                    "isaaclab": "dynamic_friction (and friction, the static)",
                },
            ),
            FrictionTerm(
                "gear_friction",
                "load-dependent friction",
                (("gear_friction", "N m/A", 0.0),),
                "gear-mesh friction that grows with the transmitted load, per amp of motor current",
                lambda p, w, sgn, load, exp: -p["gear_friction"] * load * sgn,
                dict(_MOTOR_SIDE),
                needs_load=True,
                size=lambda p, i, w: abs(p["gear_friction"]) * i,
            ),
            FrictionTerm(
                "stribeck",
                "static (Stribeck) friction",
                (("stribeck", "N m", 0.0), ("stribeck_speed", "rad/s", 1.0)),
                "extra friction at rest that fades over the Stribeck speed",
                lambda p, w, sgn, load, exp: -p["stribeck"] * sgn * exp(-((w / p["stribeck_speed"]) ** 2)),
                {**_MOTOR_SIDE, "isaaclab": "friction (static: Coulomb plus this excess at rest)"},
            ),
            FrictionTerm(
                "viscous",
                "viscous friction",
                (("viscous", "N m s/rad", 0.0),),
                "drag in proportion to speed",
                lambda p, w, sgn, load, exp: -p["viscous"] * w,
                {**_MOTOR_SIDE, **_tendons_and_urdfs("damping", "damping"), "isaaclab": "viscous_friction"},
                size=lambda p, i, w: abs(p["viscous"]) * w,
            ),
        ),
        key=lambda t: t.name,
    )
}


def register(term: FrictionTerm, *, replace: bool = False) -> FrictionTerm:
    """Add a friction term (kept sorted by name); its parameter names must be new. SpecError otherwise."""
    if term.name in TERMS and not replace:
        raise SpecError(f"friction term '{term.name}' is already registered; pick another name or pass replace=True")
    taken = {p: t.name for t in TERMS.values() if t.name != term.name for p, _, _ in t.parameters}
    for p, _, _ in term.parameters:
        if p in taken:
            raise SpecError(f"friction term '{term.name}': parameter '{p}' is already term '{taken[p]}''s")
    TERMS[term.name] = term
    for key in sorted(TERMS):
        TERMS[key] = TERMS.pop(key)
    return term
