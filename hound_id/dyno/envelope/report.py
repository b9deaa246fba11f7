"""The comparison as JSON (``hound-id/mor-compare/2``), its verdict, and the measured-envelope spec file."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hound_id.dyno.envelope.compare import EXPLAINED, OUTSIDE_OK, Comparison, Suggestion
from hound_id.dyno.envelope.offsets import coverage

Array = NDArray[np.float64]

SCHEMA = "hound-id/mor-compare/2"

#: A bin off the final model by more than OFF_SIGMAS standard errors (5 sigma: chance once in 1.7 million bins) and
#: OFF_FLOOR of the torque limit (1 %: smaller misses do not change a trainer's clip) is not explained. Calibrated on
#: test_mor_compare_cli::test_out_is_refused_when_the_model_does_not_explain_the_log and
#: test_hold_protocol::test_a_hot_winding_without_its_temperature_is_not_explained.
OFF_SIGMAS = 5.0
OFF_FLOOR = 0.01
#: A noise level above INFLATED x that of the bins whose samples spread less than WIDE x the typical sample noise is
#: flagged: a few wide bins (samples counted at the limit that were not) would let any model pass. Calibrated on
#: test_hold_protocol::test_an_inflated_noise_level_is_flagged.
INFLATED = 1.5
WIDE = 3.0


def suggestion_dict(s: Suggestion) -> dict[str, Any]:
    """A suggestion of the JSON: the fitted parameter (``value`` in ``unit``), the envelope error with it (``rmse``
    [N m]), the partial F statistic and its uncorrected p-value."""
    return {
        "effect": s.effect,
        "value": s.value,
        "unit": s.unit,
        "explained": s.explained,
        "rmse": s.rmse,
        "f_statistic": s.statistic,
        "p_value": s.p_value,
        "significant": s.significant,
        "reason": s.reason,
        "supported": s.supported,
        "refit": dict(s.refit),
    }


def _rung(c: Comparison, k: int) -> dict[str, Any]:
    """One step of the ladder, with the suggestion (from the step before) that added its effect."""
    step = c.ladder[k]
    why = None
    if k > 0:
        why = next((suggestion_dict(x) for x in c.ladder[k - 1].suggestions if x.effect == step.added), None)
    # the spec sheet's rung on the final walls, as the headline "before" (its suggestions' texts are on the first)
    off = c.baseline if k == 0 and c.baseline is not None else step.offsets
    return {
        "added": step.added,
        "model": step.model,
        "envelope_rmse": off.rmse,
        "noise_level": off.noise,
        "bins": int(off.offset.size),
        "walls_found_again": step.refound,
        "why": why,
    }


@dataclass(frozen=True)
class Flag:
    """Why a model does not explain a log: one kind of evidence against it."""

    kind: str
    """``bins_off_model`` or ``noise_inflated``."""
    bins: int
    """How many speed bins show it."""
    text: str
    """What it is and where, in one sentence."""

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "bins": self.bins, "text": self.text}


@dataclass(frozen=True)
class Verdict:
    """Whether the final model explains the log (:func:`verdict`), and the flags that say why not."""

    explained: bool
    flags: tuple[Flag, ...]

    def to_dict(self) -> dict[str, Any]:
        return {"explained": self.explained, "flags": [f.to_dict() for f in self.flags]}


def verdict(c: Comparison) -> Verdict:
    """``explained`` and the ``flags`` that say why not: the model explains the log when its envelope error is at
    the noise level (:data:`EXPLAINED` x), no bin sits off it by more than :data:`OFF_SIGMAS` standard errors (the
    bin's, or the typical sample noise's if larger) and :data:`OFF_FLOOR` of the torque limit, and (against the spec
    sheet) no share of the samples lies past its edges. A noise level inflated by bins whose samples spread more
    than :data:`WIDE` x the typical sample noise (over :data:`INFLATED` x the other bins' noise level) would pass
    any model: it is flagged, and the error must also be at the other bins' level."""
    off, spec = c.final.offsets, c.inputs.spec
    flags: list[Flag] = []
    typical, off_model, inflated = off.noise, False, False
    if off.offset.size:
        # a bin's own spread is a noisy estimate of the noise (few independent samples): never below the typical one
        se = off.se * np.maximum(1.0, off.sample_noise / np.maximum(off.spread, 1e-30))
        far = (np.abs(off.offset) > OFF_SIGMAS * se) & (np.abs(off.offset) > OFF_FLOOR * spec.linear_torque_limit)
        off_model = bool(far.any())
        if off_model:
            worst = int(np.argmax(np.where(far, np.abs(off.offset) / np.maximum(se, 1e-30), -1.0)))
            where = "; ".join(
                f"{name} edge at {_speeds(off.speeds[far & (off.side == s)])} rad/s"
                for s, name in ((1, "upper"), (-1, "lower"))
                if (far & (off.side == s)).any()
            )
            flags.append(Flag(
                "bins_off_model",
                int(far.sum()),
                f"{int(far.sum())} bin{'s' if far.sum() > 1 else ''} sit{'' if far.sum() > 1 else 's'} off "
                f"the model by more than {OFF_SIGMAS:g} standard errors and "
                f"{OFF_FLOOR:.1%} of the torque limit ({where}), up to {off.offset[worst]:+.3g} N m "
                f"({abs(off.offset[worst]) / max(se[worst], 1e-30):.0f} SE at {off.speeds[worst]:.4g} rad/s): the "
                "model misses something there",
            ))  # fmt: skip
        wide = off.spread > WIDE * off.sample_noise
        if wide.any() and not wide.all():
            typical = float(np.sqrt(np.mean(off.se[~wide] ** 2)))
            inflated = off.noise > INFLATED * typical
            if inflated:
                flags.append(Flag(
                    "noise_inflated",
                    int(wide.sum()),
                    f"the noise level {off.noise:.3g} N m is {off.noise / max(typical, 1e-30):.1f}x the "
                    f"{typical:.3g} N m of the other bins, from {int(wide.sum())} bin(s) at "
                    f"{_speeds(off.speeds[wide])} rad/s whose samples spread up to "
                    f"{float(np.max(off.spread[wide])):.3g} N m (typical sample noise {off.sample_noise:.3g} N m): "
                    "samples counted at the limit that were not, or an edge that moves within the bin",
                ))  # fmt: skip
    rmse = off.rmse
    explained = (
        rmse <= EXPLAINED * max(off.noise, 1e-12)
        and (not inflated or rmse <= EXPLAINED * typical)
        and not off_model
        and (bool(c.final.model) or c.outside.fraction <= OUTSIDE_OK)
        and c.outside_final <= OUTSIDE_OK
    )
    return Verdict(bool(explained), tuple(flags))


def _speeds(w: Array) -> str:
    """Speeds [rad/s] for a message: all of up to four ("-483, 12, 496"), else the range ("-483 to 496")."""
    values = sorted(float(x) for x in w)
    return ", ".join(f"{v:.4g}" for v in values) if len(values) <= 4 else f"{values[0]:.4g} to {values[-1]:.4g}"


def comparison_json(c: Comparison) -> dict[str, Any]:
    """The ``hound-id/mor-compare/2`` JSON."""
    first, last = c.ladder[0], c.final
    before = c.baseline if c.baseline is not None else first.offsets
    return {
        "schema": SCHEMA,
        "source": c.log.source,
        "side": c.log.side,
        "motor": c.inputs.spec.name,
        "samples": c.log.n,
        "rows_dropped": c.log.dropped,
        "limit_method": c.walls.method,
        "limit_detection": c.walls.commanded.to_dict() if c.walls.commanded is not None else None,
        "bins_at_limit": int(last.offsets.offset.size),
        "outside_fraction": c.outside.fraction,
        "outside": c.outside.to_dict(),
        "envelope_rmse": {"model": before.rmse, "with_added": last.offsets.rmse},
        **verdict(c).to_dict(),
        "outside_final": c.outside_final,
        "coverage": coverage(last.offsets).to_dict(),
        "noise_level": last.offsets.noise,
        "sample_noise": first.offsets.sample_noise,
        "model": last.model,
        "added": [s.added for s in c.ladder[1:]],
        "suggestions": [suggestion_dict(s) for s in last.suggestions],
        "unneeded": [u.to_dict() for u in c.unneeded],
        "isolated_bins": [b.to_dict() for b in c.isolated],
        "ladder": [_rung(c, k) for k in range(len(c.ladder))],
        "bins": [
            {
                "speed": float(w),
                "edge": "upper" if side == 1 else "lower",
                "offset_model": float(o0),
                "se": float(se),
                "offset_with_added": float(o1),
            }
            for w, side, o0, se, o1 in zip(
                before.speeds,
                before.side,
                before.offset,
                before.se,
                last.offsets.offset,
                strict=True,
            )
        ],  # fmt: skip
        "polyline": c.polyline.to_dict(),
        "units": "SI, motor side: N m, rad/s",
    }


def envelope_spec(spec_path: Path, out_path: Path, c: Comparison) -> dict[str, Any]:
    """A motor spec file (``hound-id/motor/1``) with the measured envelope, for the saturation and the export:
    the spec sheet (by ``base:``, relative to ``out_path``) plus ``envelope`` = the model's effects and its
    polyline edges (:func:`~hound_id.mor.envelope.polyline`)."""
    import os

    from hound_id.io import read_yaml

    raw = read_yaml(spec_path, "motor spec")
    line = c.polyline
    env = {
        "effects": dict(line.model),
        "speeds": line.speeds.tolist(),
        "lower": [None if not math.isfinite(v) else v for v in line.lower.tolist()],
        "upper": [None if not math.isfinite(v) else v for v in line.upper.tolist()],
        "tolerance": line.tolerance,
        "coverage": coverage(c.final.offsets).to_dict(),
        "units": "rad/s, N m (motor side); outside the coverage the polyline is the model's extrapolation",
        "source": f"hound-id mor --compare {c.log.source}",
    }
    folder = out_path.resolve().parent
    if isinstance(raw, dict) and "base" in raw:  # a fitted spec: keep its own fields, rebase its base
        data = dict(raw)
        data["base"] = os.path.relpath((spec_path.resolve().parent / raw["base"]).resolve(), folder)
    else:
        data = {"schema": "hound-id/motor/1", "base": os.path.relpath(spec_path.resolve(), folder)}
    data["envelope"] = env
    return data
