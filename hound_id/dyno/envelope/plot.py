"""The ``mor --compare`` figure: the log, the spec sheet's edges and the fitted model's, and the bins at the limit."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from hound_id.mor.plot import new_figure, style_panel

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def plot_compare(comparison: Any) -> Figure:
    """A measured log on the spec sheet's region (left) and the edge offsets per speed before and after
    the added effects (right); see :mod:`hound_id.dyno.envelope.compare`."""
    from hound_id.dyno.envelope.offsets import outside_mask
    from hound_id.mor.envelope import envelope

    c = comparison
    log, inputs = c.log, c.inputs
    fig = new_figure(1, 2, (12.5, 5.2))
    ax, off = fig.axes
    rng = np.random.default_rng(0)
    show = rng.choice(log.n, size=min(log.n, 6000), replace=False)
    ax.scatter(log.torque[show], log.velocity[show], s=2, color="0.7", label="log", rasterized=True)
    walls = np.concatenate([*c.walls.upper, *c.walls.lower]) if c.walls.upper else np.array([], dtype=int)
    if walls.size:
        ax.scatter(log.torque[walls], log.velocity[walls], s=3, color="tab:blue", label="at the limit")
    out = outside_mask(log, inputs, c.ladder[0].offsets.sample_noise)
    if out.any():
        ax.scatter(
            log.torque[out], log.velocity[out], s=6, color="tab:red", label=f"outside the region ({out.mean():.1%})"
        )
    top = float(np.max(np.abs(log.velocity))) * 1.05
    w = np.linspace(-top, top, 400)
    lo, hi = envelope(w, {}, _reference(inputs))
    ax.plot(hi, w, color="k", lw=1.5, label="spec sheet region")
    ax.plot(lo, w, color="k", lw=1.5)
    if c.final.model:
        plain = {k: v for k, v in c.final.model.items() if k != "thermal_resistance"}
        lo2, hi2 = envelope(w, plain, _reference(inputs))
        label = "with " + " + ".join(c.final.model)
        ax.plot(hi2, w, color="tab:orange", lw=1.5, ls="--", label=label)
        ax.plot(lo2, w, color="tab:orange", lw=1.5, ls="--")
    style_panel(ax, f"{inputs.spec.name}: {log.source} ({log.side})", "motor")
    ax.legend(fontsize=7, loc="center")  # the edges, where the region is wrong, stay clear
    first = c.baseline if c.baseline is not None else c.ladder[0].offsets
    last = c.final.offsets
    series = [(first, "k", "spec sheet")] + ([(last, "tab:orange", "with added")] if c.final.model else [])
    for offsets_, colour, name in series:
        for side, marker in ((1, "^"), (-1, "v")):
            sel = offsets_.side == side
            edge = "upper" if side == 1 else "lower"
            off.errorbar(
                offsets_.speeds[sel], offsets_.offset[sel], yerr=3 * offsets_.se[sel], fmt=marker, ms=4,
                color=colour, capsize=2, label=f"{name}, {edge} edge",
            )  # fmt: skip
    off.axhline(0, color="0.4", lw=0.8)
    off.set_xlabel("motor speed [rad/s]", fontsize=8)
    off.set_ylabel("edge offset: measured - model [N m] (+-3 SE)", fontsize=8)
    off.set_title(
        f"envelope error {first.rmse:.3g} -> {last.rmse:.3g} N m (noise level {last.noise:.2g} N m)", fontsize=8
    )
    off.tick_params(labelsize=7)
    off.grid(alpha=0.3)
    off.legend(fontsize=7)
    return fig


def _reference(inputs: Any) -> Any:
    from hound_id.mor.envelope import EnvelopeInputs

    return EnvelopeInputs(inputs.spec, curve=inputs.curve)
