"""``hound-id dyno``: record a rig, serve a simulated rig, write a test plan."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Optional

import typer
from rich.table import Table

from hound_id.cli._render import console, err_console, print_json, warn
from hound_id.errors import HoundIdError
from hound_id.io import check_output


def _quiet_and_terminable() -> None:
    """pymodbus logs through the logging module; its messages would break our one-line errors. SIGTERM (kill, a
    shutdown) stops like Ctrl-C, so recordings end cleanly; background jobs of a script ignore SIGINT."""
    import logging
    import signal

    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)

    def stop(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, stop)


app = typer.Typer(
    help="Dyno acquisition: record a rig, serve a simulated rig, write a test plan.", no_args_is_help=True
)


@app.command("record")
def record_cmd(
    rig: Path = typer.Option(..., "--rig", help="Rig YAML (devices and channels)."),
    out: Path = typer.Option(
        ..., "--out", help="CSV log to write (canonical columns, SI); locked while recording, one recorder per file."
    ),
    duration: Optional[float] = typer.Option(
        None, "--duration", help="Seconds to record, > 0 (default: until Ctrl-C)."
    ),
    rate: float = typer.Option(500.0, "--rate", help="Sampling rate [Hz], 0.01 to 10000."),
    flush: float = typer.Option(0.25, "--flush", help="Longest time between writes to disk [s], 0.05 to 60."),
    overwrite: bool = typer.Option(
        False,
        "--overwrite",
        help="Replace a log already at --out, once the first sample is in (kept if none comes).",
    ),
    json_out: bool = typer.Option(False, "--json", help="Print the run summary as JSON (schema hound-id/record/2)."),
) -> None:
    """Poll the rig at a fixed rate into a CSV that fit-current reads; Ctrl-C stops cleanly.

    Ticks the rig did not answer (refused, timed out, hung) are booked as gaps, ticks the loop was too late for
    as missed. A full disk stops the run (status failed) with whole rows only in the file.
    """
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from hound_id.dyno.acquire.run import record_rig

    _quiet_and_terminable()
    columns = (TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[info]}"), TimeElapsedColumn())
    with Progress(*columns, console=err_console, disable=not err_console.is_terminal) as progress:
        task = progress.add_task("recording", total=duration, info="")

        def on_progress(r) -> None:  # type: ignore[no-untyped-def]
            progress.update(
                task,
                completed=r.duration if duration else None,
                info=f"{r.samples} samples, {r.achieved_rate:.0f} Hz, {r.missed} missed, {r.failed} in gaps",
            )

        result = record_rig(
            rig,
            out,
            rate_hz=rate,
            duration=duration,
            flush_interval=flush,
            overwrite=overwrite,
            on_progress=on_progress,
        )
    meta = dict(result.metadata)  # what the sidecar says
    if json_out:
        print_json(meta)
    else:
        table = Table(title=f"recorded {out}", title_justify="left")
        table.add_column("quantity")
        table.add_column("value", justify="right")
        for key in (
            "status",
            "samples",
            "rate_requested",
            "rate_achieved",
            "missed_ticks",
            "failed_ticks",
            "longest_interval",
            "duration",
        ):
            value = meta[key]
            table.add_row(key.replace("_", " "), f"{value:.4g}" if isinstance(value, float) else str(value))
        console.print(table)
        for gap in meta["gaps"][:10] if result.status != "failed" else ():  # a failed run: its one line (gaps in JSON)
            warn(f"gap {gap['start']:.3f}-{gap['end']:.3f} s ({gap['ticks']} ticks): {gap['reason']}")
        if not result.kept_existing:
            console.print(f"metadata in {result.sidecar}", highlight=False)
    if result.status == "failed":
        held = "" if result.kept_existing else " (the file holds what was recorded)"
        raise HoundIdError(f"{out}: recording stopped: {result.message}{held}")


@app.command("simulate-rig")
def simulate_rig_cmd(
    effects: str = typer.Option("linear,saturation", "--effects", help="Hidden effects, comma-separated."),
    seed: int = typer.Option(0, "--seed", help="Random seed of the simulated log."),
    plan: Optional[Path] = typer.Option(None, "--plan", help="Test plan YAML (hound-id dyno plan)."),
    port: int = typer.Option(5020, "--port", help="Modbus TCP port on 127.0.0.1 (0: any free port)."),
    rig_out: Path = typer.Option(Path("sim-rig.yaml"), "--rig-out", help="Where to write the rig file."),
    speedup: float = typer.Option(
        1.0, "--speedup", help="Play the plan this many times faster than real time (0.001 to 1000)."
    ),
    serial: bool = typer.Option(True, "--serial/--no-serial", help="Also stream lines on a pseudo-terminal."),
    duration: Optional[float] = typer.Option(
        None, "--duration", help="Serve for this long [s], > 0 (default: until Ctrl-C)."
    ),
) -> None:
    """Serve a simulated motor and torque transducer over Modbus TCP (and a serial pty) on 127.0.0.1."""
    from hound_id.dyno.acquire.run import serve_simulated_rig

    names = tuple(e.strip() for e in effects.split(",") if e.strip())
    _quiet_and_terminable()
    sim = serve_simulated_rig(
        names, rig_out, seed=seed, plan=plan, port=port, speedup=speedup, serial=serial, duration=duration
    )
    try:
        host, bound = sim.address
        console.print(
            f"simulated rig: Modbus TCP on {host}:{bound} (transducer unit 1, drive unit 2)"
            + (f", serial lines on {sim.serial_port}" if sim.serial_port else ""),
            highlight=False,
        )
        console.print(
            f"rig file: {rig_out}; hidden effects: {', '.join(names)}; seed {seed}; "
            f"plan {sim.period:.0f} s at speedup {speedup:g}. Ctrl-C stops.",
            highlight=False,
        )
        end = None if duration is None else time.monotonic() + duration
        while end is None or time.monotonic() < end:
            time.sleep(0.1)
    except KeyboardInterrupt:
        pass
    finally:
        sim.stop()


@app.command("plan")
def plan_cmd(
    max_current: float = typer.Option(..., "--max-current", help="The application's maximum current [A]."),
    out: Path = typer.Option(Path("plan.yaml"), "--out", help="Plan YAML to write."),
    speeds: Optional[str] = typer.Option(None, "--speeds", help="Plateau speeds [rad/s], comma-separated."),
    levels: Optional[int] = typer.Option(None, "--levels", help="Current step levels per sign (>= 1)."),
    overdrive: Optional[float] = typer.Option(None, "--overdrive", help="Top level / max current (> 1; 1.3)."),
    plateau: Optional[float] = typer.Option(None, "--plateau", help="Current excitation per plateau [s] (> 0)."),
    pause: Optional[float] = typer.Option(None, "--pause", help="Zero-current pause after each plateau [s] (>= 0)."),
    hold: Optional[float] = typer.Option(None, "--hold", help="Hold at max current to heat the winding [s] (>= 0)."),
    transition: Optional[float] = typer.Option(None, "--transition", help="Speed change between plateaus [s] (> 0)."),
    rise: Optional[float] = typer.Option(
        None, "--rise", help="Duration of each current edge [s] (> 0, shorter than a step; 0.001)."
    ),
    schedule_out: Optional[Path] = typer.Option(None, "--schedule", help="Also write the set-points as CSV."),
    json_out: bool = typer.Option(False, "--json", help="Print the plan as JSON (schema hound-id/plan/1)."),
) -> None:
    """Write a test plan under which every effect of the fit-current library is identifiable.

    The plan lasts at most an hour. The YAML and the --schedule table are written all or nothing.
    """
    from hound_id.dyno.acquire.plan import make_plan, write_plan

    check_output(out, (".yaml", ".yml"), "plan")
    check_output(schedule_out, (".csv", ".parquet"), "schedule")
    speed_list = None
    if speeds is not None:
        try:
            speed_list = [float(w) for w in speeds.split(",")]
        except ValueError as err:
            raise HoundIdError(f"--speeds: found {speeds!r}, expected numbers in rad/s such as -40,-2,2,40") from err
    plan = make_plan(
        max_current,
        speeds=speed_list,
        levels=levels,
        overdrive=overdrive,
        plateau=plateau,
        pause=pause,
        hold=hold,
        transition=transition,
        rise=rise,
    )
    data = write_plan(plan, max_current, out, schedule_out)
    if json_out:
        print_json(data)
        return
    console.print(
        f"plan written to {out}: {len(plan.speeds)} plateaus, {plan.duration:.0f} s, currents up to "
        f"{plan.overdrive * max_current:.3g} A, edges of {plan.current_rise_time:g} s",
        highlight=False,
    )
    for key, why in data["why"].items():
        console.print(f"  {key}: {why}", highlight=False)
