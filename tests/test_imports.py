import subprocess
import sys

HEAVY = ("torch", "pinocchio", "mujoco", "casadi", "trimesh", "manifold3d", "matplotlib")


def test_core_modules_do_not_import_heavy_libraries():
    code = (
        "import sys, hound_id, hound_id.mor.spec, hound_id.mor.region, hound_id.mor.transmission, "
        "hound_id.mor.robot, hound_id.mor.joint_space, hound_id.mor.saturation, hound_id.dyno, hound_id.cli, "
        "hound_id.foot.leg, hound_id.dyno.acquire.rig, hound_id.dyno.acquire.transport, "
        "hound_id.dyno.acquire.recorder; "
        f"print(' '.join(m for m in {HEAVY!r} if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == ""
