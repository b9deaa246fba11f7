"""Transmissions: the velocity map from motor space to joint space.

A transmission is the matrix A with ``qd_joint = A thetad_motor``. Power balance,
tau_joint . qd_joint = tau_motor . thetad_motor for every velocity, fixes the
torque map:

    tau_motor = A^T tau_joint,        tau_joint = A^-T tau_motor.

The paper (eq. "GearboxMatrix2") prints tau_motor = A^-T tau_joint, which does not
conserve power whenever A is not orthogonal; hound-id implements the
power-consistent form above (tests check the balance for random A).

Arrays are batched along leading axes: a (..., k) joint vector maps to a (..., k)
motor vector, so the maps are written as right-multiplications (``x @ M``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hound_id.arrays import frozen
from hound_id.errors import TransmissionError

#: Matrices with a condition number above this are treated as singular.
MAX_CONDITION = 1e10
#: Largest reduction (motor turns per joint turn) and largest speed-up (joint turns per motor
#: turn) of any real gearbox, with margin: a worm drive reaches a few thousand, a step-up a few.
MAX_REDUCTION, MAX_STEP_UP = 1e4, 100.0


@dataclass(frozen=True)
class Transmission:
    """Gearbox coupling of a group of joints to the motors that drive them."""

    kind: str
    """How it was given: ``ratio``, ``matrix`` or ``hollow_shaft``."""
    joints: tuple[str, ...]
    """Joint names, the rows of A."""
    motors: tuple[str, ...]
    """Motor names, the columns of A; motor k is the one listed with joint k."""
    A: NDArray[np.float64]
    """Velocity map qd_joint = A thetad_motor [rad/s per rad/s], shape (k, k)."""
    A_inv: NDArray[np.float64]
    """Inverse velocity map thetad_motor = A^-1 qd_joint."""

    @property
    def coupled(self) -> bool:
        """True when A is not diagonal (a motor moves or loads more than one joint)."""
        return bool(np.any(self.A[~np.eye(len(self.joints), dtype=bool)] != 0.0))

    def motor_velocity(self, qd_joint: ArrayLike) -> NDArray[np.float64]:
        """thetad_motor = A^-1 qd_joint [rad/s], batched over leading axes."""
        return np.asarray(qd_joint, float) @ self.A_inv.T

    def joint_velocity(self, thetad_motor: ArrayLike) -> NDArray[np.float64]:
        """qd_joint = A thetad_motor [rad/s]."""
        return np.asarray(thetad_motor, float) @ self.A.T

    def motor_torque(self, tau_joint: ArrayLike) -> NDArray[np.float64]:
        """tau_motor = A^T tau_joint [N m] (power-consistent, not the paper's A^-T)."""
        return np.asarray(tau_joint, float) @ self.A

    def joint_torque(self, tau_motor: ArrayLike) -> NDArray[np.float64]:
        """tau_joint = A^-T tau_motor [N m]."""
        return np.asarray(tau_motor, float) @ self.A_inv

    def reflected_inertia(self, rotor_inertia: ArrayLike) -> NDArray[np.float64]:
        """Rotor inertias [kg m^2] seen in joint space: A^-T diag(J) A^-1, shape (k, k)."""
        J = np.diag(np.asarray(rotor_inertia, float))
        return self.A_inv.T @ J @ self.A_inv


def _names(joints: Sequence[str], motors: Sequence[str], k: int, what: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    if len(joints) != k or len(motors) != k:
        raise TransmissionError(
            f"{what}: found {len(joints)} joints and {len(motors)} motors for a {k}x{k} map; "
            "a transmission needs one motor per joint",
            joints=list(joints),
            motors=list(motors),
        )
    return tuple(joints), tuple(motors)


def from_matrix(
    joints: Sequence[str], motors: Sequence[str], matrix: ArrayLike, *, kind: str = "matrix", what: str = "transmission"
) -> Transmission:
    """A transmission from an explicit velocity map A (qd_joint = A thetad_motor).

    Raises:
        TransmissionError: A is not square, not finite, or singular.
    """
    try:
        A = np.array(matrix, dtype=float)
    except (TypeError, ValueError) as err:
        raise TransmissionError(f"{what}: matrix {matrix!r} is not numeric; expected a list of rows") from err
    if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] == 0:
        raise TransmissionError(
            f"{what}: matrix has shape {A.shape}, expected a square k x k list of rows", shape=A.shape
        )
    if not np.all(np.isfinite(A)):
        raise TransmissionError(f"{what}: matrix has non-finite entries {A.tolist()}")
    j, m = _names(joints, motors, A.shape[0], what)
    cond = float(np.linalg.cond(A))
    if not np.isfinite(cond) or cond > MAX_CONDITION:
        raise TransmissionError(
            f"{what}: matrix {A.tolist()} is singular (condition number {cond:.3g}); "
            "every motor must drive an independent combination of joints",
            condition=cond,
        )
    A_inv = np.linalg.inv(A)
    if np.abs(A).max() > MAX_STEP_UP or np.abs(A_inv).max() > MAX_REDUCTION:
        raise TransmissionError(
            f"{what}: matrix {A.tolist()} turns a joint up to {np.abs(A).max():.3g} times per motor turn and a motor "
            f"up to {np.abs(A_inv).max():.3g} times per joint turn; expected reductions up to {MAX_REDUCTION:g} and "
            f"speed-ups up to {MAX_STEP_UP:g} (real gearboxes): check the ratios (motor turns per joint turn)",
            condition=cond,
        )
    return Transmission(kind=kind, joints=j, motors=m, A=frozen(A), A_inv=frozen(A_inv))


def from_ratios(
    joints: Sequence[str], motors: Sequence[str], ratios: Sequence[float], *, what: str = "transmission"
) -> Transmission:
    """Independent gearboxes: joint k turns 1/G_k as fast as motor k (negative G reverses it)."""
    g = np.asarray(ratios, dtype=float)
    if g.ndim != 1 or not np.all(np.isfinite(g)) or np.any(g == 0.0):
        raise TransmissionError(
            f"{what}: ratios {list(ratios)!r} must be finite and non-zero (reduction G, motor turns per joint turn)"
        )
    return from_matrix(joints, motors, np.diag(1.0 / g), kind="ratio", what=what)


def hollow_shaft(
    joints: Sequence[str], motors: Sequence[str], hip_ratio: float, knee_ratio: float, *, what: str = "transmission"
) -> Transmission:
    """The paper's coaxial hip/knee module (HFE hollow shaft carrying the KFE gearbox ring).

    A = [[1/G_h, 0], [-1/(G_h G_k), 1/G_k]], so thetad_motor = [[G_h, 0], [1, G_k]] qd:
    the knee motor also turns with the hip.
    """
    gh, gk = float(hip_ratio), float(knee_ratio)
    if not (np.isfinite(gh) and np.isfinite(gk)) or gh == 0.0 or gk == 0.0:
        raise TransmissionError(
            f"{what}: hip_ratio {hip_ratio!r} and knee_ratio {knee_ratio!r} must be finite and non-zero"
        )
    A = [[1.0 / gh, 0.0], [-1.0 / (gh * gk), 1.0 / gk]]
    return from_matrix(joints, motors, A, kind="hollow_shaft", what=what)
