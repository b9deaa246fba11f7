"""How many workers a local cluster starts: at most one per usable CPU and per log, and the output says when it capped.

``--workers 100000`` once started no work and printed nothing for over a minute: every worker is a process. The
command-line tests pin the command to one CPU (its affinity mask, which its Dask workers inherit), so that the cap by
the CPUs shows on any machine with two or more.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from hound_id.dyno.current.run import FitCurrentOptions
from hound_id.dyno.fleet.engine import local_workers, run_fleet, usable_cpus
from hound_id.dyno.simulate.fleet import FLEET_MODEL
from hound_id.errors import FleetError
from hound_id.samples import samples_dir

SAMPLE = samples_dir() / "fleet"
LOGS = sorted(SAMPLE.glob("*.csv"))
OPTIONS = FitCurrentOptions(model=FLEET_MODEL)
CAN_PIN = hasattr(os, "sched_setaffinity") and len(os.sched_getaffinity(0)) >= 2


def _one_cpu() -> None:
    """``preexec_fn``: the child may run on one CPU only (its lowest)."""
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})


def run_fleet_cli(*args: str, cwd: Path, one_cpu: bool = False) -> subprocess.CompletedProcess[str]:
    """``hound-id fleet ARGS`` in a subprocess, as a user runs it (as ``tests.conftest.run_cli``), optionally pinned."""
    return subprocess.run(
        [sys.executable, "-m", "hound_id", "fleet", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=dict(os.environ, COLUMNS="200"),
        timeout=120,
        preexec_fn=_one_cpu if one_cpu else None,
    )


@pytest.mark.parametrize(
    ("asked", "logs", "cpus", "count"),
    [
        (100000, 12, 2, 2),  # the CPUs cap
        (100000, 1, 2, 1),  # the logs cap
        (5, 3, 3, 3),  # both
        (3, 12, 8, 3),  # within both: what was asked
        (2, 2, 2, 2),
        (None, 12, 2, 2),  # the default: one per CPU ...
        (None, 1, 8, 1),  # ... and per log, with nothing to say
    ],
)
def test_workers_are_capped_at_the_usable_cpus_and_the_logs(asked, logs, cpus, count):
    workers = local_workers(asked, logs, cpus)
    assert (workers.count, workers.asked) == (count, asked)
    if asked is not None and count < asked:
        assert workers.capped == (
            f"--workers {asked} capped at {count}: a local cluster has at most one worker per usable CPU ({cpus} here) "
            f"and per log ({logs})"
        )
    else:
        assert workers.capped is None
    assert local_workers(100000, None, cpus).count == cpus  # without a log count (client_for): the CPUs alone


@pytest.mark.parametrize("asked", [0, -3])
def test_zero_or_negative_workers_are_refused(asked):
    with pytest.raises(FleetError, match=f"^--workers: found {asked}, expected 1 or more$"):
        local_workers(asked, 4, 2)


@pytest.mark.parametrize("asked", ["0", "-3"])
def test_zero_or_negative_workers_are_one_line_and_exit_2_before_any_work(tmp_path, asked):
    proc = run_fleet_cli(str(LOGS[0]), "--workers", asked, "--csv", "fleet.csv", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip().splitlines() == [f"hound-id: error: --workers: found {asked}, expected 1 or more"]
    assert proc.stdout == "" and list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not CAN_PIN, reason="needs an affinity mask of two CPUs or more to pin a child to one")
def test_usable_cpus_are_the_affinity_mask_not_the_machines_count():
    code = "import os; from hound_id.dyno.fleet.engine import usable_cpus; print(usable_cpus(), os.cpu_count())"
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, preexec_fn=_one_cpu, check=True
    )
    pinned, machine = map(int, proc.stdout.split())
    assert pinned == 1 and machine >= 2
    assert usable_cpus() == len(os.sched_getaffinity(0))


@pytest.mark.skipif(not CAN_PIN, reason="needs an affinity mask of two CPUs or more to pin a child to one")
def test_workers_beyond_the_usable_cpus_are_capped_and_the_json_says_so(tmp_path):
    proc = run_fleet_cli(str(LOGS[0]), str(LOGS[1]), "--model", FLEET_MODEL, "--workers", "5", "--json",
                         cwd=tmp_path, one_cpu=True)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["schema"] == "hound-id/fleet/2" and data["fitted"] == 2
    engine = data["engine"]
    assert engine["local_cluster"] and engine["workers"] == 1 and engine["workers_asked"] == 5
    assert engine["capped"] == (
        "--workers 5 capped at 1: a local cluster has at most one worker per usable CPU (1 here) and per log (2)"
    )


def test_workers_beyond_the_logs_are_capped_and_the_table_says_so(tmp_path):
    proc = run_fleet_cli(str(LOGS[0]), "--model", FLEET_MODEL, "--workers", "3", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    cpus = usable_cpus()
    assert "1 fitted, 0 failed on 1 Dask workers (local cluster)" in proc.stdout
    note = f"note: --workers 3 capped at 1: a local cluster has at most one worker per usable CPU ({cpus} here) and "
    assert [line for line in proc.stdout.splitlines() if line.startswith("note: --workers")] == [note + "per log (1)"]


def test_the_default_is_one_worker_per_log_at_most_with_nothing_to_say():
    run = run_fleet(LOGS[:1], OPTIONS)
    assert run.workers == 1 and run.workers_asked is None and run.capped is None
    assert run.actuators[0].ok


def test_a_cluster_at_a_scheduler_keeps_its_workers(cluster):
    """The remote cluster decides: two workers for one log are neither capped nor reported as capped."""
    run = run_fleet(LOGS[:1], OPTIONS, scheduler=cluster.scheduler_address)
    assert run.workers == 2 and run.workers_asked is None and run.capped is None
    with pytest.raises(FleetError, match="give one or the other"):
        run_fleet(LOGS[:1], OPTIONS, scheduler=cluster.scheduler_address, workers=100000)
