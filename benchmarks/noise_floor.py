"""Benchmark: what the neighbour noise floor and its strata of the current cost the diagnosis of a long log.

The simulated log of ``benchmarks/fit_current.py`` (linear, saturation, Coulomb friction, cogging, thermal drift;
1 kHz) of --rows rows is fitted once with linear+saturation; then, in the same process, the full diagnosis is timed
with the neighbour estimate and with it switched off (the still and sample-to-sample estimates stay), and with the
strata of the current switched off (every estimate read over the whole log only), and with the residual's time scale
(hound_id.dyno.current.wander) switched off, the median of --repeats runs each, and the neighbour estimate alone.
It prints the seconds and the ratios with / without.

Run: .venv/bin/python benchmarks/noise_floor.py [--rows 1000000] [--repeats 3] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.timing import timed  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rows", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    import numpy as np

    import hound_id.dyno.current.noise as noise
    from benchmarks.fit_current import make_log
    from hound_id.dyno.current.diagnose import diagnose
    from hound_id.dyno.current.effects import Signals
    from hound_id.dyno.current.fit import fit_model
    from hound_id.dyno.logs import load_log

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "log.parquet"
        make_log(args.rows, path)
        log = load_log(path)
    signals = Signals.from_log(log)
    fit = fit_model(signals, log.torque, ("linear", "saturation"))
    residual = np.asarray(fit.residual)
    real = noise.neighbour_scatter
    with_it = timed(lambda: diagnose(signals, log.torque, fit), args.repeats)
    noise.neighbour_scatter = lambda *a, **k: None  # type: ignore[assignment]
    try:
        without = timed(lambda: diagnose(signals, log.torque, fit), args.repeats)
    finally:
        noise.neighbour_scatter = real
    strata = noise.Strata.of
    noise.Strata.of = classmethod(lambda cls, current: None)  # type: ignore[method-assign,assignment]
    try:
        unstratified = timed(lambda: diagnose(signals, log.torque, fit), args.repeats)
    finally:
        noise.Strata.of = strata  # type: ignore[method-assign]
    import hound_id.dyno.current.diagnose as diagnosis

    time_scale = diagnosis.wander
    diagnosis.wander = lambda *a, **k: None  # type: ignore[assignment]
    try:
        still_scale = timed(lambda: diagnose(signals, log.torque, fit), args.repeats)
    finally:
        diagnosis.wander = time_scale
    alone = timed(lambda: real(signals, residual), args.repeats)
    inputs = [x for x in (signals.current, signals.velocity) if x is not None]
    held_out = np.asarray(fit.held_out)
    scale_alone = timed(lambda: time_scale(signals.time, held_out, 0.05, None, inputs), args.repeats)
    out = {
        "schema": "hound-id/bench-noise-floor/1",
        "rows": args.rows,
        "diagnosis_with_neighbours_s": with_it,
        "diagnosis_without_s": without,
        "neighbours_alone_s": alone,
        "ratio": with_it / without,
        "diagnosis_without_strata_s": unstratified,
        "strata_ratio": with_it / unstratified,
        "diagnosis_without_wander_s": still_scale,
        "wander_ratio": with_it / still_scale,
        "wander_alone_s": scale_alone,
        "wander_alone_share": scale_alone / with_it,
    }
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(
            f"diagnosis of {args.rows} rows: {with_it:.3f} s with the neighbour floor, {without:.3f} s without "
            f"(ratio {with_it / without:.3f}); the neighbour estimate alone {alone:.3f} s "
            f"(median of {args.repeats}); without the strata of the current {unstratified:.3f} s "
            f"(ratio {with_it / unstratified:.3f}); without the residual's time scale (slow or fast, what it "
            f"follows) {still_scale:.3f} s (ratio {with_it / still_scale:.3f}: it is read only where the summary may "
            f"say it, no significant effect left); that time scale alone {scale_alone:.3f} s, "
            f"{scale_alone / with_it:.2f}x the diagnosis"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
