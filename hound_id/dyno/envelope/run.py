"""The ``mor --compare`` verb: a torque-speed log against a motor's operating region.

:func:`compare_envelope` does everything the command decides: load the spec, the robot and
the log, compare (``add`` / ``auto``), the verdict, how far the log covers the speeds (the
coverage policy), and whether a measured envelope may be written to ``out`` (only when the
model explains the log). It prints nothing and writes nothing; :func:`write_outputs` writes the
plot and the motor spec with the measured envelope. The command line and ``hound-id demo``
call these two and only render.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from hound_id import io
from hound_id.errors import SpecError

if TYPE_CHECKING:
    from hound_id.dyno.envelope.compare import Comparison
    from hound_id.dyno.identify.engine import Suggestion
    from hound_id.dyno.logs import EnvelopeLog
    from hound_id.mor.spec import MotorSpec

#: The verdict holds only where the log shows both motoring edges up to this share of the no-load speed:
#: the effects that act at speed (bus_sag, inductance, thermal_resistance) show little or nothing below it.
COVERAGE_FRACTION = 0.9

Verdict = Literal["suggest", "explained", "unexplained"]


@dataclass(frozen=True)
class CompareOptions:
    """What ``hound-id mor --compare`` is asked, as given on the command line (texts are parsed by the verb)."""

    columns: str | dict[str, str] | None = None
    """Column map, ``torque=tau_m,velocity=w`` (or already a mapping channel -> file column)."""
    units: str | dict[str, str] | None = None
    """Units of columns, ``velocity=rpm,torque=mN*m`` (or a mapping)."""
    robot: Path | None = None
    """Robot YAML mapping a joint-side log to the motor side."""
    joint: str | None = None
    """The log's joint in ``robot``."""
    add: tuple[str, ...] = ()
    """Effects to add, in order."""
    auto: bool = False
    """Add significant effects until none is left."""
    plot: Path | None = None
    """PNG of the comparison."""
    out: Path | None = None
    """Motor spec YAML with the measured envelope (refused unless the model explains the log)."""


@dataclass(frozen=True, eq=False)
class EnvelopeComparison:
    """Everything ``mor --compare`` found and decided."""

    spec_path: Path
    """The motor spec file."""
    options: CompareOptions
    """The options it ran with."""
    spec: MotorSpec
    """The motor spec."""
    log: EnvelopeLog
    """The torque-speed log, motor side."""
    comparison: Comparison
    """The comparison and its ladder."""
    data: dict[str, Any]
    """The ``hound-id/mor-compare/2`` JSON (without ``plot`` and ``out``)."""
    verdict: Verdict
    """``suggest`` (a significant effect is missing), ``explained`` or ``unexplained`` (nothing significant left,
    yet the model does not explain the log)."""
    motoring_speeds: tuple[float, float]
    """How far the log shows the motoring edges: forward (upper edge) and backward (lower edge) [rad/s], >= 0."""
    covers_speed: bool
    """Both motoring edges reach :data:`COVERAGE_FRACTION` of the no-load speed: the verdict holds at speed too."""
    ignored_warning: str | None
    """Warning about channels left out because they hold no finite value (None: none was)."""
    flag_warnings: tuple[str, ...]
    """The verdict's flags: why the model does not explain the log."""

    @property
    def warnings(self) -> tuple[str, ...]:
        """Every warning, in the order the command shows them."""
        return ((self.ignored_warning,) if self.ignored_warning else ()) + self.flag_warnings

    @property
    def suggestion(self) -> Suggestion | None:
        """The first significant candidate effect on the final model, if any."""
        return next((s for s in self.comparison.final.suggestions if s.significant), None)


def compare_envelope(spec_path: Path, log_path: Path, options: CompareOptions = CompareOptions()) -> EnvelopeComparison:
    """Compare a torque-speed log with a motor's operating region and name what explains the difference.

    Args:
        spec_path: Motor spec YAML whose region the log is compared with.
        log_path: Torque-speed log, CSV or Parquet.
        options: What to add, how to read the log, what will be written (:class:`CompareOptions`).

    Raises:
        SpecError: ``options.out`` is given but the model does not explain the log (the message says why).
        HoundIdError: A bad input (spec, robot, log, option, output path).
    """
    from hound_id.dyno.envelope.compare import compare
    from hound_id.dyno.envelope.offsets import coverage
    from hound_id.dyno.envelope.report import comparison_json
    from hound_id.dyno.envelope.report import verdict as verdict_of
    from hound_id.dyno.logs import load_envelope_log, parse_mapping
    from hound_id.mor.envelope import EnvelopeInputs, fitted_curve
    from hound_id.mor.spec_sheet import load_motor_spec

    plot, out, robot_path = options.plot, options.out, options.robot
    io.check_output(plot, (".png",), "plot", inputs=(spec_path, log_path, robot_path))
    io.check_output(out, (".yaml", ".yml"), "motor spec", inputs=(spec_path, log_path, robot_path))
    spec = load_motor_spec(spec_path)
    robot = None
    if robot_path is not None:
        from hound_id.mor.robot import load_robot

        robot = load_robot(robot_path)
    columns = options.columns if isinstance(options.columns, dict) else parse_mapping(options.columns, "--columns")
    units = options.units if isinstance(options.units, dict) else parse_mapping(options.units, "--units")
    log = load_envelope_log(log_path, columns, units, robot=robot, joint=options.joint)
    result = compare(log, EnvelopeInputs(spec, curve=fitted_curve(spec)), add=options.add, auto=options.auto)
    data = comparison_json(result)
    judged = verdict_of(result)
    if out is not None and not judged.explained:
        final, noise = result.final.offsets.rmse, result.final.offsets.noise
        raise SpecError(
            f"--out {out}: the model does not explain {log.source} (envelope error {final:.3g} N m, "
            f"{final / max(noise, 1e-12):.0f}x the noise level"
            + "".join(f"; {f.text}" for f in judged.flags)
            + "); a measured envelope is written only when it explains the log: run without --out to see what is "
            "missing"
        )
    cov = coverage(result.final.offsets)
    forward = max((cov.upper or (0.0, 0.0))[1], 0.0)  # the motoring edges: upper forward, lower backward
    backward = max(-(cov.lower or (0.0, 0.0))[0], 0.0)
    verdict: Verdict
    if any(s.significant for s in result.final.suggestions):
        verdict = "suggest"
    elif judged.explained:
        verdict = "explained"
    else:
        verdict = "unexplained"
    return EnvelopeComparison(
        spec_path=spec_path,
        options=options,
        spec=spec,
        log=log,
        comparison=result,
        data=data,
        verdict=verdict,
        motoring_speeds=(forward, backward),
        covers_speed=min(forward, backward) >= COVERAGE_FRACTION * spec.no_load_speed,
        ignored_warning=(
            f"{log.source}: column(s) {', '.join(log.ignored)} hold no finite value and were left out"
            if log.ignored
            else None
        ),
        flag_warnings=tuple(flag.text for flag in judged.flags),
    )


def envelope_spec_of(result: EnvelopeComparison, out: Path) -> dict[str, Any]:
    """The motor spec (``hound-id/motor/1``) with the measured envelope, as written to ``out``."""
    from hound_id.dyno.envelope.report import envelope_spec

    return envelope_spec(result.spec_path, out, result.comparison)


def write_outputs(result: EnvelopeComparison, dpi: int = 120) -> None:
    """Write ``options.plot`` and then ``options.out`` (the motor spec with the measured envelope), each atomically.

    Args:
        result: What :func:`compare_envelope` returned (it refused ``out`` already if the log is not explained).
        dpi: Resolution of the PNG [dots per inch].
    """
    plot, out = result.options.plot, result.options.out
    if plot is not None:
        from hound_id.dyno.envelope.plot import plot_compare

        fig = plot_compare(result.comparison)
        io.check_output(plot, (".png",), "plot")
        io.write_png(fig, plot, dpi)
    if out is not None:
        import yaml

        io.write_text(out, yaml.safe_dump(envelope_spec_of(result, out), sort_keys=False))


__all__ = [
    "COVERAGE_FRACTION",
    "CompareOptions",
    "EnvelopeComparison",
    "compare_envelope",
    "envelope_spec_of",
    "write_outputs",
]
