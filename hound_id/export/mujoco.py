"""MuJoCo export: every motor a ``<dcmotor>`` on a fixed tendon that encodes the transmission.

For motor k the fixed tendon's length is the motor angle, theta_k = sum_j (A^-1)_kj q_j, so its
velocity is the motor speed and a tendon force f (the motor torque) reaches the joints as
A^-T f: the coupled hip/knee is exact, and power balances. On the tendon:

* ``armature`` = the rotor inertia (MuJoCo adds A^-T diag(J) A^-1 to the joint-space mass
  matrix, the reflected inertia);
* ``frictionloss`` = the fitted Coulomb friction, ``damping`` = the fitted viscous friction
  (motor side).

The actuator is MuJoCo's ``dcmotor``. MuJoCo has one motor constant K for torque and back-EMF, so
hound-id sets K = Ke = 1/Kv and scales the resistance to R' = R Ke/Kt: then stall torque Kt V/R
and no-load speed V Kv are the spec's, and the voltage lines are exact. Two inputs:

* ``dcmotor`` (the default): voltage input, ``ctrl`` limited to +-V_bus; the torque is
  K (v - K omega) / R' clamped to the torque limit (``saturation``). It loads in MuJoCo 3.x and
  4.x (the ``input`` attribute is left at its default, which 3.x reads). Send
  ``hound_id.runtime.Runtime.voltage(tau, qd)``: the voltage R tau_m / Kt + omega_m / Kv of the
  saturated motor torques, clamped to the bus, which MuJoCo turns back into those torques;
* ``dcmotor-ff`` (MuJoCo >= 4.0): a torque feed-forward input (``input="ff"``): its on-board
  controller drives v = (R'/K) tau + K omega, clamped to V_bus (``controller`` Vmax), and the
  torque is clamped to the torque limit: the operating region's clip at the current speed.

Numbers are written at full precision (:func:`full_precision`), not MuJoCo's 6 digits.

Differences from the paper's clip are listed in :data:`DIFFERENCES`; the tests measure them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from hound_id.errors import SpecError
from hound_id.export.target import Export, Written, put_feet

#: Where the exported dcmotor differs from hound-id's clip, and by how much.
DIFFERENCES = (
    "motor constant: MuJoCo uses one K for torque and back-EMF; hound-id sets K = 1/Kv and R' = R Ke/Kt so "
    "the voltage lines and the torque limit are exact; MuJoCo's internal current is then tau/Ke, which differs "
    "from the real current tau/Kt by the factor Kt Kv (0.867 for the sample motor): read currents from "
    "hound_id.runtime.current, not from MuJoCo",
    "rated speed: dcmotor has no max_speed cut-off; a motor with max_speed in its spec is clipped by hound-id "
    "to braking torque only above it, by MuJoCo not at all (use --mujoco-actuator motor with the runtime)",
    "state: the export adds no inductance, thermal or LuGre state, so the dcmotor is algebraic like the "
    "paper's clip; the clip uses the velocity at the start of each step, as the paper's does",
    "friction: MuJoCo's frictionloss is a constraint (exact dry friction, sticks at rest), the fit's Coulomb "
    "term is smooth (tanh(omega / 0.01 rad/s)); damping is the same linear term",
)


def _foot_urdf(ex: Export) -> str:
    """The robot's URDF for MuJoCo: optimised feet, no visuals, no joint dynamics (friction lives on the tendons)."""
    import xml.etree.ElementTree as ET

    from hound_id.foot.urdf import parse_urdf, rebase_meshes

    path = ex.urdf()
    root = parse_urdf(path)
    rebase_meshes(root, path, None)
    if ex.bundle.foot:
        put_feet(root, ex.bundle.foot, path)
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
    for joint in root.iter("joint"):
        for dyn in joint.findall("dynamics"):
            joint.remove(dyn)
    return ET.tostring(root, encoding="unicode")


def mujoco_spec(ex: Export, actuator: str = "dcmotor", scene: bool = True) -> Any:
    """The MjSpec of the robot with tendons and actuators (see the module docstring); ``actuator="none"``: the
    tendons without actuators (a trainer adds its own, as mjlab does); ``scene=False``: no floor and no keyframe
    (a trainer's scene has its own)."""
    import mujoco

    if actuator not in ("dcmotor", "dcmotor-ff", "motor", "none"):
        raise SpecError(f"--mujoco-actuator: found {actuator!r}, expected dcmotor, dcmotor-ff or motor")
    if actuator == "dcmotor-ff" and not hasattr(mujoco, "mjtCtrlInput"):
        raise SpecError(
            "--mujoco-actuator dcmotor-ff: the dcmotor's torque input needs MuJoCo >= 4.0, this is "
            f"{mujoco.__version__}; use --mujoco-actuator dcmotor (voltage input, with hound_id.runtime's voltage) or "
            "upgrade mujoco"
        )
    try:
        spec = mujoco.MjSpec.from_string(_foot_urdf(ex))
    except ValueError as err:
        raise SpecError(f"{ex.urdf()}: MuJoCo cannot read the URDF ({err})") from err
    spec.modelname = ex.robot.name
    joints = {j.name for j in spec.joints}
    missing = [j for j in ex.bundle.joints if j not in joints]
    if missing:
        raise SpecError(f"{ex.urdf()}: joints {', '.join(missing)} of robot {ex.robot.name} are not in the URDF")
    for joint in spec.joints:  # the URDF's effort limits would clamp the tendon actuators at the joints
        joint.actfrclimited = mujoco.mjtLimited.mjLIMITED_FALSE
    base = spec.worldbody.first_body()
    base.add_freejoint(name="floating_base")
    if scene:
        spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05])
    A_inv = np.linalg.inv(ex.A)
    for k, m in enumerate(ex.bundle.motors):
        tendon = spec.add_tendon(name=f"{m.name}_tendon")
        for j, joint in enumerate(ex.bundle.joints):
            if A_inv[k, j] != 0.0:
                tendon.wrap_joint(joint, float(A_inv[k, j]))
        tendon.armature = float(m.rotor_inertia or 0.0)
        tendon.frictionloss = float(m.friction["coulomb"])
        tendon.damping = [float(m.friction["viscous"]), 0.0, 0.0]  # linear: f = -a v
        if actuator == "none":
            continue
        act = spec.add_actuator(name=m.name, target=tendon.name, trntype=mujoco.mjtTrn.mjTRN_TENDON)
        if actuator == "dcmotor-ff":
            ke = 1.0 / float(m.kv)
            act.set_to_dcmotor(
                motorconst=[ke, ke],
                resistance=float(m.resistance) * ke / float(m.kt),
                saturation=[float(m.torque_limit), 0.0, 0.0],
                controller=[0.0, 0.0, 0.0, 0.0, 0.0, float(m.bus_voltage)],
                ctrlspec=int(mujoco.mjtCtrlInput.mjINPUT_FF),
            )
        elif actuator == "dcmotor":  # voltage input, ctrl limited to the bus: loads in MuJoCo 3.x and 4.x
            ke = 1.0 / float(m.kv)
            inputs = getattr(mujoco, "mjtCtrlInput", None)  # MuJoCo 3.x has the voltage input only
            extra = {"ctrlspec": int(inputs.mjINPUT_VOLTAGE)} if inputs is not None else {}
            act.set_to_dcmotor(
                motorconst=[ke, ke],
                resistance=float(m.resistance) * ke / float(m.kt),
                saturation=[float(m.torque_limit), 0.0, 0.0],
                **extra,
            )
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = [-float(m.bus_voltage), float(m.bus_voltage)]
        else:
            act.set_to_motor()
            act.forcelimited = True
            act.forcerange = [-float(m.torque_limit), float(m.torque_limit)]
    if scene:
        _stand_key(spec)
    return spec


def _stand_key(spec: Any) -> None:
    """A keyframe ``stand``: :func:`stand_qpos`."""
    spec.add_key(name="stand", qpos=stand_qpos(spec.compile()).tolist())


def stand_qpos(model: Any) -> Any:
    """A standing start of a compiled model whose first joint is the floating base: joints at 0 clamped to their
    ranges, the base just above the floor (the lowest geom other than ``floor`` 5 mm above z = 0)."""
    import mujoco

    data = mujoco.MjData(model)
    qpos = model.qpos0.copy()
    qpos[2] = 1.0
    for j in range(model.njnt):
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE and model.jnt_limited[j]:
            lo, hi = model.jnt_range[j]
            qpos[model.jnt_qposadr[j]] = min(max(0.0, lo), hi)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    lowest = min(data.geom_xpos[g, 2] - model.geom_rbound[g] for g in range(model.ngeom) if g != floor)
    qpos[2] = 1.0 - lowest + 0.005
    return qpos


def mujoco_files(ex: Export, out: Path) -> Written:
    """``<robot>.xml``: the MJCF, compiled once here and again from the written text."""
    import mujoco

    spec = mujoco_spec(ex, ex.mujoco_actuator)
    spec.compile()
    xml = full_precision(spec.to_xml(), ex)
    mujoco.MjModel.from_xml_string(xml)  # what is written loads
    files = {f"{ex.stem}.xml": xml}
    curved = [m.name for m in ex.bundle.motors if m.envelope]
    notes: tuple[str, ...] = ()
    if curved and ex.mujoco_actuator.startswith("dcmotor"):
        notes += (
            f"motors {', '.join(curved)} have a measured envelope (mor --compare --out): dcmotor holds the spec "
            "sheet's straight voltage lines, not its polyline; use --mujoco-actuator motor with hound_id.runtime to "
            "apply it",
        )
    bent = _curve_gaps(ex)
    if bent and ex.mujoco_actuator.startswith("dcmotor"):
        worst = max(bent.values())
        short = max(ex.straight_gap(m)[1] for m in bent)
        notes += (
            f"motors {', '.join(bent)} have a saturating current-torque curve: dcmotor's torque limit is the curve's "
            f"but its voltage lines are straight, passing hound-id's curved edges by up to {worst:.3g} N m (motor "
            "side, between the corner and the overspeed, either way: just past the drive's loss of control the diode "
            "bridge brakes less than the limit dcmotor holds)"
            + (f" and falling short of them by up to {short:.3g} N m (field weakening)" if short > 1e-9 * worst else "")
            + "; past overspeed dcmotor holds the torque limit where the back-EMF forces more braking. For the exact "
            "clip use --mujoco-actuator motor with hound_id.runtime",
        )
    past = max((ex.past_overspeed(m.name) for m in ex.bundle.motors), default=(0.0, 0.0))
    if past[0] > 0 and ex.mujoco_actuator.startswith("dcmotor"):
        notes += (
            f"past overspeed the runtime brakes by up to {past[0]:.4g} N m more than dcmotor's torque limit (motor "
            f"side, to {past[1]:.4g} rad/s, twice the no-load speed): the back-EMF's forced braking, the diode "
            "bridge's with a winding reactance; dcmotor's forcerange holds the torque limit there",
        )
    if ex.mujoco_actuator == "dcmotor":
        notes = (
            "voltage input (loads in MuJoCo 3.x and 4.x): ctrl is each motor's voltage, limited to the bus; send "
            "hound_id.runtime.load(bundle).voltage(tau, qd) for the saturated torques",
            *notes,
        )
    lost = ex.friction_not_held("mujoco")
    if notes:
        return Written(files, (*DIFFERENCES, *notes, *lost))
    if ex.mujoco_actuator == "motor":
        notes = (
            "plain <motor> actuators on the tendons, force-limited to the torque limit only: call "
            "hound_id.runtime.load(bundle).saturate(tau, qd) every step and send sat.motor_torque(tau) as ctrl",
        )
        return Written(files, (*notes, *lost))
    return Written(files, (*DIFFERENCES, *lost))


def _repr(values: Any) -> str:
    """Floats as Python writes them back exactly (shortest round-trip), space separated."""
    return " ".join(repr(float(v)) for v in np.atleast_1d(values))


def full_precision(xml: str, ex: Export) -> str:
    """The MJCF with every number hound-id computed written at full precision (MuJoCo's writer keeps 6 digits: R'
    0.114881 instead of 0.11488123..., a tendon coefficient of the hollow shaft likewise), and the voltage input left
    as the default, which MuJoCo 3.x reads (it does not know ``input="voltage"``).

    Rewritten: each motor tendon's joint coefficients (the row of A^-1), armature, frictionloss and damping; each
    actuator's forcerange, ctrlrange and its dcmotor gainprm (R', K; Vmax for the feed-forward input)."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(xml)
    A_inv = np.linalg.inv(ex.A)
    tendons = {t.get("name"): t for t in root.iter("fixed")}
    actuators = {a.get("name"): a for tag in ("general", "motor") for a in root.iter(tag)}
    for k, m in enumerate(ex.bundle.motors):
        tendon = tendons.get(f"{m.name}_tendon")
        if tendon is not None:
            coefs = [A_inv[k, j] for j in range(len(ex.bundle.joints)) if A_inv[k, j] != 0.0]
            for child, coef in zip(tendon.findall("joint"), coefs, strict=True):
                child.set("coef", _repr(coef))
            for key, value in (
                ("armature", m.rotor_inertia or 0.0),
                ("frictionloss", m.friction["coulomb"]),
                ("damping", m.friction["viscous"]),
            ):
                if tendon.get(key) is not None:
                    tendon.set(key, _repr(value))
        act = actuators.get(m.name)
        if act is None:
            continue
        if act.get("forcerange") is not None:
            act.set("forcerange", _repr([-m.torque_limit, m.torque_limit]))
        if act.get("gaintype") == "dcmotor":
            gain = act.get("gainprm", "").split()
            ke = 1.0 / float(m.kv)
            gain[:2] = [_repr(float(m.resistance) * ke / float(m.kt)), _repr(ke)]
            if len(gain) >= 8:
                gain[7] = _repr(m.bus_voltage)
            act.set("gainprm", " ".join(gain))
            if act.get("input") == "voltage":
                del act.attrib["input"]  # the default; MuJoCo 3.x refuses the keyword
        if act.get("ctrlrange") is not None:
            act.set("ctrlrange", _repr([-m.bus_voltage, m.bus_voltage]))
    return ET.tostring(root, encoding="unicode")


def _curve_gaps(ex: Export) -> dict[str, float]:
    """Per motor whose curve saturates (no measured envelope): the most a straight dcmotor passes its region [N m]."""
    return {
        m.name: ex.straight_gap(m.name)[0]
        for m in ex.bundle.motors
        if not m.envelope and ex.robot.motor_specs[m.name].current_curve.form != "linear"
    }


def rollout_check(xml: Path, bundle: Path, seconds: float = 1.0) -> dict[str, float]:
    """Drive the exported model with PD commands far past the region and compare each step's realised
    motor torques with :mod:`hound_id.runtime`'s saturation (the demo's check; the tests have their own).

    Returns the steps, the fraction whose commands were clipped, the largest difference between MuJoCo
    and the runtime [N m], and the largest excursion outside the region [N m] (0 when inside).
    """
    import mujoco

    import hound_id.runtime

    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)
    sat = hound_id.runtime.load(bundle)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    joints = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in sat.joints]
    actuators = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, m) for m in sat.motors]
    qadr, vadr = model.jnt_qposadr[joints], model.jnt_dofadr[joints]
    voltage = bool(np.all(model.actuator_ctrllimited[actuators]))
    q0 = data.qpos[qadr].copy()
    steps = int(round(seconds / model.opt.timestep))
    clipped, worst, outside = 0, 0.0, 0.0
    for step in range(steps):
        q, qd = data.qpos[qadr].copy(), data.qvel[vadr].copy()
        target = q0 + 0.6 * np.sin(2 * np.pi * 3 * step * model.opt.timestep)
        tau_cmd = 2000.0 * (target - q) - 5.0 * qd
        # voltage input (ctrl limited to the bus): the voltage of the saturated torques; feed-forward: the torque
        data.ctrl[actuators] = sat.voltage(tau_cmd, qd) if voltage else sat.motor_torque(tau_cmd)
        mujoco.mj_forward(model, data)
        realised = data.actuator_force[actuators]
        expected = sat.motor_torque(sat.saturate(tau_cmd, qd))
        lo, hi = sat.clip.torque_bounds(qd)
        clipped += bool(np.any(np.abs(expected - sat.motor_torque(tau_cmd)) > 1e-9))
        worst = max(worst, float(np.max(np.abs(realised - expected))))
        outside = max(outside, float(np.max(realised - hi)), float(np.max(lo - realised)), 0.0)
        mujoco.mj_step(model, data)
    if not np.all(np.isfinite(data.qpos)):
        raise SpecError(f"{xml}: the simulation diverged (NaN in qpos)")
    return {"steps": steps, "clipped_fraction": clipped / steps, "max_difference": worst, "max_outside": outside}
