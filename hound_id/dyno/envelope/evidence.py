"""Logged channels that settle what the envelope alone cannot: the bus voltage (a sagging pack) and the current
(a saturating core)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.logs import EnvelopeLog
from hound_id.mor.envelope import EnvelopeInputs

Array = NDArray[np.float64]

#: A fitted pack resistance this many standard errors (and CONTRADICT_SHARE of itself) above the one the logged bus
#: voltage shows is contradicted by it. Calibrated on test_compare::test_a_wrong_add_does_not_hide_the_right_effect.
EVIDENCE_SIGMAS = 5.0
CONTRADICT_SHARE = 1.0 / 3.0
#: A logged channel shows an effect when its slope is this many standard errors above zero (5 sigma). Calibrated on
#: test_compare::test_the_hidden_effect_is_named_and_explains_the_envelope.
SHOWN_SIGMAS = 5.0
#: The bus evidence uses the motoring samples above MOTORING_SHARE of the peak power (the bus sags measurably there),
#: needs MIN_MOTORING of them, and a pack resistance above MIN_R_PACK [ohm] (a milliohm: below any real pack's) to show
#: a sag. Calibrated on test_compare::test_the_hidden_effect_is_named_and_explains_the_envelope.
MOTORING_SHARE = 0.05
MIN_MOTORING = 20
MIN_R_PACK = 1e-3
#: The bus voltage is floored at this share of the nominal one when dividing by it (a logged zero).
BUS_FLOOR = 1e-3


@dataclass(frozen=True)
class Evidence:
    """What a logged channel shows about one effect: a slope with its standard error."""

    value: float
    """The slope: the pack resistance [ohm] (bus voltage), or the current's excess over tau/Kt per (N m)^3 [A/Kt]."""
    se: float
    """Its standard error [same unit]."""
    significant: bool
    """Whether the channel shows the effect (:data:`SHOWN_SIGMAS` standard errors above zero)."""
    text: str
    """The evidence in one clause, for a suggestion's reason."""


def contradicts(value: float, evidence: Evidence) -> bool:
    """Whether a fitted pack resistance is ruled out by the logged bus voltage's own: more than
    :data:`EVIDENCE_SIGMAS` standard errors and :data:`CONTRADICT_SHARE` of the fitted value above it."""
    return bool(value - evidence.value > max(EVIDENCE_SIGMAS * evidence.se, CONTRADICT_SHARE * value))


def current_evidence(log: EnvelopeLog, inputs: EnvelopeInputs) -> Evidence | None:
    """Whether the logged current grows faster than tau / Kt at high torque (a saturating core): the slope of
    Kt i - tau against tau^3, with its standard error; None without a current channel."""
    if log.current is None:
        return None
    x = log.torque**3
    slope, se = _leading(np.column_stack([x, log.torque, np.ones_like(x)]), inputs.spec.kt * log.current - log.torque)
    significant = slope > SHOWN_SIGMAS * se
    text = f"the logged current exceeds tau/Kt by {slope:.3g} +- {se:.2g} A/Kt per (N m)^3"
    return Evidence(slope, se, bool(significant), text + ("" if significant else " (not significant)"))


def _leading(A: Array, y: Array) -> tuple[float, float]:
    """Least squares y ~ A c: the first coefficient and its standard error."""
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    resid = y - A @ coef
    cov = np.linalg.pinv(A.T @ A) * float(np.sum(resid**2)) / max(y.size - A.shape[1], 1)
    return float(coef[0]), math.sqrt(max(float(cov[0, 0]), 0.0))


def bus_evidence(log: EnvelopeLog, inputs: EnvelopeInputs) -> Evidence | None:
    """The pack resistance the logged bus voltage shows: V_nominal - V_bus against the bus current P / V_bus
    of motoring samples (P = (R i + omega/Kv) i, i from the current channel or tau / Kt); None without the channel.
    """
    if log.bus_voltage is None:
        return None
    spec = inputs.spec
    i = log.current if log.current is not None else log.torque / spec.kt
    power = (spec.resistance * i + log.velocity / spec.kv) * i
    motoring = power > MOTORING_SHARE * float(np.max(np.abs(power)))
    if motoring.sum() < MIN_MOTORING:
        return None
    x = power[motoring] / np.maximum(log.bus_voltage[motoring], BUS_FLOOR * spec.bus_voltage)  # the bus current
    r_pack, se = _leading(np.column_stack([x, np.ones_like(x)]), spec.bus_voltage - log.bus_voltage[motoring])
    significant = r_pack > SHOWN_SIGMAS * se and r_pack > MIN_R_PACK
    text = f"the logged bus voltage falls {r_pack:.3g} +- {se:.2g} ohm x bus current while motoring"
    return Evidence(r_pack, se, bool(significant), text + ("" if significant else " (not significant)"))
