"""Each format through the tool that consumes it: mujoco, Pinocchio, Isaac Lab's clip, the runtime."""

from pathlib import Path

import numpy as np
import pytest

import hound_id.runtime
from hound_id.errors import SpecError
from hound_id.export.run import formats_from, prepare
from hound_id.mor.saturation import dc_motor_clip
from tests.conftest import MOTOR, ROBOT
from tests.export.conftest import fitted_motor, write_export


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    from tests.export.conftest import fitted_motor

    folder = tmp_path_factory.mktemp("export")
    ex = prepare(ROBOT, [fitted_motor(folder)])
    report = write_export(ex, formats_from("all"), folder / "out")
    return ex, report, folder / "out"


def _ids(model, kind, names):
    import mujoco

    return [mujoco.mj_name2id(model, kind, n) for n in names]


def drive(model, sat, seconds, on_step):
    """PD commands far past the region (2000 N m/rad) towards a 3 Hz sweep, from the stand keyframe."""
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    jids = _ids(model, mujoco.mjtObj.mjOBJ_JOINT, sat.joints)
    qadr, vadr = model.jnt_qposadr[jids], model.jnt_dofadr[jids]
    aid = _ids(model, mujoco.mjtObj.mjOBJ_ACTUATOR, sat.motors)
    q0 = data.qpos[qadr].copy()
    for step in range(int(seconds / model.opt.timestep)):
        t = step * model.opt.timestep
        q, qd = data.qpos[qadr].copy(), data.qvel[vadr].copy()
        target = q0 + 0.6 * np.sin(2 * np.pi * 3 * t) * np.array([0.3, 1.0, 1.0] * 4)
        tau_cmd = 2000.0 * (target - q) - 5.0 * qd
        on_step(data, aid, tau_cmd, qd)
        mujoco.mj_step(model, data)
    return data


@pytest.mark.parametrize("actuator", ["dcmotor", "dcmotor-ff"])
def test_mujoco_dcmotor_realises_the_operating_region(exported, tmp_path, actuator):
    """The fitted motor's curve is linear: the dcmotor's straight lines are the region's. Voltage input (the
    default): ctrl = runtime.voltage, exact to rounding (full-precision numbers); feed-forward (MuJoCo >= 4.0):
    ctrl = the commanded motor torque, which the dcmotor's own controller clips."""
    from dataclasses import replace

    import mujoco

    ex, report, out = exported
    if actuator != "dcmotor":
        write_export(replace(ex, mujoco_actuator=actuator), ["mujoco"], tmp_path)
    xml = (out if actuator == "dcmotor" else tmp_path) / "hound_like.xml"
    assert ('input="ff"' in xml.read_text()) == (actuator == "dcmotor-ff")
    assert 'input="voltage"' not in xml.read_text()  # the default: MuJoCo 3.x refuses the keyword
    model = mujoco.MjModel.from_xml_path(str(xml))
    sat = hound_id.runtime.load(out / "hound_like_bundle.yaml")
    assert model.nu == 12 and model.ntendon == 12 and model.nkey == 1
    stats = {"steps": 0, "clipped": 0, "worst": 0.0, "outside": 0.0}

    def on_step(data, aid, tau_cmd, qd):
        data.ctrl[aid] = sat.voltage(tau_cmd, qd) if actuator == "dcmotor" else sat.motor_torque(tau_cmd)
        mujoco.mj_forward(model, data)
        realised = data.actuator_force[aid]
        expected = sat.motor_torque(sat.saturate(tau_cmd, qd))
        lo, hi = sat.clip.torque_bounds(qd)
        stats["steps"] += 1
        stats["clipped"] += bool(np.any(np.abs(expected - sat.motor_torque(tau_cmd)) > 1e-9))
        stats["worst"] = max(stats["worst"], float(np.max(np.abs(realised - expected))))
        stats["outside"] = max(stats["outside"], float(np.max(realised - hi)), float(np.max(lo - realised)))

    data = drive(model, sat, 3.0, on_step)
    assert np.all(np.isfinite(data.qpos))
    assert stats["steps"] == 1500 and stats["clipped"] > stats["steps"] / 2  # the commands violate the region
    assert stats["outside"] <= 1e-9  # realised motor torques inside the region
    # and equal to the runtime's saturation [N m]: full-precision parameters (MuJoCo's own 6 digits gave 2.4e-6)
    assert stats["worst"] < 1e-9
    # the tendons carry the transmission: motor speed = A^-1 qd, rotor inertia as armature
    assert model.tendon_armature == pytest.approx([1.7e-4] * 12)
    assert model.tendon_frictionloss == pytest.approx([0.08] * 12)  # every motor is the fitted ILM85


def test_mujoco_motor_fallback_with_the_runtime_each_step(exported, tmp_path):
    import mujoco

    ex, _, out = exported
    from dataclasses import replace

    write_export(replace(ex, mujoco_actuator="motor"), ["mujoco"], tmp_path)
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "hound_like.xml"))
    sat = hound_id.runtime.load(out / "hound_like_bundle.yaml")
    worst = []

    def on_step(data, aid, tau_cmd, qd):
        data.ctrl[aid] = sat.motor_torque(sat.saturate(tau_cmd, qd))
        mujoco.mj_forward(model, data)
        lo, hi = sat.clip.torque_bounds(qd)
        worst.append(max(float(np.max(data.actuator_force[aid] - hi)), float(np.max(lo - data.actuator_force[aid]))))

    drive(model, sat, 1.0, on_step)
    assert max(worst) <= 1e-9


def test_urdf_with_limits_loads_in_pinocchio(exported):
    import pinocchio as pin

    ex, _, out = exported
    model = pin.buildModelFromUrdf(str(out / "hound_like_limits.urdf"))
    boxes = ex.bundle.joint_boxes
    for joint in ex.bundle.joints:
        jid = model.getJointId(joint)
        v = model.joints[jid].idx_v
        assert model.effortLimit[v] == pytest.approx(boxes[joint]["inner"]["effort"], rel=1e-8)
        assert model.velocityLimit[v] == pytest.approx(boxes[joint]["inner"]["velocity"], rel=1e-8)
    # HAA of ratio 9: friction 9 x 0.08 N m, damping 81 x 2e-4 N m s/rad
    haa = model.joints[model.getJointId("FL_HAA")].idx_v
    assert model.friction[haa] == pytest.approx(0.72) and model.damping[haa] == pytest.approx(0.0162)


@pytest.mark.parametrize("fitted", [True, False], ids=["linear_fit", "sheet_curve"])
def test_isaaclab_fields_reproduce_the_clip_on_uncoupled_joints(exported, tmp_path, fitted):
    ex, _, out = exported
    import yaml

    if not fitted:  # the spec sheet's 20 % point: a saturating curve
        ex = prepare(ROBOT, [])
        out = tmp_path / "out"
        write_export(ex, formats_from("bundle,isaaclab"), out)
    fields = yaml.safe_load((out / "hound_like_isaaclab.yaml").read_text())
    assert fields["schema"] == "hound-id/isaaclab/2"
    sat = hound_id.runtime.load(out / "hound_like_bundle.yaml")
    rng = np.random.default_rng(4)
    for i, joint in enumerate(sat.joints):
        f = fields["joints"][joint]
        if f["coupled"]:
            assert f["use"] == "hound_id.runtime" and "per-joint DCMotor" in f["reason"]
            continue
        d = f["dcmotor_isaaclab2"]
        new = f["dcmotor"]  # Isaac Lab 3.0's names for the same numbers, and the friction split
        assert (
            new["actuator_effort_limit"] == d["effort_limit"] and new["actuator_velocity_limit"] == d["velocity_limit"]
        )
        assert all(new[k] == d[k] for k in ("friction", "dynamic_friction", "armature", "saturation_effort"))
        assert new["viscous_friction"] == pytest.approx(f["viscous_friction"])
        tau = rng.uniform(-300, 300, 2000)
        overspeed = d["velocity_limit"] * (1 + d["effort_limit"] / d["saturation_effort"])  # of the straight line
        qd = rng.uniform(-1.0, 1.0, 2000) * overspeed * 0.999
        full_tau, full_qd = np.zeros((2000, 12)), np.zeros((2000, 12))
        full_tau[:, i], full_qd[:, i] = tau, qd
        ours = sat.saturate(full_tau, full_qd)[:, i]
        isaac = dc_motor_clip(tau, qd, d["saturation_effort"], d["velocity_limit"], d["effort_limit"])
        gap = f["dcmotor_error"]
        if ex.robot.motor_specs[sat.motors[i]].current_curve.form == "linear":  # a fit without saturation
            assert "use" not in f and gap["over"] == pytest.approx(0.0, abs=1e-9)
            assert ours == pytest.approx(isaac, abs=1e-9)  # within overspeed DCMotor is exact
            continue
        # the spec sheet's curve saturates: DCMotor's straight line differs from the curved edges by at most the
        # stated dcmotor_error, and the joint points to the runtime
        assert f["use"] == "hound_id.runtime" and "curve" in f["reason"]
        assert np.max(isaac - ours) <= gap["over"] * (1 + 1e-6) + 1e-9
        assert np.max(ours - isaac) <= max(gap["over"], gap["under"]) * (1 + 1e-6) + 1e-9
        assert gap["over"] > 0.05 * d["effort_limit"]  # about 0.94 N m at the motor, 8.4 N m at the joint
        assert d["armature"] == pytest.approx(1.7e-4 * 81) and d["friction"] == pytest.approx(0.72 if fitted else 0.0)
        assert set(d) == {"saturation_effort", "effort_limit", "velocity_limit", "armature", "friction",
                          "dynamic_friction", "viscous_friction"}  # fmt: skip
        assert set(new) == {"saturation_effort", "actuator_effort_limit", "actuator_velocity_limit", "armature",
                            "friction", "dynamic_friction", "viscous_friction"}  # fmt: skip
    assert sum(not f["coupled"] for f in fields["joints"].values()) == 4
    # coupled joints still get their reflected inertia (diagonal of A^-T diag(J) A^-1) and friction
    hfe = fields["joints"]["FL_HFE"]
    assert hfe["armature"] == pytest.approx(ex.bundle.reflected_inertia[1][1]) and (hfe["friction"] > 0) == fitted
    # ... and the off-diagonal term Isaac Lab cannot hold is written, with its size
    group = hfe["reflected_inertia_group"]
    M = np.asarray(ex.bundle.reflected_inertia)[np.ix_([1, 2], [1, 2])]
    assert group["joints"] == ["FL_HFE", "FL_KFE"] and np.allclose(group["matrix"], M)
    assert group["dropped_off_diagonal"] == pytest.approx(1.275e-3)
    assert group["dropped_relative"] == pytest.approx(1.275e-3 / np.sqrt(M[0, 0] * M[1, 1]))
    # the kinetic-energy error, by brute force over joint-velocity directions
    a = np.linspace(0, np.pi, 20001)
    q = np.stack([np.cos(a), np.sin(a)])
    err = np.abs(np.einsum("in,ij,jn->n", q, np.diag(np.diag(M)) - M, q) / np.einsum("in,ij,jn->n", q, M, q))
    assert group["kinetic_energy_error"] == pytest.approx(err.max(), rel=1e-6)


def test_formats_that_need_the_urdf_say_so(tmp_path, write_yaml):
    text = ROBOT.read_text().replace("urdf: hound_like.urdf\n", "")
    robot = write_yaml("r.yaml", text.replace("../motors/", str(ROBOT.parent.parent / "motors") + "/"))
    ex = prepare(robot)
    with pytest.raises(SpecError, match="needs the robot's URDF; add 'urdf: my_robot.urdf'"):
        write_export(ex, ["bundle", "mujoco"], tmp_path / "out")
    assert not (tmp_path / "out").exists()
    with pytest.raises(SpecError, match="--format: found 'mjcf'"):
        formats_from("mjcf")


def test_a_failing_format_leaves_the_output_folder_as_it_was(exported, tmp_path):
    """All formats or none: a URDF that lacks a joint stops the export before anything moves in."""
    ex, _, out = exported
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    broken = tmp_path / "broken.urdf"
    broken.write_text(Path(ex.robot.urdf).read_text().replace('"RR_KFE"', '"RR_knee"'))
    from dataclasses import replace

    with pytest.raises(SpecError, match="RR_KFE"):
        write_export(replace(ex, robot=replace(ex.robot, urdf=str(broken))), formats_from("all"), out)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert [p.name for p in out.parent.iterdir() if p.name.startswith(".")] == []  # no staging folder left
    with pytest.raises(SpecError):
        write_export(replace(ex, robot=replace(ex.robot, urdf=str(broken))), ["bundle", "urdf"], tmp_path / "new")
    assert not (tmp_path / "new").exists()


def test_the_voltage_input_of_a_curved_motor_is_within_its_straight_line_gap(tmp_path):
    """The sample sheet's quadratic and its winding's reactance bend the region's edges; MuJoCo's dcmotor lines are
    straight. With the runtime's voltage the realised torques equal the runtime's where the voltage is inside the bus,
    and differ by at most the straight-line gap the export states, over random states across +-overspeed."""
    import mujoco

    from hound_id.mor.region import operating_region
    from hound_id.mor.region_report import straight_gap

    ex = prepare(ROBOT, [])
    write_export(ex, formats_from("bundle,mujoco"), tmp_path)
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "hound_like.xml"))
    data = mujoco.MjData(model)
    sat = hound_id.runtime.load(tmp_path / "hound_like_bundle.yaml")
    region = operating_region(ex.robot.motor_specs["FL_HAA_motor"])
    gap = straight_gap(region)
    aid = _ids(model, mujoco.mjtObj.mjOBJ_ACTUATOR, sat.motors)
    vadr = model.jnt_dofadr[_ids(model, mujoco.mjtObj.mjOBJ_JOINT, sat.joints)]
    rng = np.random.default_rng(7)
    worst_inside, worst = 0.0, 0.0
    for _ in range(300):
        omega = rng.uniform(-1, 1, 12) * region.overspeed * 0.999
        qd = omega @ sat.clip.A.T  # joint speeds giving these motor speeds
        tau = rng.uniform(-1, 1, 12) * 150.0
        data.qvel[vadr] = qd
        data.ctrl[aid] = v = sat.voltage(tau[None], qd[None])[0]
        mujoco.mj_forward(model, data)
        diff = np.abs(data.actuator_force[aid] - sat.motor_torque(sat.saturate(tau[None], qd[None]))[0])
        inside = np.abs(v) < 0.999 * sat.bus_voltage  # the bus clamp does not bind
        worst_inside = max(worst_inside, float(np.max(diff[inside], initial=0.0)))
        worst = max(worst, float(np.max(diff)))
    assert worst_inside < 1e-9
    # within the drive's overspeed the sample's region lies inside the straight voltage band (its reactance and its
    # curve only take torque away), so the bus never clamps the runtime's voltage there: MuJoCo applies it exactly
    assert worst <= max(gap) + 1e-9


@pytest.mark.parametrize("fits", ["linear_fit", "sheet_curve"])
def test_mujoco_to_twice_the_no_load_speed_within_the_stated_braking(tmp_path, fits):
    """Motor speeds drawn to twice the no-load speed: MuJoCo's voltage-input dcmotor realises the runtime's torques
    wherever the bus does not clamp, and elsewhere differs by no more than the export's notes state (the straight
    line's gap, the braking past overspeed it holds at the torque limit), and by that much."""
    import mujoco

    from hound_id.export.target import TRAINER_REACH
    from hound_id.mor.region import operating_region

    ex = prepare(ROBOT, [fitted_motor(tmp_path)] if fits == "linear_fit" else [])
    report = write_export(ex, formats_from("bundle,mujoco"), tmp_path / "out")
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "out" / "hound_like.xml"))
    data = mujoco.MjData(model)
    sat = hound_id.runtime.load(tmp_path / "out" / "hound_like_bundle.yaml")
    motor = ex.bundle.motors[0].name
    past = ex.past_overspeed(motor)[0]
    stated = max(ex.straight_gap(motor)[0], past)
    assert any(f"up to {past:.4g} N m more than dcmotor" in n for n in report["formats"]["mujoco"]["notes"])
    reach = TRAINER_REACH * operating_region(ex.robot.motor_specs[motor]).no_load_speed
    aid = _ids(model, mujoco.mjtObj.mjOBJ_ACTUATOR, sat.motors)
    vadr = model.jnt_dofadr[_ids(model, mujoco.mjtObj.mjOBJ_JOINT, sat.joints)]
    rng = np.random.default_rng(11)
    worst = 0.0
    for _ in range(400):
        omega = rng.uniform(-1, 1, 12) * reach
        qd = omega @ sat.clip.A.T
        tau = rng.uniform(-1, 1, 12) * 150.0
        data.qvel[vadr] = qd
        data.ctrl[aid] = sat.voltage(tau[None], qd[None])[0]
        mujoco.mj_forward(model, data)
        diff = np.abs(data.actuator_force[aid] - sat.motor_torque(sat.saturate(tau[None], qd[None]))[0])
        worst = max(worst, float(np.max(diff)))
    assert 0.95 * past < worst <= stated + 1e-9 * max(1.0, stated)


def test_the_open_urdf_never_fights_the_runtime_and_the_armature_is_a_sidecar(tmp_path):
    """For simulators that enforce URDF effort limits (Genesis): the open limits hold every torque the runtime returns
    for motor speeds up to twice the overspeed, huge commands included; Pinocchio loads the file; the armature sidecar
    is the bundle's reflected inertia."""
    import xml.etree.ElementTree as ET

    import pinocchio
    import yaml

    from hound_id.export.urdf import OPEN_REACH
    from hound_id.mor.region import operating_region

    ex = prepare(ROBOT, [])
    report = write_export(ex, formats_from("bundle,urdf-open"), tmp_path)
    assert any("open" in n for n in report["formats"]["urdf-open"]["notes"])
    urdf = tmp_path / "hound_like_open_limits.urdf"
    assert "never fight hound_id.runtime" in urdf.read_text()
    pinocchio.buildModelFromUrdf(str(urdf))
    limits = {j.get("name"): j.find("limit") for j in ET.parse(urdf).getroot().iter("joint")}
    sat = hound_id.runtime.load(tmp_path / "hound_like_bundle.yaml")
    effort = np.array([float(limits[j].get("effort")) for j in sat.joints])
    velocity = np.array([float(limits[j].get("velocity")) for j in sat.joints])
    overspeed = np.array([operating_region(ex.robot.motor_specs[m]).overspeed for m in sat.motors])
    rng = np.random.default_rng(11)
    omega = rng.uniform(-1, 1, (20000, 12)) * overspeed * OPEN_REACH
    qd = omega @ sat.clip.A.T
    tau = rng.choice([-1e6, 1e6], (20000, 12)) * rng.uniform(0, 1, (20000, 12))
    out = sat.saturate(tau, qd)
    assert np.all(np.abs(out) <= effort * (1 + 1e-9)) and np.all(np.abs(qd) <= velocity * (1 + 1e-9))
    assert np.max(np.abs(out), axis=0) == pytest.approx(effort, rel=0.05)  # and not much wider than needed
    side = yaml.safe_load((tmp_path / "hound_like_armature.yaml").read_text())
    M = np.asarray(ex.bundle.reflected_inertia)
    assert side["schema"] == "hound-id/armature/1" and side["armature"]["FL_KFE"] == pytest.approx(M[2, 2])
    assert [g["joints"] for g in side["groups"]][0] == ["FL_HFE", "FL_KFE"]
    assert side["groups"][0]["dropped_off_diagonal"] == pytest.approx(1.275e-3)


def test_isaaclab_friction_split_static_kinetic_viscous_and_mjlab_names_what_it_drops(tmp_path):
    """A fit with Stribeck friction: Isaac Lab's static friction is G (f_c + f_s), its dynamic friction G f_c, its
    viscous friction G^2 b (joint side, HAA gear 9); mjlab, which has Coulomb frictionloss only, says what it drops."""
    import yaml

    text = fitted_motor(tmp_path).read_text()
    text = text.replace("model: [linear, coulomb, viscous]", "model: [linear, coulomb, viscous, stribeck]")
    text = text.replace(
        "  compensation:",
        "    stribeck: {value: 0.03, stderr: 1.0e-4, unit: N m}\n"
        "    stribeck_speed: {value: 0.5, stderr: 1.0e-3, unit: rad/s}\n  compensation:",
    )
    (tmp_path / "stribeck.yaml").write_text(text)
    ex = prepare(ROBOT, [tmp_path / "stribeck.yaml"])
    write_export(ex, formats_from("isaaclab,mjlab"), tmp_path / "out")
    haa = yaml.safe_load((tmp_path / "out" / "hound_like_isaaclab.yaml").read_text())["joints"]["FL_HAA"]
    assert haa["dcmotor"]["friction"] == pytest.approx(9 * (0.08 + 0.03))
    assert haa["dcmotor"]["dynamic_friction"] == pytest.approx(9 * 0.08)
    assert haa["dcmotor"]["viscous_friction"] == pytest.approx(81 * 2.0e-4)
    module = (tmp_path / "out" / "hound_like_mjlab.py").read_text()
    assert "static (Stribeck) friction (stribeck): up to 0.03 N m at the motor" in module


def test_a_rated_speed_is_named_as_a_cause_of_the_straight_line_gap(tmp_path):
    """HAA on the small motor (max_speed 2000 rpm): the straight-line gap is mostly the rated-speed cut-off, and the
    Isaac Lab reason and mjlab's NOT_HELD say so, besides the curve (the review found the curve blamed for all)."""
    import yaml

    from tests.conftest import SAMPLES, SMALL_MOTOR

    text = (SAMPLES / "robots" / "hound_like.yaml").read_text()
    text = text.replace("  ilm85: ../motors/hound_ilm85.yaml", f"  ilm85: {MOTOR}\n  qdd: {SMALL_MOTOR}")
    text = text.replace("motor_spec: ilm85, ratios: [9.0]", "motor_spec: qdd, ratios: [9.0]")
    text = text.replace("urdf: hound_like.urdf", f"urdf: {SAMPLES / 'robots' / 'hound_like.urdf'}")
    (tmp_path / "mixed.yaml").write_text(text)
    write_export(prepare(tmp_path / "mixed.yaml", []), formats_from("isaaclab,mjlab"), tmp_path / "out")
    haa = yaml.safe_load((tmp_path / "out" / "hound_like_isaaclab.yaml").read_text())["joints"]["FL_HAA"]
    assert "rated speed cuts them" in haa["reason"] and "current-torque curve" in haa["reason"]
    module = (tmp_path / "out" / "hound_like_mjlab.py").read_text()
    assert "a rated-speed cut-off, braking only above max_speed (motors FL_HAA_motor" in module


def test_a_robot_file_covering_part_of_the_urdf_says_what_the_other_joints_get(tmp_path):
    """One leg of the sample URDF in the robot file: the URDF-based formats say the other nine joints keep the URDF's
    limits and get nothing from hound-id; the bundle, which does not use the URDF, says nothing (the review's case)."""
    from tests.conftest import SAMPLES

    text = (SAMPLES / "robots" / "hound_like.yaml").read_text()
    text = text.replace("../motors/hound_ilm85.yaml", str(MOTOR))
    text = text.replace("urdf: hound_like.urdf", f"urdf: {SAMPLES / 'robots' / 'hound_like.urdf'}")
    keep = [line for line in text.splitlines() if not any(f"[{leg}_" in line for leg in ("FR", "RL", "RR"))]
    text = "\n".join(keep).replace(
        "joints: [FL_HAA, FL_HFE, FL_KFE, FR_HAA, FR_HFE, FR_KFE, RL_HAA, RL_HFE, RL_KFE, RR_HAA, RR_HFE, RR_KFE]",
        "joints: [FL_HAA, FL_HFE, FL_KFE]",
    )
    (tmp_path / "oneleg.yaml").write_text(text)
    report = write_export(prepare(tmp_path / "oneleg.yaml", []), formats_from("bundle,mjlab,urdf"), tmp_path / "out")
    for name in ("mjlab", "urdf"):
        notes = " ".join(report["formats"][name]["notes"])
        assert "the URDF's joints FR_HAA, FR_HFE, FR_KFE, RL_HAA" in notes and "keep the URDF's own limits" in notes
    assert not any("URDF's joints" in n for n in report["formats"]["bundle"]["notes"])
    assert report["joints"] == ["FL_HAA", "FL_HFE", "FL_KFE"]


def test_the_exports_state_the_braking_past_overspeed_they_cannot_hold(tmp_path):
    """Past overspeed the runtime brakes harder than a straight-line actuator's torque limit (the diode bridge's
    braking, with the sample's reactance): the MuJoCo and mjlab notes state by how much, to twice the no-load speed,
    as a scan of the region's interval finds it."""
    from hound_id.export.mjlab import not_held
    from hound_id.mor.region import operating_region, torque_interval

    ex = prepare(ROBOT, [])
    region = operating_region(ex.robot.motor_specs["FL_HAA_motor"])
    w = np.linspace(region.overspeed, 2.0 * region.no_load_speed, 20001)
    most = float(np.max(np.abs(torque_interval(w, region)[1]))) - region.torque_limit
    assert most == pytest.approx(5.32, abs=0.01)  # 13.74 N m of diode braking against the 8.416 N m limit
    stated = f"up to {most:.4g} N m more than"
    assert stated in not_held(ex, "voltage", "newton")[-1]
    report = write_export(ex, formats_from("bundle,mujoco"), tmp_path / "out")
    assert any(f"up to {most:.4g} N m more than dcmotor" in n for n in report["formats"]["mujoco"]["notes"])


#: A toy export format in one module, as ARCHITECTURE.md's recipe has it: a function taking ``Export`` and the
#: folder, returning ``Written``: its file's text and the friction it cannot hold.
TOY_FORMAT = """
from hound_id import io
from hound_id.export.target import Export, Written


def toy_files(ex: Export, out):
    table = {"joints": list(ex.bundle.joints), "torque_limit": [m.torque_limit for m in ex.bundle.motors]}
    return Written({f"{ex.stem}_toy.json": io.json_text(table)}, ex.friction_not_held("toy"))
"""


def test_a_new_format_is_one_module_and_one_registry_line(tmp_path, monkeypatch):
    """The toy format's module plus its line in FORMATS: --format toy and all write it, atomically with the others,
    and it states the fitted friction it has no home for."""
    import importlib.util
    import json

    from hound_id.export.formats import FORMATS

    (tmp_path / "toy_format.py").write_text(TOY_FORMAT)
    spec = importlib.util.spec_from_file_location("toy_format", tmp_path / "toy_format.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    monkeypatch.setitem(FORMATS, "toy", module.toy_files)  # the one registry line
    ex = prepare(ROBOT, [fitted_motor(tmp_path)])
    report = write_export(ex, formats_from("bundle,toy"), tmp_path / "out")
    written = json.loads((tmp_path / "out" / "hound_like_toy.json").read_text())
    assert written["joints"] == list(ex.bundle.joints)
    notes = report["formats"]["toy"]["notes"]
    assert [n.split(" (")[0] for n in notes] == ["Coulomb friction", "viscous friction"]  # the fit's 0.08 N m, 2e-4
    assert notes[0].startswith("Coulomb friction (coulomb): up to 0.08 N m at the motor")
    assert "toy" in formats_from("all")
