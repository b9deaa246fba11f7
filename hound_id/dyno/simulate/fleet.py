"""A simulated fleet of actuators of one type, some with planted faults, for the fleet report's tests.

Every actuator is the same motor (:class:`~hound_id.dyno.simulate.current.SimMotor`) with the
unit-to-unit scatter of a production batch (assumed: Kt 1 %, saturation 2 %, each friction term
and the cogging amplitude 10 % log-normal, cogging phase anywhere), run through the same short
test plan. A fault changes one unit the way the physical defect would:

========================  ======================================================  ==================
fault                     change (against the unit's own healthy values)          the flag expected
========================  ======================================================  ==================
``weak_magnet``           Kt 10 % low (a demagnetised rotor)                      ``kt`` low
``bearing``               Coulomb friction x3 (a damaged or over-preloaded one)   ``coulomb`` high
``gearbox``               load-dependent friction x3 (worn or dry gears)          ``gear_friction`` high
``different_motor``       cogging order 28 instead of 24 (another slot count)     ``cogging_order``
========================  ======================================================  ==================

A weak magnet also lowers the peak torque (it follows Kt), so ``peak_torque`` low may come with it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from hound_id.dyno.simulate.current import SimMotor, SimulatedLog, TestPlan, simulate, typical_truth
from hound_id.errors import DynoDataError

#: Effects every simulated actuator has.
FLEET_EFFECTS = ("linear", "saturation", "offset", "coulomb", "viscous", "gear_friction", "cogging")
#: The fleet's model: what fits a healthy unit to its noise floor.
FLEET_MODEL = "+".join(FLEET_EFFECTS)
#: A short four-quadrant plan (12.5 s): four speeds, ramps and three step levels per plateau.
FLEET_PLAN = TestPlan(
    speeds=(-20.0, -5.0, 5.0, 20.0),
    plateau_time=1.5,
    pause_time=1.0,
    hold_time=0.0,
    transition_time=0.5,
    current_levels=3,
)
#: Logging rate of the simulated fleet [Hz].
FLEET_RATE_HZ = 400.0


@dataclass(frozen=True)
class Fault:
    """A planted defect."""

    description: str
    """What it is, physically."""
    flags: tuple[str, ...]
    """The metrics that must be flagged."""
    may_flag: tuple[str, ...] = ()
    """Metrics that may be flagged too, as its consequence."""


FAULTS: Mapping[str, Fault] = MappingProxyType(
    {
        "bearing": Fault("Coulomb friction x3: a damaged or over-preloaded bearing", ("coulomb",)),
        "different_motor": Fault("cogging order 28 instead of 24: another motor's slot count", ("cogging_order",)),
        "gearbox": Fault("load-dependent friction x3: worn or dry gears", ("gear_friction",)),
        "weak_magnet": Fault("Kt 10 % low: a demagnetised rotor", ("kt",), ("peak_torque",)),
    }
)


@dataclass(frozen=True)
class FleetMember:
    """One simulated actuator."""

    name: str
    """Its name (and log file stem)."""
    log: SimulatedLog
    """Its log and truth."""
    fault: str | None
    """The planted fault (a key of :data:`FAULTS`), None when healthy."""


def planted(n: int, every: int = 10) -> dict[int, str]:
    """Faults for a fleet of ``n``: one in every ``every`` actuators, the kinds in turn, none at index 0."""
    kinds = sorted(FAULTS)
    return {i: kinds[k % len(kinds)] for k, i in enumerate(range(every // 2, n, every))}


def member_truth(rng: np.random.Generator, fault: str | None, motor: SimMotor = SimMotor()) -> dict[str, float]:
    """One unit's true parameters: the typical ones with a batch's scatter, and its fault."""
    truth = typical_truth(FLEET_EFFECTS, motor)
    truth["kt"] *= 1.0 + 0.01 * rng.standard_normal()
    truth["k_sat"] *= 1.0 + 0.02 * rng.standard_normal()
    for name in ("coulomb", "viscous", "gear_friction"):
        truth[name] *= float(np.exp(0.1 * rng.standard_normal()))
    truth["offset"] *= float(rng.uniform(-1.0, 1.0))
    scale, turn = float(np.exp(0.1 * rng.standard_normal())), float(rng.uniform(0.0, 2 * np.pi))
    for h in (1, 2):
        s, c = truth[f"cogging_sin_{h}"], truth[f"cogging_cos_{h}"]
        # a rotor mounted at another angle: each harmonic's phase turns h times as far
        truth[f"cogging_sin_{h}"] = scale * (s * np.cos(h * turn) - c * np.sin(h * turn))
        truth[f"cogging_cos_{h}"] = scale * (s * np.sin(h * turn) + c * np.cos(h * turn))
    truth["noise_std"] *= float(np.exp(0.1 * rng.standard_normal()))
    if fault == "weak_magnet":
        truth["kt"] *= 0.90
    elif fault == "bearing":
        truth["coulomb"] *= 3.0
    elif fault == "gearbox":
        truth["gear_friction"] *= 3.0
    elif fault == "different_motor":
        truth["cogging_order"] = 28.0
    elif fault is not None:
        raise DynoDataError(f"unknown fault {fault!r}; expected one of {', '.join(FAULTS)}")
    return truth


def simulate_fleet(
    n: int = 12,
    faults: Mapping[int, str] | None = None,
    seed: int = 0,
    plan: TestPlan = FLEET_PLAN,
    rate_hz: float = FLEET_RATE_HZ,
    names: Sequence[str] | None = None,
) -> list[FleetMember]:
    """``n`` actuators of one type with a batch's scatter and the planted ``faults`` (index -> fault).

    Args:
        n: Number of actuators.
        faults: Index -> a key of :data:`FAULTS` (default :func:`planted`).
        seed: Seed of the scatter and of the noise.
        plan: The test plan every actuator runs.
        rate_hz: Logging rate [Hz].
        names: Actuator names (default ``act_000`` ...).

    Raises:
        DynoDataError: An unknown fault, an index outside the fleet, or names of the wrong count.
    """
    faults = planted(n) if faults is None else dict(faults)
    for index, fault in faults.items():
        if not 0 <= index < n or fault not in FAULTS:
            raise DynoDataError(f"fault {fault!r} at actuator {index}: expected an index below {n} and a known fault")
    names = [f"act_{i:03d}" for i in range(n)] if names is None else list(names)
    if len(names) != n:
        raise DynoDataError(f"names: found {len(names)}, expected {n}")
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        truth = member_truth(rng, faults.get(i))
        log = simulate(FLEET_EFFECTS, plan=plan, truth=truth, rate_hz=rate_hz, seed=seed * 100_003 + i)
        out.append(FleetMember(names[i], log, faults.get(i)))
    return out


#: The channels a fleet log is written with.
FLEET_COLUMNS = ("time", "current", "torque", "velocity", "position")


__all__ = [
    "FAULTS", "FLEET_COLUMNS", "FLEET_EFFECTS", "FLEET_MODEL", "FLEET_PLAN", "FLEET_RATE_HZ", "Fault", "FleetMember",
    "member_truth", "planted", "simulate_fleet",
]  # fmt: skip
