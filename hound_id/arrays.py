"""Small array helpers shared by the result types."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray


def frozen(a: Any, dtype: Any = np.float64) -> NDArray[Any]:
    """A copy of ``a`` (float64 unless ``dtype`` says otherwise) that cannot be written to.

    Results never alias inputs, so aliasing bugs cannot creep in.
    """
    out = np.array(a, dtype=dtype)
    out.setflags(write=False)
    return out
