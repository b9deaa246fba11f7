"""The fleet plot: one panel per quantity, every actuator a point with its error bar, outliers in red."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from hound_id.dyno.fleet.analyse import FleetReport, Stats

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Actuators beyond this count get no tick label each; only the flagged ones are named.
MAX_TICK_LABELS = 40
#: Longest name on an axis [characters]: longer ones keep their end ("...trial3").
MAX_LABEL = 24
#: Flagged points beyond this count in one panel are not annotated (their tick labels are red).
MAX_ANNOTATIONS = 8
FLAGGED = "#c0392b"
HEALTHY = "#1f4e79"
NOT_IDENTIFIED = "#999999"


def plot_fleet(report: FleetReport) -> Figure:
    """Every compared quantity against the actuators: the fleet's median, its flag limits, the outliers named.

    The shaded band is where a value with no error of its own is not flagged (median +- the larger of z
    robust spreads and the tolerance); error bars are two standard errors. The last panels are the
    cogging order against the fleet's and the verdict: held-out RMSE over the noise floor.
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    names = [a.name for a in report.fitted]
    index = {n: i for i, n in enumerate(names)}
    panels: list[Stats | str] = [*report.stats]
    if any(o is not None for o in report.cogging_order.values()):
        panels.append("cogging_order")
    panels.append("verdict")
    ncols = 2
    nrows = math.ceil(len(panels) / ncols)
    longest = max((len(_short(n)) for n in names), default=0)
    fig = Figure(figsize=(6.5 * ncols, 2.6 * nrows + 0.8 + 0.07 * longest), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, sharex=True)
    flagged = {(f.actuator, f.metric) for f in report.flags}
    for ax, panel in zip(axes.flat, panels, strict=False):
        if isinstance(panel, Stats):
            _metric_panel(ax, report, panel, index, flagged)
        elif panel == "cogging_order":
            _order_panel(ax, report, index, flagged)
        else:
            _verdict_panel(ax, report, index, flagged)
    for ax in list(axes.flat)[len(panels) :]:
        ax.set_visible(False)
    for ax in axes[-1]:
        _ticks(ax, names, {f.actuator for f in report.flags})
    # a hidden panel's row: the panel above it carries the labels
    if len(panels) % ncols:
        _ticks(axes[-2][-1], names, {f.actuator for f in report.flags})
        axes[-2][-1].tick_params(labelbottom=True)
    failed = f", {len(report.failed)} failed" if report.failed else ""
    who = {f.actuator for f in report.flags}
    fig.suptitle(
        f"fleet of {len(report.actuators)} actuators ({len(names)} fitted{failed}), model {'+'.join(report.model)}: "
        f"{len(who)} flagged (red)",
        fontsize=10,
    )
    return fig


def _short(name: str) -> str:
    return name if len(name) <= MAX_LABEL else "..." + name[-(MAX_LABEL - 3) :]


def _ticks(ax: Axes, names: list[str], flagged: set[str]) -> None:
    marks = range(len(names)) if len(names) <= MAX_TICK_LABELS else [i for i, n in enumerate(names) if n in flagged]
    ticks = ax.set_xticks(list(marks), [_short(names[i]) for i in marks], rotation=90, fontsize=7)
    for i, tick in zip(marks, ticks, strict=True):
        if names[i] in flagged:
            tick.label1.set_color(FLAGGED)
    ax.set_xlabel("actuator" if len(names) <= MAX_TICK_LABELS else "actuator (only the flagged ones named)")


def _metric_panel(
    ax: Axes, report: FleetReport, st: Stats, index: dict[str, int], flagged: set[tuple[str, str]]
) -> None:
    m = st.metric
    limits = st.limits()
    if st.median is not None:
        ax.axhline(st.median, color="k", lw=0.8, label=f"median {st.median:.4g}")
    annotate = sum((n, m.key) in flagged for n in index) <= MAX_ANNOTATIONS
    for name, i in index.items():
        v = report.values[name][m.key]
        if v.value is None:
            continue
        bad = (name, m.key) in flagged
        ax.errorbar(
            i,
            v.value,
            yerr=2 * v.stderr if v.stderr else None,
            fmt="o" if not v.why else "^",
            ms=4,
            color=FLAGGED if bad else HEALTHY,
            ecolor="0.4",
            elinewidth=0.8,
        )
        if bad and annotate:
            ax.annotate(
                _short(name), (i, v.value), xytext=(4, 3), textcoords="offset points", fontsize=7, color=FLAGGED
            )
    if limits is not None and st.judged:
        ax.autoscale_view()
        bottom, top = ax.get_ylim()
        bottom, top = (
            min(bottom, limits[0]) if m.side != "high" else bottom,
            max(top, limits[1]) if m.side != "low" else top,
        )
        low = limits[0] if m.side in ("both", "low") else bottom
        high = limits[1] if m.side in ("both", "high") else top
        ax.axhspan(low, high, color="0.88", zorder=0, label="not flagged")
        ax.set_ylim(bottom, top)
    spread = "" if st.spread is None else f", robust spread {st.spread:.2g}"
    judged = "" if st.judged else f" (only {st.n} values: not judged)"
    ax.set_title(f"{m.label} [{m.unit}]{spread}{judged}", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")


def _order_panel(ax: Axes, report: FleetReport, index: dict[str, int], flagged: set[tuple[str, str]]) -> None:
    for name, i in index.items():
        order = report.cogging_order.get(name)
        if order is None:
            ax.plot(i, 0, "x", color=NOT_IDENTIFIED, ms=4)
            continue
        bad = (name, "cogging_order") in flagged
        ax.plot(i, order, "s", ms=4, color=FLAGGED if bad else HEALTHY)
        if bad:
            ax.annotate(_short(name), (i, order), xytext=(4, 3), textcoords="offset points", fontsize=7, color=FLAGGED)
    if report.fleet_order is not None:
        ax.axhline(report.fleet_order, color="k", lw=0.8, label=f"fleet's order {report.fleet_order:g}")
        ax.legend(fontsize=7, loc="best")
    ax.set_title("cogging order [1/rev] (x at 0: not identified)", fontsize=9)
    ax.grid(alpha=0.3)


def _verdict_panel(ax: Axes, report: FleetReport, index: dict[str, int], flagged: set[tuple[str, str]]) -> None:
    for name, i in index.items():
        a = report.fitted[i]
        assert a.report is not None
        floor = a.report.noise_floor
        ratio = a.report.rmse_test / floor if floor > 0 else math.nan
        bad = (name, "verdict") in flagged
        at_floor = a.report.at_noise_floor
        ax.plot(
            i, ratio, "o" if at_floor else "D", ms=4, color=FLAGGED if bad else (HEALTHY if at_floor else "#e67e22")
        )
    ax.axhline(1.0, color="k", lw=0.8, label="the noise floor")
    if ax.get_ylim()[1] > 10:  # logs far above their floor: a log scale keeps the ones near it readable
        ax.set_yscale("log")
    ax.set_title("verdict: held-out RMSE / noise floor (diamond: an effect is missing)", fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
