"""The bad-input catalogue by class: every input slot of every command against each kind of file that is not
what it should be (a FIFO, a device, a folder, a file far too large), every YAML slot against each structure
hound-id does not read (aliases that expand exponentially or into themselves, keys that are lists, nesting
thousands deep), and every model the command line accepts.

Each case runs the real entry point in this process and must exit 2 with one line naming the file, print no
traceback, leave no file behind and never block: a FIFO is opened for writing from a watchdog thread after
:data:`WATCHDOG` seconds, so that a command that regressed to reading it gets an end of file (and fails this
test on its message) instead of hanging the suite; devices are links to /dev/null for the same reason.
"""

from __future__ import annotations

import contextlib
import errno
import os
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tests.cli.test_bad_input_catalogue import (
    COMMANDS,
    DYNO,
    DYNO_COLUMNS,
    ENVELOPE_COLUMNS,
    files_under,
    invoke,
)
from tests.conftest import MOTOR, ROBOT, restore_sigint, run_cli

#: Seconds after which a FIFO input gets a writer (and so an end of file), should a command open it.
WATCHDOG = 20.0

#: Every input file slot: (id, argv with IN.<suffix> where the file goes).
SLOTS: dict[str, tuple[str, ...]] = {
    "mor-spec": ("mor", "--spec", "IN.yaml"),
    "fit-spec": ("fit-current", str(DYNO), "--columns", DYNO_COLUMNS, "--spec", "IN.yaml"),
    "fit-log": ("fit-current", "IN.csv", "--columns", DYNO_COLUMNS),
    "fit-effects-file": ("fit-current", str(DYNO), "--columns", DYNO_COLUMNS, "--effects-file", "IN.py"),
    "compare-log": ("mor", "--spec", str(MOTOR), "--compare", "IN.csv", "--columns", ENVELOPE_COLUMNS),
    "saturate-commands": ("saturate", "IN.csv", "--robot", str(ROBOT)),
    "saturate-robot": ("saturate", str(COMMANDS), "--robot", "IN.yaml"),
    "foot-gait": ("foot", "--gait", "IN.csv"),
    "foot-leg": ("foot", "--optimise", "--leg", "IN.urdf", "--angles", "30,40"),
    "foot-material": ("foot", "--optimise", "--material", "IN.yaml"),
    "export-robot": ("export", "--robot", "IN.yaml", "--out", "bundle"),
    "export-fit": ("export", "--robot", str(ROBOT), "--fit", "IN.yaml", "--out", "bundle"),
    "export-urdf": ("export", "--robot", str(ROBOT), "--urdf", "IN.urdf", "--out", "bundle"),
    "export-foot": ("export", "--robot", str(ROBOT), "--foot", "IN.json", "--out", "bundle"),
    "record-rig": ("dyno", "record", "--rig", "IN.yaml", "--out", "log.csv", "--duration", "1"),
    "simulate-rig-plan": ("dyno", "simulate-rig", "--plan", "IN.yaml", "--duration", "1", "--port", "0"),
    "fleet-log": ("fleet", "IN.csv", "--workers", "1"),
}
YAML_SLOTS = {key: argv for key, argv in SLOTS.items() if "IN.yaml" in argv}


def _in_name(argv: tuple[str, ...]) -> str:
    return next(a for a in argv if a.startswith("IN."))


@contextlib.contextmanager
def fifo_watchdog(fifo: Path) -> Iterator[None]:
    """Open ``fifo`` for writing (and close it) once a reader holds it, after :data:`WATCHDOG` seconds."""
    done = threading.Event()

    def release() -> None:
        if done.wait(WATCHDOG):
            return
        while not done.is_set():
            try:
                fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
            except OSError as err:  # ENXIO: nobody reads it
                if err.errno != errno.ENXIO:
                    return
                done.wait(0.1)
                continue
            os.close(fd)

    thread = threading.Thread(target=release, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()


def run_case(tmp_path: Path, monkeypatch, argv: tuple[str, ...], make: Callable[[Path], None], *names: str) -> str:
    """Make the input, run ``hound-id argv`` in ``tmp_path``; the one error line (asserted: exit 2, nothing left)."""
    target = tmp_path / _in_name(argv)
    make(target)
    before = files_under(tmp_path)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("COLUMNS", "200")
    guard = fifo_watchdog(target) if target.is_fifo() else contextlib.nullcontext()
    with guard:
        code, _, err = invoke(list(argv))
    lines = err.strip().splitlines()
    assert code == 2, (code, err)
    assert "Traceback" not in err, err
    assert len(lines) == 1, err
    for name in names:
        assert name in lines[0], (name, lines[0])
    assert files_under(tmp_path) == before, files_under(tmp_path) ^ before
    return lines[0]


# --- special files ------------------------------------------------------------------------------------------------

SPECIAL: dict[str, tuple[Callable[[Path], None], str]] = {
    "fifo": (lambda p: os.mkfifo(p), "is a FIFO (named pipe), not a regular file"),
    "device": (lambda p: p.symlink_to("/dev/null"), "is a character device, not a regular file"),
    "folder": (lambda p: p.mkdir(), "is a folder"),
}


#: Slots where a folder is an input too: what they say of a folder without what they look for.
FOLDER_TAKEN = {("fleet-log", "folder"): "the folder holds no log"}


@pytest.mark.parametrize("kind", sorted(SPECIAL))
@pytest.mark.parametrize("slot", sorted(SLOTS))
def test_an_input_that_is_not_a_regular_file_is_refused_before_it_is_opened(slot, kind, tmp_path, monkeypatch):
    argv = SLOTS[slot]
    make, said = SPECIAL[kind]
    said = FOLDER_TAKEN.get((slot, kind), said)
    run_case(tmp_path, monkeypatch, argv, make, _in_name(argv), said)


def test_a_spec_that_is_an_endless_device_ends_at_once():
    """``mor --spec /dev/zero`` grew to 12 GB in 18 s: now refused before a byte is read (a process of its own,
    so that a regression is a timeout here, not the suite's memory)."""
    proc = run_cli("mor", "--spec", "/dev/zero")
    assert proc.returncode == 2 and proc.stderr.strip() == (
        "hound-id: error: /dev/zero: is a character device, not a regular file; expected a motor spec YAML file "
        "(a pipe or device is never read: save what it gives to a file first)"
    ), proc.stderr


@pytest.mark.parametrize("slot", sorted(YAML_SLOTS))
def test_a_yaml_input_of_megabytes_is_refused_by_its_size(slot, tmp_path, monkeypatch):
    argv = YAML_SLOTS[slot]
    run_case(tmp_path, monkeypatch, argv, lambda p: p.write_text("# padding\n" * 120_000), _in_name(argv), "MB")


# --- YAML structures ----------------------------------------------------------------------------------------------


def _laughs(levels: int, key: str) -> str:
    """Nine levels of nine aliases under ``key``: 9**levels strings once expanded, a few hundred bytes as text."""
    lines = ['l0: &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for k in range(1, levels):
        lines.append(f"l{k}: &l{k} [" + ", ".join([f"*l{k - 1}"] * 9) + "]")
    lines.append(f"{key}: [" + ", ".join([f"*l{levels - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


STRUCTURES: dict[str, tuple[str, str]] = {
    "alias-bomb-in-name": (_laughs(9, "name"), "its aliases *name expanded"),
    "alias-bomb-in-joints": (_laughs(9, "joints"), "its aliases *name expanded"),
    "recursive-alias": ("name: &a [x, *a]\n", "alias inside the value it names"),
    "complex-key": ("? [a, b]\n: 1\nname: m\n", "a key that is a list or mapping"),
    "flow-complex-key": ("{[a, b]: 1}\n", "a key that is a list or mapping"),
    "deep-brackets": ("name: " + "[" * 3000 + "]" * 3000 + "\n", "nested more than 64 levels deep"),
    "keys-of-every-scalar-type": ("1: x\ntrue: y\nnull: z\n1.5: q\n2024-01-01: d\nfoo: 1\n", "IN.yaml"),
    "several-documents": ("name: a\n---\nname: b\n", "IN.yaml"),
    "deep-mappings": ("".join(" " * k + f"k{k}:\n" for k in range(200)) + " " * 200 + "x: 1\n", "nested more than"),
}


@pytest.mark.parametrize("structure", sorted(STRUCTURES))
@pytest.mark.parametrize("slot", sorted(YAML_SLOTS))
def test_a_yaml_structure_hound_id_does_not_read_is_one_line(slot, structure, tmp_path, monkeypatch):
    argv = YAML_SLOTS[slot]
    content, said = STRUCTURES[structure]
    line = run_case(tmp_path, monkeypatch, argv, lambda p: p.write_text(content), _in_name(argv), said)
    assert len(line) < 400  # the expanded value is never rendered


def test_an_alias_within_bounds_is_read_as_the_value_it_names(tmp_path, monkeypatch):
    """Anchors and aliases are YAML a user may write (a shared block of values): within the bounds they work."""
    spec = tmp_path / "m.yaml"
    text = MOTOR.read_text().replace("name: hound_ilm85", "name: &n hound_ilm85")
    spec.write_text(text + "source_name: *n\n" if "source_name" in text else text)
    monkeypatch.chdir(tmp_path)
    code, out, err = invoke(["mor", "--spec", str(spec), "--json"])
    assert code == 0, err


def test_a_message_never_renders_an_unbounded_value(tmp_path, monkeypatch):
    """A name that is a list of 90,000 strings (within the expansion bound) is cut in the message."""

    def write(path: Path) -> None:
        kept = [k for k in MOTOR.read_text().splitlines() if not k.startswith("name:")]
        path.write_text("\n".join([*kept, "name: [" + ", ".join(["x"] * 90_000) + "]"]) + "\n")

    line = run_case(tmp_path, monkeypatch, ("mor", "--spec", "IN.yaml"), write, "IN.yaml", "characters cut")
    assert len(line) < 2200


# --- values the structure allows but the field does not -----------------------------------------------------------


@pytest.mark.parametrize(
    ("line", "said"),
    [
        ("assumed: [[kt, kv]]", "field 'assumed': found ['kt', 'kv'] in the list"),
        ("assumed: [kt, {a: 1}]", "field 'assumed': found {'a': 1} in the list"),
        ("kt: N*m/A", "field 'kt': found 'N*m/A', a unit without a number"),
        ("kv: rpm/V", "field 'kv': found 'rpm/V', a unit without a number"),
    ],
)
def test_a_spec_field_of_the_wrong_shape_is_one_line(line, said, tmp_path, monkeypatch):
    key = line.split(":")[0]

    def write(path: Path) -> None:
        kept = [k for k in MOTOR.read_text().splitlines() if not k.startswith(f"{key}:")]
        path.write_text("\n".join([*kept, line]) + "\n")

    run_case(tmp_path, monkeypatch, ("mor", "--spec", "IN.yaml"), write, "IN.yaml", said)


# --- models -------------------------------------------------------------------------------------------------------


def _effects() -> list[str]:
    from hound_id.dyno.current.effects import REGISTRY

    return sorted(REGISTRY)


@pytest.mark.parametrize("effect", [e for e in _effects() if e != "linear"])
def test_a_model_without_linear_is_refused_in_one_line(effect, tmp_path, monkeypatch):
    argv = ("fit-current", "IN.csv", "--columns", DYNO_COLUMNS, "--model", effect)
    line = run_case(tmp_path, monkeypatch, argv, lambda p: p.write_bytes(DYNO.read_bytes()), "--model")
    assert f"write linear+{effect}" in line


def test_every_effect_added_to_linear_fits_or_is_refused_in_one_line(tmp_path, monkeypatch):
    """``--model linear+X`` for every effect X: a fit (exit 0, a Kt) or one line; never a traceback."""
    import json

    short = tmp_path / "short.csv"
    short.write_text("".join(DYNO.read_text().splitlines(keepends=True)[:6001]))
    monkeypatch.chdir(tmp_path)
    outcomes = {}
    for effect in _effects():
        model = "linear" if effect == "linear" else f"linear+{effect}"
        code, out, err = invoke(["fit-current", str(short), "--columns", DYNO_COLUMNS, "--model", model, "--json"])
        assert "Traceback" not in err, (model, err)
        if code == 0:
            assert json.loads(out)["parameters"]["kt"]["value"] > 0, model
        else:
            errors = [line for line in err.splitlines() if line.startswith("hound-id: error")]
            assert code == 2 and len(errors) == 1, (model, err)
        outcomes[model] = code
    assert outcomes["linear+saturation"] == 0 and outcomes["linear"] == 0


# --- advice the tool gives is advice it takes ---------------------------------------------------------------------

FLEET = sorted((DYNO.parent.parent / "fleet").glob("*.csv"))


def _advice(report: dict) -> list[list[str]]:
    """The options a report tells the user to run: the headline's ``--window`` and every "add 'x'"."""
    import re

    said = " ".join([report.get("summary") or "", *report.get("warnings", [])])
    options = [["--add", name] for name in sorted(set(re.findall(r"add '(\w+)'", said)))]
    headline = report.get("headline") or {}
    if headline.get("option"):
        options.append(headline["option"].split(" ", 1))
    return options


@pytest.mark.parametrize("log", [DYNO, *FLEET], ids=lambda p: p.stem)
def test_every_option_a_fit_suggests_is_taken_as_printed(log, tmp_path, monkeypatch):
    """Each ``--add`` and ``--window`` a report suggests, run as printed on the same file, fits (no refusal);
    no report states Kt = 0 as a finding."""
    import json
    import re

    monkeypatch.chdir(tmp_path)
    columns = ["--columns", DYNO_COLUMNS] if log == DYNO else []
    code, out, err = invoke(["fit-current", str(log), *columns, "--json"])
    assert code == 0, err
    report = json.loads(out)
    advice = _advice(report)
    assert advice or log.stem not in ("FL_hip", "RL_knee")  # the sample logs that give advice still give it
    for option in advice:
        again, out2, err2 = invoke(["fit-current", str(log), *columns, *option, "--json"])
        assert again == 0, (option, err2)
        second = json.loads(out2)
        assert second["parameters"]["kt"]["value"] > 0, option
        for text in (second["summary"], *second.get("warnings", [])):
            assert not re.search(r"Kt = -?0(\.0*)? N", text), text
    assert not re.search(r"Kt = -?0(\.0*)? N", out)


def test_a_current_in_ma_under_a_plain_header_is_named(tmp_path, monkeypatch):
    """A fleet sample's current written in mA under a plain 'current' header gave Kt = 1.4e-4 N m/A and a peak
    current of 68 kA: refused, naming mA; with the unit stated it fits the sample's Kt."""
    import json

    import pandas as pd

    frame = pd.read_csv(FLEET[0])
    frame["current"] *= 1000.0

    def write(path: Path) -> None:
        frame.to_csv(path, index=False)

    line = run_case(tmp_path, monkeypatch, ("fit-current", "IN.csv"), write, "IN.csv", "reads like mA", "current=mA")
    assert "no motor makes so little torque from kiloamps" in line
    code, out, err = invoke(["fit-current", "IN.csv", "--units", "current=mA", "--json"])
    assert code == 0, err
    truth = json.loads((FLEET[0].parent / "fleet_truth.json").read_text())["actuators"][FLEET[0].stem]["kt"]
    assert json.loads(out)["parameters"]["kt"]["value"] == pytest.approx(truth, rel=0.02)
    # a large motor in amps is not a slip: 1.2 kA for 60 N m (0.05 N m/A)
    big = frame.copy()
    big["current"] = frame["current"] / 1000.0 * 18.0
    big["torque"] = frame["torque"] * 6.0
    big.to_csv(tmp_path / "big.csv", index=False)
    code, _, err = invoke(["fit-current", "big.csv"])
    assert "reads like mA" not in err and code == 0, err


def test_the_simulated_rig_refuses_to_write_its_rig_file_over_its_plan(tmp_path, monkeypatch):
    def write(path: Path) -> None:
        path.write_text("schema: hound-id/plan/1\n")

    argv = ("dyno", "simulate-rig", "--plan", "IN.yaml", "--rig-out", "IN.yaml", "--duration", "1", "--port", "0")
    run_case(tmp_path, monkeypatch, argv, write, "IN.yaml", "is also an input of this command")
    assert (tmp_path / "IN.yaml").read_text() == "schema: hound-id/plan/1\n"


# --- found by an independent review of a fresh clone --------------------------------------------------------------

SAMPLE_URDF = ROBOT.parent / "hound_like.urdf"


def _robot_folder(folder: Path, robot_name: str = "r.yaml", urdf_name: str = "hound_like_limits.urdf") -> Path:
    """The sample robot, its motor spec and its URDF copied into ``folder``; the robot file's path."""
    folder.mkdir()
    (folder / "m.yaml").write_text(MOTOR.read_text())
    (folder / urdf_name).write_text(SAMPLE_URDF.read_text())
    lines = []
    for line in ROBOT.read_text().splitlines():
        line = line.replace("../motors/hound_ilm85.yaml", "m.yaml")
        lines.append(f"urdf: {urdf_name}" if line.startswith("urdf:") else line)
    (folder / robot_name).write_text("\n".join(lines) + "\n")
    return folder / robot_name


@pytest.mark.parametrize(
    ("robot_name", "urdf_name", "extra", "replaced"),
    [
        ("r.yaml", "hound_like_limits.urdf", ("--format", "urdf"), "hound_like_limits.urdf"),
        ("hound_like_bundle.yaml", "hound_like.urdf", (), "hound_like_bundle.yaml"),
    ],
    ids=["its-urdf", "the-robot-file"],
)
def test_export_never_writes_over_an_input_kept_in_its_out_folder(
    robot_name, urdf_name, extra, replaced, tmp_path, monkeypatch
):
    robot = _robot_folder(tmp_path / "rb", robot_name, urdf_name)
    before = {p.name: p.read_bytes() for p in robot.parent.iterdir()}
    monkeypatch.chdir(tmp_path)
    code, _, err = invoke(["export", "--robot", str(robot), "--out", str(robot.parent), *extra])
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"writing {replaced} there would replace the input" in err
    assert {p.name: p.read_bytes() for p in robot.parent.iterdir()} == before


def test_export_never_writes_over_a_fit_kept_in_its_out_folder(tmp_path, monkeypatch):
    out = tmp_path / "o"
    out.mkdir()
    fit = out / "hound_like_bundle.yaml"
    monkeypatch.chdir(tmp_path)
    code, _, err = invoke(
        ["fit-current", str(DYNO), "--columns", DYNO_COLUMNS, "--spec", str(MOTOR), "--out", str(fit)]
    )
    assert code == 0, err
    kept = fit.read_bytes()
    code, _, err = invoke(["export", "--robot", str(ROBOT), "--out", str(out), "--fit", str(fit)])
    assert code == 2 and "would replace the input" in err, err
    assert fit.read_bytes() == kept and sorted(p.name for p in out.iterdir()) == ["hound_like_bundle.yaml"]


@pytest.mark.parametrize("case", ["sidecar-holds-a-file", "rig-is-the-sidecar", "sidecar-is-a-fifo"])
def test_the_recorder_never_writes_its_sidecar_over_a_file(case, tmp_path, monkeypatch):
    """``<out>.meta.json`` is an output too: a user's file there needs --overwrite, the rig file there is refused,
    a FIFO there is refused, all before the rig is contacted and before the log is created."""
    side = tmp_path / "run.csv.meta.json"
    rig = tmp_path / "rig.yaml"
    rig.write_text("name: r\ndevices: {}\n")
    if case == "sidecar-holds-a-file":
        side.write_text('{"my": "notes"}')
        said = "run.csv.meta.json: already holds 15 bytes"
    elif case == "rig-is-the-sidecar":
        rig = side
        rig.write_text("name: r\ndevices: {}\n")
        said = "run.csv.meta.json: is also an input of this command"
    else:
        os.mkfifo(side)
        said = "run.csv.meta.json: is a FIFO (named pipe), not a regular file"
    before = files_under(tmp_path)
    kept = side.read_bytes() if side.is_file() else None
    monkeypatch.chdir(tmp_path)
    code, _, err = invoke(["dyno", "record", "--rig", str(rig), "--out", "run.csv", "--duration", "1"])
    assert code == 2 and len(err.strip().splitlines()) == 1 and said in err, err
    assert files_under(tmp_path) == before
    assert kept is None or side.read_bytes() == kept


UNIT_TYPOS: dict[str, tuple[tuple[str, ...], Callable[[Path], None], str]] = {
    "spec-unbalanced-bracket": (("mor", "--spec", "IN.yaml"), None, "cannot read '0.138 N*m/A)' as a quantity"),
    "spec-trailing-slash": (("mor", "--spec", "IN.yaml"), None, "cannot read '0.138 N*m/' as a quantity"),
    "spec-400k-characters": (("mor", "--spec", "IN.yaml"), None, "too long for a quantity"),
    "header-unit": (("fit-current", "IN.csv"), None, "cannot read the unit 'A)'"),
    "units-option": (("fit-current", str(DYNO), "--columns", DYNO_COLUMNS, "--units", "current=A)"), None, "'A)'"),
    "fleet-units-option": (("fleet", str(DYNO), "--columns", DYNO_COLUMNS, "--units", "current=A)"), None, "'A)'"),
    "foot-grf": (("foot", "--optimise", "--grf", "1.5 kN/"), None, "cannot read '1.5 kN/' as a quantity"),
}


def _spec_kt(value: str) -> Callable[[Path], None]:
    def write(path: Path) -> None:
        kept = [k for k in MOTOR.read_text().splitlines() if not k.startswith("kt:")]
        path.write_text("\n".join([*kept, f"kt: {value}"]) + "\n")

    return write


UNIT_FILES = {
    "spec-unbalanced-bracket": _spec_kt("0.138 N*m/A)"),
    "spec-trailing-slash": _spec_kt('"0.138 N*m/"'),
    "spec-400k-characters": _spec_kt("0.138 " + "N*" * 200_000 + "m/A"),
    "header-unit": lambda p: p.write_text(
        "time,current[A)],torque\n" + "".join(f"{k},{k % 7},{k % 5}\n" for k in range(200))
    ),
}


@pytest.mark.parametrize("case", sorted(UNIT_TYPOS))
def test_a_unit_pint_cannot_parse_is_one_line_wherever_a_unit_is_read(case, tmp_path, monkeypatch):
    argv, _, said = UNIT_TYPOS[case]
    make = UNIT_FILES.get(case)
    if make is None:  # no input file: the option is the bad input
        monkeypatch.chdir(tmp_path)
        code, _, err = invoke(list(argv))
        assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
        assert said in err, err
        return
    run_case(tmp_path, monkeypatch, argv, make, _in_name(argv), said)


@pytest.mark.parametrize(
    ("argv", "content", "said"),
    [
        (("mor", "--spec", "IN.yaml"), "name: m\nkt: " + "9" * 5000 + "\n", "a value cannot be read"),
        (
            ("export", "--robot", str(ROBOT), "--foot", "IN.json", "--out", "o"),
            '{"mass": 1' + "0" * 5000 + "}",
            "not JSON",
        ),
        (
            ("export", "--robot", str(ROBOT), "--foot", "IN.json", "--out", "o"),
            "[" * 100_000 + "]" * 100_000,
            "not JSON",
        ),
        (("export", "--robot", str(ROBOT), "--foot", "IN.json", "--out", "o"), '{"schema": NaN}', "NaN is not a JSON"),
    ],
    ids=["yaml-int-of-5000-digits", "json-int-of-5000-digits", "json-nested-100000-deep", "json-nan"],
)
def test_numbers_and_nesting_python_cannot_hold_are_one_line(argv, content, said, tmp_path, monkeypatch):
    run_case(tmp_path, monkeypatch, argv, lambda p: p.write_text(content), _in_name(argv), said)


def test_a_foot_json_with_a_negative_mass_is_refused_naming_the_field(tmp_path, monkeypatch):
    import json

    monkeypatch.chdir(tmp_path)
    code, _, err = invoke(["foot", "--optimise", "--out", "ft"])
    assert code == 0, err
    data = json.loads((tmp_path / "ft" / "foot.json").read_text())
    data["foot"]["closed_form"]["mass"] = -1.0
    argv = ("export", "--robot", str(ROBOT), "--foot", "IN.json", "--out", "o")
    run_case(tmp_path, monkeypatch, argv, lambda p: p.write_text(json.dumps(data)), "field 'foot.closed_form.mass'")


@pytest.mark.parametrize(
    ("key", "value", "said"),
    [("plateau_time", "1e9", "the plan lasts"), ("overdrive", "1e300", "overdrive: found 1e+300")],
)
def test_a_plan_file_edited_past_its_bounds_is_one_line(key, value, said, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = invoke(["dyno", "plan", "--max-current", "40", "--out", "plan.yaml"])
    assert code == 0, err
    text = "".join(
        f"{key}: {value}\n" if line.startswith(f"{key}:") else line
        for line in (tmp_path / "plan.yaml").read_text().splitlines(keepends=True)
    )
    (tmp_path / "plan.yaml").unlink()
    argv = ("dyno", "simulate-rig", "--plan", "IN.yaml", "--duration", "1", "--port", "0", "--no-serial")
    run_case(tmp_path, monkeypatch, argv, lambda p: p.write_text(text), "IN.yaml", said)


def _padded(path: Path) -> None:
    path.write_bytes(DYNO.read_bytes())
    os.truncate(path, 200_000_000)  # sparse: NULs a crash left, no disk used


def _long_row(path: Path) -> None:
    lines = DYNO.read_text().splitlines(keepends=True)
    path.write_text(lines[0] + "1," * 1_000_000 + "\n" + "".join(lines[1:]))


def _utf16(path: Path) -> None:
    path.write_bytes(DYNO.read_text().encode("utf-16"))


def _repeated_column(path: Path) -> None:
    lines = DYNO.read_text().splitlines()
    path.write_text("\n".join(f"{line},{line.split(',')[1]}" for line in lines) + "\n")


@pytest.mark.parametrize(
    ("make", "said"),
    [
        (_padded, "ends in at least 65,536 NUL bytes"),
        (_long_row, "line 2 is 2,000,000 bytes long"),
        (_utf16, "is UTF-16 text; save it as UTF-8"),
        (_repeated_column, "column 'iq[A]' appears 2 times"),
    ],
    ids=["nul-padded", "a-row-of-a-million-fields", "utf-16", "a-column-twice"],
)
def test_a_log_that_is_no_table_of_samples_is_one_line_at_once(make, said, tmp_path, monkeypatch):
    run_case(tmp_path, monkeypatch, ("fit-current", "IN.csv", "--columns", DYNO_COLUMNS), make, "IN.csv", said)


def test_merge_keys_are_read_and_may_be_overridden(tmp_path, monkeypatch):
    robot = _robot_folder(tmp_path / "rb", "r.yaml", "hound_like.urdf")
    text = robot.read_text()
    first = next(line for line in text.splitlines() if line.strip().startswith("- {type: ratio"))
    second = next(line for line in text.splitlines() if line.strip().startswith("- {type: ratio") and line != first)
    anchored = first.replace("- {", "- &first {", 1)
    joints = second.split("joints: ")[1].split("]")[0] + "]"
    motors = second.split("motors: ")[1].split("]")[0] + "]"
    merged = f"{second[: second.index('- {')]}- {{<<: *first, joints: {joints}, motors: {motors}}}"
    robot.write_text(text.replace(first, anchored).replace(second, merged))
    monkeypatch.chdir(tmp_path)
    code, _, err = invoke(["mor", "--robot", str(robot), "--json"])
    assert code == 0, err


def test_native_code_writing_to_stderr_is_caught_for_the_one_line():
    from hound_id.foot.leg import native_stderr

    with native_stderr() as said:
        os.write(2, b"Error:   Error=XML_ERROR_PARSING ErrorID=15\n at line 103 in model.cpp\n")
        first = said()
    assert first == "Error:   Error=XML_ERROR_PARSING ErrorID=15"


def test_ctrl_c_while_the_command_line_starts_is_one_line_and_exit_130():
    """SIGINT while the command line imports its libraries (or runs): one line, exit 130. A signal that lands
    before Python installed its handler kills the process silently (-2): the system's doing, no traceback either."""
    import signal
    import subprocess
    import sys
    import time

    codes = []
    for delay in (0.3, 0.6, 1.0):
        proc = subprocess.Popen(
            [sys.executable, "-m", "hound_id", "mor", "--spec", str(MOTOR)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            preexec_fn=restore_sigint,  # a suite run as a background job would pass SIGINT on ignored
        )
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        assert "Traceback" not in err, (delay, err)
        assert proc.returncode in (0, 130, -signal.SIGINT), (delay, proc.returncode, err)
        if proc.returncode == 130:
            assert err == "hound-id: interrupted\n", (delay, err)
        codes.append(proc.returncode)
    assert 130 in codes, codes


@pytest.mark.parametrize(
    "unit", ["9**9**9 N*m/A", "0.138 kN**1000*m**-999/A", "0.138 N*m/A\x00", "0.138 N*m/A`"], ids=repr
)
def test_unit_text_pint_would_evaluate_for_minutes_or_misread_is_refused(unit, tmp_path, monkeypatch):
    write = _spec_kt('"' + unit.replace("\x00", "\\0") + '"')
    run_case(tmp_path, monkeypatch, ("mor", "--spec", "IN.yaml"), write, "IN.yaml", "field 'kt'")


def test_export_never_writes_over_a_motor_spec_the_robot_names_from_its_out_folder(tmp_path, monkeypatch):
    robot = _robot_folder(tmp_path / "rb", "r.yaml", "hound_like.urdf")
    out = tmp_path / "o"
    out.mkdir()
    spec = out / "hound_like_bundle.yaml"
    spec.write_text(MOTOR.read_text())
    robot.write_text(robot.read_text().replace("m.yaml", "../o/hound_like_bundle.yaml"))
    monkeypatch.chdir(tmp_path)
    code, _, err = invoke(["export", "--robot", str(robot), "--out", str(out)])
    assert code == 2 and "would replace the input" in err, err
    assert spec.read_text() == MOTOR.read_text()
