"""The process entry point (the ``hound-id`` script, ``python -m hound_id``), kept apart from :mod:`hound_id.cli`
so that a Ctrl-C while the command line's libraries are still being imported ends in one line, not a traceback."""

from __future__ import annotations

import os
import sys


def run() -> None:
    """Import the command line and run it (:func:`hound_id.cli.run`); Ctrl-C during the import: exit 130."""
    try:
        from hound_id.cli import run as run_cli
    except KeyboardInterrupt:
        sys.stderr.write("hound-id: interrupted\n")
        sys.stderr.flush()
        os._exit(130)
    run_cli()
