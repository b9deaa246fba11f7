"""``hound-id export``: load the robot, apply the dyno fits and the foot, write the formats."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from hound_id import io
from hound_id.errors import SpecError
from hound_id.export.bundle import apply_fits, build_bundle, foot_from_json
from hound_id.export.formats import FORMATS
from hound_id.export.target import Export, Written

SCHEMA = "hound-id/export/1"


@dataclass(frozen=True)
class ExportOptions:
    """The options of ``hound-id export``, as the user gives them."""

    formats: str = "bundle"
    """``bundle,mujoco`` (comma-separated) or ``all``."""
    fits: tuple[Path, ...] = ()
    """Fitted motor specs from ``fit-current --out``."""
    foot: Path | None = None
    """``foot.json`` from ``hound-id foot --optimise``."""
    urdf: Path | None = None
    """The robot's URDF, instead of the robot file's ``urdf:``."""
    mujoco_actuator: str = "dcmotor"
    """``dcmotor`` (the region in MuJoCo, voltage input), ``dcmotor-ff`` (torque feed-forward, MuJoCo >= 4.0) or
    ``motor`` (saturate with the runtime)."""


def run_export(robot_path: Path, out: Path, options: ExportOptions = ExportOptions()) -> ExportResult:
    """``hound-id export``: check the options and ``out`` before any work, load the robot with its fits, URDF and
    foot, and build every format's files for ``out`` (:func:`write_outputs` writes them)."""
    names = formats_from(options.formats)
    io.check_folder(out)
    ex = prepare(robot_path, options.fits, options.foot, options.urdf, options.mujoco_actuator)
    return export_robot(ex, names, out)


def formats_from(text: str) -> list[str]:
    """``bundle,mujoco`` or ``all`` -> format names, checked against :data:`FORMATS`."""
    names = list(FORMATS) if text.strip() == "all" else [t.strip() for t in text.split(",") if t.strip()]
    unknown = [n for n in names if n not in FORMATS]
    if unknown or not names:
        raise SpecError(
            f"--format: found {text!r}, expected one or more of {', '.join(FORMATS)} (comma-separated) or all"
        )
    return names


#: Formats built from the robot's URDF.
URDF_FORMATS = ("mjlab", "mujoco", "newton", "urdf", "urdf-open")

#: MuJoCo actuators of the export: the voltage-input dcmotor (MuJoCo 3.x and 4.x), the torque feed-forward dcmotor
#: (MuJoCo >= 4.0) and plain motors saturated by the runtime.
MUJOCO_ACTUATORS = ("dcmotor", "dcmotor-ff", "motor")


def prepare(
    robot_path: Path,
    fits: Sequence[Path] = (),
    foot: Path | None = None,
    urdf: Path | None = None,
    mujoco_actuator: str = "dcmotor",
) -> Export:
    """The robot with its fits, URDF and foot, and its bundle."""
    from hound_id.mor.robot import load_robot
    from hound_id.mor.spec_sheet import load_motor_spec

    if mujoco_actuator not in MUJOCO_ACTUATORS:
        raise SpecError(f"--mujoco-actuator: found {mujoco_actuator!r}, expected one of {', '.join(MUJOCO_ACTUATORS)}")
    robot = load_robot(robot_path)
    robot = apply_fits(robot, [load_motor_spec(f) for f in fits])
    if urdf is not None:
        io.check_input(urdf, "URDF", SpecError, io.TEXT_MAX_BYTES, option="--urdf")
        robot = replace(robot, urdf=str(urdf.resolve()))
    sources = {
        "robot": str(Path(robot_path).resolve()),
        "fits": [str(Path(f).resolve()) for f in fits],
        "foot": str(foot.resolve()) if foot else None,
        "urdf": robot.urdf,
    }
    bundle = build_bundle(robot, foot_from_json(foot) if foot else None, sources)
    return Export(robot=robot, bundle=bundle, mujoco_actuator=mujoco_actuator)


def _spec_files(robot_path: str | None) -> list[Path]:
    """The motor spec files a robot file names (its ``motor_specs``, relative to it): inputs an export must not
    write over."""
    if robot_path is None:
        return []
    data = io.read_yaml(robot_path, "robot")
    files = data.get("motor_specs") if isinstance(data, dict) else None
    base = Path(robot_path).parent
    return [base / rel for rel in (files or {}).values() if isinstance(rel, str)] if isinstance(files, dict) else []


@dataclass(frozen=True)
class ExportResult:
    """What ``hound-id export`` produced, not yet written: every format's files and notes, for one folder."""

    robot: str
    """The robot's name."""
    out: Path
    """The folder the files go to (:func:`write_outputs`)."""
    formats: Mapping[str, Written]
    """Format name -> its files' text and notes, in the order asked for."""
    fitted_motors: tuple[str, ...]
    """The motor specs a fit replaced (sorted)."""
    foot: bool
    """Whether the optimised foot is on the robot."""
    joints: tuple[str, ...]
    """The bundle's joints, in its order."""
    inputs: tuple[str, ...]
    """The files the export read (robot, fits, foot, URDF, the robot's spec sheets): never written over."""

    def files(self, name: str) -> list[str]:
        """The paths format ``name`` writes, in ``out``."""
        return [str(self.out / f) for f in self.formats[name].files]

    def to_json(self) -> dict[str, Any]:
        """The ``hound-id/export/1`` report: each format's files (their paths in ``out``) and notes."""
        return {
            "schema": SCHEMA,
            "robot": self.robot,
            "formats": {n: {"files": self.files(n), "notes": list(w.notes)} for n, w in self.formats.items()},
            "fitted_motors": list(self.fitted_motors),
            "foot": self.foot,
            "joints": list(self.joints),
        }


def export_robot(ex: Export, formats: Sequence[str], out: Path) -> ExportResult:
    """Every format's files for the folder ``out``, and their notes; nothing is written (:func:`write_outputs`)."""
    if out.exists() and not out.is_dir():
        raise SpecError(f"--out {out}: is a file; give a folder")
    if any(f in URDF_FORMATS for f in formats):
        ex.urdf()  # fail before any format's work
    sources = ex.bundle.sources
    inputs = [sources.get("robot"), *(sources.get("fits") or ()), sources.get("foot"), ex.robot.urdf]
    inputs += _spec_files(sources.get("robot"))
    written = {name: FORMATS[name](ex, out) for name in formats}
    unlisted = ex.unlisted_joints() if any(f in URDF_FORMATS for f in formats) else []
    if unlisted:  # the robot file covers part of the URDF: say what the rest gets
        note = (
            f"the URDF's joints {', '.join(unlisted)} are not in robot {ex.robot.name}'s file: they keep the URDF's "
            "own limits and get no armature, friction or actuator from hound-id; add their transmissions to the "
            "robot file to export them"
        )
        written = {n: (replace(w, notes=(*w.notes, note)) if n in URDF_FORMATS else w) for n, w in written.items()}
    return ExportResult(
        robot=ex.robot.name,
        out=out,
        formats=written,
        fitted_motors=tuple(sorted({m.spec for m in ex.bundle.motors if m.fitted})),
        foot=ex.bundle.foot is not None,
        joints=tuple(ex.bundle.joints),
        inputs=tuple(str(f) for f in inputs if f is not None),
    )


def write_outputs(result: ExportResult) -> None:
    """Write every format's files into ``result.out`` (created if missing), all or nothing: they are written into a
    temporary folder beside it and moved in together, never over one of the export's inputs. Formats that share a
    file (the bundle JSON of bundle, mjlab and Newton) write it once."""
    files: dict[str, str] = {}
    for written in result.formats.values():
        files.update(written.files)
    with io.staged_folder(result.out, inputs=result.inputs) as staging:
        for name, text in files.items():
            io.write_text(staging / name, text)
