"""Where the shipped sample inputs live."""

from __future__ import annotations

import os
from pathlib import Path

from hound_id.errors import SpecError


def samples_dir() -> Path:
    """The ``data/samples`` folder of the checkout (override with ``HOUND_ID_SAMPLES``)."""
    env = os.environ.get("HOUND_ID_SAMPLES")
    path = Path(env) if env else Path(__file__).resolve().parent.parent / "data" / "samples"
    if not path.is_dir():
        raise SpecError(
            f"{path}: sample folder not found; install hound-id from a checkout (pip install -e .) "
            "or point HOUND_ID_SAMPLES at a copy of data/samples",
            path=str(path),
        )
    return path
