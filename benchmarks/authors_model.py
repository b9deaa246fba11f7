"""Compare hound-id's current-torque curve with the identified model the authors of real logs published.

neurobionics/TMotorCANControl (GPL: fetch it yourself; nothing of it is in this repository) identified its AK80-9
on ``sys_ID_final/trial8.csv`` (``test/mit_can/derive_torque_constants.py``) and ships the result as ``a_hat`` in
``mit_can.py``::

    tau = a0 + gr (a1 kt - a2 |i|) i - sgn(v) (a3 + a4 |i|),   i = I / (kt gr),  kt = 0.091 N m/A,  gr = 9

with I the logged current and the ADC torque negated. On the logged current that is a1 I - a2 gr / (kt gr)^2 I|I|:
Kt = a1 and a quadratic saturation k = a2 / (kt^2 gr), Coulomb friction a3 and load-dependent friction a4 / (kt gr)
per logged amp. This script runs ``hound-id fit-current --auto --flip-torque --json`` on trial5, trial8 and
trial9-compensation (a fresh process each, as a user would) and prints, per log, the largest difference between the
two current-torque curves over the log's measured current, as a share of the log's peak torque (the largest
|torque| it holds), with both models' Kt, saturation and friction.

Run: python benchmarks/authors_model.py PATH/TO/TMotorCANControl/src/TMotorCANControl/test/saved_logs [--json]
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

#: a_hat of the AK80-9 in mit_can.py (commit bb8d071 of neurobionics/TMotorCANControl), and the constants
#: derive_torque_constants.py used with it.
A_HAT = (0.0, 1.15605006, 4.17389589e-04, 2.68556072e-01, 4.90424140e-02)
KT_NOMINAL, GEAR = 0.091, 9.0
LOGS = ("sys_ID_final/trial5.csv", "sys_ID_final/trial8.csv", "sys_ID_final/trial9-compensation.csv")
COLUMNS = (
    "time=loop_time,current=motor_measured_current,torque=adc_measured_torque,velocity=motor_measured_speed,"
    "torque_cmd=motor_torque_command"
)


def authors() -> dict[str, float]:
    """The authors' model on the logged current: Kt [N m/A], k_sat [N m/A^2], Coulomb [N m], gear [N m/A]."""
    a0, a1, a2, a3, a4 = A_HAT
    return {
        "kt": a1,
        "k_sat": a2 / (KT_NOMINAL**2 * GEAR),
        "coulomb": a3,
        "gear_friction": a4 / (KT_NOMINAL * GEAR),
        "offset": a0,
    }


def curve(model: dict[str, float], i: np.ndarray) -> np.ndarray:
    return model["kt"] * i - model.get("k_sat", 0.0) * i * np.abs(i)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folder", type=Path, help="TMotorCANControl's src/TMotorCANControl/test/saved_logs")
    parser.add_argument("--json", action="store_true", help="Print JSON (schema hound-id/bench-authors/1).")
    parser.add_argument("--whole-log", action="store_true", help="Pass --whole-log (the headline is the whole log).")
    args = parser.parse_args()
    exe = shutil.which("hound-id") or str(Path(sys.executable).with_name("hound-id"))
    theirs = authors()
    rows = []
    for name in LOGS:
        path = args.folder / name
        if not path.is_file():
            print(f"{path}: not found (point at TMotorCANControl's saved_logs folder)", file=sys.stderr)
            return 2
        proc = subprocess.run(
            [exe, "fit-current", str(path), "--auto", "--flip-torque", "--columns", COLUMNS, "--json"]
            + (["--whole-log"] if args.whole_log else []),
            capture_output=True,
            text=True,
            check=False,
        )
        if proc.returncode != 0:
            rows.append({"log": name, "error": proc.stderr.strip().splitlines()[-1]})
            continue
        report = json.loads(proc.stdout)
        ours = {k: v["value"] for k, v in report["parameters"].items()}
        frame = pd.read_csv(path, index_col=False, usecols=["motor_measured_current", "adc_measured_torque"])
        i_max = float(np.max(np.abs(frame["motor_measured_current"])))
        peak = float(np.max(np.abs(frame["adc_measured_torque"])))
        i = np.linspace(-i_max, i_max, 401)
        gap = float(np.max(np.abs(curve(ours, i) - curve(theirs, i))))
        rows.append(
            {
                "log": name,
                "max_current": i_max,
                "peak_torque": peak,
                "curve_gap": gap,
                "curve_gap_share": gap / peak,
                "ours": {k: ours.get(k) for k in ("kt", "k_sat", "coulomb", "gear_friction")},
                "theirs": {k: theirs[k] for k in ("kt", "k_sat", "coulomb", "gear_friction")},
                "model": report["model"],
                "left_out": [s["kind"] for s in report.get("left_out", [])],
            }
        )
    if args.json:
        print(json.dumps({"schema": "hound-id/bench-authors/1", "logs": rows}, indent=2))
        return 0
    for r in rows:
        if "error" in r:
            print(f"{r['log']}: {r['error']}")
            continue
        o, t = r["ours"], r["theirs"]

        def fmt(m: dict[str, float | None]) -> str:
            return ", ".join(f"{k} {v:.4g}" for k, v in m.items() if v is not None)

        print(
            f"{r['log']}: curves differ by at most {r['curve_gap']:.3g} N m over |i| <= {r['max_current']:.3g} A, "
            f"{100 * r['curve_gap_share']:.2f} % of its peak torque {r['peak_torque']:.3g} N m\n"
            f"    hound-id ({'+'.join(r['model'])}): {fmt(o)}\n    authors: {fmt(t)}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
