"""Run ``hound-id fit-current --auto`` over a folder of real dyno logs, one line per log.

Real logs are what the synthetic suites cannot stand in for. This script runs the CLI
exactly as a user would (a fresh process per log, ``--auto --json``) on every CSV or
Parquet file under a folder you point it at, and prints per log: rows loaded, Kt with
its cluster-robust standard error, the effects added with their values, the
cross-validated RMSE against the noise floor, and the verdict (at the noise floor,
flagged blocks, or the one-line reason the tool refused).

A log whose torque falls as current rises is run again with ``--flip-torque`` (the
sensor is mounted reversed), and the line says so.

Example, on the AK80-9 logs of neurobionics/TMotorCANControl (GPL: fetch it yourself,
do not copy its files into this repository)::

    .venv/bin/python benchmarks/real_logs.py /path/to/TMotorCANControl/src/TMotorCANControl/test/saved_logs \\
        --columns time=loop_time,current=motor_measured_current,torque=adc_measured_torque,\\
velocity=motor_measured_speed,torque_cmd=motor_torque_command

Add ``--markdown`` for a table for docs/fit-current.md, ``--json`` for every report. The last line (``summary`` in
the JSON) gives the figures over the fitted logs: the median cross-validated RMSE / noise floor, with and without the
stretches each log flags, how the floors were found, on how many logs a drift is named, and for the logs above 2x
their floor what the report names as the cause (a flagged stretch, a slow wander, fast noise, a drift) and which
name none.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

SUFFIXES = (".csv", ".parquet", ".txt", ".tsv")
CAUSES = ("flagged stretch", "slow wander", "offset", "fast noise", "drift")
#: Longest verdict in a Markdown table cell [characters].
MARKDOWN_VERDICT = 150


def run_one(exe: str, path: Path, extra: list[str]) -> dict[str, Any]:
    """Fit one log; retry with --flip-torque when the tool says the sensor looks reversed."""
    flipped = False
    for flip in (False, True):
        args = [exe, "fit-current", str(path), "--auto", "--json", *extra, *(["--flip-torque"] if flip else [])]
        proc = subprocess.run(args, capture_output=True, text=True, check=False)
        if proc.returncode == 0:
            report = json.loads(proc.stdout)
            report["flipped"] = flipped
            return report
        message = (proc.stderr.strip().splitlines() or ["(no message)"])[-1]
        if proc.returncode == 2 and not flip and "reversed" in message and "--flip-torque" in message:
            flipped = True
            continue
        return {"error": message, "exit": proc.returncode, "flipped": flipped}
    return {"error": "unreachable", "exit": -1, "flipped": flipped}


def excess(report: dict[str, Any]) -> str:
    """What the report says the residual's excess over the floor is, in a few words ('-' when it names nothing)."""
    wander = report.get("wander") or {}
    said = []
    sentence = wander.get("sentence") or ""
    if sentence and not sentence.startswith("half or more of that floor"):
        kind, share = wander["kind"], wander["share_slow"]
        if kind == "slow":
            follows = wander.get("follows_inputs")
            known = "" if follows is None else f" ({follows:.0%} predicted by the inputs)"
            said.append(f"{share:.0%} slow: wander {wander['slow_rms']:.3g} N m RMS{known}")
        elif kind == "offset":
            said.append(f"{share:.0%} slow: offset {wander['mean']:+.3g} N m")
        else:
            said.append(f"{1 - share:.0%} fast ({wander['fast_ratio']:.2g}x the floor)")
    elif sentence:
        said.append(f"floor half or more slow: wander {wander['slow_rms']:.3g} N m RMS")
    if (report.get("noise") or {}).get("drift"):
        said.append("drift")
    return "; ".join(said) or "-"


def line(report: dict[str, Any]) -> dict[str, str]:
    """The fields of one output line."""
    if "error" in report:
        return {
            "rows": "-",
            "kt": "-",
            "effects": "-",
            "cv": "-",
            "excess": "-",
            "verdict": f"exit {report['exit']}: {report['error']}",
        }
    kt = report["parameters"]["kt"]
    err = kt["stderr"]
    added = [e for e in report["model"] if e not in ("linear", "saturation")]
    shown = []
    for name, est in report["parameters"].items():
        if name == "kt":
            continue
        value = est["value"]
        shown.append(f"{name} {value:.3g}{' (bound)' if est.get('at_bound') else ''}")
    floor = report["noise_floor"]
    method = (report.get("noise") or {}).get("method", "sample-to-sample")
    cv = report["rmse"]["test"]
    if report["at_noise_floor"]:
        verdict = "at the noise floor"
    elif report["flags"]:
        verdict = f"{len(report['flags'])} flag(s): {report['flags'][0]}"
    else:
        verdict = report["summary"]
    return {
        "rows": f"{report['rows']['fitted']}/{report['rows']['read']}",
        "kt": f"{kt['value']:.4g} +- {err:.2g}" if err is not None else f"{kt['value']:.4g}",
        "effects": ("+" + "+".join(added) + ": " if added else "") + ", ".join(shown),
        "cv": f"{cv:.3g} / {floor:.3g} ({method})",
        "excess": excess(report),
        "verdict": ("(flipped) " if report.get("flipped") else "") + _left_out(report) + verdict,
    }


#: Above this cross-validated RMSE / floor a log's excess is looked for a named cause.
EXCESS = 2.0


def causes(report: dict[str, Any]) -> list[str]:
    """What the report names as the cause of its excess over the floor: flagged stretches, a slow wander, an offset the
    model lacks, fast noise the floor misses, a drift between moments with the same inputs (several may apply)."""
    found = []
    if report.get("flags"):
        found.append("flagged stretch")
    wander = report.get("wander") or {}
    if wander.get("kind") in ("slow", "offset", "fast") and wander.get("sentence"):
        found.append({"slow": "slow wander", "offset": "offset"}.get(wander.get("kind", ""), "fast noise"))
    if (report.get("noise") or {}).get("drift"):
        found.append("drift")
    return found


HEADER = (
    "| log | rows used/read | Kt [N m/A] | effects added, values (SI) | CV RMSE / floor [N m] | excess over the floor "
    "| verdict |\n|---|---|---|---|---|---|---|"
)


def markdown_row(name: str, report: dict[str, Any]) -> str:
    """One log's row of the Markdown table (the verdict cut at MARKDOWN_VERDICT characters; --json has every word)."""
    f = line(report)
    verdict = f["verdict"].replace("|", "/")
    if len(verdict) > MARKDOWN_VERDICT:
        verdict = verdict[: MARKDOWN_VERDICT - 3].rsplit(" ", 1)[0] + " ..."
    return "| " + " | ".join([name, f["rows"], f["kt"], f["effects"], f["cv"], f["excess"], verdict]) + " |"


def summary(results: list[dict[str, Any]]) -> dict[str, Any]:
    """The figures over the fitted logs: how far from their floor, where the excess is, how the floor was found."""
    fitted = [r for r in results if "error" not in r]
    ratios = [r["rmse"]["test"] / r["noise_floor"] for r in fitted if r["noise_floor"] > 0]
    # outside the flagged stretches: the whole log's ratio when nothing is flagged
    outside = [
        (r["rmse"].get("outside_flagged") or r["rmse"]["test"]) / r["noise_floor"]
        for r in fitted
        if r["noise_floor"] > 0
    ]
    noise = [r.get("noise") or {} for r in fitted]
    above = [r for r in fitted if r["noise_floor"] > 0 and r["rmse"]["test"] / r["noise_floor"] > EXCESS]
    methods = [n.get("method", "sample-to-sample") for n in noise]
    return {
        "logs": len(results),
        "fitted": len(fitted),
        "median_ratio": statistics.median(ratios) if ratios else None,
        "ratio_range": [min(ratios), max(ratios)] if ratios else None,
        "within_2x": sum(x <= 2.0 for x in ratios),
        "within_1.2x": sum(x <= 1.2 for x in ratios),
        "at_noise_floor": sum(bool(r["at_noise_floor"]) for r in fitted),
        "median_ratio_outside_flagged": statistics.median(outside) if outside else None,
        "within_2x_outside_flagged": sum(x <= 2.0 for x in outside),
        "floor_methods": {m: methods.count(m) for m in sorted(set(methods))},
        "drift_named": sum(1 for n in noise if n.get("drift")),
        "above_2x": len(above),
        "causes_above_2x": {c: sum(c in causes(r) for r in above) for c in CAUSES},
        "no_cause_above_2x": [r["log"] for r in above if not causes(r)],
    }


def summary_line(s: dict[str, Any]) -> str:
    """The summary in one paragraph."""
    if not s["fitted"]:
        return f"{s['logs']} logs, none fitted"
    lo, hi = s["ratio_range"]
    methods = ", ".join(f"{k} {v}" for k, v in s["floor_methods"].items())
    causes = ", ".join(f"{k} {v}" for k, v in s["causes_above_2x"].items())
    return (
        f"{s['fitted']} of {s['logs']} logs fitted; cross-validated RMSE / noise floor: median {s['median_ratio']:.3g} "
        f"({lo:.3g} to {hi:.3g}), {s['within_2x']} within 2x, {s['within_1.2x']} within 1.2x, {s['at_noise_floor']} at "
        f"the floor; outside the flagged stretches: median {s['median_ratio_outside_flagged']:.3g}, "
        f"{s['within_2x_outside_flagged']} within 2x; floor from {methods}; a drift named on {s['drift_named']}; "
        f"of the {s['above_2x']} above 2x, {causes} ({len(s['no_cause_above_2x'])} with no cause named)"
    )


def _left_out(report: dict[str, Any]) -> str:
    """'[left out: 2 another regime, motor off] ' when the headline leaves part of the log out, else ''."""
    kinds = [s["kind"] for s in report.get("left_out", [])]
    if not kinds:
        return ""
    counted = [f"{kinds.count(k)} {k}" if kinds.count(k) > 1 else k for k in dict.fromkeys(kinds)]
    return f"[left out: {', '.join(counted)}] "


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folder", type=Path, help="Folder searched recursively for logs.")
    parser.add_argument("--columns", help="Column mapping passed to fit-current --columns.")
    parser.add_argument("--units", help="Units passed to fit-current --units.")
    parser.add_argument("--model", default=None, help="Starting model (fit-current --model).")
    parser.add_argument("--exclude", action="append", default=[], help="Skip paths containing this text (repeatable).")
    parser.add_argument("--markdown", action="store_true", help="Print a Markdown table.")
    parser.add_argument("--json", action="store_true", help="Print every report as JSON (schema hound-id/real-logs/1).")
    args = parser.parse_args()
    exe = shutil.which("hound-id") or str(Path(sys.executable).with_name("hound-id"))
    extra = []
    for flag in ("columns", "units", "model"):
        if getattr(args, flag):
            extra += [f"--{flag}", getattr(args, flag)]
    paths = sorted(
        p
        for p in args.folder.rglob("*")
        if p.suffix.lower() in SUFFIXES and p.is_file() and not any(x in str(p) for x in args.exclude)
    )
    if not paths:
        print(f"{args.folder}: no logs ({', '.join(SUFFIXES)}) found", file=sys.stderr)
        return 2
    results = []
    if args.markdown:
        print(HEADER)
    for path in paths:
        report = run_one(exe, path, extra)
        name = str(path.relative_to(args.folder))
        results.append({"log": name, **report})
        if args.json:
            continue
        if args.markdown:
            print(markdown_row(name, report), flush=True)
        else:
            f = line(report)
            print(
                f"{name}: rows {f['rows']}; Kt {f['kt']}; {f['effects']}; CV/noise {f['cv']}; excess {f['excess']}; "
                f"{f['verdict']}",
                flush=True,
            )
    totals = summary(results)
    if args.json:
        print(json.dumps({"schema": "hound-id/real-logs/1", "summary": totals, "logs": results}, indent=2))
    else:
        print(("\n" if args.markdown else "") + summary_line(totals))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
