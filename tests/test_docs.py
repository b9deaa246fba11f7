"""The manual (README.md and docs/): it builds with ``mkdocs build --strict``, and every code block that claims to
run is run here or by the test its tag names.

A block claims to run when it is fenced ``bash`` or ``python``; output, synopses and file contents are fenced
``text`` or ``yaml``. Python blocks start with ``# example: TAG``, a tag of :data:`PYTHON_TAGS` (the test that runs
it), or, for a trainer's snippet, ``# runs in: TRAINER (tests/PATH.py::TEST; ...)``: that test executes the block as
printed in the trainer's own environment by calling ``run_snippet(..., "TRAINER", ...)``
(``tests/export/test_doc_snippets.py``; :func:`python_block_problem` checks the call). Bash blocks are run line by
line, in page order, in one scratch folder holding the samples (so the export after the quickstart finds the
quickstart's fitted motor and foot), with these exceptions, each checked instead:

* the set-up commands are the test command itself: the second must be what ``.ci/run`` runs;
* ``benchmarks/`` scripts are timing runs, never run as tests: the script exists and its ``--help`` lists every
  option the line uses;
* a command naming an input that is not in the scratch folder (your own URDF, a public log folder you fetch): its
  ``--help`` lists every option the line uses.
"""

from __future__ import annotations

import ast
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT

DOCS = ROOT / "docs"
#: Pages in the order their bash blocks run (later pages use what the quickstart wrote); then the rest, sorted.
ORDER = ("README.md", "docs/quickstart.md", "docs/mor-compare.md", "docs/fleet.md", "docs/foot.md", "docs/export.md")
#: ``# example: TAG`` -> the test that runs that Python block.
PYTHON_TAGS = {
    "quickstart": "tests/test_docs.py::test_the_quickstart_python_runs",
    "effects_file": "tests/test_docs.py::test_the_effects_file_example_fits",
    "runtime": "tests/test_runtime.py::test_readme_runtime_example",
    "isaaclab": "tests/test_runtime.py::test_readme_isaaclab_actuator_example",
    "legged_gym": "tests/test_runtime.py::test_readme_legged_gym_example",
    "heat": "tests/test_runtime.py::test_readme_heat_example",
}
#: Options whose value is a file or folder a command writes (not an input it needs).
OUTPUTS = {"--out", "--plot", "--csv", "--rig-out", "--reports", "--schedule", "--markdown"}
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def pages() -> list[Path]:
    rest = sorted(p for p in [ROOT / "README.md", *DOCS.glob("*.md")] if str(p.relative_to(ROOT)) not in ORDER)
    return [ROOT / p for p in ORDER] + rest


def blocks(lang: str) -> list[tuple[Path, str]]:
    """(page, text) of every block fenced ``lang``, in :func:`pages` order."""
    return [(p, m.group(2)) for p in pages() for m in FENCE.finditer(p.read_text()) if m.group(1) == lang]


def example(tag: str) -> str:
    """The one Python block of the manual tagged ``# example: TAG``."""
    found = [text for _, text in blocks("python") if text.startswith(f"# example: {tag}\n")]
    assert len(found) == 1, f"{len(found)} blocks tagged {tag}"
    return found[0]


def snippet(trainer: str) -> str:
    """The one Python block of the manual that runs in ``trainer``: ``# runs in: TRAINER (...)``, as printed."""
    found = [text for _, text in blocks("python") if text.startswith(f"# runs in: {trainer} (")]
    assert len(found) == 1, f"{len(found)} blocks run in {trainer}"
    return found[0]


def commands(text: str) -> list[str]:
    """The command lines of a bash block: continuations joined, comments and blank lines dropped."""
    joined = re.sub(r"\\\n\s*", " ", text)
    return [line for line in joined.splitlines() if line.strip() and not line.lstrip().startswith("#")]


def options(line: str) -> list[str]:
    return sorted({t.split("=")[0] for t in re.findall(r"(?<![\w-])--[a-z][\w-]*", line)})  # comments too


def outputs(words: list[str]) -> set[str]:
    """What a command writes: the values of :data:`OUTPUTS` options and of ``>``, and what lies under them."""
    return {words[k] for k in range(1, len(words)) if words[k - 1] in OUTPUTS or words[k - 1] == ">"}


def missing_inputs(words: list[str], folder: Path, written: set[str]) -> list[str]:
    """Path-like words of a command that are inputs, neither in ``folder`` nor ``written`` by an earlier command (a
    file, or a folder the word lies in)."""
    out = []
    for k, word in enumerate(words):
        if k and (words[k - 1] in OUTPUTS or words[k - 1] == ">"):
            continue
        if ("/" in word or re.search(r"\.(csv|yaml|urdf|json|parquet|py)$", word)) and not word.startswith("-"):
            made = word in written or any(word.startswith(w.rstrip("/") + "/") for w in written)
            if not made and not any(folder.glob(word.strip("'"))) and not (folder / word).exists():
                out.append(word)
    return out


def help_lists(line: str, cwd: Path) -> None:
    """The line's program and subcommands print a --help that lists every option the line uses."""
    words = shlex.split(line.split(" #")[0].replace("[", " ").replace("]", " "))
    if words[0].endswith("python"):
        program = [sys.executable, words[1]]
    else:
        program = [sys.executable, "-m", "hound_id"] + [w for w in words[1:3] if re.fullmatch(r"[a-z][a-z-]*", w)]
    proc = subprocess.run([*program, "--help"], capture_output=True, text=True, cwd=cwd, timeout=120)
    assert proc.returncode == 0, f"{line}: {proc.stderr[-300:]}"
    for option in options(line):
        assert option in proc.stdout, f"{line}: {option} is not in {' '.join(program[-2:])} --help"


def test_the_manual_builds_strictly(tmp_path):
    """``mkdocs build --strict``: a broken link, a missing page or anchor, or a docstring the API pages cannot
    render fails it; the command-line page is generated from the commands themselves (mkdocs-click)."""
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    cli = (tmp_path / "site" / "cli" / "index.html").read_text()
    for name in ("fit-current", "fleet", "mor", "saturate", "foot", "export", "demo", "simulate-rig", "record"):
        assert f"hound-id {name}" in cli or f"hound-id dyno {name}" in cli, name
    assert "--effects-file" in cli and "--mujoco-actuator" in cli
    for page in (tmp_path / "site").glob("*/index.html"):
        html = page.read_text()
        # a list that follows a paragraph line without a blank line renders as one run-on paragraph
        runs = [p[:80] for p in re.findall(r"<p>((?:(?!</p>).)*?)</p>", html, re.S) if re.search(r"\n[-*] \S", p)]
        assert not runs, (page.parent.name, runs)
        assert not re.search(r":(?:attr|class|data|exc|func|meth|mod|obj):<code", html), page.parent.name


def test_the_readme_is_short_and_no_page_says_issue_n():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) < 250
    for path in [*pages(), *ROOT.glob("*.md")]:
        assert not re.search(r"(?i)\bissue \d", path.read_text()), path


#: ``# runs in: TRAINER (tests/PATH.py::TEST`` followed by ``;`` or ``)``.
RUNS_IN = re.compile(r"# runs in: (\w+) \((tests/[\w/]+\.py)::(test_\w+)[;)]")


def python_block_problem(first: str) -> str | None:
    """Why a Python block with this first line is not run by a test (None when it is): ``# example: TAG`` needs a tag
    of :data:`PYTHON_TAGS`; ``# runs in: TRAINER (tests/PATH.py::TEST...)`` needs TEST in that file to call
    ``run_snippet`` with ``"TRAINER"`` (the helper that executes the printed block in the trainer's environment)."""
    if first.startswith("# example: "):
        tag = first.removeprefix("# example: ")
        return None if tag in PYTHON_TAGS else f"{first!r}: {tag} is not a tag of PYTHON_TAGS"
    if not first.startswith("# runs in: "):
        return f"a python block starts {first!r}, neither '# example: TAG' nor '# runs in: TRAINER (TEST...)'"
    match = RUNS_IN.match(first)
    if not match:
        return f"{first!r} names no test: '# runs in: TRAINER (tests/PATH.py::TEST; ...)'"
    trainer, path, name = match.groups()
    if not (ROOT / path).is_file():
        return f"{first!r}: {path} does not exist"
    tests = [f for f in ast.parse((ROOT / path).read_text()).body if isinstance(f, ast.FunctionDef) and f.name == name]
    if not tests:
        return f"{first!r}: {path} has no {name}"
    runs = [
        call
        for call in ast.walk(tests[0])
        if isinstance(call, ast.Call)
        and getattr(call.func, "id", None) == "run_snippet"
        and any(isinstance(a, ast.Constant) and a.value == trainer for a in call.args)
    ]
    return None if runs else f"{first!r}: {name} does not call run_snippet(..., {trainer!r}, ...)"


def test_every_python_block_is_run_by_a_named_test():
    """Each Python block carries a tag whose test exists, or is a trainer snippet whose named test executes it in the
    trainer's environment (a new snippet without either fails here); one block per tag and per trainer."""
    for page, text in blocks("python"):
        problem = python_block_problem(text.splitlines()[0])
        assert problem is None, f"{page.name}: {problem}"
    for tag, where in PYTHON_TAGS.items():
        assert len([1 for _, t in blocks("python") if t.startswith(f"# example: {tag}\n")]) == 1, tag
        path, _, name = where.partition("::")
        assert f"def {name}(" in (ROOT / path).read_text(), (tag, where)
    trainers = [m.group(1) for _, t in blocks("python") if (m := RUNS_IN.match(t))]
    assert len(trainers) == len(set(trainers)) >= 4, trainers
    for trainer in trainers:
        assert snippet(trainer).startswith(f"# runs in: {trainer} (")


@pytest.mark.parametrize(
    "first",
    [
        "# sketch: genesis (its calls run in tests/export/in_trainers/genesis_check.py)",
        "# runs in: genesis",
        "# runs in: genesis (tests/export/test_nothing_here.py::test_the_genesis_snippet_runs_in_genesis)",
        "# runs in: genesis (tests/export/test_doc_snippets.py::test_the_genesis_snippet_is_run_somewhere)",
        "# runs in: mujoco (tests/export/test_doc_snippets.py::test_the_genesis_snippet_runs_in_genesis)",
        "# runs in: genesis (tests/export/test_trainers.py::"
        "test_genesis_applies_the_runtime_torques_from_the_open_urdf_and_fights_the_inner_one)",
        "# example: no_such_tag",
    ],
)
def test_a_python_block_no_test_runs_is_caught(first):
    """A trainer snippet whose named test is missing, or does not run that trainer's snippet, fails the check (as do
    the old ``# sketch:`` marker and an unknown example tag); the manual's own first lines pass it."""
    assert python_block_problem(first) is not None
    assert python_block_problem(snippet("genesis").splitlines()[0]) is None


def test_the_set_up_commands_are_the_test_command():
    ci = (ROOT / ".ci" / "run").read_text()
    setup = [c for _, text in blocks("bash") for c in commands(text) if c.startswith("python3 -m venv")]
    assert setup, "the set-up commands are missing"
    install, test = setup[0], setup[1]
    assert install == "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/hound-id demo"

    def plain(command: str) -> str:  # quiet flags aside, the same words
        return re.sub(r"\s+", " ", re.sub(r"\\\n", " ", command).replace(" -q", "")).strip()

    assert plain(test) == plain(ci.split('cd "$(dirname "$0")/.."')[1]), "the README's test command is not .ci/run's"


def test_every_bash_block_runs(tmp_path):
    """The manual's commands, as a new user runs them from a checkout (see the module docstring)."""
    (tmp_path / "data").symlink_to(ROOT / "data")
    (tmp_path / "benchmarks").symlink_to(ROOT / "benchmarks")
    (tmp_path / ".venv").symlink_to(Path(sys.executable).parent.parent)
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}:{os.environ['PATH']}", "COLUMNS": "120"}
    ran, checked, written = [], [], set()
    for page, text in blocks("bash"):
        lines = commands(text)
        if any(c.startswith("python3 -m venv") for c in lines):
            continue  # test_the_set_up_commands_are_the_test_command
        script = []
        for line in lines:
            words = shlex.split(line.split(" #")[0])
            if "benchmarks/" in line or missing_inputs(words, tmp_path, written):
                help_lists(line, tmp_path)
                checked.append(line)
            else:
                script.append(line)
                written |= outputs(words)
        if script:
            body = "set -e\ntrap 'kill $(jobs -p) 2>/dev/null || true' EXIT\n" + "\n".join(script) + "\n"
            proc = subprocess.run(
                ["bash", "-c", body], cwd=tmp_path, capture_output=True, text=True, env=env, timeout=900
            )
            assert proc.returncode == 0, f"{page.name}: {proc.stderr[-1500:]}"
            ran.extend(script)
    assert len(ran) >= 20 and len(checked) >= 10, (ran, checked)
    assert not [line for line in checked if "data/samples" in line and "benchmarks/" not in line], checked


def test_the_quickstart_python_runs(monkeypatch):
    monkeypatch.chdir(ROOT)
    ns: dict = {}
    exec(example("quickstart"), ns)
    assert ns["tau_applied"].shape == (4096, 12) and ns["tau_applied"].dtype == ns["tau_cmd"].dtype


def test_the_effects_file_example_fits(tmp_path):
    """The effects-file example, saved as the file it names and given to fit-current, fits its effect."""
    import json

    from tests.conftest import SAMPLES, run_cli

    (tmp_path / "my_effects.py").write_text(example("effects_file"))
    log = SAMPLES / "dyno" / "ilm85_dyno.csv"
    columns = "time=timestamp,current=iq,torque=adc_torque,velocity=speed,position=angle,temperature=winding_temp"
    proc = run_cli(
        "fit-current", str(log), "--columns", columns, "--effects-file", "my_effects.py", "--add", "bus_ripple",
        "--json", cwd=tmp_path,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "bus_ripple_sin" in json.loads(proc.stdout)["parameters"]


@pytest.mark.parametrize("line", ["hound-id fit-current x.csv --modle a", ".venv/bin/python benchmarks/foot.py --nope"])
def test_a_stale_option_in_the_manual_is_caught(line, tmp_path):
    """The --help check fails on an option the program does not have."""
    (tmp_path / "benchmarks").symlink_to(ROOT / "benchmarks")
    with pytest.raises(AssertionError, match="is not in"):
        help_lists(line, tmp_path)
