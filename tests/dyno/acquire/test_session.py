"""hound_id.dyno.acquire.run.record_rig: a rig file in, a log out, against a real simulated rig (Modbus, pty)."""

import pandas as pd
import pytest
import yaml

from hound_id.dyno.acquire.run import record_rig
from hound_id.dyno.acquire.simulated_rig import SimulatedRig
from hound_id.dyno.simulate.current import TestPlan
from hound_id.errors import DynoDataError

PLAN = TestPlan(speeds=(-10.0, 10.0), plateau_time=2.0, pause_time=2.0, hold_time=0.5)


def test_a_session_records_the_rig_and_the_sidecar_names_it(tmp_path):
    rig_file, out = tmp_path / "rig.yaml", tmp_path / "log.csv"
    seen = []
    with SimulatedRig(("linear",), seed=1, plan=PLAN) as sim:
        rig_file.write_text(yaml.safe_dump(sim.rig_mapping(), sort_keys=False))
        result = record_rig(rig_file, out, rate_hz=50.0, duration=0.6, flush_interval=0.1, on_progress=seen.append)
    assert result.status == "complete" and result.samples >= 20
    log = pd.read_csv(out)
    assert len(log) == result.samples and {"time", "current", "torque"} <= set(log.columns)
    assert result.metadata["rig"] == str(rig_file.resolve()) and result.metadata["rig_name"]
    assert "transport_errors" in result.metadata and seen


def test_bad_settings_are_refused_before_the_rig_is_read(tmp_path):
    with pytest.raises(DynoDataError, match="--rate"):
        record_rig(tmp_path / "no-such-rig.yaml", tmp_path / "log.csv", rate_hz=1e9, duration=1.0, flush_interval=0.25)
    assert not (tmp_path / "log.csv").exists()


def test_the_simulated_rig_verb_serves_and_writes_a_rig_file_the_recorder_reads(tmp_path):
    from hound_id.dyno.acquire.run import serve_simulated_rig

    rig_file = tmp_path / "sim.yaml"
    sim = serve_simulated_rig(("linear",), rig_file, port=0, serial=False, speedup=10.0)
    try:
        assert sim.running and rig_file.is_file() and sim.period > 0
        result = record_rig(rig_file, tmp_path / "log.csv", rate_hz=50.0, duration=0.4, flush_interval=0.1)
        assert result.samples >= 10
    finally:
        sim.stop()
    for kwargs, match in (({"port": 70000}, "--port"), ({"seed": -1}, "--seed"), ({"duration": 0.0}, "--duration")):
        with pytest.raises(DynoDataError, match=match):
            serve_simulated_rig(("linear",), tmp_path / "other.yaml", **kwargs)
    assert not (tmp_path / "other.yaml").exists()
