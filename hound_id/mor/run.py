"""The verbs of ``hound-id mor --spec``, ``mor --robot`` and ``saturate``: files in, regions and clipping out.

Each verb loads its inputs, computes, and returns a frozen value with what the command and
``hound-id demo`` render; it prints nothing. The figures are drawn on demand from the value,
so nothing is computed twice.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from hound_id.mor.heat import Heat
    from hound_id.mor.joint_space import RobotRegions
    from hound_id.mor.region import OperatingRegion
    from hound_id.mor.region_report import AtSpeed, Binding, Overpromise
    from hound_id.mor.robot import Robot
    from hound_id.mor.saturate_log import LogSummary
    from hound_id.mor.spec import MotorSpec


@dataclass(frozen=True, eq=False)
class MotorRegions:
    """A motor's region: the measured envelope's if the spec carries one, and the spec sheet's."""

    spec: MotorSpec
    """The motor spec."""
    region: OperatingRegion
    """The region its limits come from (the measured envelope's, else the spec sheet's)."""
    sheet: OperatingRegion
    """The spec sheet's region."""
    warnings: tuple[str, ...]
    """Plausibility warnings on the spec."""

    @property
    def bindings(self) -> tuple[Binding, ...]:
        """Which limit bounds the spec sheet's region where."""
        from hound_id.mor.region_report import bindings

        return bindings(self.sheet, self.spec)

    @property
    def linear_kt(self) -> Overpromise:
        """What the linear-Kt region promises beyond the spec sheet's curve-limited one."""
        from hound_id.mor.region import linear_region
        from hound_id.mor.region_report import overpromise

        return overpromise(linear_region(self.spec), self.sheet)

    @cached_property
    def at_speed(self) -> AtSpeed | None:
        """The drive model's and the battery's effect on the spec sheet's region (None under the DC law at one bus)."""
        from hound_id.mor.region_report import at_speed

        if self.spec.drive is None and not self.spec.bus_voltage_range:
            return None
        return at_speed(self.spec, self.sheet)

    @cached_property
    def heat(self) -> Heat | None:
        """The warm and continuous regions (None without a thermal model, or with a measured envelope)."""
        from hound_id.mor.heat import heat

        return heat(self.spec)

    @property
    def measured(self) -> bool:
        """Whether the region is a measured envelope's."""
        return bool(self.spec.envelope)

    def report(self) -> dict[str, Any]:
        """The ``hound-id/mor/3`` JSON, with ``spec_sheet`` (None unless measured)."""
        from hound_id.mor.region_report import motor_report

        data = motor_report(self.spec, self.region, self.sheet)
        data["heat"] = None if self.heat is None else self.heat.to_dict()
        data["spec_sheet"] = self.sheet.to_dict() if self.measured else None
        return data

    def figure(self) -> Figure:
        """The region (against the spec sheet's when measured)."""
        from hound_id.mor.plot import plot_region
        from hound_id.mor.region import linear_region

        curved = self.spec.current_curve.form != "linear"
        return plot_region(
            self.region,
            self.sheet if self.measured else None,
            linear_region(self.spec) if curved else None,
            outlines=self._outlines() + self._heat_outlines(),
        )

    def _outlines(self) -> tuple[tuple[OperatingRegion, str], ...]:
        """The DC law's region (when the spec has a drive model) and the region at the battery's lowest voltage, as
        :attr:`at_speed` built them."""
        speed = self.at_speed
        out: list[tuple[OperatingRegion, str]] = []
        if speed is None:
            return ()
        if self.spec.drive is not None:
            out.append((speed.dc_region, "DC law (no reactance, i_d = 0): what the paper's eq. 2 promises"))
        if speed.battery_regions:
            low = speed.battery[0].bus_voltage
            out.append((speed.battery_regions[0], f"at the battery's lowest {low:.4g} V"))
        return tuple(out)

    def _heat_outlines(self) -> tuple[tuple[OperatingRegion, str], ...]:
        """The warm region and the continuous one (:attr:`heat`)."""
        h = self.heat
        if h is None:
            return ()
        return (
            (
                h.warm_region,
                f"winding at {h.thermal.derate_start:.4g} degC, full current (where derating starts; the weaker flux "
                "reaches a higher no-load speed)",
            ),
            (
                h.continuous_region,
                f"continuous: {h.continuous_current:.3g} A at {h.continuous_temperature:.4g} degC, what the winding "
                "holds for ever",
            ),
        )


def motor_regions(path: str | Path, bus_range: str | None = None) -> MotorRegions:
    """Load a motor spec and build its regions (``hound-id mor --spec``); ``bus_range`` (``"66 V,84 V"``) replaces
    its battery's range."""
    from hound_id.mor.joint_space import motor_region
    from hound_id.mor.region import operating_region
    from hound_id.mor.spec import spec_warnings
    from hound_id.mor.spec_sheet import load_motor_spec, with_bus_range

    spec = load_motor_spec(path)
    if bus_range is not None:
        spec = with_bus_range(spec, bus_range)
    sheet = operating_region(spec)
    region = motor_region(spec)  # the measured envelope, if the spec carries one
    return MotorRegions(spec, region, sheet, tuple(spec_warnings(spec)))


@dataclass(frozen=True, eq=False)
class RobotRegionsRun:
    """A robot's joint-space regions and URDF boxes."""

    robot: Robot
    """The robot."""
    regions: RobotRegions
    """Its joint-space regions."""
    warnings: tuple[str, ...]
    """Plausibility warnings on its motor specs (each spec once)."""

    def figure(self) -> Figure:
        """One panel per joint."""
        from hound_id.mor.plot import plot_robot

        return plot_robot(self.regions)


def robot_regions_of(path: str | Path, on_warnings: Callable[[tuple[str, ...]], None] | None = None) -> RobotRegionsRun:
    """Load a robot and build its joint-space regions (``hound-id mor --robot``).

    Args:
        path: Robot YAML.
        on_warnings: Given the specs' warnings once the robot is loaded, before the regions are built (so they are
            seen even when building fails).
    """
    from hound_id.mor.joint_space import robot_regions
    from hound_id.mor.robot import load_robot
    from hound_id.mor.spec import spec_warnings

    robot = load_robot(path)
    warnings = tuple(
        w for spec in {s.name: s for s in robot.motor_specs.values()}.values() for w in spec_warnings(spec)
    )
    if on_warnings is not None:
        on_warnings(warnings)
    return RobotRegionsRun(robot, robot_regions(robot), warnings)


@dataclass(frozen=True, eq=False)
class SaturateRun:
    """A command log saturated as training does."""

    robot: Robot
    """The robot whose motors and transmissions applied."""
    summary: LogSummary
    """The clipping per joint and motor (and the rows kept for the plot)."""

    def figure(self) -> Figure | None:
        """Each motor's commands against its spec-sheet region (None when no rows were kept for it)."""
        from hound_id.mor.plot import plot_log_saturation
        from hound_id.mor.region import operating_region

        if self.summary.sample is None:
            return None
        regions = tuple(operating_region(self.robot.motor_specs[m]) for m in self.robot.motors)
        return plot_log_saturation(self.summary.sample, regions)


def saturate_commands(
    commands: str | os.PathLike[str],
    robot: str | Path,
    out: str | os.PathLike[str] | None = None,
    plot: bool = False,
) -> SaturateRun:
    """Saturate a log of joint torque commands (streamed: memory stays bounded), ``hound-id saturate``.

    Args:
        commands: CSV or Parquet with ``tau_<joint>`` [N m] and ``qd_<joint>`` [rad/s] columns.
        robot: Robot YAML whose motors and transmissions apply.
        out: Write the table with ``tau_sat_<joint>`` columns added here (None: not written).
        plot: Keep up to :data:`hound_id.mor.saturate_log.PLOT_ROWS` rows for :meth:`SaturateRun.figure`.
    """
    from hound_id.mor.robot import load_robot
    from hound_id.mor.saturate_log import PLOT_ROWS, saturate_file

    rob = load_robot(robot)
    return SaturateRun(rob, saturate_file(rob, commands, out=out, plot_rows=PLOT_ROWS if plot else 0))


__all__ = [
    "MotorRegions",
    "RobotRegionsRun",
    "SaturateRun",
    "motor_regions",
    "robot_regions_of",
    "saturate_commands",
]
