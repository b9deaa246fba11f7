"""The leg as Pinocchio sees it: masses and pitch inertias about the knee and the hip.

The URDF is loaded with Pinocchio. In the joint-space mass matrix M(q) (composite rigid
body algorithm), the diagonal entry of a revolute joint is the inertia of everything
below that joint about its axis, at configuration q. So:

* knee pitch inertia = M[KFE, KFE]: calf + foot about the knee axis (independent of q for a
  planar leg);
* hip inertia = M[HFE, HFE] at the nominal pose: thigh + calf + foot about the hip axis;
* calf + foot mass = the subtree mass below the knee (``computeSubtreeMasses``);
* calf + foot pitch inertia about its own centre of mass = the knee pitch inertia minus
  m d^2, d the distance of the subtree's centre of mass from the knee axis (parallel axes).

The reflected inertia of the knee motor's rotor is J_rotor G^2 for a single-stage knee
(physics notes); with a coupled transmission see
:meth:`hound_id.mor.transmission.Transmission.reflected_inertia`.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hound_id.errors import SpecError
from hound_id.foot.urdf import parse_urdf


@dataclass(frozen=True)
class LegProperties:
    """Mass properties of a leg at a configuration, SI."""

    calf_foot_mass: float
    """Mass of everything below the knee joint [kg]."""
    knee_pitch_inertia: float
    """Inertia of everything below the knee about the knee axis [kg m^2]."""
    hip_pitch_inertia: float
    """Inertia of everything below the hip about the hip axis, at the configuration [kg m^2]."""
    com_pitch_inertia: float
    """Inertia of everything below the knee about the pitch axis through its own centre of mass [kg m^2]."""
    com_distance: float
    """Distance of the centre of mass of everything below the knee from the knee axis [m]."""
    reflected_knee_inertia: float | None
    """Knee rotor inertia seen at the knee, J_rotor G^2 [kg m^2], if rotor inertia and ratio are given."""
    knee_angle: float
    """Knee angle of the configuration [rad]."""

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def load_leg(path: str | Path) -> Any:
    """The Pinocchio model of a leg URDF (raises SpecError with the parser's complaint)."""
    import pinocchio as pin

    p = Path(path)
    parse_urdf(p)  # a regular file of bounded size, UTF-8, its inertials those of rigid bodies
    with native_stderr() as said:  # urdfdom prints its complaints on the process's stderr
        try:
            return pin.buildModelFromUrdf(str(p))
        except (RuntimeError, ValueError) as err:
            first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
            raise SpecError(
                f"{p}: Pinocchio cannot load the URDF ({first}{'; ' + said() if said() else ''})", path=str(p)
            ) from err


@contextmanager
def native_stderr() -> Iterator[Callable[[], str]]:
    """Catch what native code writes on file descriptor 2 while the block runs (urdfdom's "Error: ..." lines), so
    that a failure stays one line; yields a function that gives the first line caught (read after the block's
    error)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as caught:
        os.dup2(caught.fileno(), 2)
        restored = False

        def first_line() -> str:
            nonlocal restored
            if not restored:
                os.dup2(saved, 2)
                restored = True
            caught.seek(0)
            lines = [line.strip() for line in caught.read(4096).decode("utf-8", "replace").splitlines() if line.strip()]
            return lines[0] if lines else ""

        try:
            yield first_line
        finally:
            if not restored:
                os.dup2(saved, 2)
            os.close(saved)


def leg_properties(
    model: Any,
    *,
    hip_joint: str = "HFE",
    knee_joint: str = "KFE",
    knee_angle: float = -1.2,
    rotor_inertia: float | None = None,
    knee_ratio: float | None = None,
) -> LegProperties:
    """Mass properties of a leg model at hip angle 0 and the given knee angle [rad].

    Args:
        model: A Pinocchio model (see :func:`load_leg`).
        hip_joint: Name of the hip pitch joint.
        knee_joint: Name of the knee pitch joint.
        knee_angle: Knee angle of the nominal pose [rad].
        rotor_inertia: Knee motor rotor inertia [kg m^2], for the reflected inertia.
        knee_ratio: Knee gear ratio G (motor turns per joint turn).
    """
    import numpy as np
    import pinocchio as pin

    ids = {}
    for name in (hip_joint, knee_joint):
        if not model.existJointName(name):
            names = [n for n in model.names if n != "universe"]
            raise SpecError(f"leg model: no joint named '{name}'; joints are {', '.join(names)}", joint=name)
        ids[name] = model.getJointId(name)
    data = model.createData()
    q = pin.neutral(model)
    knee = model.joints[ids[knee_joint]]
    q[knee.idx_q] = knee_angle
    M = pin.crba(model, data, q)
    M = np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle
    pin.computeSubtreeMasses(model, data)
    pin.forwardKinematics(model, data, q)
    kid = ids[knee_joint]
    # the subtree's centre of mass, world frame, from each body's (fixed links are merged into their joint's)
    below = list(model.subtrees[kid])
    com = sum(model.inertias[j].mass * data.oMi[j].act(model.inertias[j].lever) for j in below) / data.mass[kid]
    offset = np.asarray(com) - np.asarray(data.oMi[kid].translation)
    d2 = float(offset[0] ** 2 + offset[2] ** 2)  # pitch axis y: the distance in the x-z plane
    reflected = None
    if rotor_inertia is not None and knee_ratio is not None:
        reflected = float(rotor_inertia * knee_ratio**2)
    return LegProperties(
        calf_foot_mass=float(data.mass[ids[knee_joint]]),
        knee_pitch_inertia=float(M[knee.idx_v, knee.idx_v]),
        hip_pitch_inertia=float(M[model.joints[ids[hip_joint]].idx_v, model.joints[ids[hip_joint]].idx_v]),
        com_pitch_inertia=float(M[knee.idx_v, knee.idx_v]) - float(data.mass[kid]) * d2,
        com_distance=math.sqrt(d2),
        reflected_knee_inertia=reflected,
        knee_angle=float(knee_angle),
    )
