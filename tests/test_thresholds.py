"""Every tuning threshold of the identification code says why it has its value and which test calibrates it.

A threshold is a module-level UPPER_CASE number (or tuple of numbers) in the modules of :data:`TUNED`. Its ``#:``
comment block (shared by constants that follow each other without a blank line) must say "Calibrated on" and
name tests as ``test_file::test_name`` (or a script in benchmarks/), each of which must exist.
"""

import ast
import functools
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TUNED = (
    "hound_id/dyno/envelope/walls.py",
    "hound_id/dyno/envelope/offsets.py",
    "hound_id/dyno/envelope/evidence.py",
    "hound_id/dyno/envelope/compare.py",
    "hound_id/dyno/envelope/report.py",
    "hound_id/dyno/current/diagnose.py",
    "hound_id/dyno/current/flags.py",
    "hound_id/dyno/current/trials.py",
    "hound_id/dyno/current/transducer.py",
    "hound_id/dyno/current/noise.py",
    "hound_id/dyno/current/still.py",
    "hound_id/dyno/current/neighbours.py",
    "hound_id/dyno/current/stretch.py",
    "hound_id/dyno/current/wander.py",
    "hound_id/dyno/fleet/scale.py",
    "hound_id/dyno/identify/engine.py",
    "hound_id/dyno/current/fit.py",
    "hound_id/dyno/current/stats.py",
    "hound_id/dyno/current/identifiable.py",
    "hound_id/dyno/current/search.py",
    "hound_id/dyno/current/slope.py",
    "hound_id/dyno/current/curve.py",
    "hound_id/dyno/logs/clean.py",
    "hound_id/dyno/logs/sensor.py",
    "hound_id/dyno/logs/envelope.py",
    "hound_id/dyno/artefacts.py",
)
#: Constants that are facts or formats, not tuning (a unit factor, a schema).
NOT_TUNING = {
    "BUS_FLOOR",
    "SPREAD_FLOOR",
    "MOVED",  # compare.py: a display rounding (a refitted parameter is named when it moved)
    "MAD_TO_SIGMA",  # logs.py: the Gaussian consistency constant of the MAD, 1 / Phi^-1(3/4), a fact of statistics
}
REFERENCE = re.compile(r"\b(test_[a-z0-9_]+)::(test_[a-z0-9_]+)\b")
BENCHMARK = re.compile(r"\bbenchmarks/([a-z0-9_]+\.py)\b")


def _numeric(node: ast.expr) -> bool:
    if isinstance(node, ast.Constant):
        return isinstance(node.value, (int, float)) and not isinstance(node.value, bool)
    if isinstance(node, ast.Tuple):
        return all(_numeric(e) for e in node.elts)
    if isinstance(node, ast.BinOp):
        return _numeric(node.left) and _numeric(node.right)
    return isinstance(node, ast.UnaryOp) and _numeric(node.operand)


def thresholds(path: Path) -> list[tuple[str, str]]:
    """(name, its comment block) of every numeric UPPER_CASE module constant."""
    lines = path.read_text().splitlines()
    out = []
    for node in ast.parse(path.read_text()).body:
        if not (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)):
            continue
        name = node.targets[0].id
        if not name.isupper() or not _numeric(node.value) or name in NOT_TUNING:
            continue
        k = node.lineno - 2  # the line above, 0-based
        while k >= 0 and re.match(r"^[A-Z_][A-Z0-9_]* = ", lines[k]):  # constants of one group share the comment
            k -= 1
        block = []
        while k >= 0 and lines[k].startswith("#:"):
            block.insert(0, lines[k][2:].strip())
            k -= 1
        out.append((name, " ".join(block)))
    return out


@functools.cache
def _test_names() -> dict[str, set[str]]:
    names: dict[str, set[str]] = {}
    for f in (ROOT / "tests").rglob("test_*.py"):
        names.setdefault(f.stem, set()).update(re.findall(r"^def (test_[a-z0-9_]+)", f.read_text(), re.M))
    return names


CASES = [(module, name, block) for module in TUNED for name, block in thresholds(ROOT / module)]


def test_the_tuned_modules_have_thresholds():
    assert len(CASES) >= 40  # the walk finds them (a broken walk would pass every case below vacuously)


@pytest.mark.parametrize(("module", "name", "block"), CASES, ids=[f"{m.split('/')[-1]}:{n}" for m, n, _ in CASES])
def test_each_threshold_names_its_reason_and_its_calibrating_test(module, name, block):
    tests = _test_names()
    assert block, f"{module}: {name} has no '#:' comment saying why it has its value"
    assert "Calibrated on" in block, f"{module}: {name}: its comment does not say which test calibrates it"
    refs, benches = REFERENCE.findall(block), BENCHMARK.findall(block)
    assert refs or benches, f"{module}: {name}: no test_file::test_name or benchmarks/ script named"
    for file, test in refs:
        assert test in tests.get(file, set()), f"{module}: {name} names {file}::{test}, which does not exist"
    for script in benches:
        assert (ROOT / "benchmarks" / script).is_file(), f"{module}: {name} names benchmarks/{script}: missing"


#: Modules whose numbers are design choices, not calibrated thresholds: each is a named module constant with a
#: ``#:`` reason, and the functions hold no other number than these small exact ones.
DESIGNED = ("hound_id/foot/optimise.py",)
PLAIN = (0, 1, 2, -1, 0.5)


def _inline_numbers(path: Path) -> list[tuple[int, object]]:
    """(line, value) of every number written inside a function, other than :data:`PLAIN`."""
    found: list[tuple[int, object]] = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for inner in ast.walk(node):
                if isinstance(inner, ast.Constant) and type(inner.value) in (int, float) and inner.value not in PLAIN:
                    found.append((inner.lineno, inner.value))
    return sorted(set(found))


@pytest.mark.parametrize("module", DESIGNED)
def test_the_designed_modules_name_every_number_with_its_reason(module):
    path = ROOT / module
    assert _inline_numbers(path) == [], f"{module}: numbers written inline (line, value); name them with a reason"
    named = thresholds(path)
    assert len(named) >= 20  # the walk finds them
    for name, block in named:
        assert len(block.split()) >= 5, f"{module}: {name} has no '#:' comment saying why it has its value"


def test_an_inline_number_is_found(tmp_path):
    """The walk sees a number inside a function (a broken walk would pass the designed modules vacuously)."""
    path = tmp_path / "m.py"
    path.write_text("X = 3\n\n\ndef f(a):\n    return a * 1e3 + 2\n")
    assert _inline_numbers(path) == [(5, 1e3)]
