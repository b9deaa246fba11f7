"""Sensitivity of the tuned thresholds: does the test that a threshold names fail when the threshold moves?

For every threshold that tests/test_thresholds.py walks (a numeric UPPER_CASE constant of the tuned modules with a
"Calibrated on" comment), the script copies this checkout's ``hound_id`` into a temporary folder, multiplies the
constant by each ``--factors`` value there (integers rounded, at least 1; tuples element-wise) and runs the tests
its comment names against that copy (``pytest -x``, a fresh process each). A threshold is *calibrated* by its tests
when at least one factor makes one of them fail; *loose* when none does (the value could move that far unnoticed).
The baseline, run first in the same way, is the unmodified copy: every named test must pass there.

Prints a table and the figures as JSON (``--json``: JSON only). It takes a while: about 10-30 s per case.

Run: .venv/bin/python benchmarks/thresholds.py [--factors 0.5,2] [--only walls.py:LAG_MAX,...] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.test_thresholds import BENCHMARK, REFERENCE, TUNED, thresholds  # noqa: E402


def test_ids(block: str) -> list[str]:
    """pytest node ids of the tests a comment block names."""
    files = {f.stem: f for f in (ROOT / "tests").rglob("test_*.py")}
    return [f"{files[f].relative_to(ROOT)}::{t}" for f, t in REFERENCE.findall(block) if f in files]


def perturbed(source: str, name: str, factor: float) -> str:
    """The module source with ``NAME = value`` scaled by ``factor``."""
    match = re.search(rf"^{name} = (.+)$", source, re.M)
    assert match is not None, name
    value = eval(match.group(1), {})  # a numeric literal expression (tests/test_thresholds.py checked it)

    def scale(v: float) -> float:
        return max(1, round(v * factor)) if isinstance(v, int) else v * factor

    new = tuple(scale(v) for v in value) if isinstance(value, tuple) else scale(value)
    return source[: match.start(1)] + repr(new) + source[match.end(1) :]


def run_tests(tree: Path, ids: list[str]) -> bool:
    """Whether the tests pass against the hound_id copy in ``tree``."""
    env = {**os.environ, "PYTHONPATH": f"{tree}{os.pathsep}{ROOT}"}
    # Run from the copy's folder (python puts the working directory first on sys.path) and with --import-mode=append
    # (pytest must not put this checkout's root, and its hound_id, before the copy).
    cmd = [sys.executable, "-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", "--import-mode=append",
           "--rootdir", str(ROOT), *(str(ROOT / i) for i in ids)]  # fmt: skip
    return subprocess.run(cmd, cwd=tree, env=env, capture_output=True).returncode == 0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--factors", default="0.5,2")
    parser.add_argument("--only", default="", help="comma-separated module:NAME cases")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    factors = [float(f) for f in args.factors.split(",")]
    only = {c for c in args.only.split(",") if c}
    rows = []
    baselines: dict[tuple[str, ...], bool] = {}  # the unmodified copy, once per set of named tests
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp)
        shutil.copytree(ROOT / "hound_id", tree / "hound_id")
        for module in TUNED:
            path = tree / module
            original = path.read_text()
            for name, block in thresholds(ROOT / module):
                case = f"{Path(module).name}:{name}"
                if only and case not in only:
                    continue
                ids = test_ids(block)
                benches = BENCHMARK.findall(block)
                start = time.perf_counter()
                if ids and tuple(ids) not in baselines:
                    baselines[tuple(ids)] = run_tests(tree, ids)
                base = baselines.get(tuple(ids))
                fails = {}
                for factor in factors:
                    path.write_text(perturbed(original, name, factor))
                    fails[str(factor)] = not run_tests(tree, ids) if ids else None
                    path.write_text(original)
                calibrated = any(v for v in fails.values()) if ids else None
                rows.append({"case": case, "tests": ids, "benchmarks": benches, "baseline_passes": base,
                             "fails_at": fails, "calibrated": calibrated,
                             "seconds": round(time.perf_counter() - start, 1)})  # fmt: skip
                if not args.json:
                    mark = {True: "calibrated", False: "LOOSE", None: "benchmark only"}[calibrated]
                    print(f"{case:32s} {mark:15s} fails at x{[f for f, v in fails.items() if v]}", flush=True)
    result = {
        "schema": "hound-id/bench-thresholds/1",
        "date": time.strftime("%Y-%m-%d"),
        "factors": factors,
        "cases": rows,
        "calibrated": sum(r["calibrated"] is True for r in rows),
        "loose": [r["case"] for r in rows if r["calibrated"] is False],
    }
    if not args.json:
        print(f"{result['calibrated']} of {len(rows)} thresholds make a named test fail; loose: {result['loose']}")
    print(json.dumps(result, indent=2 if args.json else None))


if __name__ == "__main__":
    main()
