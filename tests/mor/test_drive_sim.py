"""The drive region's edges against an independent drive simulator: motulator 0.5.0 (a PMSM drive simulator from
Aalto University: its own machine model, current controller, anti-windup and PWM), in its own virtual environment
under ``.venv-trainers/``, running ``tests/mor/in_drive_sim/motulator_check.py`` (which imports no hound_id).

For the sample motor, with and without field weakening, at the lowest and highest bus voltage of its battery, at 24
speeds from 0 to twice the no-load speed and 12 between the corner speed and the loss of control: wherever the
region's edge is set by the voltage (not by the current limit), the dq current 2 % of the current limit inside the
edge must be held by motulator's drive and the current 2 % outside must not be. The simulator's own discrete-time
edge lies outward of the continuous-time one by ``edge_bias`` (0.04-0.3 % of the voltage: its zero-order-hold PWM
and current sampling, measured and explained in ``in_drive_sim/README.md``); an outside point motulator still holds
must lie within three times that bias of the continuous-time voltage limit, as motulator itself computes it. Past
the speed where the drive loses control the region is the diode bridge's braking, which motulator cannot show (it
cannot turn its switches off): those speeds are not checked here.
"""

import json
import math
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hound_id.mor.region import drive_region, torque_interval
from hound_id.mor.spec_sheet import load_motor_spec
from tests.conftest import SAMPLES
from tests.export.conftest import trainer_python

SCRIPT = Path(__file__).parent / "in_drive_sim" / "motulator_check.py"
MOTULATOR = ("motulator==0.5.0",)
#: The margin either side of an edge, as a share of the current the torque limit needs.
MARGIN = 0.02
#: Speeds per case, from 0 to twice the no-load speed.
SPEEDS = 24


@pytest.fixture(scope="module")
def motulator() -> str:
    return trainer_python("motulator-0.5.0", MOTULATOR)


def _points(spec, volts):
    """The (speed, i_d, i_q, inside, edge) references around the voltage-set edges of the region at ``volts``."""
    region = drive_region(spec, bus_voltage=volts)
    kt = region.curve.kt if region.curve is not None else spec.kt
    limit = region.limit_x / kt  # the current the torque limit needs [A]
    circle = spec.drive.phase_current_limit
    r_ph, l_ph = spec.resistance / math.sqrt(3.0), spec.drive.inductance_phase
    # 24 speeds to twice the no-load speed, and 12 more where the voltage sets the edge (corner to loss of control)
    speeds = np.concatenate(
        [np.linspace(0.0, 2.0 * spec.kv * volts, SPEEDS), np.linspace(region.corner_speed, region.overspeed, 14)[1:-1]]
    )
    x_lo, x_hi = (np.asarray(e) for e in _x_window(speeds, region))
    out = []
    for w, lo, hi in zip(speeds, x_lo / kt, x_hi / kt, strict=True):
        if not lo < hi:  # past control: the diode bridge's braking, which motulator cannot show
            continue
        for edge, inward in ((hi, -1.0), (lo, 1.0)):
            if abs(abs(edge) - limit) <= 1e-9 * limit:
                continue  # the current limit sets it, not the voltage
            for inside in (True, False):
                i_q = edge + (inward if inside else -inward) * MARGIN * limit
                i_d = 0.0
                if spec.field_weakening:  # the d current that needs the least voltage, within the current circle
                    x = spec.drive.pole_pairs * w * l_ph
                    e = w / (math.sqrt(3.0) * spec.kv)
                    i_d = max(-e * x / (r_ph**2 + x**2), -math.sqrt(max(circle**2 - i_q**2, 0.0)))
                out.append({"speed": float(w), "i_d": i_d, "i_q": float(i_q), "inside": inside, "edge": float(edge)})
    return out


def _x_window(speeds, region):
    """The linear-equivalent window (Kt i) of the region at ``speeds``: the torque interval before the curve."""
    from hound_id.mor.region import current_window

    return current_window(speeds, region)


def _request(spec, volts, points):
    return {
        "mode": "references",
        "R": spec.resistance / math.sqrt(3.0),
        "L": spec.drive.inductance_phase,
        "psi": 1.0 / (math.sqrt(3.0) * spec.kv * spec.pole_pairs),
        "n_p": spec.pole_pairs,
        "u_dc": volts,
        "i_max": spec.drive.phase_current_limit,
        "points": [{k: p[k] for k in ("speed", "i_d", "i_q")} for p in points],
    }


@pytest.mark.parametrize("weakening", [False, True], ids=["id0", "field_weakening"])
def test_the_drive_regions_edges_are_what_motulators_drive_holds(motulator, weakening):
    spec = replace(load_motor_spec(SAMPLES / "motors" / "hound_ilm85.yaml"), field_weakening=weakening)
    low, high = spec.bus_voltage_range
    checked = 0
    for volts in (low, high):
        points = _points(spec, volts)
        proc = subprocess.run(
            [motulator, str(SCRIPT)], input=json.dumps(_request(spec, volts, points)), capture_output=True,
            text=True, timeout=900,
        )  # fmt: skip
        assert proc.returncode == 0, proc.stderr[-3000:]
        result = json.loads(proc.stdout)
        assert result["schema"] == "motulator-check/2" and result["motulator"] == "0.5.0"
        for p, r in zip(points, result["points"], strict=True):
            ref = f"({p['i_d']:.2f}, {p['i_q']:.2f}) A"
            where = f"{volts:g} V, {p['speed']:.1f} rad/s, edge {p['edge']:.2f} A, reference {ref}"
            if p["inside"]:
                assert r["held_control"], f"inside the region but not held: {where}, u_ratio {r['u_ratio']:.4f}"
            elif r["held_control"]:  # only within the simulator's own discrete-time bias past the voltage limit
                assert r["u_ratio_ideal"] <= 1.0 + 3.0 * r["edge_bias"], f"outside but held: {where}"
            checked += 1
    assert checked >= 50  # voltage-set edges at both bus voltages


def test_the_drive_region_is_the_dc_law_without_reactance():
    """The dq window with no reactance and i_d = 0 is the paper's DC law to rounding, at every speed."""
    spec = load_motor_spec(SAMPLES / "motors" / "hound_ilm85.yaml")
    dc = replace(spec, inductance=None)
    with_zero = replace(spec, inductance=1e-30)
    w = np.linspace(-3.0, 3.0, 6001) * dc.no_load_speed
    lo_dc, hi_dc = torque_interval(w, replace(drive_region(with_zero), drive=None))
    lo, hi = torque_interval(w, drive_region(with_zero))
    assert np.allclose(lo, lo_dc, atol=1e-9) and np.allclose(hi, hi_dc, atol=1e-9)


@pytest.mark.parametrize(("temperature", "volts"), [(100.0, 84.0), (112.0, 66.0)], ids=["100C_84V", "112C_66V"])
def test_the_clip_at_a_temperature_is_what_motulators_warm_drive_holds(motulator, temperature, volts):
    """The winding warm: motulator's machine with the resistance and flux at that temperature, written here from the
    physics (R_ph (1 + a_R (T - 20)), psi (1 + a_K (T - 20)), L unchanged) and the drive's derated current limit;
    hound-id's clip at ``temperature`` (its exact scaling of the 20 degC window, no region rebuilt) sets the edges.
    At 112 degC the drive has derated to 40 % of its current."""
    from hound_id.mor.robot import load_robot
    from hound_id.mor.saturation import saturation_for
    from tests.conftest import ROBOT

    spec = load_motor_spec(SAMPLES / "motors" / "hound_ilm85.yaml")
    th = spec.thermal
    sat = saturation_for(load_robot(ROBOT))
    gear = 1.0 / float(sat.A[0, 0])  # motor 0 (FL_HAA) turns with joint 0 alone
    s_r = 1.0 + th.alpha_resistance * (temperature - 20.0)
    s_k = 1.0 + th.alpha_kt * (temperature - 20.0)
    derate = min(1.0, (th.winding_limit - temperature) / (th.winding_limit - th.derate_start))
    i_max = derate * spec.max_current
    curve = spec.current_curve
    from hound_id.mor.heat import hot_spec

    warm = drive_region(replace(hot_spec(spec, temperature), bus_voltage=volts))  # only to place the speeds
    speeds = np.concatenate(
        [np.linspace(0.0, 2.0 * spec.kv * volts / s_k, SPEEDS), np.linspace(warm.corner_speed, warm.overspeed, 22)]
    )
    qd = np.zeros((speeds.size, 12))
    qd[:, 0] = speeds / gear
    lo, hi = sat.torque_bounds(qd, bus_voltage=np.full((speeds.size, 1), volts), temperature=temperature)
    points = []
    for w, t_lo, t_hi in zip(speeds, lo[:, 0], hi[:, 0], strict=True):
        if not t_lo < t_hi:
            continue  # past control: the diode bridge's braking, which motulator cannot show
        for tau, inward in ((t_hi, -1.0), (t_lo, 1.0)):
            edge = float(curve.current(tau / s_k))  # the current of that torque on the warm curve
            if abs(abs(edge) - i_max) <= 1e-9 * i_max:
                continue  # the (derated) current limit sets it
            for inside in (True, False):
                i_q = edge + (inward if inside else -inward) * MARGIN * i_max
                points.append({"speed": float(w), "i_d": 0.0, "i_q": i_q, "inside": inside, "edge": edge})
    request = {
        "mode": "references",
        "R": s_r * spec.resistance / math.sqrt(3.0),
        "L": spec.drive.inductance_phase,
        "psi": s_k / (math.sqrt(3.0) * spec.kv * spec.pole_pairs),
        "n_p": spec.pole_pairs,
        "u_dc": volts,
        "i_max": i_max,
        "points": [{k: p[k] for k in ("speed", "i_d", "i_q")} for p in points],
    }
    proc = subprocess.run(
        [motulator, str(SCRIPT)], input=json.dumps(request), capture_output=True, text=True, timeout=900
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    result = json.loads(proc.stdout)
    for p, r in zip(points, result["points"], strict=True):
        where = f"{temperature:g} degC, {volts:g} V, {p['speed']:.1f} rad/s, edge {p['edge']:.2f} A, i_q {p['i_q']:.2f}"
        if p["inside"]:
            assert r["held_control"], f"inside the warm region but not held: {where}, u_ratio {r['u_ratio']:.4f}"
        elif r["held_control"]:
            assert r["u_ratio_ideal"] <= 1.0 + 3.0 * r["edge_bias"], f"outside but held: {where}"
    assert len(points) >= 40
