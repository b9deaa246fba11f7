"""Compare two text files as numbers: the words must match, the numbers may differ in their last bits.

A generated file (a sample log, a truth JSON, a URDF) is the same file on another machine only up to rounding: the
last bit of a float differs between CPUs (numpy's SIMD kernels for sin, cos and exp; the BLAS kernel OpenBLAS picks)
and between thread counts (the order of a parallel sum). A byte comparison therefore fails on a machine that did not
write the file. This compares the text between the numbers exactly and each number within a stated tolerance.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

# a decimal number with optional exponent, or a whole-word nan/inf (not the "nan" inside "resonance")
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?|(?<![A-Za-z_])[-+]?(?:nan|inf)(?![A-Za-z_])")
_PARTS = re.compile(r"[-+]?(\d*)\.?(\d*)(?:[eE]([-+]?\d+))?$")


def last_digit(text: str) -> float:
    """The value of one unit in the last printed digit of a number written as ``text`` (0 for nan/inf)."""
    m = _PARTS.match(text)
    if m is None:
        return 0.0
    return 10.0 ** (int(m.group(3) or 0) - len(m.group(2) or ""))


@dataclass(frozen=True)
class Mismatch:
    """Where two files differ beyond the tolerance."""

    line: int
    """1-based line of the first file."""
    found: str
    expected: str

    def __str__(self) -> str:
        return f"line {self.line}: {self.found!r} against {self.expected!r}"


def mismatches(found: str, expected: str, rel: float) -> list[Mismatch]:
    """Differences between two texts beyond ``rel`` (relative) plus one unit in the last printed digit.

    The words between the numbers must be identical; each pair of numbers ``a``, ``b`` must satisfy
    ``|a - b| <= rel max(|a|, |b|) + u``, where ``u`` is a unit in the last digit either side printed
    (a value rounded to 6 digits may round the other way when its last bit differs).
    """
    a_words, b_words = NUMBER.split(found), NUMBER.split(expected)
    a_nums, b_nums = NUMBER.findall(found), NUMBER.findall(expected)
    if a_words != b_words or len(a_nums) != len(b_nums):
        for k, (x, y) in enumerate(zip(found.splitlines(), expected.splitlines(), strict=False)):
            if NUMBER.split(x) != NUMBER.split(y):
                return [Mismatch(k + 1, x, y)]
        n_a, n_b = found.count("\n"), expected.count("\n")
        return [Mismatch(min(n_a, n_b) + 1, f"{n_a} lines", f"{n_b} lines")]
    out = []
    offsets = [m.start() for m in NUMBER.finditer(found)]
    for at, x, y in zip(offsets, a_nums, b_nums, strict=True):
        if x == y:
            continue
        fx, fy = float(x), float(y)
        if math.isnan(fx) and math.isnan(fy):
            continue
        scale = max(abs(fx), abs(fy))
        if not (math.isfinite(fx) and math.isfinite(fy)) or abs(fx - fy) > rel * scale + max(
            last_digit(x), last_digit(y)
        ):
            out.append(Mismatch(found.count("\n", 0, at) + 1, x, y))
    return out


def assert_same_numbers(found: Path, expected: Path, rel: float) -> None:
    """Fail with the first few places where ``found`` differs from ``expected`` (see :func:`mismatches`)."""
    bad = mismatches(found.read_text(), expected.read_text(), rel)
    assert not bad, f"{found.name} differs from {expected} beyond rel {rel:g}: " + "; ".join(map(str, bad[:5]))
