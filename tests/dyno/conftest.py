from __future__ import annotations

import dataclasses
from functools import lru_cache

from hound_id.dyno.current.effects import Signals
from hound_id.dyno.logs import log_from_frame
from hound_id.dyno.simulate.current import SimMotor, TestPlan, simulate

# Rigs differ across tests so the method does not hinge on one protocol: sample rate, motor size, sweep shape.
RIGS = (
    {"rate_hz": 1000.0, "motor": SimMotor()},
    {
        "rate_hz": 500.0,
        "motor": SimMotor().scaled(0.3),
        "plan": dataclasses.replace(TestPlan(), current_rise_time=0.01),
    },
    {"rate_hz": 2000.0, "motor": SimMotor().scaled(2.0), "plan": dataclasses.replace(TestPlan(), shape="ramps")},
)


@lru_cache(maxsize=64)
def simulated(effects: tuple[str, ...], seed: int = 0, rig: int = 0):
    """(signals, torque, simulated log) for a rig with the given hidden effects."""
    sim = simulate(effects, seed=seed, **RIGS[rig])
    log = log_from_frame(sim.frame, source=f"sim{effects}")
    return Signals.from_log(log), log.torque, sim
