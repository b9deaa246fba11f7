"""The ``fleet`` verb: many logs in, one fit each on Dask, the fleet report and its outputs out.

:func:`fleet` checks every option before the work (so a bad option fails once, not on every log),
fits the logs (:mod:`hound_id.dyno.fleet.engine`) and compares them
(:mod:`hound_id.dyno.fleet.analyse`); :func:`write_outputs` writes the CSV, the plot and the per-log
reports. The command line and ``hound-id demo`` call these two and only render.
"""

from __future__ import annotations

import csv
import io as textio
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hound_id import io
from hound_id.dyno.current.run import FitCurrentOptions
from hound_id.dyno.fleet.analyse import Z_THRESHOLD, ActuatorFit, FleetReport, analyse, check_z, parse_tolerances
from hound_id.dyno.fleet.engine import FleetRun, find_logs, run_fleet, seconds_per_log


@dataclass(frozen=True)
class FleetOptions:
    """What ``hound-id fleet`` is asked besides the logs and the fit's own options."""

    scheduler: str | None = None
    """Address of an existing Dask scheduler (None: a local cluster)."""
    workers: int | None = None
    """Worker processes of the local cluster (None: one per usable CPU); capped at the usable CPUs and the logs."""
    z: float = Z_THRESHOLD
    """Modified z-score limit of an outlier."""
    tolerance: str | Mapping[str, float] | None = None
    """Least relative difference flagged per metric (``kt=0.05,coulomb=1``)."""
    csv: Path | None = None
    """The fleet table as CSV."""
    plot: Path | None = None
    """The fleet plot (PNG)."""
    reports: Path | None = None
    """Folder for each log's fit report (what ``fit-current --json`` prints)."""


@dataclass(frozen=True)
class FleetResult:
    """A fleet run and its report."""

    run: FleetRun
    """What the engine did."""
    report: FleetReport
    """The comparison."""
    options: FleetOptions
    """The options it ran with."""

    def to_dict(self) -> dict[str, Any]:
        """The JSON of ``fleet --json`` (schema ``hound-id/fleet/2``)."""
        run = self.run
        out = self.report.to_dict()
        per_log = seconds_per_log(run)
        out["engine"] = {
            "scheduler": run.scheduler,
            "local_cluster": self.options.scheduler is None,
            "workers": run.workers,
            "workers_asked": run.workers_asked,
            "capped": run.capped,
            "seconds": run.seconds,
            "seconds_per_log": None if math.isnan(per_log) else per_log,
            "refitted": list(run.refitted),
        }
        out["notes"] = [*out["notes"], *run.notes]
        out["csv"] = None if self.options.csv is None else str(self.options.csv)
        out["plot"] = None if self.options.plot is None else str(self.options.plot)
        out["reports"] = None if self.options.reports is None else str(self.options.reports)
        return out


def check_fit_options(options: FitCurrentOptions) -> None:
    """Fail once, before any work, on a model, window or column option every log would fail on."""
    from hound_id.dyno.current.effects import parse_model, parse_start_model
    from hound_id.dyno.logs import parse_mapping, parse_windows

    if options.flip_torque and options.auto_sign:
        from hound_id.errors import FitError

        raise FitError(
            "--flip-torque and --auto-sign: found both; pass --flip-torque to negate every log's torque, or "
            "--auto-sign to let each log's own slope decide"
        )
    parse_start_model(options.model)
    for extra in options.add:
        parse_model(extra)
    parse_windows(options.window)
    for value, option in ((options.columns, "--columns"), (options.units, "--units")):
        if value is None or isinstance(value, str):
            parse_mapping(value, option)
    if isinstance(options.units, str):  # a unit pint cannot read fails every log: say it once
        import numpy as np

        from hound_id.dyno.logs import UNITS, convert_units

        for name, text in parse_mapping(options.units, "--units").items():
            if name in UNITS:
                convert_units(np.zeros(1), text, "--units", name, name, "--units")


def fleet(
    logs: Sequence[str | Path],
    fit: FitCurrentOptions = FitCurrentOptions(),
    options: FleetOptions = FleetOptions(),
    on_result: Callable[[ActuatorFit, int, int], None] | None = None,
    on_pass: Callable[[str, int], None] | None = None,
) -> FleetResult:
    """Fit every log with the same ``fit`` options on Dask and compare the fleet.

    Args:
        logs: Log files, folders and glob patterns.
        fit: ``fit-current``'s options for every log (no plot, output or spec sheet).
        options: Engine, outlier limits and outputs (:class:`FleetOptions`).
        on_result: Called with each log's outcome as it arrives, the count done and the pass's count.
        on_pass: Called when a pass starts, with its description and log count.

    Raises:
        HoundIdError: No log, a bad option or output path, or a cluster that cannot be had.
    """
    paths = find_logs(logs)
    sources = [str(p) for p in paths]
    io.check_output(options.csv, (".csv",), "fleet table", inputs=sources)
    io.check_output(options.plot, (".png",), "plot", inputs=sources)
    io.check_folder(options.reports, "--reports")
    check_fit_options(fit)
    tolerances = parse_tolerances(options.tolerance)
    check_z(options.z)
    run = run_fleet(paths, fit, options.scheduler, options.workers, on_result=on_result, on_pass=on_pass)
    report = analyse(run.actuators, options.z, tolerances, model=run.model or None)
    return FleetResult(run, report, options)


def table_csv(report: FleetReport) -> str:
    """The fleet table as CSV text."""
    header, rows = report.table()
    buffer = textio.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buffer.getvalue()


def write_outputs(result: FleetResult, dpi: int = 120) -> None:
    """Write the per-log reports (all or none), the plot and the CSV, each atomically."""
    opts, report = result.options, result.report
    if opts.reports is not None:
        with io.staged_folder(opts.reports, "--reports") as folder:
            for a in report.fitted:
                assert a.report is not None
                target = folder / f"{a.name}.json"
                target.parent.mkdir(parents=True, exist_ok=True)  # names with folders when stems repeat
                io.write_json(target, a.report.to_json())
    if opts.plot is not None:
        from hound_id.dyno.fleet.plot import plot_fleet

        io.write_png(plot_fleet(report), opts.plot, dpi)
    if opts.csv is not None:
        io.write_text(opts.csv, table_csv(report))


__all__ = ["FleetOptions", "FleetResult", "check_fit_options", "fleet", "table_csv", "write_outputs"]
