"""Read the original foot from a leg URDF and write the URDF with a new foot.

hound-id expects a common layout of legged-robot URDFs: the foot is a link hung on the calf
by a fixed joint whose origin lies on the calf's -z axis, ``xyz="0 0 -L"`` with no rotation
(Unitree's URDFs and the sample leg do this; ANYmal's shank-to-foot joint has an offset and
must be re-expressed). The calf's parent joint is the knee, the knee's parent joint the hip,
both about the pitch axis y.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.errors import SpecError
from hound_id.foot.geometry import MassProperties
from hound_id.io import TEXT_MAX_BYTES, check_input


@dataclass(frozen=True)
class FootMount:
    """Where and what the original foot is, read from a leg URDF, SI."""

    path: str
    """The URDF file."""
    foot_link: str
    calf_link: str
    knee_joint: str
    hip_joint: str
    """The joint carrying the knee's parent link (the thigh)."""
    mount_length: float
    """Distance L from the knee axis to the foot mount along the calf [m]."""
    foot: MassProperties
    """The original foot's inertial, in the foot frame."""
    contact_radius: float
    """Radius r0 of the original foot's contact surface (cylinder or sphere) [m]."""
    contact_width: float
    """Width of the original foot along y [m] (0 for a sphere: 2 r0 is used for plots)."""
    contact_shape: str
    """``cylinder`` or ``sphere``."""


def _floats(text: str | None, n: int, where: str, default: str) -> NDArray[np.float64]:
    raw = (text if text is not None else default).split()
    try:
        values = np.array([float(v) for v in raw])
    except ValueError:
        values = np.array([])
    if values.shape != (n,) or not np.all(np.isfinite(values)):
        raise SpecError(f"{where}: found '{text}', expected {n} finite numbers")
    return values


def rebase_meshes(root: ET.Element, source: Path, out_dir: Path | None) -> None:
    """Rewrite relative mesh paths of a URDF read from ``source`` so that they resolve from
    ``out_dir`` (absolute paths when None); ``package://`` and absolute paths are kept."""
    source_dir = source.resolve().parent
    for mesh in root.iter("mesh"):
        name = mesh.get("filename", "")
        if name and "://" not in name and not Path(name).is_absolute():
            target = source_dir / name
            mesh.set("filename", os.path.relpath(target, out_dir.resolve()) if out_dir is not None else str(target))


def parse_urdf(path: Path) -> ET.Element:
    """The <robot> element of a URDF file, comments kept (SpecError if missing or not a URDF)."""
    check_input(path, "leg URDF", SpecError, TEXT_MAX_BYTES)
    with open(path, "rb") as handle:  # urdfdom (Pinocchio, the exports) reads UTF-8 only
        head = handle.read(4)
    if head.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in head:
        raise SpecError(
            f"{path}: is UTF-16 or UTF-32 text; URDF readers (urdfdom, MuJoCo) read UTF-8: save it as UTF-8 (iconv -t "
            f"UTF-8 {path.name} > leg-utf8.urdf)",
            path=str(path),
        )
    try:
        tree = ET.parse(path, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
        root = tree.getroot()
    except ET.ParseError as err:
        raise SpecError(f"{path}: not valid XML ({err})", path=str(path)) from err
    if root is None or root.tag != "robot":
        raise SpecError(f"{path}: expected a URDF <robot> document", path=str(path))
    check_inertials(root, str(path))
    return root


def check_inertials(root: ET.Element, source: str) -> None:
    """Every link's ``<inertial>``: a positive finite mass, a finite inertia tensor that is positive
    semi-definite and meets the triangle inequality (Ixx + Iyy >= Izz, ...), as a rigid body's must; else a
    one-line SpecError naming the link. A massless link has no ``<inertial>``."""
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        name = link.get("name", "?")
        fix = f"fix the <inertial> of link '{name}' (a massless link has none)"
        mass = inertial.find("mass")
        raw = None if mass is None else mass.get("value")
        value = _number(raw)
        if value is None or not value > 0:
            raise SpecError(
                f"{source}: link '{name}': <mass value={raw!r}>, expected a positive finite mass [kg]; {fix}"
            )
        tensor = inertial.find("inertia")
        if tensor is None:
            continue
        got = {key: _number(tensor.get(key, "0")) for key in _INERTIA}  # ixx ixy ixz iyy iyz izz
        bad = [key for key, v in got.items() if v is None]
        if bad:
            raise SpecError(
                f"{source}: link '{name}': <inertia {bad[0]}={tensor.get(bad[0])!r}>, expected a finite number "
                f"[kg m^2]; {fix}"
            )
        xx, xy, xz, yy, yz, zz = (float(got[key] or 0.0) for key in _INERTIA)
        matrix = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        eig = np.linalg.eigvalsh(matrix)
        tol = 1e-9 * max(float(np.max(np.abs(eig))), 1e-300)
        if eig[0] < -tol or eig[0] + eig[1] < eig[2] - tol:
            raise SpecError(
                f"{source}: link '{name}': the inertia tensor (ixx {xx:g}, iyy {yy:g}, izz {zz:g}, ixy {xy:g}, "
                f"ixz {xz:g}, iyz {yz:g} kg m^2) has principal moments {', '.join(f'{e:.3g}' for e in eig)}: a rigid "
                f"body's are >= 0 and no one exceeds the sum of the other two; {fix}"
            )


def _number(text: str | None) -> float | None:
    """A finite float from an attribute's text, else None."""
    try:
        value = float(text) if text is not None else math.nan
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def _rotation(rpy: NDArray[np.float64]) -> NDArray[np.float64]:
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def _inertial(link: ET.Element, where: str) -> MassProperties:
    inertial = link.find("inertial")
    if inertial is None:
        raise SpecError(f"{where}: link '{link.get('name')}' has no <inertial>; the original foot's mass is needed")
    origin = inertial.find("origin")
    xyz = _floats(origin.get("xyz") if origin is not None else None, 3, f"{where}: foot inertial origin xyz", "0 0 0")
    rpy = _floats(origin.get("rpy") if origin is not None else None, 3, f"{where}: foot inertial origin rpy", "0 0 0")
    mass_el, inertia_el = inertial.find("mass"), inertial.find("inertia")
    if mass_el is None or inertia_el is None:
        raise SpecError(f"{where}: the foot's <inertial> needs <mass> and <inertia>")
    mass = _floats(mass_el.get("value"), 1, f"{where}: foot mass", "")[0]
    if not mass > 0:
        raise SpecError(f"{where}: the foot's mass is {mass:g} kg, expected a positive mass")
    k = {n: _floats(inertia_el.get(n), 1, f"{where}: foot inertia {n}", "0")[0] for n in _INERTIA}
    local = np.array(
        [[k["ixx"], k["ixy"], k["ixz"]], [k["ixy"], k["iyy"], k["iyz"]], [k["ixz"], k["iyz"], k["izz"]]], dtype=float
    )
    rot = _rotation(rpy)
    return MassProperties(mass=float(mass), com=frozen(xyz), inertia=frozen(rot @ local @ rot.T))


_INERTIA = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def read_foot(path: str | Path, foot_link: str = "foot") -> FootMount:
    """The original foot of a leg URDF (see the module docstring for the expected layout)."""
    p = Path(path)
    root = parse_urdf(p)
    links = {link.get("name"): link for link in root.iter("link")}
    if foot_link not in links:
        raise SpecError(f"{p}: no link named '{foot_link}'; links are {', '.join(map(str, links))} (use --foot-link)")
    joints = list(root.iter("joint"))
    to_foot = [j for j in joints if (c := j.find("child")) is not None and c.get("link") == foot_link]
    if not to_foot or to_foot[0].get("type") != "fixed":
        raise SpecError(f"{p}: link '{foot_link}' must hang on the calf by a fixed joint")
    mount_joint = to_foot[0]
    parent = mount_joint.find("parent")
    calf = parent.get("link") if parent is not None else None
    origin = mount_joint.find("origin")
    where = f"{p}: joint '{mount_joint.get('name')}'"
    xyz = _floats(origin.get("xyz") if origin is not None else None, 3, f"{where} origin xyz", "0 0 0")
    rpy = _floats(origin.get("rpy") if origin is not None else None, 3, f"{where} origin rpy", "0 0 0")
    if not (abs(xyz[0]) < 1e-9 and abs(xyz[1]) < 1e-9 and xyz[2] < 0 and np.all(np.abs(rpy) < 1e-9)):
        raise SpecError(
            f"{where}: found origin xyz={xyz.tolist()} rpy={rpy.tolist()}, expected the foot on the calf's -z axis "
            "(xyz='0 0 -L', rpy='0 0 0'); re-express the calf frame so that it points along -z"
        )
    to_calf = [j for j in joints if (c := j.find("child")) is not None and c.get("link") == calf]
    if not to_calf or to_calf[0].get("type") not in ("revolute", "continuous"):
        raise SpecError(f"{p}: the calf link '{calf}' must hang on a revolute knee joint")
    thigh = to_calf[0].find("parent")
    to_thigh = [
        j
        for j in joints
        if (c := j.find("child")) is not None and thigh is not None and c.get("link") == thigh.get("link")
    ]
    if not to_thigh or to_thigh[0].get("type") not in ("revolute", "continuous"):
        raise SpecError(f"{p}: the knee's parent link must hang on a revolute hip joint")
    for joint in (to_calf[0], to_thigh[0]):
        axis_el = joint.find("axis")
        axis = _floats(axis_el.get("xyz") if axis_el is not None else None, 3, f"{p}: joint axis", "1 0 0")
        if not np.allclose(np.abs(axis / np.linalg.norm(axis)), [0.0, 1.0, 0.0], atol=1e-9):
            raise SpecError(
                f"{p}: joint '{joint.get('name')}' turns about {axis.tolist()}, expected the pitch axis y "
                "('0 1 0' or '0 -1 0'); hound-id's foot works in the sagittal plane of a pitch hip and knee"
            )
    shape, radius, width = _contact_shape(links[foot_link], str(p))
    return FootMount(
        path=str(p),
        foot_link=foot_link,
        calf_link=str(calf),
        knee_joint=str(to_calf[0].get("name")),
        hip_joint=str(to_thigh[0].get("name")),
        mount_length=float(-xyz[2]),
        foot=_inertial(links[foot_link], str(p)),
        contact_radius=radius,
        contact_width=width,
        contact_shape=shape,
    )


def _contact_shape(link: ET.Element, where: str) -> tuple[str, float, float]:
    for collision in link.iter("collision"):
        geometry = collision.find("geometry")
        if geometry is None:
            continue
        sphere, cylinder = geometry.find("sphere"), geometry.find("cylinder")
        origin = collision.find("origin")
        xyz = _floats(origin.get("xyz") if origin is not None else None, 3, f"{where}: foot collision xyz", "0 0 0")
        if np.any(np.abs(xyz) > 1e-9):
            raise SpecError(f"{where}: the foot's collision shape must be centred on the foot frame, found {xyz}")
        if sphere is not None:
            return "sphere", float(_floats(sphere.get("radius"), 1, f"{where}: sphere radius", "")[0]), 0.0
        if cylinder is not None:
            rpy = _floats(origin.get("rpy") if origin is not None else None, 3, f"{where}: collision rpy", "0 0 0")
            axis = _rotation(rpy) @ np.array([0.0, 0.0, 1.0])  # a URDF cylinder's axis is its local z
            if not np.allclose(np.abs(axis), [0.0, 1.0, 0.0], atol=1e-6):
                raise SpecError(
                    f"{where}: the foot cylinder's axis is {np.round(axis, 6).tolist()}, expected the lateral axis y "
                    "(rpy='1.5708 0 0'): the ground must touch its round side"
                )
            r = float(_floats(cylinder.get("radius"), 1, f"{where}: cylinder radius", "")[0])
            length = float(_floats(cylinder.get("length"), 1, f"{where}: cylinder length", "")[0])
            return "cylinder", r, length
    raise SpecError(
        f"{where}: the foot link has no <collision> sphere or cylinder; hound-id needs the original contact "
        "radius to keep the leg length"
    )


def _fmt(v: float) -> str:
    return f"{v:.9g}"


def patched_urdf(
    mount: FootMount,
    props: MassProperties,
    *,
    mesh_filename: str,
    spheres: Sequence[Sequence[float]],
    comment: str,
    out_dir: Path | None = None,
) -> str:
    """The leg URDF with the foot link's inertial, visual and collision replaced (XML text).

    The collision becomes the spheres (x, y, z, r) along the cap's arc
    (:mod:`hound_id.foot.collision`); the visual is the foot's mesh. Relative mesh
    paths of the other links are rewritten relative to ``out_dir``, where the new URDF will be
    written (absolute when None); ``package://`` and absolute paths are kept.
    """
    root = parse_urdf(Path(mount.path))
    rebase_meshes(root, Path(mount.path), out_dir)
    link = next(link for link in root.iter("link") if link.get("name") == mount.foot_link)
    replace_foot(link, props, mesh_filename, spheres, comment)
    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def replace_foot(
    link: ET.Element,
    props: MassProperties,
    mesh_filename: str | None,
    spheres: Sequence[Sequence[float]],
    comment: str,
) -> None:
    """Give a foot link (in place) the new inertial, a mesh visual (if a file is named) and one
    collision sphere per (x, y, z, r) of ``spheres`` (foot frame, metres)."""
    for child in list(link):
        if child.tag in ("inertial", "visual", "collision"):
            link.remove(child)
    link.append(ET.Comment(f" {comment} "))
    inertial = ET.SubElement(link, "inertial")
    ET.SubElement(inertial, "origin", xyz=" ".join(_fmt(v) for v in props.com), rpy="0 0 0")
    ET.SubElement(inertial, "mass", value=_fmt(props.mass))
    i = props.inertia
    ET.SubElement(
        inertial,
        "inertia",
        ixx=_fmt(i[0, 0]),
        ixy=_fmt(i[0, 1]),
        ixz=_fmt(i[0, 2]),
        iyy=_fmt(i[1, 1]),
        iyz=_fmt(i[1, 2]),
        izz=_fmt(i[2, 2]),
    )
    if mesh_filename is not None:
        visual = ET.SubElement(link, "visual")
        ET.SubElement(visual, "origin", xyz="0 0 0", rpy="0 0 0")
        ET.SubElement(ET.SubElement(visual, "geometry"), "mesh", filename=mesh_filename)
    for k, (x, y, z, r) in enumerate(spheres):
        collision = ET.SubElement(link, "collision", name=f"{link.get('name')}_cap_{k}")
        ET.SubElement(collision, "origin", xyz=f"{_fmt(x)} {_fmt(y)} {_fmt(z)}", rpy="0 0 0")
        ET.SubElement(ET.SubElement(collision, "geometry"), "sphere", radius=_fmt(r))
