"""Current-scale groups: logs whose Kt differ by one fixed ratio were logged with another current scale.

A fleet's Kt values should scatter by a few per cent around one value. When they fall into
separate tight groups instead, the per-amp numbers of one group are those of another times a
fixed ratio: the current column was written on another scale (a logging script whose current
factor changed between runs, an amplitude against an RMS current, a phase against a line
current, mA against A), not several faulty motors. :func:`scale_groups` finds them:

* the identified Kt values (> 0) are sorted on a log scale and cut where two neighbours differ
  by more than :data:`GAP` (12 %: more than twice the fleet's Kt tolerance, far beyond a batch's
  scatter);
* a run of at least :data:`MIN_GROUP` logs is a group; the rest stay single values (outliers,
  for the usual outlier rule);
* with two groups or more, each group's ratio to the largest one is named when it is a known
  convention within :data:`NAMED_WITHIN` (sqrt 2: amplitude against RMS; sqrt 3: line against
  phase; 3/2: amplitude-invariant against power-invariant dq; 1000: mA against A), else it is
  "another current scale in the logging";
* first of all, when the logs show the range their current channel is encoded in (``current_range``
  of each report: half a wrap-around's period, a clamp level), logs are grouped by that range
  (within :data:`RANGE_GAP`): when Kt times the range is the same in every group (within
  :data:`RANGE_AGREE`), the current's scale changed with the encoding and each group's ratio is
  the ranges' ratio. Logs that show no range join the group whose Kt is nearest (within
  :data:`GAP`).

Per-amp quantities (Kt, load-dependent friction) are then compared within their group, each
divided by its group's ratio; torques are compared across the fleet as before.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from statistics import median as _median

#: Neighbouring Kt values (sorted) more than this ratio apart start a new group. Calibrated on
#: test_analyse::test_current_scale_groups_are_named_and_not_flagged.
GAP = 1.12
#: Fewest logs in a group. Calibrated on test_analyse::test_current_scale_groups_are_named_and_not_flagged.
MIN_GROUP = 3
#: A group ratio within this share of a named convention is read as that convention. Calibrated on
#: test_analyse::test_current_scale_groups_are_named_and_not_flagged.
NAMED_WITHIN = 0.03
#: Encoding ranges within this ratio are one range (a wrap's period is measured to a few per mille); Kt x range agrees
#: across groups within this share when the scale changed with the range. Calibrated on
#: test_analyse::test_current_scale_groups_are_named_and_not_flagged.
RANGE_GAP = 1.03
RANGE_AGREE = 0.1
#: Known current conventions: ratio -> what it means.
CONVENTIONS: Mapping[float, str] = {
    math.sqrt(2.0): "an amplitude against an RMS current (sqrt 2)",
    math.sqrt(3.0): "a line against a phase current (sqrt 3)",
    1.5: "amplitude-invariant against power-invariant dq currents (3/2)",
    1000.0: "a current in mA read as A (1000)",
}


@dataclass(frozen=True)
class ScaleGroup:
    """Logs whose Kt agree, and their ratio to the largest group."""

    members: tuple[str, ...]
    """Actuator names, by Kt."""
    kt: float
    """The group's median Kt [N m/A]."""
    ratio: float
    """kt / the largest group's kt [-]."""
    reading: str
    """What the ratio is ("" for the reference group)."""
    current_range: float | None = None
    """The range the group's current channels are encoded in [A] (median), when the logs show one."""


def _reading(ratio: float) -> str:
    r = max(ratio, 1.0 / ratio)
    for value, text in CONVENTIONS.items():
        if abs(r / value - 1.0) <= NAMED_WITHIN:
            return text
    return f"another current scale in the logging (x{ratio:.3g})"


def scale_groups(kt: Mapping[str, float], ranges: Mapping[str, float | None] | None = None) -> tuple[ScaleGroup, ...]:
    """The current-scale groups of a fleet (module docstring); empty when its Kt form one group or fewer.

    Args:
        kt: Actuator name -> identified Kt [N m/A] (values <= 0 are ignored).
        ranges: Actuator name -> the range its current channel is encoded in [A], if the log shows one.
    """
    by_range = _by_range(kt, ranges or {})
    if by_range:
        return by_range
    items = sorted(((v, n) for n, v in kt.items() if v > 0), key=lambda vn: vn[0])
    runs = _runs(items, GAP)
    groups = [r for r in runs if len(r) >= MIN_GROUP]
    if len(groups) < 2:
        return ()
    reference = max(groups, key=len)
    ref_kt = _median([v for v, _ in reference])
    out = []
    for g in groups:
        median = _median([v for v, _ in g])
        ratio = median / ref_kt
        out.append(ScaleGroup(tuple(n for _, n in g), median, ratio, "" if g is reference else _reading(ratio)))
    return tuple(out)


def _runs(items: list[tuple[float, str]], gap: float) -> list[list[tuple[float, str]]]:
    """Sorted (value, name) pairs cut where neighbours differ by more than the ratio ``gap``."""
    runs: list[list[tuple[float, str]]] = []
    for value, name in items:
        if runs and value / runs[-1][-1][0] <= gap:
            runs[-1].append((value, name))
        else:
            runs.append([(value, name)])
    return runs


def _by_range(kt: Mapping[str, float], ranges: Mapping[str, float | None]) -> tuple[ScaleGroup, ...]:
    """Groups by encoding range, when Kt x range is one value across them; empty otherwise."""
    known = sorted(((abs(r), n) for n, r in ranges.items() if r and n in kt and kt[n] > 0), key=lambda rn: rn[0])
    groups = [r for r in _runs(known, RANGE_GAP) if len(r) >= MIN_GROUP]
    if len(groups) < 2:
        return ()
    products = [_median([kt[n] * r for r, n in g]) for g in groups]
    if max(products) / min(products) > 1.0 + RANGE_AGREE:
        return ()
    reference = max(groups, key=len)
    ref_range = _median([r for r, _ in reference])
    members = [[n for _, n in g] for g in groups]
    levels = [_median([r for r, _ in g]) for g in groups]
    kts = [_median([kt[n] for n in m]) for m in members]
    for name, value in kt.items():  # a log that shows no range joins the group of the nearest Kt
        if value <= 0 or any(name in m for m in members):
            continue
        k = min(range(len(kts)), key=lambda j: abs(math.log(value / kts[j])))
        if max(value / kts[k], kts[k] / value) <= GAP:
            members[k].append(name)
    product = _median(products)
    out = []
    for g, m, level in zip(groups, members, levels, strict=True):
        reading = ""
        if g is not reference:
            reading = (
                f"the current encoded in +-{level:.4g} A against +-{ref_range:.4g} A: another current scale "
                f"(Kt x range = {product:.3g} N m in every group)"
            )
        median = _median([kt[n] for n in m])
        out.append(ScaleGroup(tuple(sorted(m, key=lambda n: kt[n])), median, ref_range / level, reading, level))
    return tuple(out)


def sentence(groups: tuple[ScaleGroup, ...]) -> str:
    """One sentence on the groups for the fleet's notes."""
    parts = []
    for g in groups:
        level = f", current range +-{g.current_range:.4g} A" if g.current_range is not None else ""
        what = f": {g.reading}" if g.reading else " (reference)"
        parts.append(f"{len(g.members)} logs at Kt {g.kt:.4g} N m/A (x{g.ratio:.3g}{level}){what}")
    return (
        f"Kt falls into {len(groups)} groups at fixed ratios, not scattered outliers: "
        + "; ".join(parts)
        + ". Per-amp values (Kt, load-dependent friction) are compared within their group"
    )


__all__ = [
    "CONVENTIONS",
    "GAP",
    "MIN_GROUP",
    "NAMED_WITHIN",
    "RANGE_AGREE",
    "RANGE_GAP",
    "ScaleGroup",
    "scale_groups",
    "sentence",
]
