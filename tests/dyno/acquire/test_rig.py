"""Rig files: validation with located messages, register decoding, block merging, serial lines."""

from __future__ import annotations

import copy
import math
import subprocess
import sys
from typing import Any

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from hound_id.dyno.acquire.rig import (
    DTYPES,
    MAX_BLOCK,
    MAX_GAP,
    Channel,
    LineFormat,
    ModbusRtuDevice,
    ModbusTcpDevice,
    ReadBlock,
    SerialLinesDevice,
    decode,
    decode_block,
    encode,
    merge_reads,
    parse_line,
)
from hound_id.dyno.acquire.rig_file import load_rig, rig_from_mapping, rig_to_mapping
from hound_id.errors import DynoDataError, SpecError

EXAMPLE = """\
schema: hound-id/rig/1
name: bench-1
devices:
  transducer: {type: modbus_tcp, host: 127.0.0.1, port: 5020, unit: 1, timeout: 0.2}
  drive: {type: modbus_rtu, port: /dev/ttyUSB0, baud: 115200, parity: N, stopbits: 1, bytesize: 8, unit: 2,
          timeout: 0.05}
  console: {type: serial_lines, port: /dev/ttyACM0, baud: 115200,
            format: {delimiter: ",", fields: [current, velocity, temperature]}}
  console2: {type: serial_lines, port: /dev/ttyACM1, baud: 115200,
             format: {regex: "I=(?P<current>[-0-9.eE+]+) W=(?P<velocity>[-0-9.eE+]+)"}}
channels:
  - {column: torque, device: transducer, register: 0, kind: input, dtype: float32, word_order: big, byte_order: big,
     scale: 1.0, offset: 0.0, unit: "N*m"}
  - {column: position, device: drive, register: 4, kind: holding, dtype: int32, scale: 0.0001, unit: rad}
  - {column: temperature, device: drive, register: 6, kind: input, dtype: int16, scale: 0.1, unit: degC}
  - {column: current, device: console, field: current, unit: A}
  - {column: coil_temp_raw, device: drive, register: 7, dtype: uint16}
"""

ORDERS = ("big", "little")


def example() -> dict[str, Any]:
    return yaml.safe_load(EXAMPLE)


def modbus(dtype: str = "int16", **kw: Any) -> Channel:
    kw.setdefault("register", 0)
    return Channel(column=kw.pop("column", "torque"), device="d", dtype=dtype, **kw)


# --- loading ---------------------------------------------------------------------------------------------------


def test_example_loads(tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text(EXAMPLE)
    rig = load_rig(path)
    assert rig.name == "bench-1"
    assert rig.source == str(path)
    assert rig.devices["transducer"] == ModbusTcpDevice(name="transducer", host="127.0.0.1", port=5020)
    assert rig.devices["drive"] == ModbusRtuDevice(name="drive", port="/dev/ttyUSB0", baud=115200, unit=2, timeout=0.05)
    console = rig.devices["console"]
    assert isinstance(console, SerialLinesDevice)
    assert console.format == LineFormat(delimiter=",", fields=("current", "velocity", "temperature"))
    assert rig.devices["console2"].format.names == ("current", "velocity")  # type: ignore[union-attr]
    assert rig.columns == ("current", "torque", "position", "temperature", "coil_temp_raw")
    torque = rig.channel("torque")
    assert (torque.kind, torque.dtype, torque.count, torque.si_factor, torque.si_offset) == (
        "input",
        "float32",
        2,
        1,
        0,
    )
    raw = rig.channel("coil_temp_raw")
    assert (raw.kind, raw.dtype, raw.count, raw.unit, raw.si_factor) == ("holding", "uint16", 1, "dimensionless", 1.0)
    current = rig.channel("current")
    assert (current.field, current.register, current.count) == ("current", None, 0)
    assert rig.channel("position").si_factor == pytest.approx(1e-4)


def test_round_trip_through_yaml(tmp_path):
    rig = rig_from_mapping(example(), "a.yaml")
    text = yaml.safe_dump(rig_to_mapping(rig), sort_keys=False)
    path = tmp_path / "again.yaml"
    path.write_text(text)
    again = load_rig(path)
    assert again == rig
    assert again.reads() == rig.reads()
    assert rig_to_mapping(again) == rig_to_mapping(rig)


def test_defaults_and_timeout_with_units():
    data = example()
    data["devices"]["transducer"] = {"type": "modbus_tcp", "host": "h", "port": 502, "timeout": "50 ms"}
    data["channels"][0] = {"column": "torque", "device": "transducer", "register": 3}
    rig = rig_from_mapping(data)
    assert rig.devices["transducer"].timeout == pytest.approx(0.05)
    assert rig.devices["transducer"].unit == 1  # type: ignore[union-attr]
    torque = rig.channel("torque")
    assert (torque.kind, torque.dtype, torque.word_order, torque.byte_order) == ("holding", "int16", "big", "big")
    assert (torque.scale, torque.offset, torque.unit) == (1.0, 0.0, "N*m")


def test_devices_are_read_only():
    rig = rig_from_mapping(example())
    with pytest.raises(TypeError):
        rig.devices["x"] = rig.devices["drive"]  # type: ignore[index]


def test_import_does_not_load_protocol_libraries():
    code = "import sys, hound_id.dyno.acquire.rig; print(any(m in sys.modules for m in ('pymodbus', 'serial', 'pint')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def _set(path: str, value: Any):
    """An edit of the example: set the value at a dotted path ('channels.1.unit'); value DELETE removes it."""

    def edit(data: dict[str, Any]) -> None:
        *parents, last = path.split(".")
        node: Any = data
        for part in parents:
            node = node[int(part)] if isinstance(node, list) else node[part]
        key: Any = int(last) if isinstance(node, list) else last
        if value is DELETE:
            del node[key]
        else:
            node[key] = value

    return edit


DELETE = object()

INVALID = [
    ("unknown top key", _set("chanels", []), r"field 'chanels': unknown key 'chanels'; did you mean 'channels'\?"),
    (
        "unknown device key",
        _set("devices.transducer.hots", "x"),
        r"devices\.transducer: field 'hots': unknown key 'hots'; did you mean 'host'\?",
    ),
    (
        "unknown channel key",
        _set("channels.1.scael", 2),
        r"channels\[1\]: field 'scael': unknown key 'scael'; did you mean 'scale'\?",
    ),
    (
        "unknown format key",
        _set("devices.console.format.delimeter", ";"),
        r"devices\.console\.format: field 'delimeter': unknown key .*did you mean 'delimiter'\?",
    ),
    (
        "missing device",
        _set("channels.1.device", "drvie"),
        r"channels\[1\] \('position'\): field 'device': found 'drvie', which is not a device.*did you mean 'drive'\?",
    ),
    (
        "bad device type",
        _set("devices.drive.type", "modbus_rtv"),
        r"devices\.drive: field 'type': found 'modbus_rtv', did you mean 'modbus_rtu'\?",
    ),
    (
        "missing device key",
        _set("devices.transducer.host", DELETE),
        r"devices\.transducer: field 'host': missing; a modbus_tcp device needs host, port",
    ),
    (
        "duplicate column",
        _set("channels.4.column", "position"),
        r"channels\[4\] \('position'\): field 'column': found 'position', already read by channels\[1\]",
    ),
    (
        "time as channel",
        _set("channels.4.column", "time"),
        r"channels\[4\] \('time'\): field 'column': found 'time'.*remove",
    ),
    ("bad column name", _set("channels.4.column", "coil temp"), r"field 'column': found 'coil temp', expected"),
    (
        "Hz velocity",
        _set("channels.4", {"column": "velocity", "device": "drive", "register": 9, "unit": "Hz"}),
        r"channels\[4\] \('velocity'\): field 'unit': found 'Hz': Hz is ambiguous.*rpm",
    ),
    (
        "plain 1/s velocity",
        _set("channels.4", {"column": "velocity", "device": "drive", "register": 9, "unit": "1/s"}),
        r"field 'unit': found '1/s' .*expected a unit of velocity convertible to rad/s",
    ),
    (
        "wrong dimension",
        _set("channels.0.unit", "N"),
        r"channels\[0\] \('torque'\): field 'unit': found 'N' \(dimension .*\), expected a unit of torque",
    ),
    ("position in metres", _set("channels.1.unit", "mm"), r"field 'unit': found 'mm'.*expected a unit of position"),
    ("not a unit", _set("channels.1.unit", "furlongs_per_fortnite"), r"field 'unit': found 'furlongs_per_fortnite'"),
    (
        "bad port",
        _set("devices.transducer.port", 70000),
        r"devices\.transducer: field 'port': found 70000, expected an integer 1-65535",
    ),
    ("zero baud", _set("devices.drive.baud", 0), r"devices\.drive: field 'baud': found 0, expected an integer"),
    ("bad parity", _set("devices.drive.parity", "X"), r"field 'parity': found 'X', expected N, E or O"),
    (
        "missing field for serial channel",
        _set("channels.3.field", DELETE),
        r"channels\[3\] \('current'\): field 'field': missing; .*\(current, velocity, temperature\)",
    ),
    (
        "unknown serial field",
        _set("channels.3.field", "curent"),
        r"field 'field': found 'curent', which is not a field of device 'console'; did you mean 'current'\?",
    ),
    (
        "register on serial channel",
        _set("channels.3.register", 3),
        r"channels\[3\] \('current'\): field 'register': does not apply: device 'console' is serial_lines",
    ),
    (
        "field on modbus channel",
        _set("channels.1.field", "x"),
        r"field 'field': does not apply: device 'drive' is modbus_rtu; use 'register'",
    ),
    (
        "no torque channel",
        _set("channels.0.column", "torqe"),
        r"field 'channels': no 'torque' channel \(is 'torqe' meant to be 'torque'\?\)",
    ),
    ("no current channel", _set("channels.3", DELETE), r"field 'channels': no 'current' channel"),
    (
        "register out of range",
        _set("channels.1.register", 70000),
        r"channels\[1\] \('position'\): field 'register': found 70000, expected an integer 0-65535",
    ),
    (
        "32-bit past the last register",
        _set("channels.1.register", 65535),
        r"field 'register': found 65535, but int32 needs 2 registers",
    ),
    ("missing register", _set("channels.1.register", DELETE), r"field 'register': missing"),
    ("bad dtype", _set("channels.1.dtype", "int64"), r"field 'dtype': found 'int64', did you mean 'int16'\?"),
    ("bad kind", _set("channels.1.kind", "coil"), r"field 'kind': found 'coil'"),
    ("zero scale", _set("channels.1.scale", 0), r"field 'scale': found 0, expected a finite non-zero number"),
    ("bad schema", _set("schema", "hound-id/rig/2"), r"field 'schema': found 'hound-id/rig/2', expected"),
    (
        "regex and fields",
        _set("devices.console2.format.fields", ["a"]),
        r"devices\.console2\.format: field 'regex': found both",
    ),
    ("regex without groups", _set("devices.console2.format.regex", "I=[0-9]+"), r"without named groups"),
    ("bad timeout", _set("devices.drive.timeout", -1), r"devices\.drive: field 'timeout': found -1"),
]


@pytest.mark.parametrize("edit, match", [(e, m) for _, e, m in INVALID], ids=[case[0] for case in INVALID])
def test_invalid_rig_files(tmp_path, edit, match):
    data = copy.deepcopy(example())
    edit(data)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    with pytest.raises(SpecError, match=match) as info:
        load_rig(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ")
    assert "\n" not in message


def test_duplicate_yaml_key_and_missing_file(tmp_path):
    path = tmp_path / "dup.yaml"
    path.write_text(EXAMPLE.replace("name: bench-1\n", "name: bench-1\nname: bench-2\n"))
    with pytest.raises(SpecError, match="key 'name' appears twice"):
        load_rig(path)
    with pytest.raises(SpecError, match="file not found"):
        load_rig(tmp_path / "none.yaml")


def test_not_a_mapping():
    with pytest.raises(SpecError, match=r"r\.yaml: found list"):
        rig_from_mapping([1, 2], "r.yaml")


# --- decoding --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "dtype, word, byte, value, registers",
    [
        ("float32", "big", "big", 1.0, [0x3F80, 0x0000]),
        ("float32", "little", "big", 1.0, [0x0000, 0x3F80]),
        ("float32", "big", "little", 1.0, [0x803F, 0x0000]),
        ("float32", "little", "little", 1.0, [0x0000, 0x803F]),
        ("float32", "big", "big", -2.5, [0xC020, 0x0000]),
        ("int16", "big", "big", -1, [0xFFFF]),
        ("int16", "big", "little", 256, [0x0001]),
        ("uint16", "big", "big", 65535, [0xFFFF]),
        ("int32", "big", "big", -2, [0xFFFF, 0xFFFE]),
        ("int32", "little", "big", 0x12345678, [0x5678, 0x1234]),
        ("int32", "big", "little", 0x12345678, [0x3412, 0x7856]),
        ("uint32", "big", "big", 0x12345678, [0x1234, 0x5678]),
        ("uint32", "little", "little", 0x12345678, [0x7856, 0x3412]),
    ],
)
def test_known_byte_patterns(dtype, word, byte, value, registers):
    ch = modbus(dtype, word_order=word, byte_order=byte)
    assert decode(registers, ch) == value
    assert encode(value, ch) == registers


def _raw_values(dtype: str) -> st.SearchStrategy[float]:
    if dtype == "float32":
        # -0.0 decodes as +0.0 (the offset is added), so it is left out.
        return st.floats(width=32, allow_nan=False, allow_infinity=False).filter(lambda v: math.copysign(1.0, v) > 0)
    bits = 16 if "16" in dtype else 32
    lo, hi = (0, 2**bits - 1) if dtype.startswith("u") else (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1)
    return st.integers(lo, hi).map(float)


@pytest.mark.parametrize("word", ORDERS)
@pytest.mark.parametrize("byte", ORDERS)
@pytest.mark.parametrize("dtype", sorted(DTYPES))
@settings(max_examples=60, deadline=None)
@given(data=st.data())
def test_encode_decode_round_trip(dtype, word, byte, data):
    ch = modbus(dtype, word_order=word, byte_order=byte)
    value = data.draw(_raw_values(dtype))
    registers = encode(value, ch)
    assert len(registers) == ch.count
    assert all(0 <= r <= 0xFFFF for r in registers)
    assert decode(registers, ch) == value
    assert encode(decode(registers, ch), ch) == registers


@pytest.mark.parametrize("dtype", sorted(DTYPES))
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_every_register_pattern_decodes_and_re_encodes(dtype, data):
    # Integers survive scaling; float32 is compared unscaled (scaling would round subnormals).
    scaling = {"scale": 0.5, "offset": 3.0} if dtype != "float32" else {}
    ch = modbus(dtype, word_order="little", byte_order="little", **scaling)
    registers = data.draw(st.lists(st.integers(0, 0xFFFF), min_size=ch.count, max_size=ch.count))
    value = decode(registers, ch)
    if math.isfinite(value) and value != 0.0:
        assert encode(value, ch) == registers


@pytest.mark.parametrize("dtype", ["int16", "uint16", "int32", "uint32"])
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_scaled_integers_round_trip(dtype, data):
    ch = modbus(dtype, column="velocity", scale=0.1, offset=-5.0, unit="rpm")
    raw = data.draw(_raw_values(dtype))
    value = raw * ch.si_factor + ch.si_offset
    assert decode(encode(value, ch), ch) == pytest.approx(value, rel=1e-12, abs=1e-9)


@pytest.mark.parametrize(
    "column, unit, scale, offset, raw, expected",
    [
        ("velocity", "rpm", 1.0, 0.0, 60, 2 * math.pi),
        ("velocity", "deg/s", 0.5, 0.0, 720, 2 * math.pi),
        ("torque", "mN*m", 1.0, 0.0, 1500, 1.5),
        ("torque", "mNm", 10.0, 0.0, 150, 1.5),
        ("temperature", "degF", 1.0, 0.0, 212, 100.0),
        ("temperature", "degF", 0.1, 32.0, 0, 0.0),
        ("temperature", "degF", 0.1, 0.0, 320, 0.0),
        ("temperature", "K", 1.0, 0.0, 300, 26.85),
        ("temperature", "degC", 0.1, 0.0, 251, 25.1),
        ("position", "deg", 1.0, 0.0, 180, math.pi),
        ("position", "turn", 0.001, 0.0, 500, math.pi),
        ("current", "mA", 1.0, -100.0, 1100, 1.0),
        ("bus_voltage", "V", 0.01, 0.0, 4800, 48.0),
        ("coil_temp_raw", "degF", 1.0, 0.0, 32, 0.0),
        ("strain", "%", 1.0, 0.0, 50, 0.5),
    ],
)
def test_unit_conversion(column, unit, scale, offset, raw, expected):
    ch = modbus("int16", column=column, unit=unit, scale=scale, offset=offset)
    assert ch.raw_to_si(raw) == pytest.approx(expected, abs=1e-9)
    assert decode(encode(expected, ch), ch) == pytest.approx(expected, abs=abs(ch.si_factor))
    assert ch.si_to_raw(expected) == pytest.approx(raw, abs=1e-9)


def test_encode_out_of_range():
    with pytest.raises(DynoDataError, match=r"channel 'torque': value 3276.8 N\*m is raw 32768.*int16 range"):
        encode(3276.8, modbus("int16", scale=0.1))
    assert encode(3276.74, modbus("int16", scale=0.1)) == [0x7FFF]
    with pytest.raises(DynoDataError, match="uint16 range"):
        encode(-1.0, modbus("uint16"))
    with pytest.raises(DynoDataError, match="float32 range"):
        encode(1e39, modbus("float32"))
    with pytest.raises(DynoDataError, match="float32 range"):
        encode(math.nan, modbus("float32"))


def test_decode_rejects_bad_input():
    with pytest.raises(DynoDataError, match="found 1 registers, expected 2 for float32"):
        decode([0], modbus("float32"))
    with pytest.raises(DynoDataError, match="found register value 70000, expected an integer 0-65535"):
        decode([70000], modbus("int16"))
    serial = Channel(column="current", device="c", field="current")
    with pytest.raises(DynoDataError, match="reads serial field 'current', not Modbus registers"):
        decode([0], serial)
    with pytest.raises(DynoDataError, match="not Modbus registers"):
        encode(0.0, serial)


# --- read blocks -----------------------------------------------------------------------------------------------


def ch(column: str, register: int, dtype: str = "int16", device: str = "d", kind: str = "holding") -> Channel:
    return Channel(column=column, device=device, register=register, dtype=dtype, kind=kind, unit="dimensionless")


def spans(blocks: list[ReadBlock]) -> list[tuple[str, str, int, int]]:
    return [(b.device, b.kind, b.start, b.count) for b in blocks]


def test_gap_of_max_gap_merges_one_more_splits():
    a, b, c = ch("a", 0, "int32"), ch("b", 2 + MAX_GAP), ch("c", 2 + MAX_GAP + 1 + MAX_GAP + 1)
    blocks = merge_reads([c, a, b])
    assert spans(blocks) == [("d", "holding", 0, 2 + MAX_GAP + 1), ("d", "holding", 2 + MAX_GAP + 1 + MAX_GAP + 1, 1)]
    assert blocks[0].channels == (a, b)
    assert blocks[0].offsets == (0, 2 + MAX_GAP)


def test_block_limit():
    channels = [ch(f"c{i}", i) for i in range(MAX_BLOCK + 5)]
    blocks = merge_reads(channels)
    assert spans(blocks) == [("d", "holding", 0, MAX_BLOCK), ("d", "holding", MAX_BLOCK, 5)]
    # A 32-bit value that would end past the limit starts a new block instead of being split.
    blocks = merge_reads([ch("a", 0), ch("b", MAX_BLOCK - 1, "float32")])
    assert spans(blocks) == [("d", "holding", 0, 1), ("d", "holding", MAX_BLOCK - 1, 2)]
    assert all(b.count <= MAX_BLOCK for b in blocks)


def test_kinds_and_devices_never_merge():
    channels = [ch("a", 0), ch("b", 1, kind="input"), ch("c", 2, device="e"), ch("d", 3), ch("f", 1, device="e")]
    blocks = merge_reads(channels, device_order=("e", "d"))
    assert spans(blocks) == [("e", "holding", 1, 2), ("d", "holding", 0, 4), ("d", "input", 1, 1)]
    assert [c.column for c in blocks[1].channels] == ["a", "d"]
    assert blocks[1].offsets == (0, 3)


def test_overlapping_channels_share_registers():
    blocks = merge_reads([ch("lo", 10, "uint16"), ch("both", 10, "uint32")])
    assert spans(blocks) == [("d", "holding", 10, 2)]
    assert decode_block(blocks[0], [0x0001, 0x0002]) == {"both": 0x00010002, "lo": 1}


def test_example_reads_and_decode_block():
    rig = rig_from_mapping(example())
    blocks = rig.reads()
    assert spans(blocks) == [("transducer", "input", 0, 2), ("drive", "holding", 4, 4), ("drive", "input", 6, 1)]
    assert [c.column for c in blocks[1].channels] == ["position", "coil_temp_raw"]
    assert blocks[1].offsets == (0, 3)
    position = rig.channel("position")
    regs = encode(1.2345, position) + [0] + encode(4242, rig.channel("coil_temp_raw"))
    values = decode_block(blocks[1], regs)
    assert values == {"position": pytest.approx(1.2345), "coil_temp_raw": 4242.0}
    assert decode_block(blocks[0], [0x3F80, 0]) == {"torque": 1.0}
    with pytest.raises(DynoDataError, match=r"device 'drive' holding registers 4-7: found 3 registers, expected 4"):
        decode_block(blocks[1], [0, 0, 0])


# --- serial lines ----------------------------------------------------------------------------------------------


def test_parse_delimited_line():
    fmt = LineFormat(delimiter=",", fields=("current", "velocity", "temperature"))
    assert parse_line("1.5, -20e1 ,31\r\n", fmt) == {"current": 1.5, "velocity": -200.0, "temperature": 31.0}


def test_parse_regex_line():
    fmt = LineFormat(regex=r"I=(?P<current>[-0-9.eE+]+) W=(?P<velocity>[-0-9.eE+]+)")
    assert parse_line("t=12 I=-3.25 W=1e2\n", fmt) == {"current": -3.25, "velocity": 100.0}


def test_parse_malformed_lines():
    fmt = LineFormat(delimiter=",", fields=("current", "velocity"))
    with pytest.raises(DynoDataError, match=r"serial line '1.0': found 1 fields, expected 2 \(current, velocity\)"):
        parse_line("1.0\n", fmt)
    with pytest.raises(DynoDataError, match=r"field 'velocity' is 'abc', expected a number"):
        parse_line("1.0,abc", fmt)
    long = "x" * 200
    with pytest.raises(DynoDataError) as info:
        parse_line(long, fmt)
    assert repr("x" * 77 + "...") in str(info.value)
    assert "x" * 78 not in str(info.value)
    regex = LineFormat(regex=r"I=(?P<current>\S+)")
    with pytest.raises(DynoDataError, match=r"serial line 'boot ok': does not match the format regex"):
        parse_line("boot ok", regex)
    with pytest.raises(DynoDataError, match=r"field 'current' is 'x', expected a number"):
        parse_line("I=x", regex)


def test_serial_channel_applies_scale_and_unit():
    rig = rig_from_mapping(example())
    console = rig.devices["console"]
    assert isinstance(console, SerialLinesDevice)
    fields = parse_line("2.0,60,70", console.format)
    current = rig.channel("current")
    assert current.raw_to_si(fields[current.field or ""]) == 2.0
    rpm = Channel(column="velocity", device="console", field="velocity", unit="rpm")
    assert rpm.raw_to_si(fields["velocity"]) == pytest.approx(2 * math.pi)
