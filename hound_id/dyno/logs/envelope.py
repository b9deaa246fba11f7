"""The torque-speed envelope log (``mor --compare``): its channels, read with the same column and unit mapping."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hound_id.dyno.logs.columns import Array, convert_units, numeric_column, split_header
from hound_id.errors import DynoDataError, SpecError

if TYPE_CHECKING:  # pragma: no cover
    pass


#: Usable rows a comparison needs: ten speed bins' worth of samples (hound_id.dyno.envelope.walls.MIN_SAMPLES each).
#: Calibrated on test_logs::test_an_envelope_log_needs_envelope_min_rows.
ENVELOPE_MIN_ROWS = 400
#: Channels of a comparison log; the first two are required.
ENVELOPE_CHANNELS = ("torque", "velocity", "torque_cmd", "current", "temperature", "bus_voltage")


@dataclass(frozen=True)
class EnvelopeLog:
    """A torque-speed log on the motor side, SI."""

    torque: Array
    velocity: Array
    torque_cmd: Array | None = None
    current: Array | None = None
    temperature: Array | None = None
    """Winding temperature [degC]."""
    bus_voltage: Array | None = None
    source: str = "log"
    side: str = "motor"
    """``motor``, or how joint-side data was mapped (joint, transmission)."""
    dropped: int = 0
    """Rows dropped for a non-finite value in any channel used."""
    ignored: tuple[str, ...] = ()
    """Optional channels left out because they hold no finite value."""

    @property
    def n(self) -> int:
        return int(self.torque.size)


def load_envelope_log(
    path: str | Path,
    columns: Mapping[str, str] | None = None,
    units: Mapping[str, str] | None = None,
    robot: Any = None,
    joint: str | None = None,
) -> EnvelopeLog:
    """Read a CSV/Parquet torque-speed log (motor side, or joint side mapped through ``robot``'s
    transmission of ``joint``). Columns are named after :data:`ENVELOPE_CHANNELS` (``[unit]`` suffixes
    converted), or mapped with ``columns``; ``units`` overrides the suffixes.

    For a coupled joint the log needs ``<joint>_torque`` and ``<joint>_velocity`` for every joint
    of its transmission group; the result is the motor paired with ``joint``.
    """
    from hound_id.tables import read_table

    source = str(path)
    frame = read_table(path)
    names = [str(c) for c in frame.columns]
    frame = frame.set_axis(names, axis=1)
    by_base = {split_header(n)[0]: n for n in names}
    columns, units = dict(columns or {}), dict(units or {})
    for key in columns:
        if key not in ENVELOPE_CHANNELS and not key.endswith(("_torque", "_velocity")):
            raise DynoDataError(f"--columns: unknown channel '{key}'; channels are {', '.join(ENVELOPE_CHANNELS)}")
    table = _Table(frame, names, by_base, columns, units, source)
    torque, velocity, side = _motor_side(table, robot, joint)
    rest = _optional_channels(table, robot, joint)
    ignored = tuple(k for k, v in rest.items() if v is not None and not np.isfinite(v).any())
    rest = {k: (None if k in ignored else v) for k, v in rest.items()}  # an empty optional channel is no channel
    data = {"torque": torque, "velocity": velocity, **rest}
    good = np.ones(torque.size, dtype=bool)
    for values in data.values():
        if values is not None:
            good &= np.isfinite(values)
    if good.sum() < ENVELOPE_MIN_ROWS:
        gaps = {k: int((~np.isfinite(v)).sum()) for k, v in data.items() if v is not None}
        worst = max(gaps, key=lambda k: gaps[k])
        raise DynoDataError(
            f"{source}: {int(good.sum())} usable rows; an envelope comparison needs at least {ENVELOPE_MIN_ROWS} "
            f"(rows with NaN or inf are dropped; most in {worst}: {gaps[worst]})"
        )
    picked = {k: (v[good] if v is not None else None) for k, v in data.items()}
    return EnvelopeLog(source=source, side=side, dropped=int((~good).sum()), ignored=ignored, **picked)  # type: ignore[arg-type]


@dataclass(frozen=True)
class _Table:
    """A log's table, its columns by base name and the --columns and --units mappings: where channels come from."""

    frame: Any
    """The table (a pandas DataFrame), its columns named as text."""
    names: list[str]
    by_base: dict[str, str]
    columns: dict[str, str]
    units: dict[str, str]
    source: str

    def channel(self, name: str, required: bool) -> Array | None:
        """The channel in SI (its unit from ``--units`` or the header), None when absent and not ``required``."""
        columns, by_base, names, source = self.columns, self.by_base, self.names, self.source
        column = columns.get(name) or by_base.get(name)
        if column is not None and column not in self.frame.columns:
            column = by_base.get(column)  # a mapped name without its [unit] suffix
            if column is None:
                raise DynoDataError(f"{source}: --columns {name}={columns[name]}: no such column; columns are {names}")
        if column is None:
            if required:
                raise DynoDataError(
                    f"{source}: column '{name}' missing; a comparison log needs torque and velocity (optionally "
                    f"torque_cmd, current, temperature, bus_voltage); the file has {names}; map with --columns"
                )
            return None
        values, _, bad = numeric_column(self.frame, column, name, source)
        if bad is not None:
            count, cell, row = bad
            raise DynoDataError(f"{source}: column '{column}' row {row} is {cell!r}, expected a number")
        unit = self.units.get(name) or split_header(column)[1]
        kind = "torque" if name.endswith("torque") or name == "torque_cmd" else name
        kind = "velocity" if name.endswith("_velocity") else kind
        if unit:
            values, _ = convert_units(values, unit, "header or --units", kind, column, source)
        return np.asarray(values, dtype=float)


def _motor_side(table: _Table, robot: Any, joint: str | None) -> tuple[Array, Array, str]:
    """(motor torque [N m], motor speed [rad/s], side): as logged, or through the robot's joint transmission."""
    channel = table.channel
    if robot is None or joint is None:
        if (robot is None) != (joint is None):
            raise SpecError("--compare: --robot and --joint go together (joint-side logs)")
        torque, velocity = channel("torque", True), channel("velocity", True)
        assert torque is not None and velocity is not None
        return torque, velocity, "motor"
    tx = robot.transmission_of(joint)
    if not tx.coupled:
        tau_j, qd_j = channel("torque", True), channel("velocity", True)
        assert tau_j is not None and qd_j is not None
        torque, velocity = tau_j * float(tx.A[0, 0]), qd_j / float(tx.A[0, 0])
    else:
        taus = [channel(f"{j}_torque", True) for j in tx.joints]
        qds = [channel(f"{j}_velocity", True) for j in tx.joints]
        k = tx.joints.index(joint)
        tau_m = np.column_stack([np.asarray(t) for t in taus]) @ tx.A  # tau_m = A^T tau_j, row form
        omega_m = np.column_stack([np.asarray(q) for q in qds]) @ tx.A_inv.T
        torque, velocity = tau_m[:, k], omega_m[:, k]
    return torque, velocity, f"joint {joint} through the {tx.kind} transmission of {', '.join(tx.joints)}"


def _optional_channels(table: _Table, robot: Any, joint: str | None) -> dict[str, Array | None]:
    """The optional channels (None where absent), a joint-side torque command mapped to the motor or dropped."""
    rest = {name: table.channel(name, False) for name in ENVELOPE_CHANNELS[2:]}
    if robot is not None and joint is not None and rest["torque_cmd"] is not None:
        tx = robot.transmission_of(joint)
        if tx.coupled:  # a joint-side command cannot be mapped without the other joints' commands
            rest["torque_cmd"] = None
        else:
            rest["torque_cmd"] = rest["torque_cmd"] * float(tx.A[0, 0])
    return rest
