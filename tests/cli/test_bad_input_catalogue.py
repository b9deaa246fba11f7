"""The bad-input catalogue: every command, every input file kind, the inputs a robotics engineer meets.

For each bad input the real entry point (``hound_id.cli.main``, in this process for speed) must
exit 2 with exactly one line on stderr that names the file, field, row or option, print no
traceback, and leave no file behind. The inputs that should be accepted give the right numbers.
Commands that import user code or hold global state (effects files, the recorder) have their
cases in subprocesses elsewhere (tests/cli/test_fit_cli.py, tests/dyno/acquire/test_recorder.py); a few
are repeated here through ``run_cli``.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hound_id.cli import main
from tests.conftest import MOTOR, ROBOT, SAMPLES, run_cli

DYNO = SAMPLES / "dyno" / "ilm85_dyno.csv"
DYNO_COLUMNS = "time=timestamp,current=iq,torque=adc_torque,velocity=speed,position=angle,temperature=winding_temp"
ENVELOPE = SAMPLES / "envelope" / "ilm85_sag_log.csv"
COMMANDS = SAMPLES / "commands" / "hound_like_running.csv"
GAIT = SAMPLES / "gait" / "hound_running.csv"
#: A folder no file can be created in: chmod 555 for a user, a sysfs folder for root (root ignores modes).
READ_ONLY = "<read-only>"


def invoke(argv: list[str]) -> tuple[int, str, str]:
    """Run ``hound-id argv`` through the console entry point; (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    code = 0
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            main(argv)
        except SystemExit as stop:
            code = stop.code if isinstance(stop.code, int) else (0 if stop.code is None else 1)
    return code, out.getvalue(), err.getvalue()


def files_under(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


@dataclass(frozen=True)
class Case:
    """One bad input: the files it needs, the arguments, and what the one line must name."""

    id: str
    argv: tuple[str, ...]
    names: tuple[str, ...]
    files: dict[str, Callable[[Path], None]] = field(default_factory=dict)


# --- input files ------------------------------------------------------------------------------------------------


def text(content: str) -> Callable[[Path], None]:
    return lambda path: path.write_text(content)


def binary(path: Path) -> None:
    path.write_bytes(bytes(range(256)) * 8)


def yaml_edit(source: Path, key: str, value: str | None) -> Callable[[Path], None]:
    """``source`` with the line of ``key`` replaced by ``key: value`` (removed when None, added if absent)."""

    def write(path: Path) -> None:
        lines = source.read_text().splitlines()
        kept = [line for line in lines if not line.startswith(f"{key}:")]
        if value is not None:
            kept.append(f"{key}: {value}")
        path.write_text("\n".join(kept) + "\n")

    return write


def spec_with_name(name: str) -> Callable[[Path], None]:
    return yaml_edit(MOTOR, "name", name)


def robot_with(key: str, value: str | None) -> Callable[[Path], None]:
    """The sample robot with ``key`` changed; its motor spec and URDF paths made absolute."""

    def write(path: Path) -> None:
        base = ROBOT.parent
        lines = []
        for line in ROBOT.read_text().splitlines():
            for rel in ("../motors/", "hound_like.urdf"):
                if rel in line:
                    line = line.replace(rel, str((base / rel).resolve()) + ("/" if rel.endswith("/") else ""))
            lines.append(line)
        text_ = "\n".join(line for line in lines if not line.startswith(f"{key}:"))
        if value is not None:
            text_ += f"\n{key}: {value}\n"
        path.write_text(text_)

    return write


def robot_ratio(ratio: str) -> Callable[[Path], None]:
    """The sample robot with its first gear ratio (HAA, 9.0) replaced."""

    def write(path: Path) -> None:
        robot_with("schema", None)(path)
        text_ = path.read_text().replace("ratios: [9.0]", f"ratios: [{ratio}]", 1)
        path.write_text(text_)

    return write


def table(source: Path, change: Callable[[pd.DataFrame], pd.DataFrame], kind: str = "csv") -> Callable[[Path], None]:
    def write(path: Path) -> None:
        frame = change(pd.read_csv(source, comment="#"))
        if kind == "csv":
            frame.to_csv(path, index=False)
        else:
            frame.to_parquet(path, index=False)

    return write


def set_column(column: str, value: object) -> Callable[[pd.DataFrame], pd.DataFrame]:
    def change(frame: pd.DataFrame) -> pd.DataFrame:
        frame = frame.copy()
        frame[column] = value
        return frame

    return change


def drop(column: str) -> Callable[[pd.DataFrame], pd.DataFrame]:
    return lambda frame: frame.drop(columns=[column])


def rename(old: str, new: str) -> Callable[[pd.DataFrame], pd.DataFrame]:
    return lambda frame: frame.rename(columns={old: new})


def trailing_comma(source: Path) -> Callable[[Path], None]:
    def write(path: Path) -> None:
        lines = source.read_text().splitlines()
        body = [line + "," if i > 2 and not line.startswith("#") else line for i, line in enumerate(lines)]
        path.write_text("\n".join(body) + "\n")

    return write


def rows(source: Path, n: int) -> Callable[[Path], None]:
    def write(path: Path) -> None:
        path.write_text("\n".join(source.read_text().splitlines()[:n]) + "\n")

    return write


# --- the catalogue ------------------------------------------------------------------------------------------------

FIT = ("fit-current", "IN.csv", "--columns", DYNO_COLUMNS)
CASES: list[Case] = []


def add(id_: str, argv: tuple[str, ...], names: tuple[str, ...], **files: Callable[[Path], None]) -> None:
    CASES.append(Case(id_, argv, names, dict(files)))


# motor spec YAML (mor --spec, fit-current --spec, the robot's motors)
SPEC_BAD = {
    "empty": (text(""), ("spec.yaml",)),
    "binary": (binary, ("spec.yaml",)),
    "list": (text("- 1\n- 2\n"), ("spec.yaml", "mapping")),
    "not_yaml": (text("kt: [0.1\n"), ("spec.yaml", "not valid YAML")),
    "duplicate_key": (text(MOTOR.read_text() + "kt: 0.2\n"), ("spec.yaml", "'kt'", "twice")),
    "typo": (yaml_edit(MOTOR, "resistnace", "0.1"), ("resistnace", "resistance")),
    "capital": (yaml_edit(MOTOR, "Kt", "0.1"), ("'Kt'", "did you mean 'kt'")),
    "missing_kt": (yaml_edit(MOTOR, "kt", None), ("'kt'", "missing")),
    "kt_nan": (yaml_edit(MOTOR, "kt", ".nan"), ("'kt'", "finite")),
    "kt_inf": (yaml_edit(MOTOR, "kt", ".inf"), ("'kt'",)),
    "kt_negative": (yaml_edit(MOTOR, "kt", "-0.1"), ("'kt'", "positive")),
    "kt_zero": (yaml_edit(MOTOR, "kt", "0"), ("'kt'", "positive")),
    "kt_tiny": (yaml_edit(MOTOR, "kt", "1.0e-300"), ("'kt'", "span of real motors")),
    "kt_text": (yaml_edit(MOTOR, "kt", "fast"), ("'kt'",)),
    "kt_wrong_unit": (yaml_edit(MOTOR, "kt", "0.1 V"), ("'kt'",)),
    "kt_mNm": (yaml_edit(MOTOR, "kt", "138 N*m/A"), ("'kt'", "span of real motors")),
    "bus_huge": (yaml_edit(MOTOR, "bus_voltage", "1.0e308"), ("'bus_voltage'", "span of real motors")),
    "bus_list": (yaml_edit(MOTOR, "bus_voltage", "[48, 50]"), ("'bus_voltage'",)),
    "kv_wrong_unit": (yaml_edit(MOTOR, "kv", "10 V"), ("'kv'",)),
    "resistance_negative": (yaml_edit(MOTOR, "resistance", "-0.1"), ("'resistance'",)),
    "peak_huge": (yaml_edit(MOTOR, "peak_torque", "1e30"), ("'peak_torque'",)),
    "max_current_text": (yaml_edit(MOTOR, "max_current", "lots"), ("'max_current'",)),
    "name_number": (spec_with_name("85"), ("'name'", "85")),
    "name_path": (spec_with_name("../../x"), ("'name'", "path separators")),
    "name_absolute": (spec_with_name("/tmp/evil"), ("'name'",)),
    "name_empty": (spec_with_name("''"), ("'name'",)),
    "schema": (yaml_edit(MOTOR, "schema", "hound-id/motor/99"), ("'schema'",)),
    "commutation": (yaml_edit(MOTOR, "commutation", "sinusoidal"), ("'commutation'",)),
}
for key, (make, names) in SPEC_BAD.items():
    add(f"mor-spec-{key}", ("mor", "--spec", "spec.yaml"), names, **{"spec.yaml": make})
for key in ("empty", "kt_nan", "kt_mNm", "name_path", "typo"):
    make, names = SPEC_BAD[key]
    add(f"fit-spec-{key}", ("fit-current", str(DYNO), "--columns", DYNO_COLUMNS, "--spec", "spec.yaml"), names,
        **{"spec.yaml": make})  # fmt: skip
add("mor-spec-missing-file", ("mor", "--spec", "nope.yaml"), ("nope.yaml", "not found"))
add("mor-spec-folder", ("mor", "--spec", "."), ("is a folder",))

# robot YAML (mor --robot, saturate, export)
ROBOT_BAD = {
    "name_traversal": (robot_with("name", "../../x"), ("'name'", "path separators")),
    "name_absolute": (robot_with("name", "/tmp/x"), ("'name'",)),
    "name_number": (robot_with("name", "85"), ("'name'",)),
    "name_dotdot": (robot_with("name", "a..b"), ("'name'",)),
    "missing_joints": (robot_with("joints", None), ("'joints'", "missing")),
    "unknown_key": (robot_with("jionts", "[a]"), ("jionts",)),
    "schema": (robot_with("schema", "hound-id/robot/9"), ("'schema'",)),
    "empty": (text(""), ("robot.yaml",)),
    "binary": (binary, ("robot.yaml",)),
    "urdf_missing": (robot_with("urdf", "nowhere.urdf"), ("'urdf'",)),
    "ratio_huge": (robot_ratio("1e308"), ("transmissions[0]", "reductions up to")),
    "ratio_tiny": (robot_ratio("1e-300"), ("transmissions[0]", "speed-ups up to")),
    "ratio_zero": (robot_ratio("0"), ("transmissions[0]", "non-zero")),
    "ratio_nan": (robot_ratio(".nan"), ("transmissions[0]",)),
}
for key, (make, names) in ROBOT_BAD.items():
    add(f"mor-robot-{key}", ("mor", "--robot", "robot.yaml"), names, **{"robot.yaml": make})
for key in ("name_traversal", "name_absolute", "empty", "urdf_missing"):
    make, names = ROBOT_BAD[key]
    add(f"export-robot-{key}", ("export", "--robot", "robot.yaml", "--out", "bundle"), names, **{"robot.yaml": make})
for key in ("name_traversal", "missing_joints", "binary"):
    make, names = ROBOT_BAD[key]
    add(f"saturate-robot-{key}", ("saturate", str(COMMANDS), "--robot", "robot.yaml"), names,
        **{"robot.yaml": make})  # fmt: skip

# dyno logs (fit-current)
DYNO_BAD = {
    "empty": (text(""), ("IN.csv",)),
    "header_only": (rows(DYNO, 1), ("IN.csv",)),
    "few_rows": (rows(DYNO, 8), ("IN.csv", "rows")),
    "binary": (binary, ("IN.csv",)),
    "no_torque": (table(DYNO, drop("adc_torque[mN*m]")), ("IN.csv", "torque")),
    "torque_text": (table(DYNO, set_column("adc_torque[mN*m]", "high")), ("IN.csv", "adc_torque", "numeric")),
    "torque_nan": (table(DYNO, set_column("adc_torque[mN*m]", np.nan)), ("IN.csv",)),
    "torque_inf": (table(DYNO, set_column("adc_torque[mN*m]", np.inf)), ("IN.csv",)),
    "torque_constant": (table(DYNO, set_column("adc_torque[mN*m]", 1.0)), ("IN.csv", "one value")),
    "torque_1e308": (
        table(DYNO, lambda f: f.assign(**{"adc_torque[mN*m]": 1e308 * np.sign(np.sin(np.arange(len(f))) + 0.1)})),
        ("IN.csv", "adc_torque", "beyond"),
    ),
    "current_in_amps_called_mA": (table(DYNO, rename("iq[A]", "iq[mA]")), ("IN.csv", "Kt", "--units")),
    "torque_unit_missing": (table(DYNO, rename("adc_torque[mN*m]", "adc_torque")), ("IN.csv", "Kt", "--units")),
    "unit_unknown": (table(DYNO, rename("iq[A]", "iq[furlong]")), ("IN.csv", "furlong")),
    "unit_wrong_kind": (table(DYNO, rename("iq[A]", "iq[V]")), ("IN.csv", "iq")),
    "duplicate_column": (
        text("timestamp[ms],iq[A],iq[A],adc_torque[mN*m]\n" + "0,1,1,1\n" * 60),
        ("IN.csv", "iq"),
    ),
}
for key, (make, names) in DYNO_BAD.items():
    add(f"fit-log-{key}", FIT, names, **{"IN.csv": make})
add("fit-log-bool-parquet", ("fit-current", "IN.parquet", "--columns", DYNO_COLUMNS), ("IN.parquet", "true/false"),
    **{"IN.parquet": table(DYNO, set_column("adc_torque[mN*m]", True), "parquet")})  # fmt: skip
add("fit-log-missing-file", ("fit-current", "nope.csv"), ("nope.csv",))
add("fit-log-wrong-suffix", ("fit-current", "log.txt"), ("log.txt",), **{"log.txt": text("a,b\n1,2\n")})
FIT_OPTIONS = {
    "columns_unknown_channel": (("--columns", "torq=adc_torque"), ("torq",)),
    "columns_missing_column": (("--columns", "torque=nope,current=iq"), ("nope",)),
    "columns_syntax": (("--columns", "torque"), ("--columns",)),
    "units_unknown": (("--units", "torque=parsec"), ("parsec",)),
    "units_wrong_kind": (("--units", "torque=A"), ("torque",)),
    "window_text": (("--window", "a:b"), ("--window",)),
    "window_reversed": (("--window", "5:1"), ("--window",)),
    "window_empty": (("--window", "1000:2000"), ("--window",)),
    "model_unknown": (("--model", "linear+magic"), ("magic",)),
    "add_twice": (("--add", "saturation"), ("saturation",)),
    "plot_suffix": (("--plot", "fit.jpg"), ("fit.jpg", ".png")),
    "plot_folder_missing": (("--plot", "no/fit.png"), ("no/fit.png", "does not exist")),
    "plot_read_only": (("--plot", f"{READ_ONLY}/fit.png"), ("fit.png",)),
    "out_suffix": (("--out", "fit.json"), ("fit.json",)),
    "out_read_only": (("--out", f"{READ_ONLY}/fit.yaml"), ("fit.yaml",)),
    "out_is_folder": (("--out", "."), (".",)),
    "effects_file_missing": (("--effects-file", "nope.py"), ("nope.py",)),
    "unknown_option": (("--bogus",), ("--bogus", "fit-current")),
    "option_without_value": (("--window",), ("--window",)),
}
for key, (extra, names) in FIT_OPTIONS.items():
    add(f"fit-option-{key}", ("fit-current", str(DYNO), "--columns", DYNO_COLUMNS, *extra), names)

# torque-speed logs (mor --compare)
ENVELOPE_COLUMNS = "velocity=speed,current=iq,temperature=winding_temp,bus_voltage=vbus"
COMPARE = ("mor", "--spec", str(MOTOR), "--compare", "IN.csv", "--columns", ENVELOPE_COLUMNS)
COMPARE_BAD = {
    "empty": (text(""), ("IN.csv",)),
    "binary": (binary, ("IN.csv",)),
    "no_speed": (table(ENVELOPE, drop("speed [rpm]")), ("IN.csv", "velocity")),
    "torque_text": (table(ENVELOPE, set_column("torque [N*m]", "x")), ("IN.csv", "torque")),
    "torque_1e308": (table(ENVELOPE, set_column("torque [N*m]", 1e308)), ("IN.csv", "torque")),
    "few_rows": (rows(ENVELOPE, 30), ("IN.csv",)),
    "unit_unknown": (table(ENVELOPE, rename("speed [rpm]", "speed [furlong]")), ("IN.csv", "furlong")),
}
for key, (make, names) in COMPARE_BAD.items():
    add(f"compare-log-{key}", COMPARE, names, **{"IN.csv": make})
add("compare-log-bool-parquet", (*COMPARE[:4], "IN.parquet", *COMPARE[5:]), ("IN.parquet", "true/false"),
    **{"IN.parquet": table(ENVELOPE, set_column("speed [rpm]", False), "parquet")})  # fmt: skip
add("compare-without-spec", ("mor", "--compare", str(ENVELOPE)), ("--compare", "--spec"))
add("compare-out-suffix", (*COMPARE[:4], str(ENVELOPE), *COMPARE[5:], "--out", "env.txt"), ("env.txt",))
add("compare-add-unknown", (*COMPARE[:4], str(ENVELOPE), *COMPARE[5:], "--add", "magic"), ("magic",))
add("compare-plot-read-only", (*COMPARE[:4], str(ENVELOPE), *COMPARE[5:], "--plot", f"{READ_ONLY}/c.png"), ("c.png",))
add("mor-plot-read-only", ("mor", "--spec", str(MOTOR), "--plot", f"{READ_ONLY}/m.png"), ("m.png",))
add("mor-plot-suffix", ("mor", "--spec", str(MOTOR), "--plot", "m.svg"), ("m.svg", ".png"))
add("mor-nothing", ("mor", "--json"), ("--spec", "--robot"))

# joint command logs (saturate)
SATURATE = ("saturate", "IN.csv", "--robot", str(ROBOT))
SATURATE_BAD = {
    "empty": (text(""), ("IN.csv",)),
    "binary": (binary, ("IN.csv",)),
    "missing_joint": (table(COMMANDS, drop("tau_FL_HAA")), ("IN.csv", "tau_FL_HAA")),
    "torque_text": (table(COMMANDS, set_column("tau_FL_HFE", "x")), ("IN.csv", "tau_FL_HFE")),
    "torque_nan": (table(COMMANDS, set_column("tau_FL_HFE", np.nan)), ("IN.csv", "tau_FL_HFE")),
    "trailing_comma": (trailing_comma(COMMANDS), ("IN.csv",)),
}
for key, (make, names) in SATURATE_BAD.items():
    add(f"saturate-log-{key}", SATURATE, names, **{"IN.csv": make})
add("saturate-log-bool-parquet", ("saturate", "IN.parquet", *SATURATE[2:]), ("IN.parquet", "tau_FL_HFE"),
    **{"IN.parquet": table(COMMANDS, set_column("tau_FL_HFE", True), "parquet")})  # fmt: skip
add("saturate-out-read-only", (*SATURATE[:1], str(COMMANDS), *SATURATE[2:], "--out", f"{READ_ONLY}/s.csv"), ("s.csv",))
add("saturate-out-suffix", (*SATURATE[:1], str(COMMANDS), *SATURATE[2:], "--out", "s.txt"), ("s.txt",))
add("saturate-plot-folder", (*SATURATE[:1], str(COMMANDS), *SATURATE[2:], "--plot", "no/s.png"), ("no/s.png",))
add("saturate-no-robot", ("saturate", str(COMMANDS)), ("--robot",))
add("saturate-out-is-the-input", ("saturate", "IN.csv", *SATURATE[2:], "--out", "IN.csv"), ("IN.csv", "input"),
    **{"IN.csv": table(COMMANDS, lambda f: f)})  # fmt: skip
add("fit-out-is-the-spec", ("fit-current", str(DYNO), "--columns", DYNO_COLUMNS, "--spec", "m.yaml", "--out", "m.yaml"),
    ("m.yaml", "input"), **{"m.yaml": yaml_edit(MOTOR, "name", "m")})  # fmt: skip
add("compare-out-is-the-spec", ("mor", "--spec", "m.yaml", "--compare", str(ENVELOPE), "--columns", ENVELOPE_COLUMNS,
    "--out", "m.yaml"), ("m.yaml", "input"), **{"m.yaml": yaml_edit(MOTOR, "name", "m")})  # fmt: skip

# gait logs and foot options
FOOT = ("foot", "--gait", "IN.csv")
GAIT_BAD = {
    "empty": (text(""), ("IN.csv",)),
    "binary": (binary, ("IN.csv",)),
    "no_contact_column": (table(GAIT, drop("RR_contact")), ("IN.csv", "RR_contact")),
    "no_knee_column": (table(GAIT, drop("FL_KFE")), ("IN.csv", "FL_KFE")),
    "no_pitch": (table(GAIT, drop("pitch")), ("IN.csv", "pitch")),
    "contact_probability": (table(GAIT, lambda f: f.assign(RR_contact=f["RR_contact"] * 0.7)), ("RR_contact",)),
    "angle_text": (table(GAIT, set_column("RR_HFE", "x")), ("IN.csv", "RR_HFE")),
    "angle_nan": (table(GAIT, set_column("RR_HFE", np.nan)), ("IN.csv", "RR_HFE")),
    "no_stance": (table(GAIT, lambda f: f.assign(**{c: 0 for c in f.columns if c.endswith("_contact")})), ("IN.csv",)),
    "degrees": (table(GAIT, lambda f: f.assign(RR_HFE=np.degrees(f["RR_HFE"]))), ("IN.csv",)),
}
for key, (make, names) in GAIT_BAD.items():
    add(f"foot-gait-{key}", FOOT, names, **{"IN.csv": make})
FOOT_OPTIONS = {
    "legs_unknown": (("--legs", "XX"), ("XX",)),
    "legs_twice": (("--legs", "FL,FL"), ("--legs", "FL")),
    "angles_text": (("--angles", "a,b"), ("--angles",)),
    "angles_one": (("--angles", "-30"), ("--angles",)),
    "angles_beyond_90": (("--angles", "-400,500"), ("--angles", "180 deg")),
    "margin_negative": (("--margin", "-5"), ("--margin",)),
    "grf_wrong_unit": (("--grf", "3 m"), ("--grf",)),
    "boss_radius_negative": (("--boss-radius", "-1 mm"), ("--boss-radius",)),
    "material_unknown": (("--material", "unobtainium"), ("unobtainium",)),
    "ground_unknown": (("--ground", "lava"), ("lava",)),
    "knee_angle_huge": (("--knee-angle", "1e308"), ("--knee-angle",)),
    "safety_zero": (("--safety", "0"), ("--safety",)),
    "grf_negative": (("--grf", "-3 kN"), ("--grf",)),
    "grf_zero": (("--grf", "0 N"), ("--grf",)),
    "roll_huge": (("--roll", "90"), ("--roll",)),
    "margin_nan": (("--margin", "nan"), ("--margin",)),
    "mesh_resolution": (("--optimise", "--mesh-resolution", "0.01"), ("--mesh-resolution",)),
    "out_without_optimise": (("--out", "foot"), ("--optimise",)),
    "out_read_only": (("--optimise", "--out", f"{READ_ONLY}/foot"), ("foot",)),
    "out_is_file": (("--optimise", "--out", "afile"), ("afile", "is a file")),
    "leg_missing": (("--leg", "nope.urdf"), ("nope.urdf",)),
    "leg_binary": (("--leg", "leg.urdf"), ("leg.urdf",)),
    "leg_not_urdf": (("--leg", "leg2.urdf"), ("leg2.urdf",)),
}
for key, (extra, names) in FOOT_OPTIONS.items():
    add(f"foot-option-{key}", ("foot", *extra), names, afile=text("x"), **{"leg.urdf": binary},
        **{"leg2.urdf": text("<html/>")})  # fmt: skip
add("foot-material-yaml-bad", ("foot", "--material", "mat.yaml"), ("mat.yaml",), **{"mat.yaml": text("density: -1\n")})

# export
EXPORT = ("export", "--robot", str(ROBOT), "--out", "bundle")
EXPORT_BAD = {
    "format_unknown": (("--format", "gazebo"), ("--format", "gazebo")),
    "fit_missing": (("--fit", "nope.yaml"), ("nope.yaml",)),
    "fit_not_fitted": (("--fit", str(MOTOR)), ("--fit",)),
    "fit_binary": (("--fit", "fit.yaml"), ("fit.yaml",)),
    "foot_missing": (("--foot", "nope.json"), ("nope.json",)),
    "foot_not_json": (("--foot", "foot.json"), ("foot.json",)),
    "urdf_missing": (("--urdf", "nope.urdf"), ("nope.urdf",)),
    "actuator_unknown": (("--mujoco-actuator", "servo"), ("servo",)),
}
for key, (extra, names) in EXPORT_BAD.items():
    add(f"export-{key}", (*EXPORT, *extra), names, **{"fit.yaml": binary, "foot.json": text("{not json")})
add("export-out-read-only", ("export", "--robot", str(ROBOT), "--out", f"{READ_ONLY}/bundle"), ("bundle",))
add("export-out-is-file", ("export", "--robot", str(ROBOT), "--out", "afile"), ("afile",), afile=text("x"))
add("export-out-parent-missing", ("export", "--robot", str(ROBOT), "--out", "no/bundle"), ("no/bundle",))

# demo and dyno plan
add("demo-out-read-only", ("demo", "--out", f"{READ_ONLY}/demo"), ("demo",))
add("demo-out-is-file", ("demo", "--out", "afile"), ("afile", "is a file"), afile=text("x"))
add("demo-out-parent-missing", ("demo", "--out", "no/demo"), ("no/demo",))
PLAN = ("dyno", "plan", "--max-current", "40", "--out", "plan.yaml")
PLAN_BAD = {
    "max_current_negative": (("dyno", "plan", "--max-current", "-1"), ("--max-current",)),
    "max_current_text": (("dyno", "plan", "--max-current", "x"), ("--max-current",)),
    "max_current_huge": (("dyno", "plan", "--max-current", "1e200", "--schedule", "s.csv"), ("--max-current",)),
    "max_current_tiny": (("dyno", "plan", "--max-current", "1e-300"), ("--max-current",)),
    "overdrive_below_one": ((*PLAN, "--overdrive", "0.5"), ("--overdrive",)),
    "rise_negative": ((*PLAN, "--rise", "-1"), ("--rise",)),
    "speeds_text": ((*PLAN, "--speeds", "a,b"), ("--speeds",)),
    "levels_zero": ((*PLAN, "--levels", "0"), ("--levels",)),
    "out_suffix": (("dyno", "plan", "--max-current", "40", "--out", "plan.txt"), ("plan.txt",)),
    "out_read_only": (("dyno", "plan", "--max-current", "40", "--out", f"{READ_ONLY}/plan.yaml"), ("plan.yaml",)),
    "schedule_read_only": ((*PLAN, "--schedule", f"{READ_ONLY}/s.csv"), ("s.csv",)),
}
for key, (argv, names) in PLAN_BAD.items():
    add(f"plan-{key}", argv, names)
RECORD = ("dyno", "record", "--rig", "rig.yaml", "--out", "log.csv", "--duration", "1")
RECORD_BAD = {
    "rig_missing": ((*RECORD[:2], "--rig", "nope.yaml", "--out", "log.csv"), ("nope.yaml",)),
    "rig_empty": (RECORD, ("rig.yaml",)),
    "rate_huge": ((*RECORD, "--rate", "1e9"), ("--rate",)),
    "rate_negative": ((*RECORD, "--rate", "-5"), ("--rate",)),
    "duration_negative": ((*RECORD[:6], "--duration", "-1"), ("--duration",)),
    "out_suffix": ((*RECORD[:4], "--out", "log.txt"), ("log.txt",)),
}
for key, (argv, names) in RECORD_BAD.items():
    add(f"record-{key}", argv, names, **{"rig.yaml": text("")})
add("simulate-rig-duration-negative", ("dyno", "simulate-rig", "--duration", "-1"), ("--duration",))
add("simulate-rig-effects-unknown", ("dyno", "simulate-rig", "--effects", "magic", "--duration", "1"), ("magic",))
add("simulate-rig-speedup-zero", ("dyno", "simulate-rig", "--speedup", "0", "--duration", "1"), ("--speedup",))

# the command line itself
add("unknown-command", ("fly",), ("fly",))
add("unknown-option", ("mor", "--spce", str(MOTOR)), ("--spce",))
add("missing-required-option", ("export", "--robot", str(ROBOT)), ("--out",))
add("wrong-option-type", ("dyno", "plan", "--max-current", "40", "--levels", "many"), ("--levels",))


def _read_only_folder(tmp_path: Path) -> str:
    if os.geteuid() != 0:
        folder = tmp_path / "locked"
        folder.mkdir()
        folder.chmod(0o555)
        return str(folder)
    return "/sys/kernel"  # sysfs: root cannot create files there either


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input_is_one_line_exit_2_and_leaves_nothing(case: Case, tmp_path: Path, monkeypatch) -> None:
    for name, make in case.files.items():
        make(tmp_path / name)
    read_only = _read_only_folder(tmp_path)
    argv = [a.replace(READ_ONLY, read_only) for a in case.argv]
    before = files_under(tmp_path)
    sys_before = set(os.listdir(read_only)) if read_only.startswith("/sys") else None
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("COLUMNS", "200")
    code, _, err = invoke(argv)
    lines = err.strip().splitlines()
    assert code == 2, (code, err)
    assert "Traceback" not in err, err
    assert len(lines) == 1, err
    for name in case.names:
        assert name in lines[0], (name, lines[0])
    assert files_under(tmp_path) == before, files_under(tmp_path) ^ before
    if sys_before is not None:
        assert set(os.listdir(read_only)) == sys_before
    if not read_only.startswith("/sys"):
        Path(read_only).chmod(0o755)


def test_the_catalogue_is_large_and_walks_every_command() -> None:
    assert len(CASES) >= 120
    first = {c.argv[0] if c.argv[0] != "dyno" else " ".join(c.argv[:2]) for c in CASES}
    commands = {"mor", "saturate", "fit-current", "foot", "export", "demo", "dyno plan", "dyno record"}
    assert commands <= first, commands - first


# --- inputs that must be accepted, with the right numbers -----------------------------------------------------------


def test_a_spec_in_other_units_gives_the_same_region(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    code, out, err = invoke(["mor", "--spec", str(MOTOR), "--json"])
    assert code == 0, err
    si = json.loads(out)
    other = tmp_path / "mixed.yaml"
    yaml_edit(MOTOR, "kt", f"{1000 * si['spec']['kt']!r} mN*m/A")(other)
    mixed = json.loads(invoke(["mor", "--spec", str(other), "--json"])[1])
    for key in ("stall_torque", "corner_speed", "torque_limit"):
        assert mixed[key] == pytest.approx(si[key], rel=1e-12)


def test_a_dyno_log_with_a_few_overflowed_values_still_fits_the_sample_numbers(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    frame = pd.read_csv(DYNO)
    frame.loc[100, "adc_torque[mN*m]"] = 1e308
    frame.loc[200, "iq[A]"] = -1e300
    frame.to_csv(tmp_path / "log.csv", index=False)
    code, out, err = invoke(["fit-current", "log.csv", "--columns", DYNO_COLUMNS, "--json"])
    assert code == 0, err
    clean = json.loads(invoke(["fit-current", str(DYNO), "--columns", DYNO_COLUMNS, "--json"])[1])
    dirty = json.loads(out)
    assert dirty["parameters"]["kt"]["value"] == pytest.approx(clean["parameters"]["kt"]["value"], rel=2e-3)
    assert "beyond 1e+06 N m as missing" in err and "at rows 101" in err


def test_names_that_are_safe_file_names_are_kept(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    spec = tmp_path / "s.yaml"
    spec_with_name("ILM85-v2.1_b+")(spec)
    code, out, err = invoke(["mor", "--spec", str(spec), "--json"])
    assert code == 0, err
    assert json.loads(out)["motor"] == "ILM85-v2.1_b+"


def test_an_effects_file_that_exits_is_an_error_not_a_silent_success(tmp_path: Path) -> None:
    effects = tmp_path / "quit.py"
    effects.write_text("import sys\nsys.exit(0)\n")
    proc = run_cli("fit-current", str(DYNO), "--columns", DYNO_COLUMNS, "--effects-file", str(effects))
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count("\n") == 1 and "quit.py" in proc.stderr and "exit" in proc.stderr


def test_export_name_traversal_writes_nothing_outside_out(tmp_path: Path) -> None:
    victim = tmp_path / "x_bundle.yaml"
    victim.write_text("precious\n")
    robot = tmp_path / "robot.yaml"
    robot_with("name", str(tmp_path / "x"))(robot)
    (tmp_path / "deep").mkdir()
    proc = run_cli("export", "--robot", str(robot), "--out", str(tmp_path / "deep" / "out"))
    assert proc.returncode == 2 and "field 'name'" in proc.stderr, proc.stderr
    assert victim.read_text() == "precious\n"
    assert files_under(tmp_path / "deep") == set()
