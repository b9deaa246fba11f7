"""``hound-id saturate``: a log of joint torque commands clipped as in training, streamed in blocks from CSV or
Parquet, with the tally of which motors clipped and how far the coupled clip turned each group; and the URDF-box
study of the demo (:func:`box_study`)."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from hound_id.arrays import frozen
from hound_id.mor.clip_turn import CLIP_TOLERANCE, ClipTurn, TurnTally
from hound_id.mor.saturation import PER_JOINT_REFERENCE, Saturation, coupled_groups, per_joint_clip, saturation_for

if TYPE_CHECKING:  # the runtime imports this module: no robot files (yaml, pint) at run time
    from hound_id.mor.robot import Robot


@dataclass(frozen=True)
class BoxStudy:
    """What a rectangular joint limit lets through that the motors cannot make."""

    samples: int
    """Number of random (tau, qd) commands drawn per box."""
    outer_infeasible: float
    """Fraction of commands inside the outer (URDF-style) box that the MOR clips."""
    outer_mean_clip: float
    """Mean |tau_cmd - tau_sat| over joints and those commands [N m]."""
    inner_infeasible: float
    """Fraction of commands inside the inner box that the MOR clips (0 by construction)."""
    max_violation_after: float
    """Largest motor-torque violation left after saturation [N m] (0 up to round-off)."""

    def to_dict(self) -> dict[str, float | int]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def box_study(
    sat: Saturation, inner: NDArray[np.float64], outer: NDArray[np.float64], samples: int = 100_000, seed: int = 0
) -> BoxStudy:
    """Draw commands uniformly in the inner and outer boxes and saturate them.

    Args:
        sat: The robot's saturation.
        inner: Inner box per joint, shape (n, 2): (effort [N m], velocity [rad/s]).
        outer: Outer box per joint, same shape.
        samples: Number of commands per box.
        seed: Random seed.
    """
    rng = np.random.default_rng(seed)
    results = []
    for box in (outer, inner):
        u = rng.uniform(-1.0, 1.0, size=(2, samples, sat.n))
        tau, qd = u[0] * box[:, 0], u[1] * box[:, 1]
        clipped = sat(tau, qd)
        changed = np.any(np.abs(clipped - tau) > 1e-9 * np.maximum(1.0, np.abs(tau)), axis=-1)
        results.append(
            (float(changed.mean()), float(np.abs(clipped - tau).mean()), float(sat.violation(clipped, qd).max()))
        )
    return BoxStudy(
        samples=samples,
        outer_infeasible=results[0][0],
        outer_mean_clip=results[0][1],
        inner_infeasible=results[1][0],
        max_violation_after=max(results[0][2], results[1][2]),
    )


#: Schema of the ``hound-id saturate --json`` summary (2: ``clip_turn`` added).
SATURATE_SCHEMA = "hound-id/saturate/2"
#: Rows a log's plot draws at most: longer logs are thinned to every k-th row (k a power of two).
PLOT_ROWS = 20_000


def motor_clipped(motor_torque_cmd: NDArray[np.float64], motor_torque_sat: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Whether each motor torque command was outside the region: it moved by more than
    :data:`CLIP_TOLERANCE` relative, or it is beyond float range (±inf, from a finite command)."""
    with np.errstate(invalid="ignore"):
        tol = CLIP_TOLERANCE * np.maximum(1.0, np.abs(motor_torque_cmd))
        return (np.abs(motor_torque_sat - motor_torque_cmd) > tol) | np.isinf(motor_torque_cmd)


@dataclass(frozen=True)
class LogSaturation:
    """A log of joint torque commands saturated by the MOR, with what was clipped."""

    joints: tuple[str, ...]
    """Joint order of the arrays."""
    motors: tuple[str, ...]
    """Motor order of the motor-space arrays."""
    tau_cmd: NDArray[np.float64]
    """Commanded joint torques [N m], shape (rows, n)."""
    qd: NDArray[np.float64]
    """Joint velocities [rad/s], shape (rows, n)."""
    tau_sat: NDArray[np.float64]
    """Saturated joint torques [N m], shape (rows, n)."""
    motor_torque_cmd: NDArray[np.float64]
    """Commanded motor torques [N m], shape (rows, n) (±inf where beyond float range)."""
    motor_torque_sat: NDArray[np.float64]
    """Saturated motor torques [N m], shape (rows, n)."""
    motor_speed: NDArray[np.float64]
    """Motor speeds [rad/s], shape (rows, n)."""
    turn: ClipTurn | None = None
    """How far the clip turned each coupled group's joint-torque vector over these rows (None: not measured)."""

    @property
    def motor_clipped(self) -> NDArray[np.bool_]:
        """Whether each motor torque command was outside the region, shape (rows, n)."""
        return motor_clipped(self.motor_torque_cmd, self.motor_torque_sat)

    def to_dict(self) -> dict[str, Any]:
        """Summary, schema ``hound-id/saturate/2``."""
        tally = _Tally(self.joints, self.motors)
        tally.add(self.tau_cmd, self.tau_sat, self.motor_clipped)
        return tally.summary(turn=self.turn).to_dict()


@dataclass(frozen=True)
class LogSummary:
    """What ``hound-id saturate`` reports on a log, gathered batch by batch (:func:`saturate_file`)."""

    joints: tuple[str, ...]
    """Joint order."""
    motors: tuple[str, ...]
    """Motor order."""
    rows: int
    """Number of commands (data rows)."""
    violating_rows: int
    """Commands with at least one motor outside its region."""
    max_clip: tuple[float, ...]
    """Per joint the largest |tau_sat - tau_cmd| [N m] (joint side)."""
    mean_clip: tuple[float, ...]
    """Per joint the mean |tau_sat - tau_cmd| [N m]."""
    clipped_rows: tuple[int, ...]
    """Per motor the number of commands it clipped."""
    sample: LogSaturation | None = None
    """Evenly spaced rows (every k-th, at most :data:`PLOT_ROWS`) for the plot; None when not asked for."""
    sample_step: int = 1
    """The k of :attr:`sample`: it holds rows 0, k, 2k, ..."""
    notes: tuple[str, ...] = ()
    """What the reader found in the file's layout (units row, title lines, separator)."""
    turn: ClipTurn | None = None
    """How far the coupled clip turned each coupled group's joint-torque vector, against the per-joint clip
    (:mod:`hound_id.mor.clip_turn`); None: not measured."""

    def to_dict(self) -> dict[str, Any]:
        """Summary, schema ``hound-id/saturate/2`` (``/1`` plus ``clip_turn``): finite numbers only (valid JSON)."""
        return {
            "schema": SATURATE_SCHEMA,
            "rows": self.rows,
            "violating_fraction": self.violating_rows / self.rows,
            "joints": [
                {"joint": j, "max_clip": self.max_clip[i], "mean_clip": self.mean_clip[i]}
                for i, j in enumerate(self.joints)
            ],
            "motors": [
                {"motor": m, "clipped_fraction": self.clipped_rows[i] / self.rows} for i, m in enumerate(self.motors)
            ],
            "units": {"clip": "N m (joint side)"},
            "clip_turn": self.turn.to_dict() if self.turn is not None else None,
        }


#: Chunk sums that overflow are kept scaled by this power of two (exact: a power-of-two scale).
_SUM_SCALE = 2.0**-64


class _Tally:
    """The summary statistics of a log, added up batch by batch.

    A single batch gives bit for bit what numpy gives on the whole arrays (``clip.mean()`` is
    ``clip.sum() / n``); several batches differ from it only by rounding (the batch sums are
    added exactly, with :func:`math.fsum`). Sums past the float range (commands near 1e308) are
    kept scaled by a power of two, so the means stay finite.
    """

    def __init__(self, joints: tuple[str, ...], motors: tuple[str, ...]) -> None:
        self.joints, self.motors = joints, motors
        n = len(joints)
        self.rows = 0
        self.violating = 0
        self.max_clip = [0.0] * n
        self.sums: list[list[float]] = [[] for _ in range(n)]
        self.scaled: list[list[float]] = [[] for _ in range(n)]
        self.clipped = [0] * n

    def add(self, tau_cmd: NDArray[np.float64], tau_sat: NDArray[np.float64], clipped: NDArray[np.bool_]) -> None:
        if not len(tau_cmd):
            return
        clip = np.abs(tau_sat - tau_cmd)
        self.rows += int(tau_cmd.shape[0])
        self.violating += int(np.any(clipped, axis=1).sum())
        for i in range(len(self.joints)):
            self.max_clip[i] = max(self.max_clip[i], float(clip[:, i].max()))
            with np.errstate(over="ignore"):  # past the float range: kept scaled below
                total = float(clip[:, i].sum())
            if math.isfinite(total):
                self.sums[i].append(total)
            else:
                self.scaled[i].append(float((clip[:, i] * _SUM_SCALE).sum()))
            self.clipped[i] += int(clipped[:, i].sum())

    def _mean(self, i: int) -> float:
        if not self.scaled[i]:
            try:
                return math.fsum(self.sums[i]) / self.rows
            except OverflowError:
                pass
        scaled = math.fsum([s * _SUM_SCALE for s in self.sums[i]] + self.scaled[i])
        return min((scaled / self.rows) / _SUM_SCALE, self.max_clip[i])

    def summary(
        self,
        sample: LogSaturation | None = None,
        notes: tuple[str, ...] = (),
        step: int = 1,
        turn: ClipTurn | None = None,
    ) -> LogSummary:
        return LogSummary(
            joints=self.joints,
            motors=self.motors,
            rows=self.rows,
            violating_rows=self.violating,
            max_clip=tuple(self.max_clip),
            mean_clip=tuple(self._mean(i) for i in range(len(self.joints))),
            clipped_rows=tuple(self.clipped),
            sample=sample,
            sample_step=step,
            notes=notes,
            turn=turn,
        )


class _Sample:
    """Every k-th row of a log, k doubling whenever more than ``limit`` rows are kept."""

    def __init__(self, limit: int) -> None:
        self.limit, self.step, self.seen = limit, 1, 0
        self.parts: list[tuple[NDArray[np.float64], ...]] = []

    def add(self, *arrays: NDArray[np.float64]) -> None:
        rows = len(arrays[0])
        first = (-self.seen) % self.step  # the first row of this batch whose global index is a multiple of step
        self.parts.append(tuple(a[first :: self.step] for a in arrays))
        self.seen += rows
        while sum(len(p[0]) for p in self.parts) > self.limit:
            merged = tuple(np.concatenate(cols) for cols in zip(*self.parts, strict=True))
            self.parts = [tuple(a[::2] for a in merged)]
            self.step *= 2

    def arrays(self) -> tuple[NDArray[np.float64], ...]:
        return tuple(np.concatenate(cols) for cols in zip(*self.parts, strict=True))


def _joint_arrays(
    columns: Any, joints: tuple[str, ...], source: str, first_row: int = 0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(tau, qd) arrays (rows, n) from columns ``tau_<joint>`` [N m] and ``qd_<joint>`` [rad/s].

    ``columns`` maps names to 1-D arrays (a DataFrame, a dict, or a pyarrow RecordBatch);
    ``first_row`` is the number of data rows before these, for messages.

    Raises:
        TableError: A column is missing, holds text, booleans or a non-finite value.
    """
    from hound_id.errors import TableError

    names = columns.schema.names if hasattr(columns, "schema") else columns
    arrays = {}
    for prefix in ("tau", "qd"):
        stacked = []
        for joint in joints:
            name = f"{prefix}_{joint}"
            if name not in names:
                raise TableError(
                    f"{source}: column '{name}' missing; expected tau_<joint> [N m] and qd_<joint> [rad/s] "
                    f"for every joint ({', '.join(joints)})",
                    column=name,
                )
            values = _numbers(columns[name], name, source, first_row)
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                row = first_row + int(bad[0]) + 1
                raise TableError(
                    f"{source}: column '{name}' data row {row} holds {values[bad[0]]}; "
                    "expected a finite number (drop or fill such rows first)",
                    column=name,
                    row=row,
                )
            stacked.append(values)
        arrays[prefix] = np.column_stack(stacked) if stacked else np.zeros((0, 0))
    return arrays["tau"], arrays["qd"]


def _numbers(column: Any, name: str, source: str, first_row: int) -> NDArray[np.float64]:
    """A column as float64 (missing values NaN), or TableError naming the first cell that is not a number."""
    from hound_id.errors import TableError

    kind = "n"
    if type(column).__module__.startswith("pyarrow"):
        import pyarrow as pa

        if pa.types.is_dictionary(column.type):
            column = column.dictionary_decode()
        kinds = (pa.types.is_floating, pa.types.is_integer, pa.types.is_null, pa.types.is_decimal)
        if any(is_kind(column.type) for is_kind in kinds):
            return _float64(column)
        kind = "b" if pa.types.is_boolean(column.type) else "O"
        if not (pa.types.is_string(column.type) or pa.types.is_large_string(column.type) or kind == "b"):
            raise TableError(f"{source}: column '{name}' holds {column.type} values; expected numbers", column=name)
        if kind == "O":
            parsed = _parse_text(column)
            if parsed is not None:
                return parsed
        column = column.to_pandas()
    raw = np.asarray(column)
    if raw.dtype.kind == "b" or kind == "b":
        raise TableError(
            f"{source}: column '{name}' holds booleans (true/false); expected numbers "
            f"({'N m' if name.startswith('tau_') else 'rad/s'}); convert the column first",
            column=name,
        )
    if raw.dtype.kind in "fiu":
        return raw.astype(np.float64, copy=False)
    import pandas as pd

    series = pd.Series(raw)
    numeric = pd.to_numeric(series, errors="coerce")
    text = np.flatnonzero(numeric.isna().to_numpy() & series.notna().to_numpy())
    if text.size:
        row = first_row + int(text[0]) + 1
        raise TableError(
            f"{source}: column '{name}' data row {row} holds {series.iloc[text[0]]!r}; expected a number",
            column=name,
            row=row,
        )
    return numeric.to_numpy(dtype=float)


#: Cells read as missing (NaN), as pandas reads them; compared lower case, spaces stripped.
_MISSING = ("", "nan", "-nan", "na", "n/a", "<na>", "#na", "#n/a", "#n/a n/a", "null", "none", "1.#ind", "-1.#ind",
            "1.#qnan", "-1.#qnan")  # fmt: skip


def _parse_text(column: Any) -> NDArray[np.float64] | None:
    """Numbers from a pyarrow text column (missing cells NaN), or None when a cell is not a number."""
    import pyarrow as pa
    import pyarrow.compute as pc

    try:
        return _float64(column)
    except pa.ArrowInvalid:
        pass
    cells = pc.utf8_trim_whitespace(column)
    missing = pc.fill_null(pc.is_in(pc.utf8_lower(cells), value_set=pa.array(_MISSING)), True)
    try:
        return _float64(pc.if_else(missing, pa.scalar(None, pa.string()), cells))
    except pa.ArrowInvalid:
        return None


def _float64(column: Any) -> NDArray[np.float64]:
    """A pyarrow array as float64 numbers, nulls as NaN (read from its buffers: to_numpy would load pandas)."""
    import pyarrow as pa

    values = column.cast(pa.float64())
    validity, data = values.buffers()[:2]
    start, end = values.offset, values.offset + len(values)
    numbers = np.frombuffer(data, dtype=np.float64, count=end)[start:] if data is not None else np.zeros(len(values))
    if values.null_count:
        valid = np.unpackbits(np.frombuffer(validity, dtype=np.uint8), bitorder="little")[start:end].astype(bool)
        numbers = np.where(valid, numbers, np.nan)
    return numbers


#: Rows :func:`saturate_file` hands the clip at a time: one batch shape (the last block padded with zeros),
#: so the clip's per-shape constants and scratch arrays (about 1 MB) are made once, whatever the batches;
#: and few enough that OpenBLAS multiplies them in one thread (it splits m x 12 x 12 products from about
#: 1800 rows on): its waiting threads and pyarrow's reader threads made a 4096-row clip 25x slower on 2 cores.
BLOCK_ROWS = 1024


def _saturate_rows(
    sat: Saturation, tau: NDArray[np.float64], qd: NDArray[np.float64], block: int = 0
) -> tuple[NDArray[np.float64], ...]:
    """(tau_sat, motor torque cmd, motor torque sat, motor speed) of rows, ``block`` rows at a time (0: all)."""
    if block <= 0 or len(tau) == block:
        tau_sat = sat(tau, qd)
        tau_m, omega = sat.motor_state(tau, qd)
        return tau_sat, tau_m, tau_sat @ sat.A, omega  # tau_sat is finite and within the limits: no overflow
    results = [np.empty_like(tau) for _ in range(4)]
    pad_tau, pad_qd = np.zeros((block, tau.shape[1])), np.zeros((block, tau.shape[1]))
    for start in range(0, len(tau), block):
        stop = min(len(tau), start + block)
        t, q = tau[start:stop], qd[start:stop]
        if stop - start < block:  # zeros are inside every region
            pad_tau[: stop - start], pad_qd[: stop - start] = t, q
            t, q = pad_tau, pad_qd
        for out, part in zip(results, _saturate_rows(sat, t, q, block), strict=True):
            out[start:stop] = part[: stop - start]
    return tuple(results)


def saturate_log(robot: Robot, columns: Any, source: str = "commands") -> LogSaturation:
    """Saturate a log with columns ``tau_<joint>`` [N m] and ``qd_<joint>`` [rad/s] for every joint.

    The whole log in memory; :func:`saturate_file` streams a file of any length.

    Args:
        robot: The robot whose motors and transmissions apply.
        columns: A mapping (or DataFrame) of column name -> 1-D numeric array.
        source: File name, for messages.

    Raises:
        TableError: A column is missing or holds a non-finite value.
    """
    tau, qd = _joint_arrays(columns, robot.joints, source)
    sat = saturation_for(robot)
    return _log_saturation(robot, sat, tau, qd, *_saturate_rows(sat, tau, qd))


def turn_tally(sat: Saturation, motors: tuple[str, ...]) -> TurnTally:
    """A :class:`hound_id.mor.clip_turn.TurnTally` for the robot of ``sat``, against :func:`per_joint_clip`
    (when every joint has a motor of its own); feed it with :func:`add_turn`."""
    reference = PER_JOINT_REFERENCE if np.all(np.diag(sat.A) != 0) else None  # each joint has a motor of its own
    return TurnTally(sat.A, coupled_groups(sat.A), sat.joints, motors, reference=reference)


def add_turn(
    tally: TurnTally,
    sat: Saturation,
    tau: NDArray[np.float64],
    qd: NDArray[np.float64],
    *saturated: NDArray[np.float64],
) -> None:
    """Add rows to a :func:`turn_tally`: commands, speeds, and (tau_sat, motor torque cmd, motor torque sat)."""
    tau_sat, tau_m, tau_m_sat = saturated[:3]
    ref = per_joint_clip(sat, tau, qd) if tally.reference is not None else None
    violation = sat.violation(ref, qd) if ref is not None else None
    tally.add(tau, tau_sat, tau_m, tau_m_sat, ref, violation)


def _log_saturation(robot: Robot, sat: Saturation, *arrays: NDArray[np.float64]) -> LogSaturation:
    """A :class:`LogSaturation` of read-only copies: tau, qd, tau_sat, tau_m, tau_m_sat, omega; with the turn."""
    tau, qd, tau_sat, tau_m, tau_m_sat, omega = (frozen(a) for a in arrays)
    turn = turn_tally(sat, robot.motors)
    add_turn(turn, sat, tau, qd, tau_sat, tau_m, tau_m_sat)
    return LogSaturation(
        joints=robot.joints,
        motors=robot.motors,
        tau_cmd=tau,
        qd=qd,
        tau_sat=tau_sat,
        motor_torque_cmd=tau_m,
        motor_torque_sat=tau_m_sat,
        motor_speed=omega,
        turn=turn.result(),
    )


def saturate_file(
    robot: Robot, path: str | os.PathLike[str], out: str | os.PathLike[str] | None = None, plot_rows: int = 0
) -> LogSummary:
    """Saturate a CSV or Parquet log of any length, batch by batch (``hound-id saturate``).

    Memory is bounded by a batch (:data:`hound_id.table_stream.BATCH_ROWS` rows of Parquet or
    :data:`hound_id.table_stream.CSV_BLOCK_BYTES` of CSV), not by the length of the log. The summary
    equals :meth:`LogSaturation.to_dict` of the whole log (bit for bit within one batch, to
    rounding beyond). Bad rows are named by their data row, counted over the whole file.

    Args:
        robot: The robot whose motors and transmissions apply.
        path: The log: columns ``tau_<joint>`` [N m] and ``qd_<joint>`` [rad/s] for every joint.
        out: If given, the log with ``tau_sat_<joint>`` [N m] columns added is written there (CSV or
            Parquet by suffix), through a temporary file renamed at the end: an error part-way
            leaves nothing behind.
        plot_rows: Keep up to this many evenly spaced rows in :attr:`LogSummary.sample` (0: none).

    Raises:
        TableError: The file cannot be read, a column is missing, a cell is not a finite number,
            a row has the wrong number of fields, or the table has no rows.
        OutputError: ``out`` cannot be written.
    """
    from pathlib import Path

    from hound_id.table_stream import TableBatches, TableRetype

    numeric = tuple(f"{p}_{j}" for p in ("tau", "qd") for j in robot.joints)
    copy_text = out is not None and Path(out).suffix.lower() == ".csv"  # CSV to CSV: cells copied as they are
    table = TableBatches(Path(path), numeric=numeric, text=copy_text, only=None if out is not None else numeric)
    sat = saturation_for(robot)
    while True:
        try:
            return _saturate_batches(robot, sat, table, out, plot_rows)
        except TableRetype:
            continue  # a column's type was widened: read the file again with it


def _saturate_batches(robot: Robot, sat: Saturation, table: Any, out: Any, plot_rows: int) -> LogSummary:
    from contextlib import nullcontext

    import pyarrow as pa

    from hound_id.errors import TableError
    from hound_id.table_stream import TableSink

    source = str(table.path)
    _joint_arrays({name: [] for name in table.names}, robot.joints, source)  # missing columns, before any work
    tally = _Tally(robot.joints, robot.motors)
    turn = turn_tally(sat, robot.motors)
    sample = _Sample(plot_rows) if plot_rows > 0 else None
    sat_names = [f"tau_sat_{j}" for j in robot.joints]
    with TableSink(out) if out is not None else nullcontext() as sink:
        for batch in table:
            tau, qd = _joint_arrays(batch, robot.joints, source, first_row=tally.rows)
            tau_sat, tau_m, tau_m_sat, omega = _saturate_rows(sat, tau, qd, BLOCK_ROWS)
            clipped = motor_clipped(tau_m, tau_m_sat)
            if sample is not None:
                sample.add(tau, qd, tau_sat, tau_m, tau_m_sat, omega)
            if sink is not None:
                for i, name in enumerate(sat_names):
                    column = pa.array(tau_sat[:, i], type=pa.float64())
                    k = batch.schema.get_field_index(name)
                    batch = batch.set_column(k, name, column) if k >= 0 else batch.append_column(name, column)
                sink.write(batch)
            tally.add(tau, tau_sat, clipped)
            add_turn(turn, sat, tau, qd, tau_sat, tau_m, tau_m_sat)
        if tally.rows == 0:
            raise TableError(f"{source}: the table has no rows", path=source)
    log = None
    if sample is not None:
        log = _log_saturation(robot, sat, *sample.arrays())
    return tally.summary(log, table.notes, sample.step if sample is not None else 1, turn.result())
