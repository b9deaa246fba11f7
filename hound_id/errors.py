"""One exception family for hound-id.

Every error the library raises on bad input is a :class:`HoundIdError`. Each
subclass also inherits the matching builtin, so ``except ValueError`` in user
code keeps working. The CLI catches :class:`HoundIdError`, prints its message on
one line and exits with status 2; anything else is a bug and keeps its traceback.

Messages name the file, the field (or row), what was found, what was expected,
and how to fix it. The offending values are kept as attributes.
"""

from __future__ import annotations

from typing import Any

#: The longest message an error keeps [characters]; the middle of a longer one is cut and the cut said.
MESSAGE_LIMIT = 2000


class HoundIdError(Exception):
    """Base of every error hound-id raises on bad input or an impossible request."""

    def __init__(self, message: str, **details: Any) -> None:
        if len(message) > MESSAGE_LIMIT:  # a value rendered whole (a list of millions) stays a line, not a page
            cut = len(message) - MESSAGE_LIMIT
            message = f"{message[: MESSAGE_LIMIT // 2]} ... [{cut} characters cut] ... {message[-MESSAGE_LIMIT // 2 :]}"
        super().__init__(message)
        self.message = message
        self.details = details
        for key, value in details.items():
            setattr(self, key, value)

    def __str__(self) -> str:
        return self.message


class UnitError(HoundIdError, ValueError):
    """A quantity has the wrong physical dimension or cannot be parsed."""


class SpecError(HoundIdError, ValueError):
    """A motor spec sheet is missing a field, has an unknown key or a non-physical value."""


class TransmissionError(HoundIdError, ValueError):
    """A transmission matrix is malformed, singular or inconsistent with its joints."""


class RobotError(HoundIdError, ValueError):
    """A robot description is inconsistent (joints, motors, transmissions)."""


class SaturationError(HoundIdError, ValueError):
    """Arrays given to the saturation have the wrong shape or type."""


class TableError(HoundIdError, ValueError):
    """A data table (CSV or Parquet) cannot be read or lacks the columns needed."""


class DynoDataError(HoundIdError, ValueError):
    """A dynamometer log is unusable as given (missing channels, reversed sensor, too few rows)."""


class FitError(HoundIdError, ValueError):
    """A model cannot be fitted to the data (unknown effect, missing channel, too little excitation)."""


class OutputError(HoundIdError, OSError):
    """An output file could not be written."""


def where(source: str | None, field: str | None = None) -> str:
    """Format the 'file: field' prefix used in every message."""
    parts = [p for p in (source, f"field '{field}'" if field else None) if p]
    return ": ".join(parts) if parts else "input"


class FleetError(HoundIdError, ValueError):
    """A fleet run cannot start or be compared (no logs found, a scheduler that cannot be reached, bad options)."""
