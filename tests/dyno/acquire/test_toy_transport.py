"""A new transport is one file and one registry call: the toy ``udp_query`` transport (tests/dyno/acquire/
udp_query.py) against a real UDP peer on 127.0.0.1, through the recorder ``hound-id dyno record`` runs and through
the command itself; its bad settings are one-line rig-file errors."""

from __future__ import annotations

import copy
import csv
import dataclasses
import importlib
import json
import math
import socket
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
import yaml

from hound_id.dyno.acquire.rig import DEVICE_TYPES, register
from hound_id.dyno.acquire.rig_file import load_rig, rig_from_mapping, rig_to_mapping
from hound_id.dyno.acquire.run import record_rig
from hound_id.dyno.acquire.transport import transports_for
from hound_id.errors import SpecError
from tests.conftest import ROOT

TOY = "tests.dyno.acquire.udp_query"


@pytest.fixture
def toy():
    """The toy transport's file imported (its last line registers udp_query); unregistered afterwards."""
    module = importlib.import_module(TOY)
    assert "udp_query" in DEVICE_TYPES
    try:
        yield module
    finally:
        DEVICE_TYPES.pop("udp_query", None)
        sys.modules.pop(TOY, None)


def served_row(k: int) -> list[str]:
    """The k-th answer's numbers, as the peer writes them: current [A], torque [mN*m], speed [rpm], a temperature
    [degF]."""
    return [repr(round(2.0 * math.sin(k / 7.0), 6)), repr(150.0 + k), repr(60.0 + 0.5 * k), repr(68.0 + 0.1 * k)]


class Peer:
    """A udp_query device on 127.0.0.1: answers ``READ n`` with ``n`` and the next row; keeps every row it sent."""

    def __init__(self) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        self.port = self.sock.getsockname()[1]
        self.served: list[list[str]] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        while not self.stop.is_set():
            try:
                data, sender = self.sock.recvfrom(4096)
            except TimeoutError:
                continue
            words = data.decode().split()
            if len(words) != 2 or words[0] != "READ":
                continue
            row = served_row(len(self.served))
            self.served.append(row)
            self.sock.sendto(" ".join([words[1], *row]).encode(), sender)

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=5)
        self.sock.close()


@pytest.fixture
def peer():
    p = Peer()
    try:
        yield p
    finally:
        p.close()


def toy_rig(port: int) -> dict[str, Any]:
    return {
        "schema": "hound-id/rig/1",
        "name": "toy",
        "devices": {"probe": {"type": "udp_query", "host": "127.0.0.1", "port": port, "timeout": "1 s"}},
        "channels": [
            {"column": "current", "device": "probe", "index": 0, "unit": "A"},
            {"column": "torque", "device": "probe", "index": 1, "unit": "mN*m"},
            {"column": "velocity", "device": "probe", "index": 2, "unit": "rpm"},
            {"column": "probe_temp", "device": "probe", "index": 3, "unit": "degF"},
        ],
    }


def write_rig(path: Path, mapping: dict[str, Any]) -> Path:
    path.write_text(yaml.safe_dump(mapping, sort_keys=False))
    return path


def check_log(out: Path, rig_path: Path, served: list[list[str]]) -> None:
    """The log holds exactly the rows the peer served, each number converted to SI by its channel."""
    rig = load_rig(rig_path)
    with out.open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["time", *rig.columns]
    assert len(rows) == len(served) > 10
    for row, sent in zip(rows, served, strict=True):
        for ch in rig.channels:
            assert float(row[ch.column]) == ch.raw_to_si(float(sent[ch.address["index"]])), (ch.column, row, sent)


def test_the_toy_rig_loads_and_writes_back(toy, tmp_path):
    rig = load_rig(write_rig(tmp_path / "toy.yaml", toy_rig(9000)))
    probe = rig.devices["probe"]
    assert probe == toy.UdpQueryDevice(name="probe", host="127.0.0.1", port=9000, query="READ", timeout=1.0)
    assert rig.channel("velocity").address == {"index": 2}
    assert rig.channel("velocity").raw_to_si(60.0) == pytest.approx(2 * math.pi)
    assert rig.channel("probe_temp").si_unit == "degC"
    assert rig_from_mapping(rig_to_mapping(rig)) == rig
    assert rig_to_mapping(rig)["channels"][0] == {
        "column": "current",
        "device": "probe",
        "index": 0,
        "scale": 1.0,
        "offset": 0.0,
        "unit": "A",
    }


def test_the_recorder_of_dyno_record_logs_what_the_peer_served(toy, peer, tmp_path):
    rig_path = write_rig(tmp_path / "toy.yaml", toy_rig(peer.port))
    out = tmp_path / "run.csv"
    result = record_rig(rig_path, out, rate_hz=100.0, duration=0.6, flush_interval=0.1)
    assert (result.status, result.failed, result.gaps) == ("complete", 0, ())
    assert result.metadata["transport_errors"] == {f"udp 127.0.0.1:{peer.port}": 0}
    check_log(out, rig_path, peer.served)


def test_the_command_records_through_the_toy_transport(toy, peer, tmp_path):
    # The command line has no plugin option: the process imports the toy's file, which registers it, then runs
    # the real `hound-id dyno record`.
    rig_path = write_rig(tmp_path / "toy.yaml", toy_rig(peer.port))
    out = tmp_path / "cli.csv"
    code = f"import {TOY}; from hound_id.entry import run; run()"
    args = ["dyno", "record", "--rig", str(rig_path), "--out", str(out), "--duration", "0.6", "--rate", "50", "--json"]
    proc = subprocess.run(
        [sys.executable, "-c", code, *args], cwd=ROOT, capture_output=True, text=True, timeout=120, check=False
    )
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert (summary["status"], summary["failed_ticks"]) == ("complete", 0)
    assert summary["transport_errors"] == {f"udp 127.0.0.1:{peer.port}": 0}
    check_log(out, rig_path, peer.served)


def test_transports_come_class_by_class_in_registry_order_then_file_order(toy):
    mapping = toy_rig(9000)
    mapping["devices"].update(
        {
            "console": {"type": "serial_lines", "port": "/dev/null", "baud": 9600, "format": {"fields": ["i"]}},
            "drive": {"type": "modbus_rtu", "port": "/dev/ttyUSB0", "baud": 115200, "unit": 2},
            "transducer": {"type": "modbus_tcp", "host": "127.0.0.1", "port": 5020},
        }
    )
    mapping["channels"] += [
        {"column": "console_i", "device": "console", "field": "i"},
        {"column": "position", "device": "transducer", "register": 0},
        {"column": "temperature", "device": "drive", "register": 0},
    ]
    labels = [t.label for t in transports_for(rig_from_mapping(mapping))]
    assert labels == ["Modbus /dev/ttyUSB0", "Modbus 127.0.0.1:5020", "serial /dev/null", "udp 127.0.0.1:9000"]


def _edit(path: str, value: Any):
    def edit(data: dict[str, Any]) -> None:
        *parents, last = path.split(".")
        node: Any = data
        for part in parents:
            node = node[int(part)] if isinstance(node, list) else node[part]
        if value is None:
            del node[last]
        else:
            node[last] = value

    return edit


BAD = [
    (
        "query with a space",
        _edit("devices.probe.query", "RE AD"),
        r"devices\.probe: field 'query': found 'RE AD', expected 1-32 printable ASCII characters without spaces, "
        r"such as READ; fix the value$",
    ),
    (
        "port out of range",
        _edit("devices.probe.port", 70000),
        r"devices\.probe: field 'port': found 70000, expected an integer 1-65535; fix the value$",
    ),
    (
        "misspelt key",
        _edit("devices.probe.qeury", "READ"),
        r"devices\.probe: field 'qeury': unknown key 'qeury'; did you mean 'query'\? expected one of type, host, "
        r"port, query, timeout for a udp_query device; rename or remove it$",
    ),
    (
        "missing host",
        _edit("devices.probe.host", None),
        r"devices\.probe: field 'host': missing; a udp_query device needs host, port$",
    ),
    (
        "index out of range",
        _edit("channels.0.index", 99),
        r"channels\[0\] \('current'\): field 'index': found 99, expected an integer 0-63; fix the value$",
    ),
    (
        "missing index",
        _edit("channels.1.index", None),
        r"channels\[1\] \('torque'\): field 'index': missing; a channel of udp_query device 'probe' needs index$",
    ),
    (
        "register on a toy channel",
        _edit("channels.1.register", 3),
        r"channels\[1\] \('torque'\): field 'register': does not apply: device 'probe' is udp_query; use 'index' "
        r"and index, scale, offset, unit$",
    ),
]


@pytest.mark.parametrize("edit, match", [(e, m) for _, e, m in BAD], ids=[case[0] for case in BAD])
def test_a_bad_toy_setting_is_one_line_naming_file_and_field(toy, tmp_path, edit, match):
    data = copy.deepcopy(toy_rig(9000))
    edit(data)
    path = write_rig(tmp_path / "bad.yaml", data)
    with pytest.raises(SpecError, match=match) as info:
        load_rig(path)
    assert str(info.value).startswith(f"{path}: ")
    assert "\n" not in str(info.value)


def test_register_refuses_a_declaration_that_does_not_fit(toy):
    with pytest.raises(SpecError, match="device type 'udp_query' is already registered"):
        register(toy.UDP_QUERY)
    no_query = dataclasses.replace(toy.UDP_QUERY, name="udp_other", settings=toy.UDP_QUERY.settings[:2])
    with pytest.raises(SpecError, match="must be a frozen dataclass with the class variable type = 'udp_other'"):
        register(no_query)
    renamed = dataclasses.replace(toy.UDP_QUERY, settings=toy.UDP_QUERY.settings[:2])
    with pytest.raises(SpecError, match=r"its settings \(host, port\) must be the fields of UdpQueryDevice"):
        register(renamed, replace=True)
    clash = dataclasses.replace(toy.UDP_QUERY, channels=dataclasses.replace(toy.UDP_QUERY.channels, keys=("unit",)))
    with pytest.raises(SpecError, match=r"its channel keys \(unit\) must be one or more distinct keys other than"):
        register(clash, replace=True)
    assert DEVICE_TYPES["udp_query"] is toy.UDP_QUERY
