"""What an effect of the current-torque model is (:class:`Effect`), the signals it is computed from (:class:`Signals`),
its searched parameters (:class:`Hyper`), and the registry every part of identification walks (:func:`register`,
:func:`get`, :func:`parse_model`, a user's ``--effects-file``). The effects hound-id ships are in
:mod:`hound_id.dyno.current.effects`."""

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

from hound_id.errors import FitError
from hound_id.io import TEXT_MAX_BYTES, check_input
from hound_id.parameter import Parameter

#: Smoothing speed of the friction sign function sgn(w) = tanh(w / EPS_SPEED) [rad/s].
EPS_SPEED = 0.01
#: Reference temperature of the fitted torque constant [degC].
T_REF = 20.0


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


#: The torque offset the identifiability check always allows for, as a partner a parameter cannot be told from.
OFFSET = "a torque offset"


@dataclass(frozen=True)
class FleetMetric:
    """A quantity ``hound-id fleet`` compares across actuators of one type, read from each actuator's fit."""

    key: str
    """Its key in the fleet's table, CSV and JSON (and ``--tolerance KEY=...``)."""
    label: str
    """Its name in tables, plots and readings."""
    short: str
    """Its column heading in the printed fleet table."""
    unit: str
    """SI unit."""
    side: str
    """Which deviations are faults: "both", "high" or "low"."""
    tolerance: float
    """Least relative difference from the fleet's median that is flagged [-] (an assumption; ``--tolerance``)."""
    parameters: tuple[str, ...] = ()
    """Read from: one parameter (its value and standard error; a value at its bound or without a standard error is
    not judged); several, the harmonics of one periodic term (their root-sum-square amplitude, the error
    propagated); none, a quantity of the whole fit the fleet reads itself (the peak torque, the noise floor)."""
    order: str | None = None
    """For harmonics: the parameter holding their order per revolution, compared across the fleet where the
    amplitude is significant (an actuator with another order is another motor)."""
    per_amp: bool = False
    """A quantity per amp of current: compared within a current-scale group (logs on different current scales)."""
    rank: int = 50
    """Its place among the fleet's columns, smaller first: the curve's (Kt 0; the peak torque, read by the fleet, is
    10), friction 20-29, periodic terms 30-39, a user's effect's 50 unless it says, the noise floor last (100)."""
    low: str = ""
    """What a low value means physically."""
    high: str = ""
    """What a high value means physically."""


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
    """Columns (n, len(parameters)) from the signals and the hyper values; None for an effect that adds no column (a
    :attr:`shift` of the inputs, a filter of the torque channel)."""
    requires: tuple[str, ...] = ()
    """Channels needed besides time and current."""
    hypers: tuple[Hyper, ...] = ()
    """Nonlinear parameters."""
    shape: bool = False
    """True for terms of the current-torque curve itself (used for the peak torque and compensation)."""
    shift: bool = False
    """True for a shift of the inputs in time rather than a term: its one hyper d [s] says how much later the torque
    channel reads than the input channels, and every other effect's columns are built from the signals as they were d
    earlier (:meth:`Signals.shifted`, :func:`inputs`). It adds no column (no parameters, no regressors); a model holds
    at most one."""
    evidence: Callable[[Mapping[str, float], Signals], str] | None = None
    """Sentence describing what the fitted term shows in the data, from its fitted values."""
    friction: str | None = None
    """The friction term of :data:`hound_id.mor.friction.TERMS` that carries the fitted values to the bundle, the
    runtime and the exports (each export holds it or states what it loses); None for an effect that is not motor
    friction."""
    trainer: str = ""
    """For an effect without a friction term: how a trainer feels it, or why it does not (one sentence)."""
    unidentified: Callable[[str, Signals], str | None] | None = None
    """Why a log cannot tell this effect's parameter from ``partner`` (another effect's parameter, or
    :data:`OFFSET`), in the log's terms and with what to record instead; None (or a callable returning None) when it
    has no reason of its own: the identifiability check then says their regressors are nearly collinear."""
    fleet: tuple[FleetMetric, ...] = ()
    """What ``hound-id fleet`` compares of it across actuators (none: it is fitted but not compared)."""
    builtin: bool = False
    """True for the effects hound-id ships: a failure of their regressors is a bug and keeps its traceback (a
    user's effect that fails is one FitError line)."""

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
            if self.builtin:
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
    if effect.shift and (effect.parameters or effect.regressors is not None or len(effect.hypers) != 1):
        raise FitError(
            f"effect '{effect.name}': a shift of the inputs has one hyper (the shift [s]) and no parameters or "
            f"regressors; it has {len(effect.parameters)} parameters, {len(effect.hypers)} hypers"
            f"{' and regressors' if effect.regressors is not None else ''}"
        )

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


def shift_of(model: Sequence[str]) -> Effect | None:
    """The model's shift of the inputs (:attr:`Effect.shift`), or None when its inputs are read as logged.

    Raises:
        FitError: The model names more than one shift.
    """
    shifts = [e for e in (get(name) for name in model) if e.shift]
    if len(shifts) > 1:
        raise FitError(
            f"the model names {len(shifts)} shifts of the inputs ({', '.join(e.name for e in shifts)}); keep one",
            effects=[e.name for e in shifts],
        )
    return shifts[0] if shifts else None


def inputs(signals: Signals, model: Sequence[str], hypers: Mapping[str, float]) -> Signals:
    """The signals every column of ``model`` is built from: as they were the model's shift earlier (its hyper's value
    in ``hypers``, 0 if absent), or as logged when the model has no shift."""
    shift = shift_of(model)
    return signals.shifted(0.0 if shift is None else hypers.get(shift.hypers[0].name, 0.0))


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


def sgn(w: Array) -> Array:
    """Smoothed sign of a speed, tanh(w / EPS_SPEED)."""
    return np.tanh(w / EPS_SPEED)  # type: ignore[no-any-return]


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
