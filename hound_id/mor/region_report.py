"""What ``hound-id mor --spec`` reports of a motor's region (:mod:`hound_id.mor.region`): which limit binds where, the
region at speed and at the battery's ends, what a linear-Kt model over-promises, and how far a straight-line
DC-motor clip passes or falls short of the region."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from hound_id.mor.region import SPEED_TOLERANCE, OperatingRegion, linear_region, operating_region, torque_interval

if TYPE_CHECKING:  # at run time only motor_report needs the spec module: the saturation (and so the runtime)
    from hound_id.mor.spec import MotorSpec  # imports this module without yaml or pint


def motor_report(
    spec: MotorSpec, region: OperatingRegion | None = None, sheet: OperatingRegion | None = None
) -> dict[str, Any]:
    """The ``hound-id/mor/3`` content for a motor: its region, its spec (SI), the spec's warnings, which limit binds
    where (of the spec sheet's region, ``sheet``: built here unless given or ``region`` is it), and what the
    linear-Kt region over-promises."""
    from hound_id.mor.spec import spec_warnings

    if sheet is None:
        sheet = region if region is not None and region.source == "spec sheet" else operating_region(spec)
    data = (region or sheet).to_dict()
    data.update(
        spec=spec.to_dict(),
        warnings=list(spec_warnings(spec)),
        bindings=[b.to_dict() for b in bindings(sheet, spec)],
        linear_kt=overpromise(linear_region(spec), sheet).to_dict(),
        at_speed=at_speed(spec, sheet).to_dict() if spec.drive is not None or spec.bus_voltage_range else None,
    )
    return data


@dataclass(frozen=True)
class Speeds:
    """A region's characteristic speeds and box at one bus voltage, motor side."""

    bus_voltage: float
    """Bus voltage [V]."""
    corner_speed: float
    """Highest speed with full motoring torque [rad/s]."""
    no_load_speed: float
    """Where the motoring edge reaches zero torque [rad/s] (with field weakening: how far it reaches)."""
    overspeed: float
    """Where the drive loses control (DC law: where even the opposing bus cannot hold the current) [rad/s]."""
    inner_box: tuple[float, float]
    """Largest symmetric box (torque [N m], speed [rad/s])."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "bus_voltage": self.bus_voltage,
            "corner_speed": self.corner_speed,
            "no_load_speed": self.no_load_speed,
            "overspeed": self.overspeed,
            "inner_box": {"torque": self.inner_box[0], "speed": self.inner_box[1]},
        }

    @classmethod
    def of(cls, region: OperatingRegion, volts: float) -> Speeds:
        """A region's speeds and box, at its bus voltage ``volts`` [V]."""
        return cls(volts, region.corner_speed, region.no_load_speed, region.overspeed, region.inner_box)


#: Speeds, as shares of the DC law's no-load speed, at which :func:`at_speed` compares the motoring edges.
COST_SPEEDS = (0.25, 0.5, 0.75, 0.85, 0.9, 0.95, 1.0, 1.1, 1.25, 1.5, 2.0)
#: Grid points (0 to the DC no-load speed, plus its corner speed) on which the largest motoring cost is found.
COST_POINTS = 4001


@dataclass(frozen=True)
class AtSpeed:
    """What the drive's dq model (winding reactance, field weakening) and the battery's range change in a spec's
    region: :func:`at_speed`."""

    drive: Speeds
    """The region as the spec states it (its drive model, at the nominal bus)."""
    dc_law: Speeds
    """The paper's DC law at the nominal bus: no reactance, no field weakening."""
    without_weakening: Speeds | None
    """With the reactance but i_d = 0 (None unless the spec has field weakening)."""
    speeds: tuple[float, ...]
    """Motor speeds of the comparison [rad/s]."""
    torque_dc: tuple[float, ...]
    """Upper (motoring, then least braking) edge under the DC law at each speed [N m]."""
    torque_drive: tuple[float, ...]
    """Upper edge with the drive model [N m]."""
    battery: tuple[Speeds, ...]
    """The region at the lowest and highest bus voltage of the battery (empty without ``bus_voltage_range``)."""
    largest_cost: tuple[float, float, float]
    """(DC-law torque - drive torque [N m], at speed [rad/s], the DC law's torque there [N m]): the most motoring
    torque the drive model takes off the DC law's edge, up to the DC no-load speed (a fine grid)."""
    dc_region: OperatingRegion = field(repr=False, compare=False)
    """The DC law's region the comparison used (for plots)."""
    battery_regions: tuple[OperatingRegion, ...] = field(default=(), repr=False, compare=False)
    """The regions at the battery's lowest and highest voltage (for plots)."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "largest_motoring_cost": {
                "torque": self.largest_cost[0],
                "at_speed": self.largest_cost[1],
                "dc_law_torque": self.largest_cost[2],
            },
            "drive": self.drive.to_dict(),
            "dc_law": self.dc_law.to_dict(),
            "without_field_weakening": None if self.without_weakening is None else self.without_weakening.to_dict(),
            "motoring_edge": {
                "speeds": list(self.speeds),
                "dc_law": list(self.torque_dc),
                "drive": list(self.torque_drive),
                "cost": [a - b for a, b in zip(self.torque_dc, self.torque_drive, strict=True)],
                "about": "the upper edge (motoring, past the no-load speed the least braking) at shares "
                f"{', '.join(f'{c:g}' for c in COST_SPEEDS)} of the DC law's no-load speed; cost = dc_law - drive, "
                "positive where the drive model gives less torque (negative past no-load: less braking forced)",
            },
            "battery": [b.to_dict() for b in self.battery],
            "units": {
                "speeds, corner_speed, no_load_speed, overspeed": "rad/s (motor side)",
                "torques, cost": "N m (motor side)",
                "bus_voltage": "V",
                "meaning": "with a drive model no_load_speed is where the motoring edge reaches zero (with field "
                "weakening: how far motoring reaches) and overspeed where the drive loses control",
            },
        }


def at_speed(spec: MotorSpec, region: OperatingRegion | None = None) -> AtSpeed:
    """The region at speed: the spec's (with its drive model) against the DC law, at each of :data:`COST_SPEEDS`
    (shares of the DC no-load speed), and at the ends of the battery's range. ``region`` is the spec's sheet region
    if already built."""
    sheet = region if region is not None else operating_region(spec)
    dc_spec = replace(spec, inductance=None, inductance_convention=None, field_weakening=False)
    dc = operating_region(dc_spec)
    plain = None
    if spec.field_weakening:
        plain = Speeds.of(operating_region(replace(spec, field_weakening=False)), spec.bus_voltage)
    w = np.array(COST_SPEEDS) * dc.no_load_speed
    fine = np.unique(np.concatenate([np.linspace(0.0, dc.no_load_speed, COST_POINTS), [dc.corner_speed]]))
    cost = torque_interval(fine, dc)[1] - torque_interval(fine, sheet)[1]
    k = int(np.argmax(cost))
    ends = spec.bus_voltage_range or ()
    battery_regions = tuple(operating_region(replace(spec, bus_voltage=v)) for v in ends)
    return AtSpeed(
        drive=Speeds.of(sheet, spec.bus_voltage),
        dc_law=Speeds.of(dc, spec.bus_voltage),
        without_weakening=plain,
        speeds=tuple(float(x) for x in w),
        torque_dc=tuple(float(x) for x in torque_interval(w, dc)[1]),
        torque_drive=tuple(float(x) for x in torque_interval(w, sheet)[1]),
        battery=tuple(Speeds.of(r, v) for r, v in zip(battery_regions, ends, strict=True)),
        largest_cost=(float(cost[k]), float(fine[k]), float(torque_interval(fine[k : k + 1], dc)[1][0])),
        dc_region=dc,
        battery_regions=battery_regions,
    )


@dataclass(frozen=True)
class Binding:
    """Which limit bounds the motoring edge of a region over a range of speeds."""

    limit: str
    """``torque`` (the peak torque), ``current`` (the driver's current limit), ``voltage`` (the bus), ``speed`` (the
    rated maximum speed: braking only) or ``back-EMF`` (past overspeed: the braking current the back-EMF forces)."""
    speeds: tuple[float, float]
    """From and to [rad/s] (motor side, omega >= 0; the region is point-symmetric)."""
    detail: str
    """One sentence with the numbers."""

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (an open end, inf, is written as null: JSON has no infinity)."""
        speeds = [None if math.isinf(w) else w for w in self.speeds]
        return {"limit": self.limit, "speeds": speeds, "detail": self.detail}


def bindings(region: OperatingRegion, spec: MotorSpec) -> tuple[Binding, ...]:
    """Which limit bounds the upper (motoring, then least-braking) edge at each speed from 0 up past overspeed."""
    out: list[Binding] = []
    curve = region.curve
    i_lim = region.limit_x / (curve.kt if curve is not None else spec.kt)
    driver = spec.max_current is not None and abs(i_lim - spec.max_current) <= 1e-9 * spec.max_current
    top = region.max_speed if region.max_speed is not None else math.inf
    corner, nl, over = region.corner_speed, min(region.no_load_speed, top), region.overspeed
    flat = "current" if driver else "torque"
    what = (
        f"the driver's current limit {i_lim:.4g} A makes {region.torque_limit:.4g} N m on the curve"
        if driver
        else f"the peak torque {region.torque_limit:.4g} N m (current {i_lim:.4g} A)"
    )
    if corner > 0:
        out.append(Binding(flat, (0.0, corner), what))
    if region.drive is not None:
        return tuple(out) + _drive_bindings(region, corner, nl, over, i_lim)
    if nl > corner:
        out.append(
            Binding(
                "voltage",
                (corner, nl),
                "the bus voltage: the current the bus can push, (V - omega/Kv)/R, through the current-torque curve",
            )
        )
    if region.max_speed is not None and region.max_speed < over:
        out.append(Binding("speed", (region.max_speed, over), "past the rated speed only braking torque passes"))
    elif over > nl:
        out.append(
            Binding(
                "voltage",
                (nl, over),
                "past the no-load speed the back-EMF forces a braking current of at least (omega/Kv - V)/R",
            )
        )
    out.append(
        Binding(
            "back-EMF",
            (over, math.inf),
            f"past overspeed {over:.4g} rad/s the braking current exceeds {i_lim:.4g} A whatever is commanded; the "
            "torque is the curve's at (omega/Kv - V)/R",
        )
    )
    return tuple(out)


def _drive_bindings(
    region: OperatingRegion, corner: float, no_load: float, over: float, i_lim: float
) -> tuple[Binding, ...]:
    """The bindings past the corner speed under the drive's dq model (:mod:`hound_id.mor.drive`)."""
    drive = region.drive
    assert drive is not None
    out = []
    voltage = (
        "the bus voltage with the winding's reactance, |(R i_q + omega/Kv, X i_q)| <= V_bus (dq model, i_d = 0)"
        if not drive.field_weakening
        else "the voltage and current circles: negative d current weakens the field, |i_dq| <= "
        f"{drive.phase_current_limit:.4g} A"
    )
    if no_load > corner:
        out.append(Binding("voltage", (corner, no_load), voltage + ", through the current-torque curve"))
    if over > no_load:
        out.append(
            Binding("voltage", (no_load, over), "past the motoring reach the back-EMF forces braking; " + voltage)
        )
    held = (
        f"no current within the {drive.phase_current_limit:.4g} A circle"
        if drive.field_weakening
        else f"no current with i_d = 0 within {i_lim:.4g} A (field weakening would hold control further)"
    )
    out.append(
        Binding(
            "back-EMF",
            (over, math.inf),
            f"past {over:.4g} rad/s the bus can hold {held}: the drive's switches are taken as off, the back-EMF "
            "drives current through the diode bridge, and its braking (smaller than (omega/Kv - V)/R with the "
            "reactance, fading at high speed) is the torque whatever is commanded; the braking steps there",
        )
    )
    return tuple(out)


@dataclass(frozen=True)
class Overpromise:
    """How much a linear-Kt region promises that the curve-limited region does not."""

    torque_limit: tuple[float, float]
    """Torque limit, linear-Kt and curve-limited [N m]."""
    corner_speed: tuple[float, float]
    """Corner speed, linear-Kt and curve-limited [rad/s]."""
    largest: float
    """Largest excess of the linear region's edges over the curved region's at one speed [N m]."""
    at_speed: float
    """Where (motor speed [rad/s], the motoring side)."""
    share: float
    """Largest excess relative to the curved region's torque there [-]."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "torque_limit": {"linear_kt": self.torque_limit[0], "curve": self.torque_limit[1]},
            "corner_speed": {"linear_kt": self.corner_speed[0], "curve": self.corner_speed[1]},
            "largest_excess": self.largest,
            "at_speed": self.at_speed,
            "relative_excess": self.share,
            "units": "N m, rad/s (motor side)",
        }


#: Speeds at which the linear and the curved regions are compared (across +-overspeed).
OVERPROMISE_POINTS = 4001


def overpromise(linear: OperatingRegion, curved: OperatingRegion) -> Overpromise:
    """Compare the linear-Kt region with the curve-limited one on a grid of speeds up to the curved overspeed."""
    w = np.linspace(0.0, curved.overspeed, OVERPROMISE_POINTS)
    lo_l, hi_l = torque_interval(w, linear)
    lo_c, hi_c = torque_interval(w, curved)
    excess = np.maximum(hi_l - hi_c, 0.0)
    k = int(np.argmax(excess))
    return Overpromise(
        torque_limit=(linear.torque_limit, curved.torque_limit),
        corner_speed=(linear.corner_speed, curved.corner_speed),
        largest=float(excess[k]),
        at_speed=float(w[k]),
        share=float(excess[k] / max(abs(hi_c[k]), 1e-12)),
    )


#: Motor speeds at which a straight-line clip is compared with a region, across +-overspeed.
STRAIGHT_POINTS = 4001


def straight_gap(region: OperatingRegion) -> tuple[float, float]:
    """(over, under) [N m, motor side]: the most a straight-line DC-motor clip (the voltage line through the linear
    stall torque Kt V/R and the no-load speed, cut at the torque limit: Isaac Lab's ``DCMotor``, MuJoCo's
    ``dcmotor``) passes or falls short of the region's interval, at speeds within +-overspeed. Both are 0 for a
    linear curve; past overspeed the straight clip holds the torque limit, the region the braking torque the back-EMF
    forces (larger), by design."""
    tl, stall, d = region.torque_limit, region.stall_torque, region.back_emf_damping
    # the kinks of both clips: where each leaves the torque limit, where each reaches the no-load speed, and where
    # the straight one clamps the speed (its own overspeed)
    kinks = np.array([(stall - tl) / d, (stall + tl) / d, (stall - region.limit_x) / d, stall / d])
    if region.max_speed is not None:  # the braking-only cut past the rated speed (the straight clip has none)
        kinks = np.append(kinks, region.max_speed * (1 + 4 * SPEED_TOLERANCE))
    kinks = kinks[np.abs(kinks) < region.overspeed]
    w = np.unique(np.concatenate([np.linspace(-region.overspeed, region.overspeed, STRAIGHT_POINTS), kinks, -kinks]))
    lo, hi = torque_interval(w, region)
    w_clamped = np.clip(w, -(stall + tl) / d, (stall + tl) / d)  # DCMotor clamps the speed at its overspeed
    s_hi = np.minimum(stall - d * w_clamped, tl)
    s_lo = np.maximum(-stall - d * w_clamped, -tl)
    over = max(float(np.max(s_hi - hi)), float(np.max(lo - s_lo)), 0.0)
    under = max(float(np.max(hi - s_hi)), float(np.max(s_lo - lo)), 0.0)
    return over, under
