"""Isaac Lab 2.3.2's actuator modules without Isaac Sim, for the scripts that run in the Isaac Lab virtual environment
(tests/export/test_trainers.py, tests/export/test_doc_snippets.py).

The pip wheel of Isaac Lab 2.3.2 holds its source; its ``isaaclab.actuators`` package __init__ imports the actuator
network's asset reader, which needs Isaac Sim's Omniverse client. The actuator modules themselves need torch and
isaaclab.utils only, so they are imported here as the package's submodules without running that __init__, and the
package is given the names ``hound_id.export.isaaclab_actuator`` imports from it. Nothing of Isaac Lab is replaced."""

import sys
import types
from pathlib import Path

import isaaclab

package = types.ModuleType("isaaclab.actuators")
package.__path__ = [str(Path(isaaclab.__path__[0]) / "actuators")]
sys.modules["isaaclab.actuators"] = package
from isaaclab.actuators import actuator_base_cfg, actuator_pd, actuator_pd_cfg  # noqa: E402

package.IdealPDActuator, package.IdealPDActuatorCfg = actuator_pd.IdealPDActuator, actuator_pd_cfg.IdealPDActuatorCfg
package.ActuatorBaseCfg = actuator_base_cfg.ActuatorBaseCfg

__all__ = ["actuator_base_cfg", "actuator_pd", "actuator_pd_cfg"]
