"""Every sample generator (data/samples/*/make_*.py) writes what is shipped, on this machine and as another would.

The generators are found by walking the folder, so a new one is tested without new test code. Each runs in a fresh
process under three environments that change the last bits of floating-point results the way another machine does:
one BLAS/OpenMP thread, two threads, and "another CPU" (numpy's SIMD dispatch held to its baseline, so sin, cos and
exp take their portable kernels instead of AVX-512 ones, and on x86-64 OpenBLAS's Nehalem kernels). Files are compared
as numbers (tests/numbers.py), never as bytes.
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT, SAMPLES
from tests.numbers import assert_same_numbers, mismatches

GENERATORS = sorted(SAMPLES.glob("*/make_*.py"))
# Relative tolerance on every number: the differences seen between machines and environments are 1-2 ulp (2e-16);
# 1e-9 leaves seven orders of magnitude for a simulation to amplify them and still catches any change of a
# parameter, which moves the sixth significant digit or earlier.
REL = 1e-9
THREADS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def _other_cpu() -> dict[str, str]:
    """Settings that make numpy and OpenBLAS take the kernels of a plainer CPU than this one."""
    probe = (
        "import numpy as np\n"
        "try:\n    from numpy._core import _multiarray_umath as m\n"
        "except ImportError:\n    from numpy.core import _multiarray_umath as m\n"
        "have = m.__cpu_features__\n"
        "print(' '.join(f for f in m.__cpu_dispatch__ if have.get(f) and f not in m.__cpu_baseline__))"
    )
    extra = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.strip()
    env = {"NPY_DISABLE_CPU_FEATURES": extra} if extra else {}
    if platform.machine() in ("x86_64", "AMD64"):
        env["OPENBLAS_CORETYPE"] = "Nehalem"
    return env


ENVIRONMENTS = {
    "one thread": dict.fromkeys(THREADS, "1"),
    "two threads": dict.fromkeys(THREADS, "2"),
    "another CPU": None,  # filled in lazily: probing numpy costs a process
}


def _environment(name: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in THREADS and k != "NPY_DISABLE_CPU_FEATURES"}
    env.update(ENVIRONMENTS[name] or _other_cpu())
    env["PYTHONPATH"] = str(ROOT)
    return env


@pytest.mark.parametrize("environment", list(ENVIRONMENTS))
@pytest.mark.parametrize("generator", GENERATORS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_the_generator_writes_what_is_shipped(generator: Path, environment: str, tmp_path: Path):
    proc = subprocess.run(
        [sys.executable, str(generator), str(tmp_path)],
        capture_output=True,
        text=True,
        env=_environment(environment),
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    written = sorted(tmp_path.iterdir())
    assert written, f"{generator} wrote nothing into the folder it was given"
    for path in written:
        shipped = generator.parent / path.name
        assert shipped.is_file(), f"{generator} wrote {path.name}, which is not shipped beside it"
        assert_same_numbers(path, shipped, REL)


def test_the_generators_are_found():
    assert {p.parent.name for p in GENERATORS} >= {"commands", "dyno", "envelope", "fleet", "gait", "robots"}


# --- the comparison itself can fail


def test_last_bits_pass_and_a_changed_digit_fails():
    assert not mismatches('{"kt": 0.07186214170314299}', '{"kt": 0.071862141703143}', REL)
    assert not mismatches("t,i\n0.1,0.123457\n", "t,i\n0.1,0.123456\n", REL)  # rounded the other way
    assert mismatches("t,i\n0.1,0.123458\n", "t,i\n0.1,0.123456\n", REL)[0].line == 2
    assert not mismatches('{"kt": 0.0718621417}', '{"kt": 0.0718621418}', REL)  # one unit in the last digit
    assert mismatches('{"kt": 0.0718621417}', '{"kt": 0.0718621419}', REL)  # two


def test_words_count_and_special_values():
    assert mismatches("time,current\n", "time,torque\n", REL)[0].found == "time,current"
    assert mismatches("1,2\n3\n", "1,2\n3,4\n", REL)
    assert not mismatches("nan,resonance,inf\n", "nan,resonance,inf\n", REL)
    assert mismatches("nan\n", "0\n", REL) and mismatches("inf\n", "1e308\n", REL)
    assert not mismatches('<origin xyz="0 -0.08 0"/>', '<origin xyz="0 -0.08 0.0"/>', REL)
    assert mismatches('<origin xyz="0 -0.08 0"/>', '<origin xyz="0 0.08 0"/>', REL)


def test_a_regenerated_sample_stays_small():
    assert (SAMPLES / "gait" / "hound_running.csv").stat().st_size < 400_000
