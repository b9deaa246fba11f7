"""Figure of a foot redesign: the sagittal section against the old foot, and the ratios."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from hound_id.foot.design import PAPER, FootReport


def _arc(cx: float, cz: float, r: float, a0: float, a1: float, n: int = 200) -> tuple[Any, Any]:
    """Points at angle phi from -z towards +x about (cx, cz)."""
    phi = np.linspace(a0, a1, n)
    return cx + r * np.sin(phi), cz - r * np.cos(phi)


def plot_foot(report: FootReport) -> Any:
    """Sagittal section (y = 0) of the new and the original foot, the contact arc and the
    touchdown/liftoff directions (left); mass and inertia ratios next to the paper's (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    g, mount = report.design.geometry, report.mount
    mm = 1e3
    fig, (ax, bars) = plt.subplots(1, 2, figsize=(11, 6.2), gridspec_kw={"width_ratios": [1.25, 1]})
    fig.subplots_adjust(left=0.08, right=0.98, top=0.93, bottom=0.27, wspace=0.25)
    _draw_feet(ax, report)
    _draw_contacts(ax, report)
    zc = g.centre_z
    ax.plot([0], [zc * mm], marker="+", color="k", zorder=5)
    ax.set_aspect("equal")
    ax.set_xlabel("x, forward in the calf frame [mm]")
    ax.set_ylabel("z along the calf [mm]")
    ax.set_title("Sagittal section (calf frame, y = 0)")
    fig.legend(*ax.get_legend_handles_labels(), fontsize=7.5, loc="lower left", bbox_to_anchor=(0.01, 0.0), ncol=2)
    ax.grid(alpha=0.3)
    lim = 1.6 * max(g.radius, mount.contact_radius) * mm
    ax.set_xlim(-lim, lim)
    ax.set_ylim(min(-1.35 * mount.contact_radius, zc - 1.35 * g.radius) * mm, 0.9 * lim)
    _draw_ratios(bars, report)
    return fig


def _draw_feet(ax: Any, report: FootReport) -> None:
    """The original foot's contact circle, the calf, and the new cap with its boss (the bore left white) [mm]."""
    g, mount = report.design.geometry, report.mount
    mm = 1e3
    # original foot: the contact circle about the mount
    ox, oz = _arc(0.0, 0.0, mount.contact_radius, -math.pi, math.pi)
    ax.fill(ox * mm, oz * mm, color="0.85", zorder=0, label=f"original {mount.contact_shape}, r = "
            f"{mount.contact_radius * mm:.1f} mm, {mount.foot.mass * 1e3:.0f} g")  # fmt: skip
    # calf tube up from the mount
    ax.plot([0, 0], [0, 0.6 * mount.mount_length * mm], color="0.4", lw=6, solid_capstyle="butt", zorder=1)
    ax.text(1.5, 0.55 * mount.mount_length * mm, "calf (to the knee)", color="0.3", fontsize=8)
    # new cap: annular sector between R - t and R over [low, high]
    zc = g.centre_z
    x_out, z_out = _arc(0.0, zc, g.radius, g.low, g.high)
    x_in, z_in = _arc(0.0, zc, g.radius - g.thickness, g.high, g.low)
    ax.fill(np.r_[x_out, x_in] * mm, np.r_[z_out, z_in] * mm, color="tab:blue", alpha=0.85, zorder=2,
            label=f"new cap R = {g.radius * mm:.1f} mm, t = {g.thickness * mm:.2f} mm, "
            f"{report.design.properties.mass * 1e3:.1f} g")  # fmt: skip
    # boss: the wall r_i <= |x| <= r_b from the mount down to the inner sphere (the bore left white)
    rb, ri, rho = g.boss_radius, g.bore_radius, g.radius - g.thickness
    bolt = report.requirements.fastener
    for sign in (-1.0, 1.0):
        xb = sign * np.linspace(ri, rb, 30)
        zb = zc - np.sqrt(rho**2 - xb**2)
        ax.fill(np.r_[xb, sign * rb, sign * ri] * mm, np.r_[zb, 0.0, 0.0] * mm, color="tab:blue", alpha=0.55,
                zorder=2, label=(f"boss r = {rb * mm:.2f} mm" + (f", {bolt.name} bore" if bolt else ", solid"))
                if sign > 0 else None)  # fmt: skip


def _draw_contacts(ax: Any, report: FootReport) -> None:
    """The collision spheres, the contact arc, and the touchdown and liftoff directions with the ground [mm]."""
    g, mount, angles = report.design.geometry, report.mount, report.angles
    mm = 1e3
    zc = g.centre_z
    # collision spheres: the outward half of each outline (the side the ground can meet)
    for k, (sx, _, sz, sr) in enumerate(report.collision.spheres):
        phi_k = math.atan2(sx, zc - sz)
        ox_s, oz_s = _arc(sx, sz, sr, phi_k - math.pi / 2, phi_k + math.pi / 2, 60)
        ax.plot(ox_s * mm, oz_s * mm, color="tab:purple", lw=0.7, alpha=0.7, zorder=3,
                label=f"collision: {len(report.collision.spheres)} spheres r = {sr * mm:.1f} mm" if k == 0
                else None)  # fmt: skip
    # the contact angles the stance needs, drawn just outside the outer surface
    cx, cz = _arc(0.0, zc, g.radius + 0.08 * mount.contact_radius, angles.low, angles.high)
    ax.plot(cx * mm, cz * mm, color="tab:orange", lw=4, zorder=3,
            label=f"contact arc {math.degrees(angles.low):.1f} to {math.degrees(angles.high):.1f} deg "
            f"(margin {math.degrees(angles.margin):.0f})")  # fmt: skip
    for name, phi, colour in (("touchdown", angles.attack, "tab:green"), ("liftoff", angles.detach, "tab:red")):
        px, pz = math.sin(phi), -math.cos(phi)
        ax.annotate("", xy=((px * g.radius) * mm, (zc + pz * g.radius) * mm), xytext=(0.0, zc * mm),
                    arrowprops={"arrowstyle": "->", "color": colour, "lw": 1.5}, zorder=4)  # fmt: skip
        # the ground at that instant: the tangent line at the contact point
        tx, tz = -pz, px
        cxp, czp = px * g.radius, zc + pz * g.radius
        s = np.array([-1.2, 1.2]) * g.radius
        ax.plot((cxp + s * tx) * mm, (czp + s * tz) * mm, color=colour, lw=1, ls="--", zorder=4,
                label=f"{name}: {math.degrees(phi):.1f} deg, ground dashed")  # fmt: skip


def _draw_ratios(bars: Any, report: FootReport) -> None:
    """The mass and inertia ratios of this design beside the paper's."""
    names = ["calf + foot\nmass", "pitch inertia\nabout the knee", "pitch inertia\nabout own COM",
             "hip pitch\ninertia"]  # fmt: skip
    ours = [report.mass_ratio, report.inertia_ratio, report.com_inertia_ratio,
            report.new.hip_pitch_inertia / report.original.hip_pitch_inertia]  # fmt: skip
    paper: list[float] = [float(PAPER["mass_ratio"]), float(PAPER["inertia_ratio"]), float(PAPER["inertia_ratio"]),
                          math.nan]  # fmt: skip
    pos = np.arange(len(names))
    b1 = bars.bar(pos - 0.2, ours, 0.4, color="tab:blue", label="this design / this leg's original foot")
    b2 = bars.bar(pos + 0.2, paper, 0.4, color="0.6", hatch=["", "//", "//", ""],
                  label="paper: its own leg; inertia axis not stated (hatched)")  # fmt: skip
    bars.bar_label(b1, fmt="%.3f", fontsize=8)
    bars.bar_label(b2, labels=[f"{v:.3f}" if math.isfinite(v) else "n/a" for v in paper], fontsize=8)
    bars.axhline(1.0, color="k", lw=0.8)
    bars.set_xticks(pos, names, fontsize=7.5)
    bars.set_xlim(-0.7, len(names) - 0.3)  # room for the last group's label
    bars.set_ylabel("new / original")
    bars.set_ylim(0, 1.15)
    bars.set_title("Ratios, new / original (Pinocchio)")
    bars.legend(fontsize=7, loc="upper right")
