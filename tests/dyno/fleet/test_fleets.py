"""Every planted fault flagged with its reading and no healthy actuator, on fleets from two independent simulators.

The fits run in this process through the engine's own worker function (:func:`fit_log`); the Dask path that
calls it is tested in ``test_engine.py`` and ``tests/cli/test_fleet_cli.py``.
"""

from __future__ import annotations

import json
from functools import lru_cache

import numpy as np
import pytest

from hound_id.dyno.current.run import FitCurrentOptions
from hound_id.dyno.fleet.analyse import analyse
from hound_id.dyno.fleet.engine import fit_log
from hound_id.dyno.simulate.fleet import FAULTS, FLEET_COLUMNS, FLEET_MODEL, simulate_fleet
from hound_id.samples import samples_dir
from tests.dyno.acquire.polledrig import COLUMNS, Rig, Truth, run, write


def fit_all(paths, options):
    return [fit_log(p.stem, str(p), p.read_bytes(), options) for p in paths]


def assert_found(result, planted):
    """Each planted fault flagged with its metric (and only its allowed consequences); nothing else flagged."""
    by_actuator = {}
    for f in result.flags:
        by_actuator.setdefault(f.actuator, set()).add(f.metric)
    assert set(by_actuator) == set(planted), (by_actuator, planted)
    for name, fault in planted.items():
        need, may = set(FAULTS[fault].flags), set(FAULTS[fault].may_flag)
        assert need <= by_actuator[name] <= need | may, (name, fault, by_actuator[name])


def test_the_sample_fleet_flags_its_four_planted_faults_and_nothing_else():
    folder = samples_dir() / "fleet"
    truth = json.loads((folder / "fleet_truth.json").read_text())
    fits = fit_all(sorted(folder.glob("*.csv")), FitCurrentOptions(model=truth["model"]))
    result = analyse(fits)
    planted = {name: entry["fault"] for name, entry in truth["faults"].items()}
    assert_found(result, planted)
    reading = {(f.actuator, f.metric): f.reading for f in result.flags}
    assert reading["FR_thigh", "kt"].startswith("Kt low: a weakened (demagnetised) magnet or a wrong winding")
    assert reading["RL_hip", "coulomb"].startswith("friction high: a bearing or gearbox problem")
    assert reading["RL_knee", "gear_friction"].startswith("load-dependent friction high: a gearbox problem")
    assert reading["RR_thigh", "cogging_order"].startswith("cogging order 28/rev against the fleet's 24/rev")
    # the fleet's medians are the healthy truth's within the scatter; Kt within 1 %
    healthy = [v for n, v in truth["actuators"].items() if n not in planted]
    kt = next(s for s in result.stats if s.metric.key == "kt")
    assert kt.median == pytest.approx(np.median([v["kt"] for v in healthy]), rel=0.01)


@pytest.mark.parametrize("seed", [3, 11])
def test_another_batch_of_thirty(tmp_path, seed):
    faults = {4: "weak_magnet", 9: "bearing", 17: "gearbox", 25: "different_motor", 28: "bearing"}
    fleet = simulate_fleet(30, faults=faults, seed=seed)
    paths = []
    for member in fleet:
        path = tmp_path / f"{member.name}.csv"
        member.log.frame[list(FLEET_COLUMNS)].to_csv(path, index=False, float_format="%.6g")
        paths.append(path)
    result = analyse(fit_all(paths, FitCurrentOptions(model=FLEET_MODEL)))
    assert_found(result, {m.name: m.fault for m in fleet if m.fault})


# --- the independent polled rig (tests/dyno/acquire/polledrig.py): late current replies, a filtered transducer,
# AR(1) noise, a jittered loop, quantised current; a model (kt, k_sat, Coulomb, gear friction) of its own ---------

POLLED_FAULTS = {"unit02": "weak_magnet", "unit05": "bearing", "unit07": "gearbox"}


@lru_cache(maxsize=2)
def polled_fleet(seed: int) -> tuple[tuple[str, Truth], ...]:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(10):
        kt, k_sat = 1.15 * (1 + 0.01 * rng.standard_normal()), 0.004 * (1 + 0.05 * rng.standard_normal())
        coulomb, gear = 0.25 * np.exp(0.1 * rng.standard_normal()), 0.05 * np.exp(0.1 * rng.standard_normal())
        name = f"unit{i:02d}"
        fault = POLLED_FAULTS.get(name)
        kt *= 0.9 if fault == "weak_magnet" else 1.0
        coulomb *= 3.0 if fault == "bearing" else 1.0
        gear *= 3.0 if fault == "gearbox" else 1.0
        out.append((name, Truth(kt=kt, k_sat=k_sat, coulomb=coulomb, gear_friction=gear)))
    return tuple(out)


def test_a_fleet_from_the_independent_polled_rig(tmp_path):
    paths = [write(run(Rig(truth=t, seed=100 + k)), tmp_path / f"{name}.csv") for k, (name, t) in enumerate(
        polled_fleet(5))]  # fmt: skip
    # the model the polled logs need: their current reply is one loop late (a negative delay)
    options = FitCurrentOptions(model="linear+saturation+coulomb+gear_friction+delay", columns=COLUMNS)
    result = analyse(fit_all(paths, options))
    assert len(result.fitted) == 10
    assert_found(result, POLLED_FAULTS)
