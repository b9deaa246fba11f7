"""Plots of a current-torque fit (matplotlib, Agg backend; imported only when plotting)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from hound_id.dyno.current.curve import PeakTorque, curve_torque
from hound_id.dyno.current.effects import Signals
from hound_id.dyno.current.fit import FitResult
from hound_id.dyno.current.stats import Array

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from hound_id.dyno.current.diagnose import Diagnosis
    from hound_id.dyno.current.wander import Wander

#: Points drawn per scatter (the log is subsampled evenly beyond this).
MAX_POINTS = 15_000


def _binned(x: Array, y: Array, bins: int = 60) -> tuple[Array, Array]:
    edges = np.linspace(float(np.min(x)), float(np.max(x)), bins + 1)
    if edges[-1] <= edges[0]:
        return np.array([edges[0]]), np.array([float(np.mean(y))])
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, bins - 1)
    count = np.bincount(idx, minlength=bins)
    mean = np.bincount(idx, y, minlength=bins) / np.maximum(count, 1)
    centres = 0.5 * (edges[1:] + edges[:-1])
    keep = count > 0
    return centres[keep], mean[keep]


def plot_fit(
    signals: Signals,
    torque: Array,
    fit: FitResult,
    peak: PeakTorque,
    residuals: Sequence[tuple[str, FitResult]] = (),
    cogging_order: float | None = None,
    diagnosis: Diagnosis | None = None,
) -> Figure:
    """Torque against current with the fit, and residual panels comparing fits.

    Args:
        signals: The log's channels.
        torque: Measured torque [N m].
        fit: The fit whose curve, 20 % point and peak torque are drawn.
        peak: Its peak torque.
        residuals: (label, fit) pairs whose residuals are compared in the panels, e.g.
            ("before: linear+saturation", start) and ("after: ...", final). Default: ``fit`` alone.
        cogging_order: Fold the position panel on this many periods per revolution.
        diagnosis: The fit's diagnosis, for the per-block panel (noise floor, disagreeing blocks).

    Channels the log lacks get no panel. The last panel shows the held-out error of every
    time block (each predicted by the fit without its fold) against the noise floor, so
    where in the log the model fails is visible.
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    panels, along = _panels(signals, cogging_order)
    count = 2 + len(panels)
    ncols = (count + 1) // 2
    fig = Figure(figsize=(5 * ncols, 9), layout="constrained")
    axes = fig.subplots(2, ncols, squeeze=False)
    for extra in axes.flat[count:]:
        extra.set_axis_off()
    n = torque.shape[0]
    pick = np.linspace(0, n - 1, min(n, MAX_POINTS)).astype(int)
    _curve_panel(axes[0, 0], signals, torque, fit, peak, pick)
    for ax, (label, x) in zip(axes.flat[1 : 1 + len(panels)], panels, strict=True):
        _residual_panel(ax, label, x, pick, fit, residuals)
        w = diagnosis.wander if diagnosis is not None and diagnosis.wander_said is not None else None
        if label == along and w is not None:
            import textwrap

            ax.set_title("\n".join(textwrap.wrap(_wander_title(w), 60)), fontsize=8)
    _block_panel(axes.flat[1 + len(panels)], signals, fit, diagnosis)
    return fig


def _panels(signals: Signals, cogging_order: float | None) -> tuple[list[tuple[str, Array]], str]:
    """(label, channel) of each residual panel the log has a channel for, and the label of the time (or row) one."""
    position = (
        None
        if signals.position is None
        else np.mod(signals.position * (cogging_order or 1.0), 2 * np.pi) / (cogging_order or 1.0)
    )
    along = ("time [s]", signals.time) if signals.timed else ("row (steady-state table)", signals.time)
    candidates: list[tuple[str, Array | None]] = [
        ("current [A]", signals.current),
        ("velocity [rad/s]", signals.velocity),
        ("position" + (f" folded on 1/{cogging_order:g} rev [rad]" if cogging_order else " mod 2 pi [rad]"), position),
        ("temperature [degC]", signals.temperature),
        along,
    ]
    return [(label, x) for label, x in candidates if x is not None], along[0]


def _curve_panel(ax: Axes, signals: Signals, torque: Array, fit: FitResult, peak: PeakTorque, pick: Array) -> None:
    """Torque against current: the measured points, the linear Kt, the fitted curve and its 20 % point."""
    import textwrap

    i = signals.current
    ax.scatter(i[pick], torque[pick], s=2, color="0.6", alpha=0.4, label="measured", rasterized=True)
    grid = np.linspace(-np.max(np.abs(i)), np.max(np.abs(i)), 400)
    kt = fit.value("kt")
    ax.plot(grid, kt * grid, color="tab:green", ls="--", lw=1.2, label=f"linear, Kt = {kt:.4g} N m/A")
    ax.plot(grid, curve_torque(fit, grid), color="tab:blue", lw=1.8, label="fitted curve")
    if peak.torque is not None and peak.current is not None:
        ax.plot(
            [peak.current, -peak.current],
            [peak.torque, -peak.torque],
            "o",
            color="tab:red",
            ms=6,
            label=f"20 % point: {peak.torque:.3g} N m at {peak.current:.3g} A",
        )
        for sign in (1, -1):
            ax.axhline(sign * peak.torque, color="tab:red", lw=0.8, ls=":")
    ax.set_xlabel("current [A]")
    ax.set_ylabel("torque [N m]")
    title = f"{' + '.join(fit.model)}: held-out RMSE {fit.rmse_test:.3g} N m"
    ax.set_title("\n".join(textwrap.wrap(title, 60)), fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    ax.grid(alpha=0.3)


def _residual_panel(
    ax: Axes, label: str, x: Array, pick: Array, fit: FitResult, residuals: Sequence[tuple[str, FitResult]]
) -> None:
    """The residuals of each compared fit against one channel, as points and as binned means."""
    pairs = list(residuals) or [("+".join(fit.model), fit)]
    colours = ["tab:red", "tab:blue", "tab:green", "tab:purple"]
    series = [(name, f.residual, colours[k % 4]) for k, (name, f) in enumerate(pairs)]
    for name, r, colour in series:
        ax.scatter(x[pick], r[pick], s=1, color=colour, alpha=0.15, rasterized=True)
        bx, by = _binned(x, r)
        ax.plot(bx, by, color=colour, lw=1.5, label=name)
    ax.axhline(0, color="0.3", lw=0.6)
    # robust limits from the newest fit: the old model's spikes may run off the panel, but the structure
    # left in the new residual stays readable
    lim = 3.0 * float(np.percentile(np.abs(series[-1][1][pick]), 99.5))
    if lim > 0:
        ax.set_ylim(-lim, lim)
    ax.set_xlabel(label)
    ax.set_ylabel("residual [N m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6, loc="upper right")


def _wander_title(w: Wander) -> str:
    """The time panel's title: whether the residual's excess is an offset, a slow wander or fast noise."""
    noise = f"{w.fast:.3g} N m of noise faster than {w.window:.2g} s"
    if w.is_offset:
        return f"an offset of {w.mean:+.3g} N m beside {noise}"
    if w.is_slow or not w.excess:
        follows = " (it follows the current and speed)" if w.follows_inputs else ""
        return f"a slow part of {w.slow:.3g} N m RMS{follows} beside {noise}"
    return f"the excess is fast: {noise}, {w.fast_ratio:.2g}x the floor"


def _block_panel(ax: Axes, signals: Signals, fit: FitResult, diagnosis: Diagnosis | None) -> None:
    """Held-out RMSE of each time block against the noise floor and its error under the fit to the agreeing half
    of the blocks (what the flags are judged on); disagreeing blocks in red."""
    edges = fit.blocks.edges
    x = signals.time
    left = x[edges[:-1]]
    right = x[np.minimum(edges[1:], x.size - 1)]
    r = np.asarray(fit.block_rmse)
    flagged = np.zeros(r.size, dtype=bool) if diagnosis is None else np.asarray(diagnosis.disagreeing, dtype=bool)
    steps = np.append(left, right[-1])
    colours = np.where(flagged, "tab:red", "tab:blue")
    ax.bar(left, r, width=right - left, align="edge", color=colours, alpha=0.45, zorder=1)
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list[Any] = [Patch(color="tab:blue", alpha=0.45, label="held-out RMSE of the block")]
    if flagged.any():
        handles.append(Patch(color="tab:red", alpha=0.45, label="held-out RMSE, block disagrees with the rest"))
    if diagnosis is not None:
        floor = np.where(np.isfinite(diagnosis.block_floor), diagnosis.block_floor, diagnosis.noise_floor)
        ax.stairs(floor, steps, color="0.2", lw=1.2, zorder=3, baseline=None)
        ax.axhline(diagnosis.noise_floor, color="0.5", lw=0.8, ls=":", zorder=3)
        handles += [
            Line2D([], [], color="0.2", lw=1.2, label="noise floor of the block"),
            Line2D([], [], color="0.5", lw=0.8, ls=":", label="noise floor of the log"),
        ]
        if diagnosis.block_agreeing.size == r.size:
            ax.stairs(diagnosis.block_agreeing, steps, color="tab:orange", lw=1.6, zorder=4, baseline=None)
            handles.append(Line2D([], [], color="tab:orange", lw=1.6, label="RMSE, model fitted to the agreeing half"))
    ax.legend(handles=handles, fontsize=6, loc="upper left")
    ax.set_yscale("log")
    ax.set_xlabel("time [s]" if signals.timed else "row (steady-state table)")
    ax.set_ylabel("RMSE of the block [N m]")
    ax.set_title(f"each block predicted by the fit without its fold ({fit.blocks.folds} folds)", fontsize=9)
    ax.grid(alpha=0.3, which="both")
