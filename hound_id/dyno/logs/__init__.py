"""Dynamometer logs in: a CSV or Parquet table to a clean, SI :class:`DynoLog`.

Real logs are dirty. This module finds the channels, converts their units and
cleans the rows, and it reports every change it makes as a :class:`CleaningNote`.
Nothing is changed silently.

**Reading.** CSV files may have a title or date line above the header, a units row under
it (``N.mm``, ``rad.s``, ``Deg C``, ``mA``), ``,``/``, ``/``;``/tab separators and a
trailing separator on every row (:mod:`hound_id.tables`); what the reader did is a
``format`` note.

**Channels.** :data:`CANONICAL` names the channels; :data:`REQUIRED` must be present.
Without a time column the table is a steady-state table: each row is an operating point,
time is the row number (:attr:`DynoLog.timed` is False), and the time-based cleaning steps
(2, 3 below) are skipped. A time column without a unit whose steps look like milliseconds
or microseconds is a ``time_unit`` warning that names the likely unit.
Without a mapping, a channel is the column with its exact name, or its name with a unit
suffix in square brackets (``velocity[rpm]``, ``torque [mN*m]``). A mapping
(``--columns torque=adc_torque``) names the file column instead, with or without its
bracketed suffix.

**Units.** Units come from the header suffix or from ``--units`` (which wins). They are
converted with pint to :data:`UNITS`: SI, except temperature, which stays in degC because
only ``T - 20 degC`` is used. ``Nm`` is newton metre, and ``Hz`` is refused for speeds as
ambiguous, as in :mod:`hound_id.units`.

**Cleaning**, in this order. Row numbers in the notes count data rows of the file from 1:

1. Rows with NaN or inf in a required channel are dropped. An optional channel with
   non-finite values in fewer than 5 % of the rows loses those rows. Otherwise the
   channel itself is dropped.
2. If time ever goes backwards, the rows are sorted by time (stable). Rows that repeat
   the previous timestamp are dropped; the first one is kept.
3. Wrap-around of the current channel is undone, and clamped replies and driver current
   limits are found (:mod:`hound_id.dyno.artefacts`): ``wrap``, ``clamp`` and
   ``current_limit`` notes. Rows whose current is unknown (at the wrap boundary, or clamped
   while the torque keeps moving) are removed; rows at a driver limit are data and kept.
4. Single-sample glitches in current and torque are removed with a Hampel-type test
   (Davies & Gather 1993; Pearson 2002): the deviation from the median of a centred
   window of 7 samples, against max(8 sigma, 5 % of the 99th-percentile magnitude).
   sigma = 1.4826 MAD(diff(x)) / sqrt(2) is the noise level. 1.4826 makes the MAD a
   standard deviation for Gaussian noise; the difference of two samples has sqrt(2)
   times the noise of one. Only runs of at most 2 flagged samples count as glitches.
   A longer run is a real step. A glitch is in one channel only: a transient that the
   other channel shares (within one sample) is data and kept.
5. ADC saturation of the torque: a channel with measurable noise elsewhere sits exactly at its own
   extreme, a large magnitude, for 5 or more consecutive samples, and at that extreme in at least 0.1 % of the rows. The
   channel is noisy elsewhere, so repeating one value exactly for whole runs is not a measured
   signal. A channel without measurable noise (a logged set-point, a simulation) is not tested:
   its flat steps are data.
   Every row at the extreme is removed.
6. A torque that falls as current rises (least-squares slope < 0, correlation < -0.5)
   means a reversed sensor. That is an error unless ``flip_torque`` negates the torque, or ``auto_sign`` lets each
   log's own slope decide (and says so in a note).

At least :data:`MIN_ROWS` rows must remain.
"""

from __future__ import annotations

from hound_id.dyno.logs.clean import (
    BEYOND,
    CURRENT_SLIP_A,
    CURRENT_SLIP_RATIO,
    FLIP_CORRELATION,
    MIN_ROWS,
    OPTIONAL_NAN_FRACTION,
    STALE_OPTIONAL,
    TIME_RATES,
)
from hound_id.dyno.logs.columns import (
    CANONICAL,
    CORE,
    NOTE_KINDS,
    REQUIRED,
    UNITS,
    Array,
    CleaningNote,
    convert_units,
    numeric_column,
    parse_mapping,
    parse_window,
    parse_windows,
    split_header,
)
from hound_id.dyno.logs.envelope import ENVELOPE_CHANNELS, ENVELOPE_MIN_ROWS, EnvelopeLog, load_envelope_log
from hound_id.dyno.logs.reader import DynoLog, load_log, log_from_frame
from hound_id.dyno.logs.sensor import (
    CLIP_MIN_FRACTION,
    CLIP_MIN_LEVEL,
    CLIP_MIN_RUN,
    CLIP_QUANTA,
    GLITCH_FLOOR,
    GLITCH_MAX_RUN,
    GLITCH_SIGMAS,
    GLITCH_WINDOW,
    MAD_TO_SIGMA,
    SENSOR_CHANNELS,
)

__all__ = [
    "Array",
    "BEYOND",
    "CANONICAL",
    "CLIP_MIN_FRACTION",
    "CLIP_MIN_LEVEL",
    "CLIP_MIN_RUN",
    "CLIP_QUANTA",
    "CORE",
    "CURRENT_SLIP_A",
    "CURRENT_SLIP_RATIO",
    "CleaningNote",
    "DynoLog",
    "ENVELOPE_CHANNELS",
    "ENVELOPE_MIN_ROWS",
    "EnvelopeLog",
    "FLIP_CORRELATION",
    "GLITCH_FLOOR",
    "GLITCH_MAX_RUN",
    "GLITCH_SIGMAS",
    "GLITCH_WINDOW",
    "MAD_TO_SIGMA",
    "MIN_ROWS",
    "NOTE_KINDS",
    "OPTIONAL_NAN_FRACTION",
    "REQUIRED",
    "SENSOR_CHANNELS",
    "STALE_OPTIONAL",
    "TIME_RATES",
    "UNITS",
    "convert_units",
    "load_envelope_log",
    "load_log",
    "log_from_frame",
    "numeric_column",
    "parse_mapping",
    "parse_window",
    "parse_windows",
    "split_header",
]
