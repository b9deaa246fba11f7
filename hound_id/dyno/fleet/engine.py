"""Fit many actuator logs in parallel on Dask (``dask.distributed``): a local cluster, or an existing one.

The same code path runs in both cases: a :class:`dask.distributed.Client` on a
:class:`~dask.distributed.LocalCluster` of one single-threaded worker process per usable CPU (the
default), or on the scheduler at ``--scheduler ADDRESS``. A local cluster never has more workers than
the CPUs this process may run on, nor than logs (:func:`local_workers`); a remote cluster has the
workers it has. Each log's bytes are read here and shipped with its task, so workers on other
machines need hound-id installed but no shared file system. At most two tasks per worker are in
flight, so a fleet of thousands of logs never sits in memory at once. A log that fails (a bad input,
or a worker that dies) is reported and the others go on.

With ``--auto`` every log first climbs its own ladder of effects; the fleet is then compared on one
model, the effects more than half of the logs needed (:func:`common_model`), and the logs that ended with
another model are fitted again with it (a second pass on the same cluster).
"""

from __future__ import annotations

import glob
import logging
import math
import os
import socket
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hound_id.dyno.fleet.analyse import ActuatorFit
from hound_id.errors import FleetError, HoundIdError
from hound_id.io import check_input

if TYPE_CHECKING:
    from dask.distributed import Client

    from hound_id.dyno.current.run import FitCurrentOptions

#: File suffixes taken from a folder.
LOG_SUFFIXES = (".csv", ".parquet", ".pq")
#: Logs larger than this are scattered to the workers ahead of their task instead of inside it [bytes].
SCATTER_BYTES = 1 << 20
#: Tasks in flight per worker.
IN_FLIGHT = 2
#: How long to try to reach an existing scheduler [s].
CONNECT_TIMEOUT = 10.0
#: How long to wait for an existing cluster to have a worker [s].
WORKER_WAIT = 30.0


@dataclass(frozen=True)
class FleetRun:
    """What the engine did."""

    actuators: tuple[ActuatorFit, ...]
    """Every log's outcome, in name order (with ``auto``, the common model's fit where one was needed)."""
    model: tuple[str, ...]
    """The model every fitted actuator has (empty when none was fitted)."""
    scheduler: str
    """The scheduler's address (a local cluster's when none was given)."""
    workers: int
    """Workers the cluster had when the work started."""
    seconds: float
    """Wall time of the fits, cluster start excluded [s]."""
    refitted: tuple[str, ...] = ()
    """Actuators fitted a second time with the common model (``auto`` only)."""
    notes: tuple[str, ...] = ()
    """What the user should know about the run (worker versions)."""
    workers_asked: int | None = None
    """The local cluster's worker count the caller asked for (None: the default, or a cluster at a scheduler)."""
    capped: str | None = None
    """Why the local cluster has fewer workers than asked, in one sentence (None: it has what was asked)."""


@dataclass(frozen=True)
class LocalWorkers:
    """How many worker processes a local cluster starts, and why."""

    count: int
    """Worker processes to start (one thread each)."""
    asked: int | None
    """The count asked for (None: the default, one per usable CPU)."""
    capped: str | None
    """Why ``count`` is below ``asked``, in one sentence (None when it is not)."""


def usable_cpus() -> int:
    """The CPUs this process may run on: its affinity mask where the system has one (Linux), else the machine's."""
    affinity = getattr(os, "sched_getaffinity", None)
    if affinity is not None:
        return max(1, len(affinity(0)))
    return os.cpu_count() or 1


def local_workers(asked: int | None, logs: int | None = None, cpus: int | None = None) -> LocalWorkers:
    """A local cluster's worker count: ``asked`` (default: one per CPU), at most one per usable CPU and per log.

    A worker is one single-threaded process, so more workers than CPUs only share them (and each costs a process
    start and its memory: ``--workers 100000`` would start no work for minutes); a worker beyond the logs would idle.

    Args:
        asked: Workers asked for (``--workers``); None for the default.
        logs: Logs to fit (None: no limit from them).
        cpus: Usable CPUs (None: :func:`usable_cpus`).

    Raises:
        FleetError: ``asked`` is not positive.
    """
    if asked is not None and asked < 1:
        raise FleetError(f"--workers: found {asked}, expected 1 or more")
    cpus = usable_cpus() if cpus is None else cpus
    limit = cpus if logs is None else max(1, min(cpus, logs))
    count = limit if asked is None else min(asked, limit)
    if asked is None or count == asked:
        return LocalWorkers(count, asked, None)
    per_log = "" if logs is None else f" and per log ({logs})"
    return LocalWorkers(
        count,
        asked,
        f"--workers {asked} capped at {count}: a local cluster has at most one worker per usable CPU ({cpus} here)"
        + per_log,
    )


def find_logs(items: Sequence[str | Path]) -> list[Path]:
    """The logs named by files, folders (their CSV and Parquet files) and glob patterns, without repeats.

    Raises:
        FleetError: An item names nothing, or no log is found.
    """
    found: dict[str, Path] = {}
    for item in items:
        path = Path(item)
        if path.is_dir():
            matches = sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in LOG_SUFFIXES)
            if not matches:
                raise FleetError(
                    f"{path}: the folder holds no log ({', '.join(LOG_SUFFIXES)} files); give log files or another "
                    "folder"
                )
        elif path.is_file():
            matches = [path]
        elif path.exists():  # a FIFO or device: never read (it would block or never end)
            check_input(path, "log (.csv or .parquet)", FleetError)
            matches = []
        elif glob.has_magic(str(item)):
            matches = sorted(Path(p) for p in glob.glob(str(item), recursive=True) if Path(p).is_file())
            if not matches:
                raise FleetError(f"{item}: no file matches the pattern; check it, or quote it so the shell passes it")
        else:
            raise FleetError(f"{path}: no such file or folder; give log files, folders or a glob pattern")
        for match in matches:
            found.setdefault(str(match.resolve()), match)
    if not found:
        raise FleetError("no log given; give log files, folders or a glob pattern")
    return list(found.values())


def actuator_names(paths: Sequence[Path]) -> list[str]:
    """Each log's actuator name: its file name without the suffix, or its path when two names repeat."""
    stems = [p.stem for p in paths]
    if len(set(stems)) == len(stems):
        return stems
    resolved = [p.resolve() for p in paths]
    root = Path(os.path.commonpath([str(r.parent) for r in resolved]))
    names = [str(r.relative_to(root).with_suffix("")) for r in resolved]
    if len(set(names)) == len(names):
        return names
    return [str(r.relative_to(root)) for r in resolved]  # act.csv beside act.parquet: the suffix tells them apart


def fit_log(name: str, source: str, data: bytes, options: FitCurrentOptions) -> ActuatorFit:
    """Fit one log from its bytes (runs on a worker); never raises: a failure is an :class:`ActuatorFit`."""
    import hound_id
    from hound_id.dyno.current.run import fit_current

    start = time.perf_counter()
    where = f"{socket.gethostname()}:{os.getpid()}"
    with tempfile.TemporaryDirectory(prefix="hound-id-fleet-") as folder:
        local = Path(folder) / (Path(source).name or "log.csv")

        def relabel(text: str) -> str:  # messages name the log as the user gave it, not the worker's copy
            return text.replace(str(local), source)

        try:
            local.write_bytes(data)
            report = fit_current(local, options).report.relabel(str(local), source)
            error, bug = None, False
        except HoundIdError as err:
            report, error, bug = None, relabel(str(err)), False
            if "rerun with --flip-torque" in error:  # --flip-torque would negate every log of the fleet
                error += " (in a fleet, --auto-sign lets each log's own slope decide)"
        except Exception as err:  # a fault in hound-id: reported with its traceback, and the fleet goes on
            report, bug = None, True
            error = relabel(f"{type(err).__name__}: {err} (a bug in hound-id; please report it)\n") + relabel(
                "".join(traceback.format_exception(err))
            )
    return ActuatorFit(
        name, source, report, error, bug, time.perf_counter() - start, where, getattr(hound_id, "__version__", "")
    )


@contextmanager
def _quiet() -> Iterator[None]:
    """Dask's own log lines are not the user's business: a log that fails is reported by the fleet itself, and a
    worker that loses its scheduler's heartbeat while the cluster closes logs a traceback at ERROR level."""
    logger = logging.getLogger("distributed")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        logger.setLevel(level)


@contextmanager
def client_for(scheduler: str | None, workers: int | None) -> Iterator[Client]:
    """A Dask client: on a new local cluster or at ``scheduler``.

    The local cluster has ``workers`` processes (default one per usable CPU), capped at the usable CPUs
    (:func:`local_workers`); a cluster at ``scheduler`` has its own workers.

    Raises:
        FleetError: ``workers`` is not positive, or the scheduler cannot be reached or has no worker.
    """
    from dask.distributed import Client, LocalCluster

    if workers is not None and workers < 1:
        raise FleetError(f"--workers: found {workers}, expected 1 or more")
    with _quiet():
        if scheduler is None:
            n = local_workers(workers).count
            with (
                LocalCluster(
                    n_workers=n,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.CRITICAL,
                ) as cluster,
                Client(cluster) as client,
            ):
                yield client
            return
        if workers is not None:
            raise FleetError("--workers: a cluster at --scheduler has its own workers; give one or the other")
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT}s")
        except (OSError, ValueError, TypeError) as err:
            raise FleetError(
                f"--scheduler {scheduler}: cannot reach a Dask scheduler there in {CONNECT_TIMEOUT:g} s ({err}); "
                "start one with 'dask scheduler' and workers with 'dask worker ADDRESS', or leave --scheduler out "
                "for a local cluster"
            ) from err
        with client:
            try:
                client.wait_for_workers(1, timeout=WORKER_WAIT)
            except (TimeoutError, OSError) as err:
                raise FleetError(
                    f"--scheduler {scheduler}: the scheduler has no worker after {WORKER_WAIT:g} s; start workers with "
                    f"'dask worker {scheduler}'"
                ) from err
            yield client


def _map(
    client: Client,
    jobs: Sequence[tuple[str, Path]],
    options: FitCurrentOptions,
    on_result: Callable[[ActuatorFit], None] | None,
) -> list[ActuatorFit]:
    """Fit ``jobs`` (name, path) on the cluster, keeping at most IN_FLIGHT tasks per worker."""
    from dask.distributed import as_completed

    results: list[ActuatorFit] = []

    def done(fit: ActuatorFit) -> None:
        results.append(fit)
        if on_result is not None:
            on_result(fit)

    queue = iter(jobs)
    running = as_completed()
    owner: dict[Any, tuple[str, Path]] = {}

    def submit_next() -> bool:
        for name, path in queue:
            try:
                data = path.read_bytes()
            except OSError as err:
                done(ActuatorFit(name, str(path), None, f"{path}: cannot read the log ({err.strerror or err})"))
                continue
            arg: Any = client.scatter(data, hash=False) if len(data) > SCATTER_BYTES else data
            future = client.submit(fit_log, name, str(path), arg, options, pure=False)
            owner[future.key] = (name, path)
            running.add(future)
            return True
        return False

    width = IN_FLIGHT * max(1, len(client.scheduler_info().get("workers", {})))
    for _ in range(width):
        if not submit_next():
            break
    for future in running:
        try:
            fit = future.result()
        except Exception as err:  # the worker died (out of memory, killed): that log fails, the rest go on
            name, path = owner[future.key]
            fit = ActuatorFit(
                name, str(path), None, f"{path}: the worker fitting it failed ({type(err).__name__}: {err})", True
            )
        future.release()
        done(fit)
        submit_next()
    return results


def common_model(fits: Sequence[ActuatorFit], start: Sequence[str]) -> tuple[str, ...]:
    """The fleet's model: ``start``'s effects, then each effect more than half of the fitted logs added.

    An effect only a few logs need (a faulty bearing's extra friction, or logs of other protocols) stays out:
    those logs are fitted without it and their verdict says what they miss, instead of every log carrying
    terms it cannot identify. Order: the order in which the logs (by name) added them.
    """
    fitted = [f for f in sorted(fits, key=lambda f: f.name) if f.report is not None]
    counts = Counter(e for f in fitted if f.report is not None for e in set(f.report.model))
    model = list(start)
    for fit in fitted:
        assert fit.report is not None
        model += [e for e in fit.report.model if e not in model and 2 * counts[e] > len(fitted)]
    return tuple(model)


def run_fleet(
    logs: Sequence[Path],
    options: FitCurrentOptions,
    scheduler: str | None = None,
    workers: int | None = None,
    on_result: Callable[[ActuatorFit, int, int], None] | None = None,
    on_pass: Callable[[str, int], None] | None = None,
) -> FleetRun:
    """Fit every log with the same options on Dask; with ``options.auto``, then compare on a common model.

    Args:
        logs: The logs (:func:`find_logs`).
        options: ``fit-current``'s options for every log (no plot, fitted-motor output or spec sheet).
        scheduler: Address of an existing Dask scheduler; None starts a local cluster.
        workers: Worker processes of the local cluster (default: one per usable CPU); capped at the usable CPUs and
            the logs (:func:`local_workers`, said in ``FleetRun.capped``).
        on_result: Called with each outcome, the count done and the count in this pass.
        on_pass: Called with a description and the log count when a pass starts.

    Raises:
        FleetError: Options a fleet cannot take, or a cluster that cannot be had.
    """
    start_model = _start_model(options)
    jobs = list(zip(actuator_names(logs), logs, strict=True))
    local = local_workers(workers, len(jobs)) if scheduler is None else None  # a remote cluster decides its own
    with client_for(scheduler, workers if local is None else local.count) as client:
        address = str(client.scheduler.address)
        versions = client.run(_version)
        count = len(versions)
        begin = time.perf_counter()
        if on_pass is not None:
            on_pass("fitting", len(jobs))
        fits = {f.name: f for f in _map(client, jobs, options, _counted(on_result, len(jobs)))}
        model = common_model(list(fits.values()), start_model)
        again = [
            (name, path)
            for name, path in jobs
            if (report := fits[name].report) is not None and set(report.model) != set(model)
        ]
        if again:
            if on_pass is not None:
                on_pass(f"fitting again with the fleet's model {'+'.join(model)}", len(again))
            common = replace(options, model="+".join(model), add=(), auto=False)
            for fit in _map(client, again, common, _counted(on_result, len(again))):
                fits[fit.name] = fit
        seconds = time.perf_counter() - begin
    notes = _version_notes(versions)
    fitted = [f for f in fits.values() if f.report is not None]
    return FleetRun(
        actuators=tuple(sorted(fits.values(), key=lambda f: f.name)),
        model=model if fitted else (),
        scheduler=address,
        workers=count,
        seconds=seconds,
        refitted=tuple(sorted(name for name, _ in again)),
        notes=notes,
        workers_asked=None if local is None else local.asked,
        capped=None if local is None else local.capped,
    )


def _start_model(options: FitCurrentOptions) -> list[str]:
    """The model every log starts from (``--model`` and each ``--add``), after refusing the options a fleet cannot
    take."""
    from hound_id.dyno.current.effects import parse_model, parse_start_model

    for given, option in ((options.plot, "--plot"), (options.out, "--out"), (options.spec, "--spec")):
        if given is not None:
            raise FleetError(f"{option}: not taken by a fleet run; fit one log with 'hound-id fit-current' for it")
    if options.effects_files:
        raise FleetError("--effects-file: not taken by a fleet run (workers cannot run your file)")
    start_model = [*parse_start_model(options.model)]
    for extra in options.add:
        start_model += [e for e in parse_model(extra) if e not in start_model]
    return start_model


def _counted(on_result: Callable[[ActuatorFit, int, int], None] | None, total: int) -> Callable[[ActuatorFit], None]:
    """A callback for one pass of ``total`` logs that calls ``on_result`` with each outcome and the count done."""
    seen = [0]

    def call(fit: ActuatorFit) -> None:
        seen[0] += 1
        if on_result is not None:
            on_result(fit, seen[0], total)

    return call


def _version_notes(versions: Mapping[str, str]) -> tuple[str, ...]:
    """A note for each worker (address -> its hound-id version) that runs another version than this machine."""
    import hound_id

    mine = getattr(hound_id, "__version__", "")
    return tuple(
        f"worker {w} runs hound-id {v}, this machine {mine}: fits may differ" for w, v in versions.items() if v != mine
    )


def _version() -> str:
    import hound_id

    return str(getattr(hound_id, "__version__", ""))


def seconds_per_log(run: FleetRun) -> float:
    """Wall time per log [s] (NaN for an empty run)."""
    n = len(run.actuators) + len(run.refitted)
    return run.seconds / n if n else math.nan
