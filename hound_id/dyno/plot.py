"""Plots of a current-torque fit (matplotlib, Agg backend; imported only when plotting)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from hound_id.dyno.curve import PeakTorque, curve_torque
from hound_id.dyno.effects import Signals
from hound_id.dyno.fit import Array, FitResult

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

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
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(15, 9), layout="constrained")
    axes = fig.subplots(2, 3)
    n = torque.shape[0]
    pick = np.linspace(0, n - 1, min(n, MAX_POINTS)).astype(int)
    i = signals.current

    ax = axes[0, 0]
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
    import textwrap

    title = f"{' + '.join(fit.model)}: held-out RMSE {fit.rmse_test:.3g} N m"
    ax.set_title("\n".join(textwrap.wrap(title, 60)), fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    ax.grid(alpha=0.3)

    panels: list[tuple[str, Array | None]] = [
        ("current [A]", i),
        ("velocity [rad/s]", signals.velocity),
        (
            "position" + (f" folded on 1/{cogging_order:g} rev [rad]" if cogging_order else " mod 2 pi [rad]"),
            None
            if signals.position is None
            else np.mod(signals.position * (cogging_order or 1.0), 2 * np.pi) / (cogging_order or 1.0),
        ),
        ("temperature [degC]", signals.temperature),
        ("time [s]", signals.time),
    ]
    for ax, (label, x) in zip(axes.flat[1:], panels, strict=True):
        if x is None:
            ax.text(0.5, 0.5, f"no {label.split(' ')[0]} channel", ha="center", va="center", transform=ax.transAxes)
            ax.set_axis_off()
            continue
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
    return fig
