"""The fleet report: one row per actuator, the fleet's median and robust spread, and the outliers.

Every actuator's log is fitted by ``fit-current`` with the same model and options (see
:mod:`hound_id.dyno.fleet.engine`); this module only reads the fit reports (schema
``hound-id/fit/3``). Pure functions, no engine, no printing.

**Outliers.** For each quantity of :func:`metrics`, over the actuators where the log identifies it:
the fleet's median m and its robust spread s = 1.4826 MAD (the standard deviation for a normal
fleet, untouched by up to half the fleet being faulty). An actuator with value x and standard
error e is flagged when both hold:

* ``|x - m| > z sqrt(s^2 + e^2)`` (``z`` = :data:`Z_THRESHOLD`, the modified z-score limit of
  Iglewicz and Hoaglin), so neither the fleet's scatter nor the log's own noise flags it; and
* ``|x - m| > tolerance |m|``: the least difference that matters physically (:class:`Metric`),
  so a fleet of near-identical motors, whose spread is tiny, does not flag a healthy one.

Friction, cogging and the noise floor are flagged only when high (low friction is no fault);
Kt and the peak torque both ways. The cogging order is compared with the fleet's most common
order, and the verdict (at the noise floor or not) with the fleet's majority. With fewer than
:data:`MIN_FLEET` identified values, nothing is flagged: five values cannot show an outlier.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

from hound_id.dyno.current.effect import FleetMetric
from hound_id.dyno.fleet.scale import ScaleGroup, scale_groups, sentence
from hound_id.errors import FleetError

if TYPE_CHECKING:
    from hound_id.dyno.current.fit_report import FitReport

#: /2: ``engine`` has ``workers_asked`` and ``capped`` (a local cluster's worker count capped at the usable CPUs and
#: the logs).
SCHEMA = "hound-id/fleet/2"

#: Modified z-score above which a value is an outlier (Iglewicz and Hoaglin, 1993).
Z_THRESHOLD = 3.5
#: Chance that any healthy actuator of a normal fleet passes the z limit: the limit grows with the fleet.
FAMILY_ALPHA = 0.01
#: MAD -> standard deviation for a normal population.
MAD_TO_SIGMA = 1.4826
#: Fewest actuators with an identified value for that value to be judged.
MIN_FLEET = 5
#: A cogging amplitude below this many standard errors is noise: its order is not identified.
COGGING_SIGNIFICANCE = 4.0


#: A quantity the fleet is compared on: declared by an effect (:attr:`Effect.fleet
#: <hound_id.dyno.current.effect.Effect.fleet>`), or by the fleet for the quantities of the whole fit below.
Metric = FleetMetric

PEAK_LOW = "peak torque low: the core saturates early (another stator or lamination)"

#: The quantities of the whole fit, which no one effect owns. Tolerances are assumptions, not measured fleet data
#: (the effects' own, in :mod:`hound_id.dyno.current.effects`, likewise): peak torque 10 % (it goes with Kt squared
#: over the saturation), the noise floor a factor 2.
FIT_METRICS: tuple[Metric, ...] = (
    Metric(
        "peak_torque",
        "peak torque",
        "peak",
        "N m",
        "both",
        0.10,
        rank=10,
        low=PEAK_LOW,
        high="peak torque high: a stronger motor than the fleet's: check the part",
    ),
    Metric(
        "noise_floor",
        "noise floor",
        "noise",
        "N m",
        "high",
        1.0,
        rank=100,
        high="noise floor high: the measurement (a loose coupling, a noisy transducer or cable), not the motor",
    ),
)


def metrics() -> tuple[Metric, ...]:
    """Every quantity the fleet is compared on, in table order (:attr:`FleetMetric.rank`): the registered effects'
    (a user's effects file included) and the whole fit's."""
    from hound_id.dyno.current.effects import REGISTRY

    declared = [m for e in REGISTRY.values() for m in e.fleet]
    return tuple(sorted((*declared, *FIT_METRICS), key=lambda m: m.rank))


def metric_keys() -> tuple[str, ...]:
    """The keys of :func:`metrics`, in table order."""
    return tuple(m.key for m in metrics())


@dataclass(frozen=True)
class ActuatorFit:
    """One actuator's log after ``fit-current``: its report, or why it failed."""

    name: str
    """The actuator's name (the log's file name without its suffix, or its path when names repeat)."""
    source: str
    """The log as given."""
    report: FitReport | None
    """The fit's report (``fit-current --json`` prints its JSON); None when it failed."""
    error: str | None = None
    """Why it failed: the one-line message ``fit-current`` gives."""
    bug: bool = False
    """The failure was not a bad input but a fault in hound-id (the error holds the traceback)."""
    seconds: float = math.nan
    """Time spent fitting it on its worker [s]."""
    worker: str = ""
    """The worker that fitted it."""
    version: str = ""
    """The hound-id version on that worker."""

    @property
    def ok(self) -> bool:
        """True when the log was fitted."""
        return self.report is not None


@dataclass(frozen=True)
class Value:
    """One quantity of one actuator."""

    value: float | None
    """The estimate (SI), None when the log does not identify it."""
    stderr: float | None
    """Its standard error (None when the fit gives none: the peak torque, the noise floor)."""
    why: str = ""
    """Why it is not identified, or what qualifies it (extrapolated)."""

    @property
    def identified(self) -> bool:
        """True when the value can be compared with the fleet's."""
        return self.value is not None


@dataclass(frozen=True)
class Stats:
    """The fleet's centre and spread of one quantity."""

    metric: Metric
    """The quantity."""
    n: int
    """Actuators where it is identified."""
    median: float | None
    """The fleet's median (None with no value)."""
    spread: float | None
    """Robust spread, 1.4826 MAD (None with no value)."""
    judged: bool
    """False with fewer than :data:`MIN_FLEET` values: no outlier is flagged."""
    z: float = Z_THRESHOLD
    """The z limit applied (:func:`z_limit` of the requested one and ``n``)."""

    def limits(self) -> tuple[float, float] | None:
        """The values beyond which an exact value (stderr 0) is flagged: (low, high)."""
        if self.median is None or self.spread is None:
            return None
        reach = max(self.z * self.spread, self.metric.tolerance * abs(self.median))
        return self.median - reach, self.median + reach


@dataclass(frozen=True)
class Flag:
    """An outlier: one actuator, one quantity, what it means."""

    actuator: str
    """The actuator's name."""
    metric: str
    """The quantity's key (``cogging_order`` and ``verdict`` too)."""
    value: Any
    """Its value (SI)."""
    fleet: Any
    """The fleet's median (or most common order / verdict)."""
    z: float | None
    """Deviation in combined standard deviations (None for orders and verdicts)."""
    reading: str
    """The physical reading."""
    trusted: bool = True
    """False when the actuator's own fit is flagged: the log may be the cause before the motor."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "actuator": self.actuator,
            "metric": self.metric,
            "value": self.value,
            "fleet": self.fleet,
            "z": self.z,
            "reading": self.reading,
            "trusted": self.trusted,
        }


@dataclass(frozen=True)
class FleetReport:
    """The fleet: each actuator's values, the fleet's statistics and the outliers."""

    actuators: tuple[ActuatorFit, ...]
    """Every log, fitted or failed, in name order."""
    values: Mapping[str, Mapping[str, Value]]
    """Actuator name -> metric key -> value (fitted actuators only)."""
    cogging_order: Mapping[str, float | None]
    """Actuator name -> its cogging order [1/rev] (None: not identified)."""
    stats: tuple[Stats, ...]
    """One per metric in the common model."""
    fleet_order: float | None
    """The fleet's most common cogging order (None when none is identified)."""
    flags: tuple[Flag, ...]
    """The outliers."""
    model: tuple[str, ...]
    """The effects every actuator was fitted with."""
    z: float = Z_THRESHOLD
    """The z-score limit used."""
    notes: tuple[str, ...] = field(default=())
    """What the fleet cannot show, and why."""
    scale_groups: tuple[ScaleGroup, ...] = field(default=())
    """Groups of logs whose Kt differ by a fixed ratio (another current scale), when the fleet has two or more."""

    @property
    def fitted(self) -> tuple[ActuatorFit, ...]:
        return tuple(a for a in self.actuators if a.ok)

    @property
    def failed(self) -> tuple[ActuatorFit, ...]:
        return tuple(a for a in self.actuators if not a.ok)

    def flags_of(self, name: str) -> tuple[Flag, ...]:
        return tuple(f for f in self.flags if f.actuator == name)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready report, schema ``hound-id/fleet/2`` (SI units)."""
        rows = []
        for a in self.actuators:
            row: dict[str, Any] = {"name": a.name, "source": a.source, "ok": a.ok, "seconds": _num(a.seconds)}
            if a.ok:
                assert a.report is not None
                row["values"] = {
                    k: {"value": v.value, "stderr": v.stderr, "note": v.why or None}
                    for k, v in self.values[a.name].items()
                }
                row["cogging_order"] = self.cogging_order.get(a.name)
                row["rmse_test"] = a.report.rmse_test
                row["at_noise_floor"] = a.report.at_noise_floor
                row["verdict"] = a.report.summary
                row["warnings"] = list(a.report.warnings)
                row["flags"] = [f.to_dict() for f in self.flags_of(a.name)]
            else:
                row["error"] = a.error
                row["bug"] = a.bug
            rows.append(row)
        return {
            "schema": SCHEMA,
            "model": list(self.model),
            "actuators": rows,
            "fleet": {
                s.metric.key: {
                    "label": s.metric.label,
                    "unit": s.metric.unit,
                    "n": s.n,
                    "median": s.median,
                    "spread": s.spread,
                    "judged": s.judged,
                    "flag_side": s.metric.side,
                    "tolerance": s.metric.tolerance,
                    "z_limit": s.z,
                    "limits": list(lim) if (lim := s.limits()) is not None else None,
                }
                for s in self.stats
            },
            "cogging_order": self.fleet_order,
            "flags": [f.to_dict() for f in self.flags],
            "fitted": len(self.fitted),
            "failed": [{"name": a.name, "source": a.source, "error": a.error, "bug": a.bug} for a in self.failed],
            "z_threshold": self.z,
            "notes": list(self.notes),
            "scale_groups": [
                {
                    "members": list(g.members),
                    "kt": g.kt,
                    "ratio": g.ratio,
                    "reading": g.reading or None,
                    "current_range": g.current_range,
                }
                for g in self.scale_groups
            ],
            "units": {s.metric.key: s.metric.unit for s in self.stats},
        }

    def table(self) -> tuple[list[str], list[list[Any]]]:
        """The CSV: a header (units in brackets, as hound-id reads them) and one row per actuator."""
        keys = [s.metric.key for s in self.stats]
        header = ["actuator", "source", "status"]
        for s in self.stats:
            unit = s.metric.unit.replace(" ", "*")
            header += [f"{s.metric.key}[{unit}]", f"{s.metric.key}_stderr[{unit}]"]
        header += ["cogging_order[1/rev]", "rmse_test[N*m]", "at_noise_floor", "flags", "verdict_or_error"]
        rows = []
        for a in self.actuators:
            if not a.ok:
                rows.append([a.name, a.source, "failed", *([""] * (2 * len(keys) + 4)), a.error])
                continue
            assert a.report is not None
            cells: list[Any] = [a.name, a.source, "flagged" if self.flags_of(a.name) else "ok"]
            for k in keys:
                v = self.values[a.name][k]
                cells += ["" if v.value is None else v.value, "" if v.value is None or v.stderr is None else v.stderr]
            order = self.cogging_order.get(a.name)
            cells += [
                "" if order is None else order,
                a.report.rmse_test,
                a.report.at_noise_floor,
                "; ".join(f.reading for f in self.flags_of(a.name)),
                a.report.summary,
            ]
            rows.append(cells)
        return header, rows


def _num(x: float) -> float | None:
    """A JSON-safe number: None for NaN and infinity (a deviation where the fleet's spread is 0)."""
    return None if x is None or not math.isfinite(x) else float(x)


def _parameter(report: FitReport, name: str) -> Value:
    p = report.parameters.get(name)
    if p is None:
        return Value(None, None, "not in the model")
    if p.at_bound:
        return Value(None, None, f"held at its physical bound {p.value:.4g}: the log cannot show it")
    if not math.isfinite(p.stderr):
        return Value(None, None, "no standard error: the log cannot separate it from another term")
    return Value(float(p.value), float(p.stderr))


def _amplitude(report: FitReport, metric: Metric) -> tuple[Value, float | None]:
    """Amplitude of harmonics (root-sum-square) with its propagated error, and their order when the amplitude is
    significant (None: not identified)."""
    params = report.parameters
    if not all(n in params for n in metric.parameters):
        return Value(None, None, "not in the model"), None
    values = [float(params[n].value) for n in metric.parameters]
    errors = [params[n].stderr for n in metric.parameters]
    if any(not math.isfinite(e) for e in errors):
        return Value(None, None, "no standard error"), None
    amplitude = math.sqrt(sum(v * v for v in values))
    if amplitude == 0.0:
        return Value(0.0, math.sqrt(sum(e * e for e in errors) / len(errors))), None
    stderr = math.sqrt(sum((v / amplitude) ** 2 * e * e for v, e in zip(values, errors, strict=True)))
    order = params[metric.order].value if metric.order is not None and metric.order in params else None
    significant = amplitude > COGGING_SIGNIFICANCE * stderr
    return Value(amplitude, stderr), (float(order) if order is not None and significant else None)


def _peak(report: FitReport) -> Value:
    peak = report.peak
    if peak.at_least is not None:
        return Value(None, None, "no saturation seen: only a bound")
    if peak.torque is None:
        return Value(None, None, "not reached by the fitted curve")
    if peak.extrapolated:  # beyond the measured current: the fit's shape, not what the log shows
        return Value(None, None, "extrapolated beyond the measured current: not judged")
    return Value(float(peak.torque), None)


def values_of(report: FitReport, compared: Sequence[Metric] | None = None) -> tuple[dict[str, Value], float | None]:
    """Every metric (default :func:`metrics`) of one fit report, and the order of its harmonics (the cogging order;
    None: not identified)."""
    out: dict[str, Value] = {}
    order: float | None = None
    for metric in metrics() if compared is None else compared:
        if metric.key == "peak_torque":
            out[metric.key] = _peak(report)
        elif metric.key == "noise_floor":
            out[metric.key] = Value(float(report.noise_floor), None)
        elif len(metric.parameters) == 1:
            out[metric.key] = _parameter(report, metric.parameters[0])
        else:
            out[metric.key], found = _amplitude(report, metric)
            order = found if found is not None else order
    return out, order


def parse_tolerances(text: str | Mapping[str, float] | None) -> dict[str, float]:
    """``kt=0.05,coulomb=1`` -> {metric: fraction}; every key must be a metric, every value >= 0."""
    if text is None:
        return {}
    if isinstance(text, Mapping):
        items = [(k, str(v)) for k, v in text.items()]
    else:
        items = []
        for part in (p.strip() for p in text.split(",") if p.strip()):
            key, sep, value = part.partition("=")
            if not sep:
                raise FleetError(f"--tolerance: found {part!r}, expected METRIC=FRACTION (kt=0.05)")
            items.append((key.strip(), value.strip()))
    out = {}
    for key, value in items:
        if key not in (keys := metric_keys()):
            raise FleetError(f"--tolerance: unknown metric {key!r}; expected one of {', '.join(keys)}")
        try:
            fraction = float(value)
        except ValueError:
            fraction = math.nan
        if not math.isfinite(fraction) or fraction < 0:
            raise FleetError(f"--tolerance {key}: found {value!r}, expected a fraction >= 0 (0.05 for 5 %)")
        out[key] = fraction
    return out


def z_limit(z: float, n: int) -> float:
    """The z limit for ``n`` values: ``z``, or more, so that a normal fleet of ``n`` flags none with chance 99 %.

    Bonferroni over the fleet, two-sided: Phi^-1(1 - FAMILY_ALPHA / (2 n)); 3.5 up to 21 actuators, 4.06 at 200.
    """
    from statistics import NormalDist

    return max(z, NormalDist().inv_cdf(1.0 - FAMILY_ALPHA / (2 * max(n, 1))))


def check_z(z: float) -> None:
    """Raise :class:`FleetError` unless ``z`` is a positive finite number."""
    if not (z > 0 and math.isfinite(z)):
        raise FleetError(f"--z: found {z}, expected a positive number (3.5 is the usual outlier limit)")


def _median(xs: Sequence[float]) -> float:
    s = sorted(xs)
    n = len(s)
    return s[n // 2] if n % 2 else 0.5 * (s[n // 2 - 1] + s[n // 2])


def analyse(
    actuators: Sequence[ActuatorFit],
    z: float = Z_THRESHOLD,
    tolerances: Mapping[str, float] | None = None,
    model: Sequence[str] | None = None,
) -> FleetReport:
    """Compare every fitted actuator with the fleet and flag the outliers with their physical reading.

    Args:
        actuators: Every log's outcome (failed ones are listed, not compared).
        z: Modified z-score limit.
        tolerances: Metric key -> least relative difference flagged, overriding :func:`metrics`' own.
        model: The fleet's model in the order to report it (default: the first fitted log's).

    Raises:
        FleetError: ``z`` is not positive, or the fitted logs were fitted with different models.
    """
    check_z(z)
    compared = [replace(m, tolerance=(tolerances or {}).get(m.key, m.tolerance)) for m in metrics()]
    ordered = tuple(sorted(actuators, key=lambda a: a.name))
    fitted = [a for a in ordered if a.report is not None]
    reports = {a.name: a.report for a in fitted if a.report is not None}
    model = _fleet_model(list(reports.values()), model)
    values: dict[str, dict[str, Value]] = {}
    orders: dict[str, float | None] = {}
    for name, report in reports.items():
        values[name], orders[name] = values_of(report, compared)
    notes: list[str] = []
    kts = {n: v["kt"].value for n, v in values.items() if v["kt"].value is not None}
    groups = scale_groups(kts, {n: r.current_range for n, r in reports.items()})
    ratio = {n: g.ratio for g in groups for n in g.members}
    if groups:
        notes.append(sentence(groups))
    stats, flags = [], []
    for metric in compared:
        present = {n: v[metric.key] for n, v in values.items()}
        if metric.per_amp and ratio:  # within its current-scale group: divided by the group's ratio
            present = {n: _scaled(v, ratio.get(n, 1.0)) for n, v in present.items()}
        if present and all(v.why == "not in the model" for v in present.values()):
            continue  # a friction or cogging term the fleet's model does not have
        st, found = _judge(metric, present, z, ratio)
        stats.append(st)
        flags += found
        if not st.judged and fitted:
            notes.append(
                f"{metric.label}: identified on {st.n} actuators; fewer than {MIN_FLEET} cannot show an "
                "outlier, so none is flagged"
            )
    flags = _peak_follows_kt(flags)
    notes += _fleet_notes(stats, z, fitted)
    fleet_order = _fleet_order(orders, notes)
    flags += _order_flags(orders, fleet_order)
    flags += _verdict_flags(fitted)
    flags = [_qualified(f, reports[f.actuator]) for f in flags]
    columns = [m.key for m in compared]
    flags.sort(key=lambda f: (f.actuator, columns.index(f.metric) if f.metric in columns else len(columns)))
    return FleetReport(
        actuators=ordered,
        values=values,
        cogging_order=orders,
        stats=tuple(stats),
        fleet_order=fleet_order,
        flags=tuple(flags),
        model=tuple(model),
        z=z,
        notes=tuple(notes),
        scale_groups=groups,
    )


def _fleet_model(reports: Sequence[FitReport], model: Sequence[str] | None) -> tuple[str, ...]:
    """The one model every fit used, in ``model``'s order when given (FleetError when the fits differ or it does)."""
    models = {frozenset(r.model): tuple(r.model) for r in reports}
    if len(models) > 1:
        raise FleetError(
            "the logs were fitted with different models ("
            + "; ".join(sorted("+".join(m) for m in models.values()))
            + "): a fleet is compared on one model"
        )
    common = next(iter(models.values()), ())
    if model is not None and reports and set(model) != set(common):
        raise FleetError(f"the logs were fitted with {'+'.join(common)}, not the model given ({'+'.join(model)})")
    return tuple(model) if model is not None else common


def _judge(
    metric: Metric, present: Mapping[str, Value], z: float, ratio: Mapping[str, float]
) -> tuple[Stats, list[Flag]]:
    """One metric over the fleet: its median, robust spread and z limit, and the actuators past both the limit and
    the metric's tolerance, on its faulty side (none when fewer than :data:`MIN_FLEET` values are known)."""
    known = {n: v for n, v in present.items() if v.value is not None}
    xs = [v.value for v in known.values() if v.value is not None]
    median = _median(xs) if xs else None
    spread = MAD_TO_SIGMA * _median([abs(x - median) for x in xs]) if median is not None else None
    judged = len(xs) >= MIN_FLEET
    limit = z_limit(z, len(xs))
    st = Stats(metric, len(xs), median, spread, judged, limit)
    if not judged:
        return st, []
    assert median is not None and spread is not None
    flags = []
    for name, v in known.items():
        assert v.value is not None
        dev = v.value - median
        side = "high" if dev > 0 else "low"
        if metric.side not in ("both", side):
            continue
        scale = math.hypot(spread, v.stderr or 0.0)
        zscore = abs(dev) / scale if scale > 0 else math.inf
        if zscore > limit and abs(dev) > metric.tolerance * abs(median):
            reading = metric.high if side == "high" else metric.low
            scaled = metric.per_amp and ratio.get(name, 1.0) != 1.0
            against = "its current-scale group's median" if scaled else "the fleet's median"
            percent = f"{dev / median:+.0%} against {against}" if median else ""
            reading = f"{reading} ({percent})" if percent else reading
            flags.append(Flag(name, metric.key, v.value, median, _num(zscore), reading))
    return st, flags


def _peak_follows_kt(flags: Sequence[Flag]) -> list[Flag]:
    """A low peak torque on an actuator whose Kt is flagged low is read as following it."""
    low_kt = {f.actuator for f in flags if f.metric == "kt" and f.value < f.fleet}
    return [
        replace(f, reading=f.reading.replace(PEAK_LOW, "peak torque low: it follows the low Kt"))
        if f.metric == "peak_torque" and f.actuator in low_kt
        else f
        for f in flags
    ]


def _fleet_notes(stats: Sequence[Stats], z: float, fitted: Sequence[ActuatorFit]) -> list[str]:
    """What the user must know of the comparison itself: a z limit raised for the fleet's size, and a model that
    most fits find short."""
    notes = []
    raised = sorted({round(st.z, 2) for st in stats if st.judged and st.z > z})
    if raised:
        notes.append(
            f"the z limit used is {', '.join(f'{r:g}' for r in raised)}, above the {z:g} asked for: with this many "
            "actuators a lower limit would flag a healthy fleet with chance above 1 %"
        )
    missing = [a for a in fitted if a.report is not None and not a.report.at_noise_floor]
    if fitted and 2 * len(missing) > len(fitted):
        notes.append(
            f"{len(missing)} of {len(fitted)} fits are not at their noise floor: the model misses effects the logs "
            "show, so faults in those effects cannot be flagged; run again with --auto or a fuller --model"
        )
    return notes


def _order_flags(orders: Mapping[str, float | None], fleet_order: float | None) -> list[Flag]:
    """Actuators whose identified cogging order is not the fleet's: another motor."""
    if fleet_order is None:
        return []
    return [
        Flag(
            name,
            "cogging_order",
            order,
            fleet_order,
            None,
            f"cogging order {order:g}/rev against the fleet's {fleet_order:g}/rev: a different motor (another slot "
            "and pole count)",
        )
        for name, order in orders.items()
        if order is not None and order != fleet_order
    ]


def _scaled(v: Value, ratio: float) -> Value:
    """A per-amp value on its current-scale group's reference scale."""
    if v.value is None or ratio == 1.0:
        return v
    return replace(v, value=v.value / ratio, stderr=None if v.stderr is None else v.stderr / ratio)


#: Longest quotation of a log's own flag in a reading [characters].
QUOTE = 160


def _qualified(flag: Flag, report: FitReport) -> Flag:
    """A flag on an actuator whose own fit is flagged says so: the log may explain it before the motor."""
    own = list(report.flags)
    if not own or flag.metric == "verdict":
        return flag
    first = own[0] if len(own[0]) <= QUOTE else own[0][: QUOTE - 3] + "..."
    return replace(
        flag,
        trusted=False,
        reading=f"{flag.reading}; but this log's own fit is flagged ({first}): the log may be the cause before "
        "the motor, check it with fit-current",
    )


def _fleet_order(orders: Mapping[str, float | None], notes: list[str]) -> float | None:
    """The most common identified cogging order, when it is a clear majority of at least MIN_FLEET actuators."""
    found = Counter(o for o in orders.values() if o is not None)
    if not found:
        return None
    (order, count), total = found.most_common(1)[0], sum(found.values())
    if count < MIN_FLEET or 2 * count <= total:
        notes.append(
            f"cogging order: {dict(sorted(found.items()))} (order: actuators); no order is shared by a majority of at "
            f"least {MIN_FLEET}, so none is flagged as different"
        )
        return None
    return order


def _verdict_flags(fitted: Sequence[ActuatorFit]) -> list[Flag]:
    """Actuators whose fit misses an effect while most of the fleet's is at the noise floor."""
    at_floor = [a for a in fitted if a.report is not None and a.report.at_noise_floor]
    if len(fitted) < MIN_FLEET or 2 * len(at_floor) <= len(fitted):
        return []
    out = []
    for a in fitted:
        assert a.report is not None
        if a.report.at_noise_floor:
            continue
        best = next((s.effect for s in a.report.suggestions if s.significant), None)
        missing = f"{best} is significant in its residual" if best else "its residual is above the noise floor"
        out.append(
            Flag(
                a.name,
                "verdict",
                False,
                True,
                None,
                f"its log shows an effect the fleet's model lacks ({missing}): run fit-current --auto on it",
            )
        )
    return out
