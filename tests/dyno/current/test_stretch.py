"""What a stretch of a log is, read from its channels; which stretches the headline may be fitted to."""

import numpy as np
import pytest

from hound_id.dyno.current.effects import Signals
from hound_id.dyno.current.stretch import candidates, read, varies

RATE = 100.0
KT = 0.8
N = 2000


def base(seed: int = 0):
    """A sweeping current and speed, torque = Kt i with a little noise: (signals pieces, torque)."""
    rng = np.random.default_rng(seed)
    t = np.arange(N) / RATE
    i = 10 * np.sin(2 * np.pi * 0.2 * t) + rng.normal(0, 0.02, N)
    w = 2 * np.sin(2 * np.pi * 0.13 * t) + rng.normal(0, 0.02, N)
    y = KT * i + rng.normal(0, 0.03, N)
    return t, i, w, y


def kind_of(t, i, w, y, a=1000, b=1500, kt=KT):
    s = Signals(time=t, current=i, velocity=w)
    return read(s, y, y - KT * i, a, b, kt)


def test_each_kind_of_stretch_is_read_from_its_channels():
    t, i, w, y = base()
    assert kind_of(t, i, w, y).kind == "another regime"  # nothing odd: the torque follows another law there

    frozen_i, frozen_w = i.copy(), w.copy()
    frozen_i[1000:1500], frozen_w[1000:1500] = i[999], w[999]  # the last reply repeats
    assert kind_of(t, frozen_i, frozen_w, y).kind == "replies frozen"
    assert kind_of(t, frozen_i, w, y).kind == "current frozen"  # the speed still moves (an opposing motor)

    off_i, off_y = i.copy(), y.copy()
    off_i[1000:1500] = np.random.default_rng(1).normal(0, 0.02, 500)
    off_y[1000:1500] = 0.2 + np.random.default_rng(2).normal(0, 0.03, 500)
    assert kind_of(t, off_i, w, off_y).kind == "motor off"

    sat_y = np.minimum(y, 5.0)  # the ADC's top
    assert kind_of(t, i, w, sat_y, 1000, 1300).kind in ("torque saturated",)

    ignored = i.copy()
    ignored[1000:1500] += np.linspace(0, 30, 500)  # the reading runs away, the torque does not follow
    stretch = kind_of(t, ignored, w, y)
    assert stretch.kind == "torque ignores the current" and "Kt = 0.8" in stretch.reading
    assert kind_of(t, ignored, w, y, kt=None).kind == "another regime"  # without a Kt to compare with

    levels = np.random.default_rng(3).uniform(5, 10, N // 100) * (-1.0) ** np.arange(N // 100)  # big steps
    steps_i = np.repeat(levels, 100) + np.random.default_rng(5).normal(0, 0.02, N)  # held levels, read with noise
    ring = np.zeros(N)
    for s in range(100, N, 100):
        ring[s : s + 3] = [3.0, -2.0, 1.0]  # a transducer ringing after each step
    stretch = kind_of(t, steps_i, w, KT * steps_i + ring, 1000, 1500)
    assert stretch.kind == "step transient" and "4 current step(s)" in stretch.reading  # 1100, ..., 1400


def test_candidates_vary_the_current_and_are_longest_first():
    t, i, w, y = base()
    s = Signals(time=t, current=i, velocity=w)
    edges = np.arange(0, N + 1, 100)
    bad = np.zeros(20, dtype=bool)
    bad[[5, 6, 15]] = True
    found = candidates(s, edges, bad, 50)
    # agreeing runs less a block either side: 0-400 and 800-1400, 1700-2000; the longest first
    assert found[0] == (800, 1400) and (0, 400) in found and all(varies(s, a, b) for a, b in found)
    # a motor-off majority: the part that runs is the candidate
    off = i.copy()
    off[600:] = np.random.default_rng(4).normal(0, 0.02, N - 600)
    s_off = Signals(time=t, current=off, velocity=w)
    bad = np.zeros(20, dtype=bool)
    bad[:6] = True
    assert candidates(s_off, edges, bad, 50) == [(0, 600)]
    assert not varies(s_off, 700, N) and varies(s, 700, N)


@pytest.mark.parametrize("kind", ["replies frozen", "another regime"])
def test_a_stretch_says_its_times(kind):
    t, i, w, y = base()
    if kind == "replies frozen":
        i, w = i.copy(), w.copy()
        i[1000:1500], w[1000:1500] = i[999], w[999]
    s = Signals(time=t, current=i, velocity=w)
    d = read(s, y, y - KT * i, 1000, 1500, KT).to_dict(s)
    assert d["kind"] == kind and d["rows"] == [1000, 1499] and d["time"] == pytest.approx([10.0, 14.99])
