"""An Isaac Lab actuator that clips with hound-id's operating regions: :class:`HoundIdActuator`.

It is Isaac Lab's ``IdealPDActuator`` (the PD law k_p (q* - q) + k_d (qd* - qd) + tau_ff) whose clip is
``hound_id.runtime``'s saturation of the whole group instead of a per-joint one: the coupled motor-space limits, the
curved edges of a saturating current-torque curve and the back-EMF braking past overspeed, as in the bundle. Import it
where Isaac Lab is installed (it imports ``isaaclab``)::

    import yaml
    from hound_id.export.isaaclab_actuator import HoundIdActuatorCfg

    joints = yaml.safe_load(open("out/hound_like_isaaclab.yaml"))["joints"]   # per joint, joint side
    actuators = {
        "legs": HoundIdActuatorCfg(
            joint_names_expr=[".*_HAA", ".*_HFE", ".*_KFE"],    # every joint of the bundle, in any order
            bundle="out/hound_like_bundle.json",
            stiffness=40.0, damping=1.0,
            armature={name: j["armature"] for name, j in joints.items()},
            friction={name: j["friction"] for name, j in joints.items()},
            viscous_friction={name: j["viscous_friction"] for name, j in joints.items()},
        )
    }

(``docs/export.md`` carries the same snippet, run as printed in Isaac Lab by ``tests/export/test_doc_snippets.py``.)

The group must hold every joint of the bundle: the clip couples joints through the motors, so one group holds all
of them (the runtime is told the group's joint order, which Isaac Lab sets breadth-first).
"""

from __future__ import annotations

from dataclasses import MISSING
from typing import Any

from isaaclab.actuators import IdealPDActuator, IdealPDActuatorCfg  # type: ignore[import-not-found]
from isaaclab.utils import configclass  # type: ignore[import-not-found]

import hound_id.runtime


class HoundIdActuator(IdealPDActuator):  # type: ignore[misc]
    """``IdealPDActuator`` with hound-id's clip (see the module docstring)."""

    cfg: HoundIdActuatorCfg

    def __init__(self, cfg: HoundIdActuatorCfg, *args: Any, **kwargs: Any) -> None:
        super().__init__(cfg, *args, **kwargs)
        self.saturation = hound_id.runtime.load(cfg.bundle, joint_names=list(self.joint_names))
        self._joint_vel = None

    def compute(self, control_action: Any, joint_pos: Any, joint_vel: Any) -> Any:
        self._joint_vel = joint_vel  # the clip's speed, as DCMotor keeps it
        return super().compute(control_action, joint_pos, joint_vel)

    def _clip_effort(self, effort: Any) -> Any:
        return self.saturation.saturate(effort, self._joint_vel)


@configclass  # type: ignore[misc]
class HoundIdActuatorCfg(IdealPDActuatorCfg):  # type: ignore[misc]
    """Configuration of :class:`HoundIdActuator`: IdealPDActuatorCfg's fields and the bundle."""

    class_type: type = HoundIdActuator

    bundle: str = MISSING  # type: ignore[assignment]  # Isaac Lab's configclass marks a required field so
    """Path of the ``hound-id export --format bundle`` file (``<robot>_bundle.json`` or ``.yaml``)."""
