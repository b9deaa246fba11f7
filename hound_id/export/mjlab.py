"""mjlab export: the robot's MJCF with a tendon per motor and no actuators, and a Python module of mjlab actuator
configs (``<robot>_mjlab.py``) that a task imports.

The MJCF is :func:`hound_id.export.mujoco.mujoco_spec` without actuators, floor or keyframe (mjlab's scene has
its own): each motor's fixed tendon encodes its row of A^-1 and carries its rotor inertia (``armature``), Coulomb
friction (``frictionloss``) and viscous friction (``damping``), so the reflected inertia is the full
A^-T diag(J) A^-1 and coupled joints are exact.

The module's :func:`actuators` returns, per motor spec:

* coupled motors (a hip/knee pair sharing motors): ``BuiltinDcMotorActuatorCfg`` on the motor's tendon, voltage
  input, K = 1/Kv and R' = R Ke/Kt (as the MuJoCo export), ``voltage_limit`` the bus voltage (mjlab clamps the
  ctrl there) and ``effort_limit`` the torque limit. The trainer sends ``hound_id.runtime``'s
  ``voltage(tau, qd)`` for those motors: a stateless voltage-mode motor without the clamp ignores the voltage
  limit;
* uncoupled joints: ``DcMotorActuatorCfg`` (mjlab's PD with the straight DC-motor clip) with the joint-side
  stall torque, no-load speed and torque limit, or with ``uncoupled="voltage"`` the same builtin dcmotor on the
  motor's tendon as the coupled motors (exact where DcMotor's straight lines are not).

What mjlab cannot hold is written in the module (``NOT_HELD``) with its size.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from hound_id import __version__
from hound_id.export.mujoco import full_precision, mujoco_spec, stand_qpos
from hound_id.export.target import Export, Written, bundle_json

#: mjlab release the generated module is written for and tested with.
MJLAB_VERSION = "1.6.0"


def coupled_motors(ex: Export) -> list[bool]:
    """Per motor (bundle order): whether its transmission couples joints (:attr:`Transmission.coupled`)."""
    coupled = {m: tx.coupled for tx in ex.robot.transmissions for m in tx.motors}
    return [coupled[m.name] for m in ex.bundle.motors]


def not_held(ex: Export, uncoupled: str, fmt: str) -> list[str]:
    """What format ``fmt``'s dcmotor/DcMotor actuators and tendons cannot hold of this robot, each with its size."""
    lines = []
    both = {m.name: ex.straight_gap(m.name) for m in ex.bundle.motors if not m.envelope}
    gaps = {k: v[0] for k, v in both.items() if v[0] > 0}
    short = max((v[1] for v in both.values()), default=0.0)
    if gaps:
        specs = ex.robot.motor_specs
        curved = [k for k in gaps if specs[k].current_curve.form != "linear"]
        rated = [k for k in gaps if specs[k].max_speed is not None]
        driven = [k for k in gaps if specs[k].drive is not None]
        weak = [k for k in gaps if specs[k].field_weakening]
        causes = (
            ([f"a saturating current-torque curve (motors {', '.join(curved)})"] if curved else [])
            + ([f"a rated-speed cut-off, braking only above max_speed (motors {', '.join(rated)})"] if rated else [])
            + ([f"the drive's dq model, a winding reactance (motors {', '.join(driven)})"] if driven else [])
            + ([f"field weakening, motoring past the no-load speed (motors {', '.join(weak)})"] if weak else [])
        )
        lines.append(
            "straight lines: hound-id's edges are not straight where a motor has "
            + " and ".join(causes)
            + f"; a dcmotor's voltage lines and DcMotor's torque-speed line are, and pass them by up to "
            f"{max(gaps.values()):.4g} N m (motor side)"
            + (f" and fall short of them by up to {short:.4g} N m" if short > 1e-9 * max(gaps.values()) else "")
            + ", either way (just past the drive's loss of control the diode bridge brakes less than the torque "
            "limit, which a dcmotor holds). Fed the runtime's voltage, a dcmotor applies the runtime's "
            "torque (rated-speed cut included) wherever that voltage is within the bus"
            + ("" if uncoupled == "voltage" else "; DcMotor joints (uncoupled) take the straight line and no cut")
        )
    envelope = [m.name for m in ex.bundle.motors if m.envelope]
    if envelope:
        lines.append(
            f"measured envelope: motors {', '.join(envelope)} have polyline edges (mor --compare --out); the "
            "actuators hold the spec sheet's straight lines: apply hound_id.runtime.saturate for the measured edge"
        )
    lines.extend(ex.friction_not_held(fmt))
    cogging = _cogging(ex)
    if cogging:
        lines.append(
            "cogging: the fitted cogging ("
            + ", ".join(f"{k} {v:.3g} N m" for k, v in cogging.items())
            + ") is not in the actuators: the fit's position channel is the dyno's rotor angle, whose zero the "
            "robot's joint angle does not share"
        )
    delay = [m.name for m in ex.bundle.motors if "delay" in (m.effects or {})]
    if delay:
        lines.append(
            f"delay: the fitted delay of motors {', '.join(delay)} is the lag between the dyno's current and torque "
            "channels (a measurement lag), not the command-to-torque latency an actuator delay models; none is set"
        )
    sensed = [m.name for m in ex.bundle.motors if {"lag_tau", "resonance_f0"} & set(m.effects or {})]
    if sensed:
        lines.append(
            f"lag, resonance: the fitted filters of motors {', '.join(sensed)} are the dyno's torque transducer and "
            "coupling (how the reading follows the shaft torque), not the actuator's; none is set"
        )
    past = {m.name: ex.past_overspeed(m.name) for m in ex.bundle.motors}
    worst = max(past.values(), default=(0.0, 0.0))
    lines.append(
        "past overspeed a dcmotor holds the torque limit where the back-EMF forces more braking (hound-id's clip "
        "returns that braking torque: the diode bridge's with a winding reactance)"
        + (
            f": up to {worst[0]:.4g} N m more than the torque limit (motor side) to {worst[1]:.4g} rad/s, twice the "
            "no-load speed"
            if worst[0] > 0
            else ""
        )
    )
    return lines


def _cogging(ex: Export) -> dict[str, float]:
    """Per motor with a fitted cogging term: its largest harmonic amplitude [N m]."""
    out = {}
    for m in ex.bundle.motors:
        p = m.effects or {}
        amps = [
            float(np.hypot(p[f"cogging_sin_{k}"]["value"], p[f"cogging_cos_{k}"]["value"]))
            for k in (1, 2)
            if f"cogging_sin_{k}" in p and f"cogging_cos_{k}" in p
        ]
        if amps:
            out[m.name] = max(amps)
    return out


def _r(v: float) -> str:
    return repr(float(v))


def mjlab_module(ex: Export, xml_name: str, bundle_name: str, stand: tuple[dict[str, float], float]) -> str:
    """The text of ``<robot>_mjlab.py``; ``stand``: the joint positions and base height of :func:`stand_pose`."""
    b = ex.bundle
    coupled = coupled_motors(ex)
    A_inv = np.linalg.inv(ex.A)
    groups: dict[str, list[int]] = {}
    for k, m in enumerate(b.motors):
        groups.setdefault(m.spec, []).append(k)
    tendon_cfgs, joint_cfgs = [], []
    for spec_name, ks in groups.items():
        m = b.motors[ks[0]]
        ke = 1.0 / float(m.kv)
        params = (
            f"motor_params=DcMotorPhysicalParams(kt={_r(ke)}, ke={_r(ke)}, "
            f"resistance={_r(float(m.resistance) * ke / float(m.kt))}),\n"
            f"            voltage_limit={_r(m.bus_voltage)},\n"
            f"            effort_limit={_r(m.torque_limit)},\n"
        )
        tendons = [f"{b.motors[k].name}_tendon" for k in ks if coupled[k]]
        tendon_cfgs.append((spec_name, tendons, params))
        for k in ks:
            if coupled[k]:
                continue
            j = int(np.flatnonzero(A_inv[k])[0])
            gear = abs(float(A_inv[k, j]))
            joint_cfgs.append((b.joints[j], b.motors[k].name, gear, m))
    lines = [
        f'"""mjlab actuators for robot {b.robot}: generated by hound-id {__version__} ({b.schema}), for mjlab '
        f"{MJLAB_VERSION}.",
        "",
        "    from " + Path(xml_name).stem + " import BUNDLE, entity_cfg, voltage_motors",
        "    import hound_id.runtime",
        "",
        "    MODE = 'dcmotor'   # or 'voltage': the uncoupled joints' actuators too (give the same MODE to both calls)",
        "    scene_cfg.entities['robot'] = entity_cfg(stiffness=40.0, damping=1.0, uncoupled=MODE)",
        "    # once the scene is built (robot = env.scene['robot']):",
        "    sat = hound_id.runtime.load(BUNDLE, joint_names=robot.joint_names)   # your joint order; torch in and out",
        "    tendons, motors = voltage_motors(uncoupled=MODE)",
        "    tendon_ids = robot.find_tendons(tendons, preserve_order=True)[0]",
        "    # every physics step, tau_cmd (envs, joints) in robot.joint_names order, qd = robot.data.joint_vel:",
        "    robot.set_tendon_effort_target(sat.voltage(tau_cmd, qd)[:, motors], tendon_ids=tendon_ids)   # volts",
        "",
        "ctrl of a voltage-input actuator is volts, not N m (mjlab's DcMotorInputMode.VOLTAGE). Units SI, motor side",
        "on the tendons (tendon length = motor angle), joint side on the joints. NOT_HELD: what mjlab cannot hold.",
        '"""',
        "",
        "from __future__ import annotations",
        "",
        "from pathlib import Path",
        "",
        "import mujoco",
        "from mjlab.actuator import (",
        "    BuiltinDcMotorActuatorCfg,",
        "    DcMotorActuatorCfg,",
        "    DcMotorInputMode,",
        "    DcMotorPhysicalParams,",
        ")",
        "from mjlab.actuator.actuator import TransmissionType",
        "from mjlab.entity import EntityArticulationInfoCfg, EntityCfg",
        "",
        f"MJCF = Path(__file__).with_name({xml_name!r})",
        f"BUNDLE = Path(__file__).with_name({bundle_name!r})",
        f"JOINTS = {list(b.joints)!r}",
        f"MOTORS = {[m.name for m in b.motors]!r}",
        f"COUPLED = {[m.name for k, m in enumerate(b.motors) if coupled[k]]!r}",
        f"NOT_HELD = {not_held(ex, 'dcmotor', 'mjlab')!r}",
        "#: A standing start: every joint at 0 clamped into its range, the base just above the ground [rad, m].",
        f"STAND_JOINTS = {stand[0]!r}",
        f"STAND_HEIGHT = {stand[1]!r}",
        "",
        "",
        "def _mode(uncoupled: str) -> str:",
        "    if uncoupled not in ('dcmotor', 'voltage'):",
        "        raise ValueError(f\"uncoupled: found {uncoupled!r}, expected 'dcmotor' or 'voltage'\")",
        "    return uncoupled",
        "",
        "",
        "def voltage_motors(*, uncoupled: str) -> tuple[list[str], list[int]]:",
        '    """(tendon names, motor indices in the runtime\'s motor order) of the voltage-input actuators, for the',
        '    same ``uncoupled`` mode as :func:`entity_cfg`."""',
        "    idx = [k for k, m in enumerate(MOTORS) if m in COUPLED or _mode(uncoupled) == 'voltage']",
        "    return [MOTORS[k] + '_tendon' for k in idx], idx",
        "",
        "",
        "def actuators(stiffness: float = 0.0, damping: float = 0.0, *, uncoupled: str) -> tuple:",
        '    """The actuator configs. ``stiffness``/``damping``: PD gains of the DcMotor joints (joint side);',
        "    ``uncoupled='voltage'``: every motor a voltage-input dcmotor on its tendon (then send",
        '    sat.voltage for all motors; no PD in mjlab)."""',
        "    _mode(uncoupled)",
        "    out = []",
    ]
    for spec_name, tendons, params in tendon_cfgs:
        all_tendons = [f"{b.motors[k].name}_tendon" for k in groups[spec_name]]
        lines += [
            f"    # motor spec {spec_name}: K = 1/Kv, R' = R Ke/Kt (stall torque Kt V/R and no-load speed V Kv exact)",
            f"    tendons = {all_tendons!r} if uncoupled == 'voltage' else {tendons!r}",
            "    if tendons:",
            "        out.append(BuiltinDcMotorActuatorCfg(",
            "            target_names_expr=tuple(tendons),",
            "            transmission_type=TransmissionType.TENDON,",
            "            mode=DcMotorInputMode.VOLTAGE,",
            "            " + params.replace("\n            ", "\n            ").rstrip(),
            "        ))",
        ]
    same: dict[tuple[str, float], list[tuple[str, str]]] = {}  # joints of one motor spec and gear share a config
    for joint, motor, gear, m in joint_cfgs:
        same.setdefault((m.spec, gear), []).append((joint, motor))
    if same:
        lines.append("    if uncoupled == 'dcmotor':")
        for (_, gear), members in same.items():
            m = b.motors[[x.name for x in b.motors].index(members[0][1])]
            joints = tuple(j for j, _ in members)
            lines += [
                f"        # motor spec {m.spec}, gear {gear:.6g} (joint side); armature and friction are on the",
                "        # motor tendons (" + ", ".join(f"{mo}_tendon" for _, mo in members) + ")",
                "        out.append(DcMotorActuatorCfg(",
                f"            target_names_expr={joints!r},",
                f"            saturation_effort={_r(m.stall_torque * gear)},",
                f"            velocity_limit={_r(m.no_load_speed / gear)},",
                f"            effort_limit={_r(m.torque_limit * gear)},",
                "            stiffness=stiffness,",
                "            damping=damping,",
                "        ))",
            ]
    lines += [
        "    return tuple(out)",
        "",
        "",
        "def spec() -> mujoco.MjSpec:",
        '    """The robot\'s MjSpec: tendons per motor (armature, friction), no actuators."""',
        "    return mujoco.MjSpec.from_file(str(MJCF))",
        "",
        "",
        "def entity_cfg(stiffness: float = 0.0, damping: float = 0.0, *, uncoupled: str) -> EntityCfg:",
        '    """The robot as an mjlab entity with its actuators, starting from the STAND pose (``dataclasses.replace``',
        '    it for another ``init_state``)."""',
        "    return EntityCfg(",
        "        init_state=EntityCfg.InitialStateCfg(pos=(0.0, 0.0, STAND_HEIGHT), joint_pos=dict(STAND_JOINTS)),",
        "        spec_fn=spec,",
        "        articulation=EntityArticulationInfoCfg(actuators=actuators(stiffness, damping, uncoupled=uncoupled)),",
        "    )",
        "",
    ]
    return "\n".join(lines)


def stand_pose(ex: Export, model: Any) -> tuple[dict[str, float], float]:
    """The standing start of the compiled robot ``model`` (:func:`hound_id.export.mujoco.stand_qpos`) as (joint
    positions by name, base height)."""
    import mujoco

    qpos = stand_qpos(model)
    joints = {
        j: float(qpos[model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j)]])
        for j in ex.bundle.joints
    }
    return joints, float(qpos[2])


def mjlab_files(ex: Export, out: Path) -> Written:
    """``<robot>_mjlab.xml`` (tendons, no actuators), ``<robot>_mjlab.py`` (the actuator configs) and
    ``<robot>_bundle.json`` (for ``hound_id.runtime``)."""
    import mujoco

    stem = ex.stem
    spec = mujoco_spec(ex, "none", scene=False)
    model = spec.compile()
    xml = full_precision(spec.to_xml(), ex)
    mujoco.MjModel.from_xml_string(xml)  # what is written loads
    (xml_name, module), (bundle, content) = (f"{stem}_mjlab.xml", f"{stem}_mjlab.py"), bundle_json(ex)
    text = mjlab_module(ex, xml_name, bundle, stand_pose(ex, model))
    compile(text, str(out / module), "exec")  # what is written parses
    files = {xml_name: xml, module: text, bundle: content}
    n_coupled = sum(coupled_motors(ex))
    notes: tuple[Any, ...] = (
        f"{n_coupled} coupled motors are voltage-input dcmotors on tendons: send hound_id.runtime's voltage(tau, qd) "
        "for them (voltage_motors); uncoupled joints are DcMotorActuatorCfg (uncoupled='voltage' for the exact "
        "clip)",
        *not_held(ex, "dcmotor", "mjlab"),
    )
    return Written(files, notes)
