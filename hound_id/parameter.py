"""The one parameter type of every identified model: a named, unit-carrying value with physical bounds.

Both model families use it: the current-torque effects (:mod:`hound_id.dyno.current.effects`, whose
parameters enter the model linearly and are fitted within their bounds) and the torque-speed envelope
effects (:mod:`hound_id.mor.envelope`, one scalar parameter each, found by a bounded search). It lives
here, below both ``dyno`` and ``mor``, because ``mor`` never imports ``dyno``; the identification
engine re-exports it (:mod:`hound_id.dyno.identify`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hound_id.errors import FitError

#: A fitted value within this share of its search interval from an end sits at the bound: the data did not
#: identify it (the search stopped against the interval, not at a minimum inside it).
AT_BOUND = 1e-3


@dataclass(frozen=True)
class Parameter:
    """A model parameter, with the physical bounds the fit respects and the reason for them."""

    name: str
    """Unique name across its model family, e.g. ``kt`` or ``r_pack``."""
    unit: str
    """SI unit, e.g. ``N m/A``."""
    doc: str = ""
    """What it is."""
    lower: float = -math.inf
    """Smallest physically possible value (e.g. 0 for a friction coefficient) [unit]."""
    upper: float = math.inf
    """Largest physically possible value [unit]."""
    bound_reason: str = ""
    """Why the bounds hold, in a few words (shown when a fit asks for a value outside them)."""
    neutral: float | None = None
    """Value at which its effect does nothing [unit] (None: no such value); a fit there is not 'at a bound'."""

    def __post_init__(self) -> None:
        if not self.lower < self.upper:
            raise FitError(f"parameter '{self.name}': lower bound {self.lower} is not below upper bound {self.upper}")

    def outside(self, value: float) -> str | None:
        """'coulomb < 0' when ``value`` breaks a bound, else None."""
        if value < self.lower:
            return f"{self.name} < {self.lower:g}"
        if value > self.upper:
            return f"{self.name} > {self.upper:g}"
        return None

    def at_bound(self, value: float, lower: float | None = None, upper: float | None = None) -> bool:
        """Whether a fitted ``value`` sits at an end of its search interval (not identified by the data).

        Args:
            value: The fitted value [unit].
            lower: Lower end of the search [unit] (default: :attr:`lower`).
            upper: Upper end of the search [unit] (default: :attr:`upper`).

        Returns:
            True when ``value`` is within :data:`AT_BOUND` of the interval's width from either end and is not
            the :attr:`neutral` value (an effect found absent is identified: it does nothing).
        """
        lo = self.lower if lower is None else lower
        hi = self.upper if upper is None else upper
        near = min(abs(value - lo), abs(hi - value)) < AT_BOUND * (hi - lo)
        return bool(near and value != self.neutral)
