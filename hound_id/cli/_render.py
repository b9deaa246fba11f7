"""Rendering helpers shared by the commands: JSON to stdout, figures and files written atomically."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import Any

from rich.console import Console

from hound_id import io

console = Console()
err_console = Console(stderr=True)


def print_json(data: Any) -> None:
    """Print machine-readable output (the ``--json`` of every command): strict JSON, a non-finite number (an
    unbounded time, a limit that is not there) written as null."""
    sys.stdout.write(json.dumps(finite(data), indent=2, allow_nan=False) + "\n")
    sys.stdout.flush()


def finite(data: Any) -> Any:
    """``data`` with every non-finite float (inf, NaN) replaced by None, through dicts, lists and tuples."""
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: finite(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return [finite(v) for v in data]
    return data


def warn(message: str) -> None:
    """A non-fatal remark on stderr (the message printed as written: a unit in brackets, ``time[ms]``, is no markup)."""
    from rich.markup import escape

    err_console.print(f"[yellow]warning:[/yellow] {escape(message)}", highlight=False, soft_wrap=True)


def save_figure(fig: Any, path: Path) -> None:
    """Save a matplotlib figure as PNG, atomically."""
    io.check_output(path, (".png",), "plot")
    io.write_png(fig, path)
