"""Regenerate hound_like.urdf: a sample 12-joint quadruped matching hound_like.yaml.

The file stands in for a Hound-like robot's URDF for the MuJoCo and URDF exports. Each leg
copies data/samples/legs/hound_leg.urdf, read at generation time: the thigh (1.20 kg, COM at
z -0.10 m) with the knee (KFE) 0.27 m down its -z axis, the calf (0.25 kg, COM at z -0.14 m),
and the foot (solid aluminium cylinder r = 30 mm, 60 mm wide, 0.458 kg, axis y) hung on the
calf by the fixed joint ``<leg>_foot_fixed`` at xyz="0 0 -0.28" rpy="0 0 0", with the sample
leg's inertials, the foot's collision cylinder and the knee's position limits (-2.8..-0.3 rad).

Sourced: the total mass, 45 kg (the paper: KAIST Hound); the joint names and the leg layout
(an ab/adduction joint HAA, then the coaxial hip/knee module HFE/KFE) of hound_like.yaml.
Assumed: the trunk, a solid box 0.60 x 0.26 x 0.14 m whose mass makes the robot 45 kg; the
HAA axes at (+-0.30, +-0.10, 0) on the trunk; a 1.0 kg hip link (a solid cylinder r = 40 mm,
80 mm long along y, centred between HAA and HFE) carrying the HFE axis 0.08 m further out
(left legs +y, right legs -y); the position limits HAA +-0.8 rad, HFE +-3.14 rad; the
placeholder effort (100 N m) and velocity (60 rad/s) limits, which the exports overwrite.
Collision geometry (for MuJoCo's contacts): the trunk box; cylinders of radius 0.02 m and
length 0.20 m along z at the middle of each thigh and calf, short enough to leave a gap at
the knee; the foot cylinder. The hip links have a visual cylinder but no collision: the HAA
axes lie on the trunk box's end faces, so a hip cylinder would intersect the trunk and the thigh.
Frames follow REP-103: x forward, y left, z up; all joints at zero hang the legs straight down.

MuJoCo reads URDF with fusestatic on: without the <mujoco><compiler fusestatic="false"/></mujoco>
extension written here it would merge the fixed-base trunk into the world body (its 33.4 kg drop
out of model.body_mass) and each foot into its calf (the foot cylinder becomes a calf geom). With
it, every link is a MuJoCo body of the same name. Pinocchio ignores the extension.

Run: python data/samples/robots/make_hound_urdf.py [OUT_DIR]
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from pathlib import Path

HERE = Path(__file__).resolve().parent
LEG_URDF = HERE.parent / "legs" / "hound_leg.urdf"

TOTAL_MASS = 45.0  # KAIST Hound (the paper)
TRUNK_SIZE = (0.60, 0.26, 0.14)  # assumed [m]
HAA_X, HAA_Y = 0.30, 0.10  # HAA axis on the trunk [m], assumed
HIP_MASS, HIP_RADIUS, HIP_OFFSET = 1.0, 0.04, 0.08  # hip link [kg], [m], HAA-to-HFE lateral offset [m]
LINK_RADIUS, LINK_COLLISION_LENGTH = 0.02, 0.20  # thigh and calf collision cylinders [m]
EFFORT, VELOCITY = "100", "60"  # placeholders, overwritten by the exports
HAA_LIMITS, HFE_LIMITS = ("-0.8", "0.8"), ("-3.14", "3.14")
LEGS = {"FL": (1, 1), "FR": (1, -1), "RL": (-1, 1), "RR": (-1, -1)}  # leg -> (sign of x, sign of y)


def _num(x: float) -> str:
    """A short, stable text for a number (6 significant digits, no -0)."""
    text = f"{x:.6g}"
    return "0" if text == "-0" else text


def _inertial_xml(xyz: str, mass: str, inertia: dict[str, str], indent: str) -> str:
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    terms = " ".join(f'{k}="{inertia[k]}"' for k in keys)
    return (
        f"{indent}<inertial>\n"
        f'{indent}  <origin xyz="{xyz}" rpy="0 0 0"/>\n'
        f'{indent}  <mass value="{mass}"/>\n'
        f"{indent}  <inertia {terms}/>\n"
        f"{indent}</inertial>\n"
    )


def _find(element: ET.Element, path: str, where: str) -> ET.Element:
    found = element.find(path)
    if found is None:
        raise ValueError(f"{where}: no <{path}>; the sample leg's layout changed")
    return found


def _unrotated(origin: ET.Element, where: str) -> None:
    if [float(v) for v in origin.get("rpy", "0 0 0").split()] != [0.0, 0.0, 0.0]:
        raise ValueError(f"{where}: expected rpy='0 0 0', found '{origin.get('rpy')}'")


def _read_leg(path: Path) -> dict[str, dict[str, str]]:
    """The numbers (as text, copied verbatim) this robot takes from the sample leg."""
    root = ET.parse(path).getroot()
    links = {link.get("name"): link for link in root.iter("link")}
    joints = {joint.get("name"): joint for joint in root.iter("joint")}
    leg: dict[str, dict[str, str]] = {}
    for name in ("thigh", "calf", "foot"):
        where = f"{path}: link {name}"
        inertial = _find(links[name], "inertial", where)
        origin, inertia = _find(inertial, "origin", where), _find(inertial, "inertia", where)
        _unrotated(origin, where)
        leg[name] = {"xyz": origin.get("xyz", "0 0 0"), "mass": _find(inertial, "mass", where).get("value", "")}
        leg[name].update({k: inertia.get(k, "0") for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")})
    for name in ("KFE", "foot_fixed"):
        origin = _find(joints[name], "origin", f"{path}: joint {name}")
        _unrotated(origin, f"{path}: joint {name}")
        leg[name] = {"xyz": origin.get("xyz", "0 0 0")}
    limit = _find(joints["KFE"], "limit", f"{path}: joint KFE")
    leg["KFE"].update(lower=limit.get("lower", ""), upper=limit.get("upper", ""))
    collision = _find(links["foot"], "collision", f"{path}: link foot")
    c_origin = _find(collision, "origin", f"{path}: foot collision")
    cylinder = _find(collision, "geometry/cylinder", f"{path}: foot collision")
    leg["foot_collision"] = {
        "xyz": c_origin.get("xyz", "0 0 0"),
        "rpy": c_origin.get("rpy", "0 0 0"),
        "radius": cylinder.get("radius", ""),
        "length": cylinder.get("length", ""),
    }
    return leg


def _trunk(mass: float) -> str:
    a, b, c = TRUNK_SIZE
    inertia = {
        "ixx": _num(mass * (b * b + c * c) / 12),
        "iyy": _num(mass * (a * a + c * c) / 12),
        "izz": _num(mass * (a * a + b * b) / 12),
        "ixy": "0",
        "ixz": "0",
        "iyz": "0",
    }
    size = " ".join(_num(s) for s in TRUNK_SIZE)
    return (
        '  <link name="base">\n'
        f"    <!-- the trunk: solid box {size} m; its mass makes the robot {_num(TOTAL_MASS)} kg -->\n"
        + _inertial_xml("0 0 0", _num(mass), inertia, "    ")
        + "    <visual>\n"
        '      <origin xyz="0 0 0" rpy="0 0 0"/>\n'
        f'      <geometry><box size="{size}"/></geometry>\n'
        "    </visual>\n"
        "    <collision>\n"
        '      <origin xyz="0 0 0" rpy="0 0 0"/>\n'
        f'      <geometry><box size="{size}"/></geometry>\n'
        "    </collision>\n"
        "  </link>\n"
    )


def _revolute(name: str, parent: str, child: str, xyz: str, axis: str, lower: str, upper: str) -> str:
    return (
        f'  <joint name="{name}" type="revolute">\n'
        f'    <parent link="{parent}"/>\n'
        f'    <child link="{child}"/>\n'
        f'    <origin xyz="{xyz}" rpy="0 0 0"/>\n'
        f'    <axis xyz="{axis}"/>\n'
        f'    <limit effort="{EFFORT}" velocity="{VELOCITY}" lower="{lower}" upper="{upper}"/>\n'
        "  </joint>\n"
    )


def _cylinder(tag: str, xyz: str, rpy: str, radius: str, length: str) -> str:
    return (
        f"    <{tag}>\n"
        f'      <origin xyz="{xyz}" rpy="{rpy}"/>\n'
        f'      <geometry><cylinder radius="{radius}" length="{length}"/></geometry>\n'
        f"    </{tag}>\n"
    )


def _segment(name: str, props: dict[str, str], middle: float) -> str:
    """A thigh or calf: the sample leg's inertial and a thin collision cylinder along z at its middle."""
    return (
        f'  <link name="{name}">\n'
        + _inertial_xml(props["xyz"], props["mass"], props, "    ")
        + _cylinder("collision", f"0 0 {_num(-middle)}", "0 0 0", _num(LINK_RADIUS), _num(LINK_COLLISION_LENGTH))
        + "  </link>\n"
    )


def _leg(leg_name: str, sx: int, sy: int, leg: dict[str, dict[str, str]]) -> str:
    r, w = HIP_RADIUS, HIP_OFFSET
    hip_inertia = {
        "ixx": _num(HIP_MASS * (3 * r * r + w * w) / 12),
        "iyy": _num(HIP_MASS * r * r / 2),
        "izz": _num(HIP_MASS * (3 * r * r + w * w) / 12),
        "ixy": "0",
        "ixz": "0",
        "iyz": "0",
    }
    hip_mid = f"0 {_num(sy * w / 2)} 0"
    knee_z = -float(leg["KFE"]["xyz"].split()[2])
    foot_z = -float(leg["foot_fixed"]["xyz"].split()[2])
    fc = leg["foot_collision"]
    hip, thigh, calf, foot = (f"{leg_name}_{part}" for part in ("hip", "thigh", "calf", "foot"))
    return (
        f"  <!-- {leg_name} leg -->\n"
        + _revolute(f"{leg_name}_HAA", "base", hip, f"{_num(sx * HAA_X)} {_num(sy * HAA_Y)} 0", "1 0 0", *HAA_LIMITS)
        + f'  <link name="{hip}">\n'
        + f"    <!-- assumed: solid cylinder r = {_num(r)} m, {_num(w)} m long along y -->\n"
        + _inertial_xml(hip_mid, _num(HIP_MASS), hip_inertia, "    ")
        + _cylinder("visual", hip_mid, "1.5707963 0 0", _num(r), _num(w))
        + "  </link>\n"
        + _revolute(f"{leg_name}_HFE", hip, thigh, f"0 {_num(sy * w)} 0", "0 1 0", *HFE_LIMITS)
        + _segment(thigh, leg["thigh"], knee_z / 2)
        + _revolute(
            f"{leg_name}_KFE", thigh, calf, leg["KFE"]["xyz"], "0 1 0", leg["KFE"]["lower"], leg["KFE"]["upper"]
        )
        + _segment(calf, leg["calf"], foot_z / 2)
        + f'  <joint name="{leg_name}_foot_fixed" type="fixed">\n'
        f'    <parent link="{calf}"/>\n'
        f'    <child link="{foot}"/>\n'
        f'    <origin xyz="{leg["foot_fixed"]["xyz"]}" rpy="0 0 0"/>\n'
        "  </joint>\n"
        f'  <link name="{foot}">\n'
        + _inertial_xml(leg["foot"]["xyz"], leg["foot"]["mass"], leg["foot"], "    ")
        + _cylinder("collision", fc["xyz"], fc["rpy"], fc["radius"], fc["length"])
        + "  </link>\n"
    )


def urdf_text(leg_urdf: Path = LEG_URDF) -> str:
    """The robot's URDF as text."""
    leg = _read_leg(leg_urdf)
    leg_mass = HIP_MASS + sum(float(leg[part]["mass"]) for part in ("thigh", "calf", "foot"))
    trunk_mass = TOTAL_MASS - len(LEGS) * leg_mass
    header = (
        '<?xml version="1.0"?>\n'
        "<!-- Generated by make_hound_urdf.py from ../legs/hound_leg.urdf; do not edit, rerun the script.\n"
        "     A Hound-like quadruped, 45 kg (the paper). The trunk box, the hip links and the HAA/HFE\n"
        "     layout are ASSUMED; thigh, calf and foot are the sample leg's. See the script's docstring. -->\n"
        '<robot name="hound_like">\n'
        "  <!-- MuJoCo only (Pinocchio and urdfdom ignore it): keep every link a body. MuJoCo's URDF default,\n"
        "       fusestatic, would merge the fixed-base trunk into the world (losing its mass) and each foot\n"
        "       into its calf. Visuals are dropped, as MuJoCo does for URDF by default. -->\n"
        '  <mujoco><compiler discardvisual="true" fusestatic="false"/></mujoco>\n'
    )
    legs = "".join(_leg(name, sx, sy, leg) for name, (sx, sy) in LEGS.items())
    return header + _trunk(trunk_mass) + legs + "</robot>\n"


def main(out_dir: str | Path = HERE) -> list[Path]:
    """Write hound_like.urdf into out_dir; return the files written."""
    out = Path(out_dir) / "hound_like.urdf"
    out.write_text(urdf_text(), encoding="utf-8")
    return [out]


if __name__ == "__main__":
    main(*sys.argv[1:2])
