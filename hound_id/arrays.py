"""Small array helpers shared by the result types."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


def frozen(a: Any) -> NDArray[np.float64]:
    """A float64 copy of ``a`` that cannot be written to (results never alias inputs)."""
    out = np.array(a, dtype=np.float64)
    out.setflags(write=False)
    return out
