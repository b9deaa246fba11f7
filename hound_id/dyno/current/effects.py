"""The effects library: named physical terms that make measured torque differ from Kt * i.

A fit model is a sum of effects. Each effect contributes regressor columns that are
linear in its parameters, given its nonlinear ("hyper") parameters, which the fit
finds by search. The model of the measured torque is

    torque(t) = sum over effects of  X_e(signals(t - delay); hypers) @ beta_e

``delay``, ``lag`` and ``resonance`` add no column: the delay shifts every input channel,
because the torque channel lags the current channel; ``lag`` and ``resonance`` pass the
model's torque through the transducer's own dynamics
(:mod:`hound_id.dyno.current.transducer`), which filters every column alike.

Conventions shared with :mod:`hound_id.dyno.simulate.current` (same names, same signs):
eps = 0.01 rad/s and sgn(w) = tanh(w / eps); temperatures in degC relative to
:data:`T_REF`; friction terms oppose the velocity.

Users add their own effect with :func:`register` (see docs/fit-current.md for a worked
example) and load it with ``hound-id fit-current --effects-file my_effects.py``.
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.current.transducer import DAMPING_RANGE, frequency_range, overshoot
from hound_id.errors import FitError
from hound_id.io import TEXT_MAX_BYTES, check_input
from hound_id.parameter import Parameter

#: Smoothing speed of the friction sign function sgn(w) = tanh(w / EPS_SPEED) [rad/s].
EPS_SPEED = 0.01
#: Reference temperature of the fitted torque constant [degC].
T_REF = 20.0
#: Share of rows a Stribeck speed needs within twice itself to be searched. Calibrated on
#: test_logs::test_a_table_of_26_operating_points_and_a_burst_written_16_times_are_read and
#: test_diagnose::test_each_hidden_effect_is_named_first_and_adding_it_reaches_the_noise.
STRIBECK_SEEN = 0.02
#: Samples the acceleration is averaged over (odd, centred): enough to tame the differentiated speed noise, short
#: against a speed change of a rig (tens of samples). Calibrated on
#: test_diagnose::test_each_hidden_effect_is_named_first_and_adding_it_reaches_the_noise.
ACCELERATION_ROWS = 5

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Signals:
    """Input channels of the model, SI (temperature in degC). Optional channels may be None."""

    time: Array
    """Sample times [s]."""
    current: Array
    """Motor current [A]."""
    velocity: Array | None = None
    """Rotor speed [rad/s]."""
    position: Array | None = None
    """Rotor angle [rad]."""
    temperature: Array | None = None
    """Winding temperature [degC]."""
    timed: bool = True
    """Whether ``time`` holds real sample times; False for a steady-state table (``time`` is the row index)."""

    @classmethod
    def from_log(cls, log: Any) -> Signals:
        """Take the channels from a :class:`hound_id.dyno.logs.DynoLog` (or anything with those attributes)."""
        return cls(
            time=np.asarray(log.time, float),
            current=np.asarray(log.current, float),
            velocity=None if log.velocity is None else np.asarray(log.velocity, float),
            position=None if log.position is None else np.asarray(log.position, float),
            temperature=None if log.temperature is None else np.asarray(log.temperature, float),
            timed=bool(getattr(log, "timed", True)),
        )

    @cached_property
    def acceleration(self) -> Array:
        """d velocity / dt [rad/s^2]: central differences over the sample times, averaged over
        :data:`ACCELERATION_ROWS` samples (a derivative amplifies the speed channel's noise)."""
        w = self.channel("velocity")
        if w.size < 3:
            return np.zeros_like(w)
        a = np.gradient(w, self.time)
        k = min(ACCELERATION_ROWS, a.size)
        return np.convolve(np.pad(a, (k // 2, k - 1 - k // 2), mode="edge"), np.full(k, 1.0 / k), mode="valid")

    @cached_property
    def velocity_sign(self) -> Array:
        """sgn(velocity) = tanh(velocity / EPS_SPEED), computed once per signals object."""
        return sgn(self.channel("velocity"))

    def channel(self, name: str) -> Array:
        """A channel that must exist (callers check :attr:`Effect.requires` first)."""
        value = getattr(self, name)
        if value is None:
            raise FitError(f"channel '{name}' is not in the log")
        return value  # type: ignore[no-any-return]

    def has(self, name: str) -> bool:
        """Whether a channel is present (``time`` only when the log has real sample times)."""
        if name == "time":
            return self.timed
        return getattr(self, name) is not None

    def take(self, rows: NDArray[np.bool_] | NDArray[np.intp] | slice) -> Signals:
        """The same signals restricted to some rows."""
        values: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            values[f.name] = v if f.name == "timed" or v is None else v[rows]
        return Signals(**values)

    def shifted(
        self, delay: float, rows: NDArray[np.intp] | None = None, channels: Sequence[str] | None = None
    ) -> Signals:
        """Every channel as it was ``delay`` seconds earlier (linear interpolation; held at the ends).

        With ``rows``, only those samples are produced (interpolated from the full record);
        with ``channels``, only those channels (and current) are kept.
        """
        keep = ("current", "velocity", "position", "temperature") if channels is None else ("current", *channels)
        if delay == 0.0 and channels is None:
            return self if rows is None else self.take(rows)
        times = self.time if rows is None else self.time[rows]
        t = times - delay
        out: dict[str, Any] = {"time": times, "timed": self.timed}
        for name in ("current", "velocity", "position", "temperature"):
            value = getattr(self, name)
            if value is None or name not in keep:
                out[name] = None
            elif delay == 0.0:
                out[name] = value if rows is None else value[rows]
            else:
                out[name] = np.interp(t, self.time, value)
        return Signals(**out)


@dataclass(frozen=True)
class Hyper:
    """A nonlinear parameter found by search."""

    name: str
    """Unique name, e.g. ``stribeck_speed``."""
    unit: str
    """SI unit."""
    candidates: Callable[[Signals, Array], Array]
    """Candidate values to search, from the signals and the current residual."""
    integer: bool = False
    """Whether the value is an integer (an order per revolution)."""
    refine: bool = True
    """Whether to refine the best candidate by a bounded scalar search."""


@dataclass(frozen=True)
class Effect:
    """A named physical term of the torque model."""

    name: str
    """Name used on the command line (``--add NAME``)."""
    physics: str
    """One sentence of physics."""
    parameters: tuple[Parameter, ...]
    """Linear parameters, one per regressor column."""
    regressors: Callable[[Signals, Mapping[str, float]], Array] | None
    """Columns (n, len(parameters)) from the signals and the hyper values; None for ``delay``."""
    requires: tuple[str, ...] = ()
    """Channels needed besides time and current."""
    hypers: tuple[Hyper, ...] = ()
    """Nonlinear parameters."""
    shape: bool = False
    """True for terms of the current-torque curve itself (used for the peak torque and compensation)."""
    evidence: Callable[[Mapping[str, float], Signals], str] | None = None
    """Sentence describing what the fitted term shows in the data, from its fitted values."""
    friction: str | None = None
    """The friction term of :data:`hound_id.mor.friction.TERMS` that carries the fitted values to the bundle, the
    runtime and the exports (each export holds it or states what it loses); None for an effect that is not motor
    friction."""
    trainer: str = ""
    """For an effect without a friction term: how a trainer feels it, or why it does not (one sentence)."""

    def columns(self, signals: Signals, hypers: Mapping[str, float]) -> Array:
        """Regressor matrix (n, k) of this effect."""
        n = signals.current.shape[0]
        if self.regressors is None:
            return np.empty((n, 0))
        try:
            cols = np.asarray(self.regressors(signals, hypers), dtype=float)
        except FitError:
            raise
        except Exception as err:  # a user's effect: report it, do not crash
            if self.name in BUILTIN:
                raise
            raise FitError(f"effect '{self.name}': its regressors failed ({type(err).__name__}: {err})") from err
        if cols.ndim == 1:
            cols = cols[:, None]
        if cols.shape != (n, len(self.parameters)):
            raise FitError(
                f"effect '{self.name}': regressors returned shape {cols.shape}, expected ({n}, {len(self.parameters)})"
                " (one column per parameter)"
            )
        if not np.all(np.isfinite(cols)):
            raise FitError(f"effect '{self.name}': regressors returned non-finite values")
        return cols


REGISTRY: dict[str, Effect] = {}


def register(effect: Effect, *, replace: bool = False) -> Effect:
    """Add an effect to the library (kept sorted by name). Parameter names must be unique."""
    if effect.name in REGISTRY and not replace:
        raise FitError(f"effect '{effect.name}' is already registered; pick another name or pass replace=True")

    def names(e: Effect) -> list[str]:
        return [p.name for p in e.parameters] + [h.name for h in e.hypers]

    taken = {n: e.name for e in REGISTRY.values() if e.name != effect.name for n in names(e)}
    for name in names(effect):
        if name in taken:
            raise FitError(f"effect '{effect.name}': parameter '{name}' is already used by effect '{taken[name]}'")
    REGISTRY[effect.name] = effect
    for key in sorted(REGISTRY):
        REGISTRY[key] = REGISTRY.pop(key)
    return effect


def get(name: str) -> Effect:
    """The registered effect of that name."""
    try:
        return REGISTRY[name]
    except KeyError:
        raise FitError(f"unknown effect '{name}'; known effects: {', '.join(REGISTRY)}", effect=name) from None


def parse_model(text: str) -> tuple[str, ...]:
    """``"linear+saturation+coulomb"`` -> the effect names, checked against the registry."""
    names = tuple(part.strip() for part in text.split("+") if part.strip())
    if not names:
        raise FitError(f"model '{text}' names no effect; write e.g. linear+saturation")
    for name in names:
        get(name)
    if len(set(names)) != len(names):
        raise FitError(f"model '{text}' names an effect twice")
    return names


def parse_start_model(text: str) -> tuple[str, ...]:
    """The ``--model`` a fit starts from: :func:`parse_model`, and it holds ``linear`` (Kt, which every report,
    the fitted spec and the peak torque are built on; the other effects bend the line, none replaces it)."""
    names = parse_model(text)
    if "linear" not in names:
        raise FitError(
            f"--model {text}: every model holds 'linear' (torque = Kt i; the other effects bend that line); "
            f"write linear+{'+'.join(names)}",
            model=text,
        )
    return names


def load_effects_file(path: str | Path) -> list[str]:
    """Import a user's Python file that calls :func:`register`; returns the names it added.

    The file is executed as Python with the user's rights, like any import: load only files
    you trust.
    """
    p = Path(path)
    check_input(p, "Python effects", FitError, TEXT_MAX_BYTES)
    before = set(REGISTRY)
    spec = importlib.util.spec_from_file_location(f"hound_id_user_effects_{p.stem}", p)
    if spec is None or spec.loader is None:
        raise FitError(f"{p}: cannot import as a Python file")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except FitError as err:
        raise FitError(f"{p}: {err}") from err
    except SystemExit as err:  # sys.exit() or exit() in the file must not end hound-id silently
        raise FitError(
            f"{p}: the effects file called exit ({err.code!r}) while it was imported; remove the call"
        ) from err
    except Exception as err:  # a user's file: report, do not crash
        raise FitError(f"{p}: importing it failed ({type(err).__name__}: {err})") from err
    added = sorted(set(REGISTRY) - before)
    if not added:
        raise FitError(f"{p}: registered no effect; call hound_id.dyno.current.effects.register(Effect(...)) in it")
    return added


# ---------------------------------------------------------------------------------------------
# Helpers for the built-in effects


def sgn(w: Array) -> Array:
    """Smoothed sign of a speed, tanh(w / EPS_SPEED)."""
    return np.tanh(w / EPS_SPEED)  # type: ignore[no-any-return]


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


# ---------------------------------------------------------------------------------------------
# Built-in effects


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


def _builtin() -> None:
    sat_doc = "magnetic saturation: the core's flux saturates and torque per amp falls at high current"
    register(
        Effect(
            name="linear",
            physics="torque is proportional to current through the torque constant Kt",
            parameters=(
                Parameter("kt", "N m/A", "torque constant at 20 degC", 0.0, bound_reason="torque follows current"),
            ),
            regressors=lambda s, h: s.current,
            shape=True,
            evidence=_evidence_linear,
            trainer=_CURVE_TRAINER,
        )
    )
    register(
        Effect(
            name="saturation",
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
            physics="dry friction opposes motion with a constant torque whatever the speed",
            parameters=(Parameter("coulomb", "N m", "Coulomb friction torque", 0.0, bound_reason=_FRICTION_BOUND),),
            regressors=lambda s, h: -s.velocity_sign,
            requires=("velocity",),
            evidence=_evidence_coulomb,
            friction="coulomb",
        )
    )
    register(
        Effect(
            name="viscous",
            physics="viscous and eddy-current drag grow in proportion to speed",
            parameters=(
                Parameter("viscous", "N m s/rad", "viscous friction coefficient", 0.0, bound_reason=_FRICTION_BOUND),
            ),
            regressors=lambda s, h: -s.channel("velocity"),
            requires=("velocity",),
            evidence=_evidence_viscous,
            friction="viscous",
        )
    )
    register(
        Effect(
            name="stribeck",
            physics="static friction exceeds Coulomb friction near rest and fades as speed builds a lubricant film",
            parameters=(
                Parameter("stribeck", "N m", "extra static friction at rest", 0.0, bound_reason=_FRICTION_BOUND),
            ),
            regressors=lambda s, h: -s.velocity_sign * np.exp(-((s.channel("velocity") / h["stribeck_speed"]) ** 2)),
            requires=("velocity",),
            hypers=(Hyper("stribeck_speed", "rad/s", _speed_grid),),
            evidence=_evidence_stribeck,
            friction="stribeck",
        )
    )
    register(
        Effect(
            name="gear_friction",
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
            evidence=_evidence_delay,
            trainer="a lag between the log's channels, not the drive's command-to-torque latency: none is set",
        )
    )


BUILTIN: tuple[str, ...] = ()
_builtin()
BUILTIN = tuple(REGISTRY)


def requirements_missing(effect: Effect, signals: Signals) -> list[str]:
    """Channels an effect needs that the signals lack."""
    return [c for c in effect.requires if not signals.has(c)]


def describe(names: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """JSON-ready description of effects (all by default)."""
    out = []
    for name in names or REGISTRY:
        e = get(name)
        out.append(
            {
                "effect": e.name,
                "physics": e.physics,
                "parameters": [
                    {
                        "name": p.name,
                        "unit": p.unit,
                        "doc": p.doc,
                        "lower": None if math.isinf(p.lower) else p.lower,
                        "upper": None if math.isinf(p.upper) else p.upper,
                    }
                    for p in e.parameters
                ],
                "hypers": [{"name": h.name, "unit": h.unit} for h in e.hypers],
                "requires": list(e.requires),
            }
        )
    return out


__all__ = [
    "BUILTIN",
    "EPS_SPEED",
    "Effect",
    "Hyper",
    "Parameter",
    "REGISTRY",
    "Signals",
    "T_REF",
    "describe",
    "get",
    "load_effects_file",
    "parse_model",
    "parse_start_model",
    "register",
    "requirements_missing",
    "sgn",
]
