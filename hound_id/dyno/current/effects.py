"""The effects library: named physical terms that make measured torque differ from Kt * i.

A fit model is a sum of effects. Each effect contributes regressor columns that are
linear in its parameters, given its nonlinear ("hyper") parameters, which the fit
finds by search. The model of the measured torque is

    torque(t) = sum over effects of  X_e(signals(t - delay); hypers) @ beta_e

``delay``, ``lag`` and ``resonance`` add no column. ``delay`` is a shift of the inputs
(:attr:`~hound_id.dyno.current.effect.Effect.shift`): the torque channel lags the current
channel, so every other effect's columns are built from the signals as they were ``delay``
earlier; ``lag`` and ``resonance`` pass the model's torque through the transducer's own
dynamics (:mod:`hound_id.dyno.current.transducer`), which filters every column alike.

Conventions shared with :mod:`hound_id.dyno.simulate.current` (same names, same signs):
eps = 0.01 rad/s and sgn(w) = tanh(w / eps); temperatures in degC relative to
:data:`T_REF`; friction terms oppose the velocity.

Users add their own effect with :func:`register` (see docs/fit-current.md for a worked
example) and load it with ``hound-id fit-current --effects-file my_effects.py``.

What an effect is and the registry are in :mod:`hound_id.dyno.current.effect`; this module registers the
effects hound-id ships and re-exports the rest, so ``from hound_id.dyno.current.effects import Effect, register``
keeps working.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping

import numpy as np

from hound_id.dyno.current.effect import (
    EPS_SPEED,
    OFFSET,
    REGISTRY,
    T_REF,
    Array,
    Effect,
    FleetMetric,
    Hyper,
    Signals,
    describe,
    get,
    inputs,
    load_effects_file,
    parse_model,
    parse_start_model,
    register,
    requirements_missing,
    sgn,
    shift_of,
)
from hound_id.dyno.current.transducer import DAMPING_RANGE, frequency_range, overshoot
from hound_id.parameter import Parameter

#: The cogging effect's parameters: the sine and cosine of its first two harmonics.
COGGING_HARMONICS = ("cogging_sin_1", "cogging_cos_1", "cogging_sin_2", "cogging_cos_2")
#: Share of rows a Stribeck speed needs within twice itself to be searched. Calibrated on
#: test_logs::test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read and
#: test_diagnose::test_each_hidden_effect_is_named_first_and_adding_it_reaches_the_noise.
STRIBECK_SEEN = 0.02


def _knee_loss(i: Array, knee: float) -> Array:
    """sign(i) * h(|i|), h(x) = x - k - k ln(x/k) above the knee k, else 0 (>= 0, smooth at the knee)."""
    x = np.abs(i)
    with np.errstate(divide="ignore", invalid="ignore"):
        h = np.where(x > knee, x - knee - knee * np.log(np.maximum(x, knee) / knee), 0.0)
    return np.sign(i) * h  # type: ignore[no-any-return]


def _speed_grid(signals: Signals, residual: Array) -> Array:
    """Stribeck speeds to search; only those with STRIBECK_SEEN of the rows within twice the speed (Stribeck friction
    shows near rest: a log with no samples there cannot tell it from Coulomb friction with any amplitude)."""
    w = np.abs(signals.channel("velocity"))
    top = float(np.percentile(w, 99)) if w.size else 1.0
    grid = np.geomspace(max(top * 1e-3, 0.05), max(top / 2, 0.1), 14)
    if not w.size:
        return grid
    seen = np.array([np.mean(w < 2.0 * ws) for ws in grid])
    return grid[seen >= STRIBECK_SEEN]  # type: ignore[no-any-return]


def _knee_grid(signals: Signals, residual: Array) -> Array:
    top = float(np.max(np.abs(signals.current)))
    return np.linspace(0.15, 0.9, 16) * top


def _order_candidates(weight_by_current: bool) -> Callable[[Signals, Array], Array]:
    """Orders per revolution whose harmonic is strongest in the residual, binned on the rotor angle."""

    def candidates(signals: Signals, residual: Array) -> Array:
        theta = np.mod(signals.channel("position"), 2 * np.pi)
        bins = 2048
        idx = np.minimum((theta * (bins / (2 * np.pi))).astype(np.int64), bins - 1)
        if weight_by_current:
            i = signals.current
            num = np.bincount(idx, residual * i, bins)
            den = np.bincount(idx, i * i, bins)
        else:
            num = np.bincount(idx, residual, bins)
            den = np.bincount(idx, None, bins).astype(float)
        seen = den > 0
        if seen.sum() < bins // 4:  # too little rotation to see an order
            return np.array([], dtype=float)
        profile = np.zeros(bins)
        profile[seen] = num[seen] / den[seen]
        profile[seen] -= profile[seen].mean()
        spectrum = np.abs(np.fft.rfft(profile))[1 : bins // 4]
        top = np.argsort(spectrum)[::-1][:3] + 1
        return top.astype(float)

    return candidates


def _harmonics(phase: Array) -> Array:
    """Columns sin(x), cos(x), sin(2x), cos(2x) (the second pair by the double-angle formulas)."""
    out = np.empty((phase.shape[0], 4))
    np.sin(phase, out=out[:, 0])
    np.cos(phase, out=out[:, 1])
    np.multiply(2.0 * out[:, 0], out[:, 1], out=out[:, 2])
    np.subtract(out[:, 1] ** 2, out[:, 0] ** 2, out=out[:, 3])
    return out


def _evidence_linear(p: Mapping[str, float], s: Signals) -> str:
    return f"torque rises {p['kt']:.4g} N m per amp"


def _evidence_saturation(name: str) -> Callable[[Mapping[str, float], Signals], str]:
    def sentence(p: Mapping[str, float], s: Signals) -> str:
        i = float(np.max(np.abs(s.current)))
        eff = get(name)
        hyp = {h.name: p[h.name] for h in eff.hypers if h.name in p}
        col = eff.columns(Signals(time=np.zeros(1), current=np.array([i])), hyp)[0]
        drop = float(col @ np.array([p[q.name] for q in eff.parameters]))
        return (
            f"the residual bends with current: {drop:+.3g} N m at {i:.3g} A against a straight line "
            f"(magnetic saturation)"
        )

    return sentence


def _evidence_offset(p: Mapping[str, float], s: Signals) -> str:
    head = f"the residual sits at {p['offset']:+.3g} N m at zero current"
    if s.velocity is not None:
        moving = s.velocity[np.abs(s.velocity) > 0]
        share = float(np.mean(moving > 0)) if moving.size else 0.5
        if share > 0.95 or share < 0.05:
            return (
                f"{head}: a sensor offset, or Coulomb friction of {abs(p['offset']):.3g} N m (the speed keeps one "
                "sign on this log, so the two cannot be told apart; record both directions of rotation to separate "
                "them)"
            )
    return f"{head} (sensor offset)"


def _evidence_coulomb(p: Mapping[str, float], s: Signals) -> str:
    return f"the residual steps by {2 * abs(p['coulomb']):.3g} N m where velocity changes sign: Coulomb friction"


def _evidence_viscous(p: Mapping[str, float], s: Signals) -> str:
    w = float(np.percentile(np.abs(s.channel("velocity")), 99))
    return f"the residual falls by {abs(p['viscous']) * w:.3g} N m from rest to {w:.3g} rad/s: viscous drag"


def _evidence_stribeck(p: Mapping[str, float], s: Signals) -> str:
    return (
        f"near zero speed the residual holds {abs(p['stribeck']):.3g} N m more friction that fades by "
        f"{p['stribeck_speed']:.3g} rad/s: Stribeck (static) friction"
    )


def _evidence_gear(p: Mapping[str, float], s: Signals) -> str:
    return f"friction grows with load by {abs(p['gear_friction']):.3g} N m per amp: load-dependent gear friction"


def _evidence_cogging(p: Mapping[str, float], s: Signals) -> str:
    amp = math.hypot(p["cogging_sin_1"], p["cogging_cos_1"])
    return (
        f"the residual repeats {int(p['cogging_order'])} times per revolution with {amp:.3g} N m amplitude, "
        "current or not: cogging"
    )


def _evidence_ripple(p: Mapping[str, float], s: Signals) -> str:
    amp = math.hypot(p["ripple_sin"], p["ripple_cos"])
    return (
        f"a ripple of {amp:.3g} N m per amp repeats {int(p['ripple_order'])} times per revolution and grows "
        "with current: torque ripple"
    )


def _evidence_thermal(p: Mapping[str, float], s: Signals) -> str:
    t = s.channel("temperature")
    span = float(np.ptp(t))
    kt = p.get("kt")
    rel = f" ({100 * p['kt_temp_coeff'] / kt:+.3g} %/K of Kt)" if kt else ""
    return f"Kt drifts by {p['kt_temp_coeff']:+.3g} N m/A per K{rel} over a {span:.3g} K temperature swing: thermal"


def _evidence_inertia(p: Mapping[str, float], s: Signals) -> str:
    a = float(np.percentile(np.abs(s.acceleration), 99))
    return (
        f"the residual falls by {p['inertia'] * a:.3g} N m where the rotor accelerates at {a:.3g} rad/s^2: the inertia "
        f"between the motor and the torque sensor, {p['inertia']:.3g} kg m^2"
    )


def _filter_grid(count: int) -> Callable[[Signals, Array], Array]:
    """Candidate frequencies [Hz] spread geometrically over the filter range the log can show."""

    def grid(signals: Signals, residual: Array) -> Array:
        lo, hi = frequency_range(signals.time)
        return np.geomspace(lo, hi, count)

    return grid


def _evidence_lag(p: Mapping[str, float], s: Signals) -> str:
    tau = p["lag_tau"]
    return (
        f"the torque channel follows the model through a first-order lag of {1e3 * tau:.3g} ms (a bandwidth of "
        f"{1.0 / (2 * math.pi * tau):.3g} Hz): the transducer's filter smooths every step"
    )


def _evidence_resonance(p: Mapping[str, float], s: Signals) -> str:
    f0, zeta = p["resonance_f0"], p["resonance_zeta"]
    ring = (
        f"a current step overshoots by {overshoot(zeta):.0%} and rings at {f0 * math.sqrt(max(1 - zeta**2, 0)):.3g} Hz"
        if zeta < 1
        else "a current step is smoothed without ringing"
    )
    return (
        f"the torque channel follows the model through a second-order resonance at {f0:.3g} Hz with damping "
        f"{zeta:.2g}: {ring} (the coupling and the transducer between the motor and the reading)"
    )


def _evidence_delay(p: Mapping[str, float], s: Signals) -> str:
    d = p["delay"]
    if d >= 0:
        return f"the torque channel lags the current channel by {1e3 * d:.3g} ms (transducer filter, bus latency)"
    return (
        f"the current channel lags the torque channel by {-1e3 * d:.3g} ms (for example a current reply read "
        "one loop late)"
    )


_SAT_BOUND = "saturation bends the curve below the straight line"
_CURVE_TRAINER = "the current-torque curve: the runtime's clip and current compensation, every export's torque limit"
_ANGLE = (
    "not carried: the fit's position channel is the dyno's rotor angle, whose zero the robot's joint angle does not "
    "share"
)
_FRICTION_BOUND = "friction dissipates energy, it opposes motion"


#: The current-torque curve's parameters and the offsets: against each other, only a varying current tells them apart.
_CURVE_PARTNERS = frozenset({"kt", "k_sat", "k_sat3", "k_knee", "offset", OFFSET})


def _held_current(partner: str, signals: Signals) -> str | None:
    """Why a curve parameter cannot be told from another or from an offset: the current hardly varies."""
    mean, std = float(np.mean(signals.current)), float(np.std(signals.current))
    if partner not in _CURVE_PARTNERS or std >= 0.1 * max(abs(mean), 1e-300):
        return None
    return (
        f"the current hardly varies ({mean:.3g} +- {std:.2g} A), so torque per amp cannot be told from a constant "
        "torque; vary the current: record a current sweep over both signs"
    )


def _one_quadrant(partner: str, signals: Signals) -> str | None:
    """Why load-dependent friction cannot be told from Kt: current and speed keep one sign relative to each other."""
    if signals.velocity is None:
        return None
    quadrant = np.sign(signals.current * signals.velocity)
    moving = quadrant[quadrant != 0]
    share = float(np.mean(moving > 0)) if moving.size else 1.0
    if 0.05 <= share <= 0.95:
        return None
    kind = "motoring" if share > 0.5 else "braking"
    return (
        f"current and speed keep one sign relative to each other ({max(share, 1 - share):.0%} of the rows "
        f"{kind}), so friction that grows with load looks like a change of Kt; record both motoring and "
        "braking (all four quadrants)"
    )


def _one_direction(partner: str, signals: Signals) -> str | None:
    """Why friction that opposes motion cannot be told from an offset: the speed keeps one sign."""
    if partner not in (OFFSET, "offset") or signals.velocity is None:
        return None
    share = float(np.mean(signals.velocity > 0))
    return (
        f"the speed keeps one sign ({max(share, 1 - share):.0%} of the rows), so friction that opposes motion "
        "looks like a sensor offset; record both directions of rotation"
    )


def _builtin() -> None:
    sat_doc = "magnetic saturation: the core's flux saturates and torque per amp falls at high current"
    register(
        Effect(
            name="linear",
            unidentified=_held_current,
            physics="torque is proportional to current through the torque constant Kt",
            parameters=(
                Parameter("kt", "N m/A", "torque constant at 20 degC", 0.0, bound_reason="torque follows current"),
            ),
            regressors=lambda s, h: s.current,
            shape=True,
            evidence=_evidence_linear,
            trainer=_CURVE_TRAINER,
            fleet=(
                FleetMetric(
                    "kt",
                    "Kt",
                    "Kt",
                    "N m/A",
                    "both",
                    0.05,
                    ("kt",),
                    per_amp=True,
                    rank=0,
                    low="Kt low: a weakened (demagnetised) magnet or a wrong winding (or, for logs from several rigs, "
                    "a torque sensor calibrated differently)",
                    high="Kt high: another winding or magnet grade than the fleet's: check the part (or, for logs from "
                    "several rigs, a torque sensor calibrated differently)",
                ),
            ),
        )
    )
    register(
        Effect(
            name="saturation",
            unidentified=_held_current,
            physics=f"{sat_doc} (odd quadratic, as in the paper: -k i|i|)",
            parameters=(
                Parameter("k_sat", "N m/A^2", "quadratic saturation coefficient", 0.0, bound_reason=_SAT_BOUND),
            ),
            regressors=lambda s, h: -s.current * np.abs(s.current),
            shape=True,
            evidence=_evidence_saturation("saturation"),
            trainer=_CURVE_TRAINER,
        )
    )
    register(
        Effect(
            name="saturation_cubic",
            unidentified=_held_current,
            physics=f"{sat_doc} (odd cubic: -k i^3)",
            parameters=(Parameter("k_sat3", "N m/A^3", "cubic saturation coefficient", 0.0, bound_reason=_SAT_BOUND),),
            regressors=lambda s, h: -(s.current**3),
            shape=True,
            evidence=_evidence_saturation("saturation_cubic"),
            trainer=_CURVE_TRAINER,
        )
    )
    register(
        Effect(
            name="saturation_knee",
            unidentified=_held_current,
            physics=(
                f"{sat_doc} (linear up to a knee current, logarithmic beyond; the 'knee plus log' curve written "
                "with ln so value and slope are continuous at the knee)"
            ),
            parameters=(
                Parameter("k_knee", "N m/A", "torque lost per amp of the log-knee term", 0.0, bound_reason=_SAT_BOUND),
            ),
            regressors=lambda s, h: -_knee_loss(s.current, h["knee_current"]),
            hypers=(Hyper("knee_current", "A", _knee_grid),),
            shape=True,
            evidence=_evidence_saturation("saturation_knee"),
            trainer=_CURVE_TRAINER,
        )
    )
    register(
        Effect(
            name="offset",
            unidentified=_held_current,
            physics="the torque transducer reads a constant bias at zero torque",
            parameters=(Parameter("offset", "N m", "sensor offset"),),
            regressors=lambda s, h: np.ones_like(s.current),
            evidence=_evidence_offset,
            trainer="a bias of the rig's torque sensor, not the motor's: trainers do not feel it",
        )
    )
    register(
        Effect(
            name="coulomb",
            unidentified=_one_direction,
            physics="dry friction opposes motion with a constant torque whatever the speed",
            parameters=(Parameter("coulomb", "N m", "Coulomb friction torque", 0.0, bound_reason=_FRICTION_BOUND),),
            regressors=lambda s, h: -s.velocity_sign,
            requires=("velocity",),
            evidence=_evidence_coulomb,
            friction="coulomb",
            fleet=(
                FleetMetric(
                    "coulomb",
                    "Coulomb friction",
                    "Coul.",
                    "N m",
                    "high",
                    0.5,
                    ("coulomb",),
                    rank=20,
                    high="friction high: a bearing or gearbox problem",
                ),
            ),
        )
    )
    register(
        Effect(
            name="viscous",
            unidentified=_one_direction,
            physics="viscous and eddy-current drag grow in proportion to speed",
            parameters=(
                Parameter("viscous", "N m s/rad", "viscous friction coefficient", 0.0, bound_reason=_FRICTION_BOUND),
            ),
            regressors=lambda s, h: -s.channel("velocity"),
            requires=("velocity",),
            evidence=_evidence_viscous,
            friction="viscous",
            fleet=(
                FleetMetric(
                    "viscous",
                    "viscous friction",
                    "visc.",
                    "N m s/rad",
                    "high",
                    0.5,
                    ("viscous",),
                    rank=21,
                    high="viscous friction high: a rubbing seal, too much or too thick grease, or a bearing problem",
                ),
            ),
        )
    )
    register(
        Effect(
            name="stribeck",
            unidentified=_one_direction,
            physics="static friction exceeds Coulomb friction near rest and fades as speed builds a lubricant film",
            parameters=(
                Parameter("stribeck", "N m", "extra static friction at rest", 0.0, bound_reason=_FRICTION_BOUND),
            ),
            regressors=lambda s, h: -s.velocity_sign * np.exp(-((s.channel("velocity") / h["stribeck_speed"]) ** 2)),
            requires=("velocity",),
            hypers=(Hyper("stribeck_speed", "rad/s", _speed_grid),),
            evidence=_evidence_stribeck,
            friction="stribeck",
            fleet=(
                FleetMetric(
                    "stribeck",
                    "static (Stribeck) friction",
                    "static",
                    "N m",
                    "high",
                    0.5,
                    ("stribeck",),
                    rank=22,
                    high="static friction high: a bearing or gearbox that sticks at rest",
                ),
            ),
        )
    )
    register(
        Effect(
            name="gear_friction",
            unidentified=_one_quadrant,
            physics="gear-mesh friction grows with the transmitted load (efficiency below 100 %), opposing motion",
            parameters=(
                Parameter(
                    "gear_friction", "N m/A", "friction per amp of load current", 0.0, bound_reason=_FRICTION_BOUND
                ),
            ),
            regressors=lambda s, h: -np.abs(s.current) * s.velocity_sign,
            requires=("velocity",),
            evidence=_evidence_gear,
            friction="gear_friction",
            fleet=(
                FleetMetric(
                    "gear_friction",
                    "load-dependent friction",
                    "gear",
                    "N m/A",
                    "high",
                    0.5,
                    ("gear_friction",),
                    per_amp=True,
                    rank=23,
                    high="load-dependent friction high: a gearbox problem (worn, misaligned or dry gears)",
                ),
            ),
        )
    )
    register(
        Effect(
            name="cogging",
            physics="magnets pull towards the stator teeth, a torque periodic in rotor angle even at zero current",
            parameters=tuple(
                Parameter(f"cogging_{f}_{k}", "N m", f"{f} amplitude of harmonic {k}")
                for k in (1, 2)
                for f in ("sin", "cos")
            ),
            regressors=lambda s, h: _harmonics(h["cogging_order"] * s.channel("position")),
            requires=("position",),
            hypers=(Hyper("cogging_order", "1/rev", _order_candidates(False), integer=True, refine=False),),
            evidence=_evidence_cogging,
            trainer=f"{_ANGLE}; its amplitude is in the bundle's effects and the export notes",
            fleet=(
                FleetMetric(
                    "cogging_amplitude",
                    "cogging amplitude",
                    "cog.",
                    "N m",
                    "high",
                    0.5,
                    COGGING_HARMONICS,
                    order="cogging_order",
                    rank=30,
                    high="cogging high: a displaced or chipped magnet, or an eccentric rotor",
                ),
            ),
        )
    )
    register(
        Effect(
            name="ripple",
            physics="non-sinusoidal back-EMF and commutation make torque per amp vary with rotor angle",
            parameters=(
                Parameter("ripple_sin", "N m/A", "sine amplitude per amp"),
                Parameter("ripple_cos", "N m/A", "cosine amplitude per amp"),
            ),
            regressors=lambda s, h: (
                s.current[:, None]
                * np.column_stack(
                    [
                        np.sin(h["ripple_order"] * s.channel("position")),
                        np.cos(h["ripple_order"] * s.channel("position")),
                    ]
                )
            ),
            requires=("position",),
            hypers=(Hyper("ripple_order", "1/rev", _order_candidates(True), integer=True, refine=False),),
            evidence=_evidence_ripple,
            trainer=f"{_ANGLE}; its amplitude is in the bundle's effects",
        )
    )
    register(
        Effect(
            name="thermal",
            physics="magnet flux, and so Kt, falls as the rotor warms (NdFeB about -0.1 %/K)",
            parameters=(
                Parameter(
                    "kt_temp_coeff",
                    "N m/A/K",
                    "change of Kt per kelvin above 20 degC",
                    upper=0.0,
                    bound_reason="magnet flux falls as the magnet warms",
                ),
            ),
            regressors=lambda s, h: s.current * (s.channel("temperature") - T_REF),
            requires=("temperature",),
            evidence=_evidence_thermal,
            trainer="Kt's temperature coefficient, in the thermal model the runtime steps (the clip at a temperature)",
        )
    )
    register(
        Effect(
            name="inertia",
            physics=(
                "the rotor, coupling and sensor flange between the air gap and the torque sensor take J dw/dt to "
                "accelerate, so the sensor reads that much less while the rotor speeds up"
            ),
            parameters=(
                Parameter(
                    "inertia",
                    "kg m^2",
                    "inertia between the motor's air gap and the torque sensor",
                    0.0,
                    bound_reason="an inertia is positive",
                ),
            ),
            regressors=lambda s, h: -s.acceleration,
            requires=("velocity", "time"),
            evidence=_evidence_inertia,
            trainer=(
                "the rig's inertia between the air gap and the torque sensor, not a joint's: the robot's rotor inertia "
                "comes from the spec sheet"
            ),
        )
    )
    register(
        Effect(
            name="lag",
            physics=(
                "the torque transducer's amplifier filters its reading: the sensor follows the shaft torque through a "
                "first-order low-pass, 1 / (1 + s tau), so a step shows as an exponential approach"
            ),
            parameters=(),
            regressors=None,
            requires=("time",),
            hypers=(Hyper("lag_tau", "s", lambda s, r: 1.0 / (2 * math.pi * _filter_grid(16)(s, r))[::-1]),),
            evidence=_evidence_lag,
            trainer="the torque sensor's filter, not the motor's: trainers do not feel it",
        )
    )
    register(
        Effect(
            name="resonance",
            physics=(
                "the coupling between the motor and the torque sensor is a spring with inertia on both sides: the "
                "sensor follows the shaft torque through a second-order low-pass w0^2 / (s^2 + 2 zeta w0 s + w0^2), "
                "and a current step makes the reading overshoot and ring at f0"
            ),
            parameters=(),
            regressors=None,
            requires=("time",),
            hypers=(
                Hyper("resonance_f0", "Hz", _filter_grid(12)),
                Hyper("resonance_zeta", "1", lambda s, r: np.geomspace(*DAMPING_RANGE, 6)),
            ),
            evidence=_evidence_resonance,
            trainer="the coupling and sensor between the motor and the reading: trainers do not feel it",
        )
    )
    register(
        Effect(
            name="delay",
            physics=(
                "one channel lags the other: positive, the torque channel lags (transducer filter, bus latency); "
                "negative, the current channel lags (e.g. a current reply read one loop late)"
            ),
            parameters=(),
            regressors=None,
            requires=("time",),
            hypers=(Hyper("delay", "s", lambda s, r: np.array([0.0])),),
            shift=True,
            evidence=_evidence_delay,
            trainer="a lag between the log's channels, not the drive's command-to-torque latency: none is set",
        )
    )


def _ship() -> tuple[str, ...]:
    """Register the effects hound-id ships, marked :attr:`Effect.builtin`; their names."""
    _builtin()
    for name in list(REGISTRY):
        REGISTRY[name] = dataclasses.replace(REGISTRY[name], builtin=True)
    return tuple(REGISTRY)


#: The effects hound-id ships, by name.
BUILTIN: tuple[str, ...] = _ship()


__all__ = [
    "BUILTIN",
    "EPS_SPEED",
    "Effect",
    "FleetMetric",
    "Hyper",
    "OFFSET",
    "Parameter",
    "REGISTRY",
    "Signals",
    "T_REF",
    "describe",
    "get",
    "inputs",
    "load_effects_file",
    "parse_model",
    "parse_start_model",
    "register",
    "requirements_missing",
    "sgn",
    "shift_of",
]
