"""Identifiability of a model's parameters on a log: the variance inflation of each (with a torque offset always
allowed for), on the whole log and with each fold left out, and why a parameter cannot be told apart."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hound_id.dyno.current.effects import OFFSET, REGISTRY, Signals
from hound_id.dyno.current.stats import Array, Stats

#: Variance inflation beyond which the log cannot tell a parameter from the others (R^2 > 0.9999). The library's effects
#: on a well-designed test stay below 1.5e3 (saturation family beside each other); one quadrant (Kt against gear
#: friction) or a held current (Kt against the offset) go far beyond. Calibrated on
#: test_polled_rig::test_one_quadrant_cannot_tell_kt_from_gear_friction,
#: test_polled_rig::test_a_held_current_cannot_identify_kt, test_fit_cli::test_logs_that_identify_nothing_are_refused
#: and test_diagnose::test_combinations_of_hidden_effects_are_found_exactly_with_nothing_extra.
VIF_MAX = 1.0e4


def vif(G: Array) -> tuple[Array, Array]:
    """Variance inflation of each column of a Gram matrix, and the normalised inverse (for partners).

    Uncentred (the columns are compared as they enter the model); a zero column gets inf.
    """
    d = np.sqrt(np.maximum(np.diag(G), 0.0))
    dead = d <= 1e-300
    d[dead] = 1.0
    Gs = G / np.outer(d, d)
    w, V = np.linalg.eigh(Gs)
    w = np.maximum(w, max(float(w[-1]), 1e-300) * 1e-16)
    inv = (V / w) @ V.T
    out = np.diag(inv).copy()
    out[dead] = np.inf
    return out, inv


@dataclass(frozen=True)
class Unidentified:
    """A parameter the log cannot tell from another."""

    parameter: str
    """The parameter."""
    partner: str
    """What it cannot be told from (a parameter, or :data:`OFFSET`)."""
    vif: float
    """Its worst variance inflation (whole log, or one fold left out)."""
    why: str
    """The reason in the log's terms, and what to record instead."""

    def sentence(self) -> str:
        return f"this log cannot tell {self.parameter} from {self.partner}: {self.why}"


def _why(a: str, b: str, signals: Signals, vif_value: float) -> str:
    """The physical reason two parameters cannot be told apart on this log, and what to record: the first that
    either parameter's effect gives (:attr:`Effect.unidentified <hound_id.dyno.current.effect.Effect.unidentified>`),
    else that their regressors are nearly collinear."""
    owner = {p.name: e for e in REGISTRY.values() for p in e.parameters}
    for name, partner in ((a, b), (b, a)):
        effect = owner.get(name)
        if effect is not None and effect.unidentified is not None:
            reason = effect.unidentified(partner, signals)
            if reason is not None:
                return reason
    return (
        f"their regressors are nearly collinear on this log (variance inflation {vif_value:.2g}, above "
        f"{VIF_MAX:.0g}); vary the current and the speed more widely"
    )


def identifiability(stats: Stats, cols: Sequence[int], names: Sequence[str], signals: Signals) -> list[Unidentified]:
    """Parameters among ``cols`` this log cannot estimate, with the reason.

    A parameter is identified when its variance inflation stays below :data:`VIF_MAX`
    on the whole log and with any one fold left out (a handful of rows must not be all
    that separates two parameters). A torque offset (column 0) is always allowed for,
    unless the model has its own.
    """
    i = signals.current
    if "kt" in names and float(np.std(i)) < 0.1 * abs(float(np.mean(i))):
        # one held current: Kt against any constant, whatever else the model has
        return [Unidentified("kt", OFFSET, math.inf, _why("kt", OFFSET, signals, math.inf))]
    with_offset = "offset" not in names
    check = [0, *cols] if with_offset else list(cols)
    labels = [OFFSET, *names] if with_offset else list(names)
    uses = [np.ones(stats.blocks.count, dtype=bool)] + [
        stats.blocks.fold != k for k in range(stats.blocks.folds) if stats.blocks.folds > 2
    ]
    worst = np.zeros(len(check))
    worst_inv: Array | None = None
    for use in uses:
        G, _, _ = stats.total(check, use)
        v, inv = vif(G)
        if worst_inv is None or float(np.max(v)) > float(np.max(worst)):
            worst_inv = inv
        worst = np.maximum(worst, v)
    out: list[Unidentified] = []
    seen: set[frozenset[str]] = set()
    assert worst_inv is not None
    # Kt first: when it is lost, that is the news, whatever else goes with it.
    order = sorted(range(len(labels)), key=lambda j: (labels[j] != "kt", -worst[j]))
    for j in order:
        if worst[j] <= VIF_MAX or labels[j] == OFFSET:
            continue
        corr = np.abs(worst_inv[j]) / np.sqrt(np.abs(np.diag(worst_inv)) * abs(worst_inv[j, j]) + 1e-300)
        corr[j] = -1.0
        k = int(np.argmax(corr))
        key = frozenset((labels[j], labels[k]))
        if key in seen:
            continue
        seen.add(key)
        out.append(Unidentified(labels[j], labels[k], float(worst[j]), _why(labels[j], labels[k], signals, worst[j])))
    return out
