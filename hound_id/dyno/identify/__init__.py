"""The identification engine shared by both model families (current-torque and torque-speed envelope).

:class:`~hound_id.parameter.Parameter` (bounds and the reason for them) lives below ``dyno`` and ``mor`` in
:mod:`hound_id.parameter`, because the envelope effects of :mod:`hound_id.mor.envelope` use it and ``mor``
never imports ``dyno``; it is re-exported here.
"""

from hound_id.dyno.identify.engine import (
    ALPHA,
    Step,
    Suggestion,
    best,
    climb,
    corrected,
    f_pvalue,
    rank,
    significant,
)
from hound_id.parameter import Parameter

__all__ = [
    "ALPHA",
    "Parameter",
    "Step",
    "Suggestion",
    "best",
    "climb",
    "corrected",
    "f_pvalue",
    "rank",
    "significant",
]
