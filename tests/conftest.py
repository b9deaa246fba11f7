from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import settings

# CI draws the same examples on every run (a property test's draw cannot differ between the run that passed here and
# the run that lands); HYPOTHESIS_PROFILE=explore draws fresh ones, as a developer does before committing.
settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "data" / "samples"
MOTOR = SAMPLES / "motors" / "hound_ilm85.yaml"
SMALL_MOTOR = SAMPLES / "motors" / "qdd_small.yaml"
ROBOT = SAMPLES / "robots" / "hound_like.yaml"


def restore_sigint() -> None:
    """``preexec_fn`` of a child a test interrupts: SIGINT's default action (Ctrl-C raises KeyboardInterrupt).

    A shell without job control starts a background job with SIGINT ignored, and children inherit that; Python then
    installs no KeyboardInterrupt handler, so a test sending SIGINT would wait on a child that never hears it.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run_cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """Run the real command line in a subprocess, as a user would."""
    env = dict(os.environ, COLUMNS="200")
    return subprocess.run(
        [sys.executable, "-m", "hound_id", *args], capture_output=True, text=True, cwd=cwd, env=env, timeout=300
    )


@pytest.fixture
def write_yaml(tmp_path: Path):
    def _write(name: str, text: str) -> Path:
        path = tmp_path / name
        path.write_text(text)
        return path

    return _write
