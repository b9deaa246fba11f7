"""Plots of operating regions (matplotlib, Agg backend; imported only when plotting)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hound_id.mor.joint_space import RobotRegions
from hound_id.mor.region import OperatingRegion, torque_interval
from hound_id.mor.saturate_log import LogSaturation

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure


def new_figure(rows: int, cols: int, size: tuple[float, float]) -> Figure:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    fig.subplots(rows, cols, squeeze=False)
    return fig


def _panels(n: int) -> Figure:
    """A grid of n small panels, three to a row, spare ones hidden."""
    cols = min(3, n)
    rows = -(-n // cols)
    fig = new_figure(rows, cols, (4.2 * cols, 3.4 * rows))
    for ax in fig.axes[n:]:
        ax.set_visible(False)
    return fig


def style_panel(ax, title: str, side: str) -> None:  # type: ignore[no-untyped-def]
    ax.axhline(0, color="0.5", lw=0.6)
    ax.axvline(0, color="0.5", lw=0.6)
    ax.set_title(title, fontsize=8)
    ax.set_xlabel(f"{side} torque [N m]", fontsize=8)
    ax.set_ylabel(f"{side} speed [rad/s]", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)


def _closed(v: np.ndarray) -> np.ndarray:
    return np.vstack([v, v[:1]])


def _box(ax, effort: float, velocity: float, **kw) -> None:  # type: ignore[no-untyped-def]
    xs = [-effort, effort, effort, -effort, -effort]
    ys = [-velocity, -velocity, velocity, velocity, -velocity]
    ax.plot(xs, ys, **kw)


#: How far past overspeed the region plot draws the forced braking torque (a multiple of the overspeed).
PAST_OVERSPEED = 1.2


def plot_region(
    region: OperatingRegion,
    sheet: OperatingRegion | None = None,
    linear: OperatingRegion | None = None,
    outlines: tuple[tuple[OperatingRegion, str], ...] = (),
) -> Figure:
    """The motor's region in (torque, speed) with quadrants labelled, against the URDF box.

    The URDF box is what a rectangular joint limit would claim: the torque limit at
    every speed up to the no-load (or rated maximum) speed. Its corners in the
    motoring quadrants (1 and 3) lie outside the region. With ``sheet`` (the region is a
    measured envelope) the spec sheet's region is drawn dashed; with ``linear`` the linear-Kt region
    (:func:`hound_id.mor.region.linear_region`), dotted; each of ``outlines`` (region, label) as a thin line (the DC
    law against a drive model, the region at the battery's lowest voltage).
    """
    fig = new_figure(1, 1, (7.5, 7.0))
    ax = fig.axes[0]
    _draw_regions(ax, region, sheet, linear, outlines)
    w_box = _draw_boxes(ax, region)
    tl = max(region.torque_limit, linear.torque_limit if linear is not None else 0.0)
    w = max(region.overspeed, w_box, linear.overspeed if linear is not None else 0.0)
    forced = _draw_past_overspeed(ax, region)
    tl = max(tl, float(np.max(np.abs(forced))) / 1.3)
    w = max(w, PAST_OVERSPEED * region.overspeed / 1.1)
    _label_quadrants(ax, region, tl, w)
    ax.set_xlim(-1.35 * tl, 1.35 * tl)
    ax.set_ylim(-1.15 * w, 1.15 * w)
    ax.set_xlabel("motor torque tau [N m]")
    ax.set_ylabel("motor speed omega [rad/s]")
    ax.set_title(
        f"{region.motor}: torque limit {region.torque_limit:.4g} N m, no-load {region.no_load_speed:.4g} rad/s, "
        f"overspeed {region.overspeed:.4g} rad/s",
        fontsize=9,
    )
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=1, fontsize=8, frameon=False)
    ax.grid(alpha=0.3)
    return fig


def _draw_regions(  # type: ignore[no-untyped-def]
    ax,
    region: OperatingRegion,
    sheet: OperatingRegion | None,
    linear: OperatingRegion | None,
    outlines: tuple[tuple[OperatingRegion, str], ...],
) -> None:
    """The region filled, and the spec sheet's, the linear-Kt one and the other outlines as lines."""
    v = region.vertices
    label = "measured envelope (MOR)" if sheet is not None else "operating region (MOR)"
    ax.fill(v[:, 0], v[:, 1], color="tab:blue", alpha=0.25, label=label)
    ax.plot(*_closed(v).T, color="tab:blue", lw=1.8)
    if sheet is not None:
        ax.plot(*_closed(sheet.vertices).T, color="0.3", lw=1.2, ls="--", label="spec sheet region")
    if linear is not None:
        ax.plot(
            *_closed(linear.vertices).T,
            color="tab:purple",
            lw=1.2,
            ls="-.",
            label=f"linear-Kt region (tau = Kt i): |tau|<={linear.torque_limit:.3g} N m, what a linear model promises",
        )
    colours = ("tab:orange", "tab:brown", "tab:olive", "tab:pink", "tab:cyan")
    for (other, text), colour in zip(outlines, colours, strict=False):
        ax.plot(*_closed(other.vertices).T, color=colour, lw=1.1, ls=(0, (5, 2, 1, 2)), label=text)


def _draw_boxes(ax, region: OperatingRegion) -> float:  # type: ignore[no-untyped-def]
    """The URDF box and the inner box; returns the URDF box's speed [rad/s]."""
    w_box = region.max_speed if region.max_speed is not None else region.no_load_speed
    _box(
        ax,
        region.torque_limit,
        w_box,
        color="tab:red",
        ls="--",
        lw=1.4,
        label=f"URDF box: |tau|<={region.torque_limit:.3g} N m, |omega|<={w_box:.4g} rad/s",
    )
    _box(
        ax,
        region.inner_box[0],
        region.inner_box[1],
        color="tab:green",
        ls=":",
        lw=1.6,
        label=f"inner box: |tau|<={region.inner_box[0]:.3g} N m, |omega|<={region.inner_box[1]:.4g} rad/s",
    )
    return w_box


def _draw_past_overspeed(ax, region: OperatingRegion) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The braking torque forced past overspeed (and a drive's step in it where control is lost); returns it [N m]."""
    # past overspeed the interval collapses onto the braking torque the back-EMF forces (region.torque_interval)
    past = np.linspace(region.overspeed, PAST_OVERSPEED * region.overspeed, 60)
    forced = torque_interval(past, region)[1]
    what = (
        "past overspeed: the braking the back-EMF forces"
        if region.drive is None
        else "past the loss of control: the diode bridge's braking"
    )
    ax.plot(forced, past, color="tab:red", lw=1.6, ls=":", label=what)
    ax.plot(-forced, -past, color="tab:red", lw=1.6, ls=":")
    held = float(torque_interval(np.array([region.overspeed * (1.0 - 1e-9)]), region)[1][0])
    if region.drive is not None and abs(held - forced[0]) > 0.01 * region.torque_limit:
        # a drive holding i_d = 0 has no state between its last held current and the diode bridge: the braking steps
        ax.plot([held, forced[0]], [region.overspeed] * 2, color="tab:red", lw=2.2)
        ax.annotate(
            f"braking steps {abs(held):.3g} -> {abs(forced[0]):.3g} N m\n"
            f"where control is lost ({region.overspeed:.4g} rad/s)",
            (0.5 * (held + forced[0]), region.overspeed),
            textcoords="offset points",
            xytext=(0, 12),
            ha="center",
            fontsize=8,
            color="tab:red",
            bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.8},
        )
    return forced


def _label_quadrants(ax, region: OperatingRegion, tl: float, w: float) -> None:  # type: ignore[no-untyped-def]
    """The axes through the origin, the quadrants' names and the corner speed."""
    ax.axhline(0, color="0.4", lw=0.8)
    ax.axvline(0, color="0.4", lw=0.8)
    for sx, sy, text in ((1, 1, "Q1 motoring"), (-1, 1, "Q2 braking"), (-1, -1, "Q3 motoring"), (1, -1, "Q4 braking")):
        ax.text(
            sx * 1.3 * tl, sy * 1.1 * w, text, ha="right" if sx > 0 else "left", va="center", fontsize=10, color="0.25"
        )
    if region.corner_speed > 0:
        ax.plot([region.torque_limit], [region.corner_speed], "o", color="k", ms=4)
        ax.annotate(
            f"corner {region.corner_speed:.4g} rad/s",
            (region.torque_limit, region.corner_speed),
            textcoords="offset points",
            xytext=(-10, 8),
            ha="right",
            fontsize=8,
        )


def plot_robot(regions: RobotRegions) -> Figure:
    """One panel per joint: reachable projection, section with the others at rest, inner and outer boxes."""
    fig = _panels(len(regions.joints))
    for ax, jr in zip(fig.axes, regions.joints, strict=False):
        p = jr.projection
        ax.fill(p[:, 0], p[:, 1], color="tab:blue", alpha=0.2, label="reachable (others free)")
        ax.plot(*_closed(jr.section).T, color="tab:blue", lw=1.4, label="others at rest")
        _box(ax, jr.outer_box.effort, jr.outer_box.velocity, color="tab:red", ls="--", lw=1.1, label="outer box")
        _box(ax, jr.inner_box.effort, jr.inner_box.velocity, color="tab:green", ls=":", lw=1.6, label="inner box")
        tag = " (coupled)" if jr.coupled else ""
        title = f"{jr.joint}{tag}: inner {jr.inner_box.effort:.3g} N m / {jr.inner_box.velocity:.3g} rad/s"
        style_panel(ax, title, "joint")
    fig.axes[0].legend(fontsize=6, loc="lower left")
    fig.suptitle(f"{regions.robot}: joint-space operating regions", fontsize=11)
    return fig


def plot_log_saturation(log: LogSaturation, regions: tuple[OperatingRegion, ...]) -> Figure:
    """Per motor: the region, the commanded (tau, omega) trajectory and the saturated one (paper, Fig. 8a)."""
    fig = _panels(len(log.motors))
    clipped = log.motor_clipped
    for i, (ax, region) in enumerate(zip(fig.axes, regions, strict=False)):
        v = region.vertices
        ax.fill(v[:, 0], v[:, 1], color="0.85", label="MOR")
        ax.plot(*_closed(v).T, color="0.4", lw=1.0)
        ax.plot(log.motor_torque_cmd[:, i], log.motor_speed[:, i], color="tab:red", lw=0.9, label="command")
        ax.plot(log.motor_torque_sat[:, i], log.motor_speed[:, i], color="tab:blue", lw=1.1, ls="--", label="saturated")
        style_panel(ax, f"{log.motors[i]}: {clipped[:, i].mean():.0%} clipped", "motor")
    fig.axes[0].legend(fontsize=6, loc="lower left")
    fig.suptitle("torque commands against each motor's operating region", fontsize=11)
    return fig
