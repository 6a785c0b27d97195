"""Are two commits' diagnosis reports the same? For a refactoring that must not change behaviour.

``run RUNS OUT`` diagnoses every run of a folder (``NAME.csv`` with ``NAME_model.json``: a vehicle
run, also written as ``--series``; with ``NAME_sensors.json`` or nothing: an attitude run) in one
process with the jaxdrift on ``PYTHONPATH`` / installed, writing ``OUT/NAME.json`` (and
``OUT/NAME_series.csv``). ``compare A B --json FILE`` compares two such folders: reports by JSON
equality leaving out the run's path and ``provenance``; series files byte by byte, and where they
differ, the largest difference of each column relative to its RMS.

Found (2026-12-02): the catalogue of causes and the Corrections record (1f88ef4) left all 31
reports of the example and 30 generated runs (16 vehicle, 6 nonlinear-suspension, 8 attitude)
equal to 84de818's, and the series files equal but for the scale-corrected forces (one rounding:
x gain in place of / scale, at most 3.2e-16 of the column's RMS) and the extended model's simulated
states (at most 2e-12): ``docs/validation/refactor-equality.json``.

Found (2026-12-03): the attitude diagnosis as steps returning frozen records (``AttitudeState``
removed) left 49 of 49 attitude reports equal to c763533's: 16 generated runs (``gen_attitude``
design seed 20261301, 13 with an accelerometer array) and the 33 recordings of the three real
corpora (ULog, ROS 1 bag, MDF4, motion-capture CSV; 30 with vibration, 13 with the reference
aligned, 3 diagnosed in parts at a gyro switch, 3 by a static segment):
``docs/validation/records-equality.json``, made by ``attitude_equality_runs.py``.

    PYTHONPATH=/path/to/old/checkout python benchmarks/validation/report_equality.py run RUNS old/
    python benchmarks/validation/report_equality.py run RUNS new/
    python benchmarks/validation/report_equality.py compare old/ new/ --json eq.json
    python benchmarks/validation/report_equality.py score RUNS old/ new/

``score RUNS DIR...`` scores the vehicle reports of each folder against the runs' truth files
(``NAME_truth.json`` of the independent generator) by the sweep's rules: singles right, pairs
right, false alarms, true values inside their intervals, and the first finding of each run.
"""

from __future__ import annotations

import argparse
import csv
import glob
import json
import os
import sys

LEFT_OUT = ("provenance", "run", "path", "file")


def run(runs: str, out: str) -> None:
    from jaxdrift.cli import main

    os.makedirs(out, exist_ok=True)
    for f in sorted(glob.glob(os.path.join(runs, "*.csv"))):
        stem = os.path.splitext(os.path.basename(f))[0]
        args = ["diagnose", f, "--json", os.path.join(out, stem + ".json")]
        if os.path.exists(f[:-4] + "_model.json"):
            args += ["--model", f[:-4] + "_model.json", "--series", os.path.join(out, stem + "_series.csv")]
        elif os.path.exists(f[:-4] + "_sensors.json"):
            args += ["--sensors", f[:-4] + "_sensors.json"]
        try:
            rc = main(args)
        except SystemExit as e:
            rc = e.code
        print(stem, rc, flush=True)


def _strip(d):
    if isinstance(d, dict):
        return {k: _strip(v) for k, v in d.items() if k not in LEFT_OUT}
    if isinstance(d, list):
        return [_strip(v) for v in d]
    return d


def _series_diff(pa: str, pb: str) -> dict:
    with open(pa) as fa, open(pb) as fb:
        ra, rb = list(csv.reader(fa)), list(csv.reader(fb))
    cols = ra[0]
    worst = {}
    for c, col in enumerate(cols):
        a = [float(r[c]) for r in ra[1:]]
        b = [float(r[c]) for r in rb[1:]]
        d = max(abs(x - y) for x, y in zip(a, b))
        if d > 0:
            rms = (sum(x * x for x in a) / len(a)) ** 0.5
            worst[col] = d / rms if rms > 0 else float("inf")
    return worst


def compare(a: str, b: str) -> dict:
    out = {"a": a, "b": b, "reports": 0, "reports_equal": 0, "reports_differing": [], "series": 0,
           "series_equal": 0, "series_differing": {}, "missing": []}
    for n in sorted(os.listdir(a)):
        pa, pb = os.path.join(a, n), os.path.join(b, n)
        if not os.path.exists(pb):
            out["missing"].append(n)
            continue
        if n.endswith(".json"):
            out["reports"] += 1
            with open(pa) as fa, open(pb) as fb:
                same = _strip(json.load(fa)) == _strip(json.load(fb))
            out["reports_equal"] += same
            if not same:
                out["reports_differing"].append(n)
        elif n.endswith(".csv"):
            out["series"] += 1
            with open(pa, "rb") as fa, open(pb, "rb") as fb:
                same = fa.read() == fb.read()
            out["series_equal"] += same
            if not same:
                out["series_differing"][n] = _series_diff(pa, pb)
    worst = {}
    for d in out["series_differing"].values():
        for c, v in d.items():
            worst[c] = max(worst.get(c, 0.0), v)
    out["series_worst_relative_to_rms"] = worst
    return out


def score(runs: str, reports: str) -> dict:
    """The sweep's scores of the vehicle reports in ``reports`` against the truth files in ``runs``."""
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    from benchmarks.validation import sweep

    per = {}
    for tf in sorted(glob.glob(os.path.join(runs, "*_truth.json"))):
        name = os.path.basename(tf)[:-len("_truth.json")]
        rp = os.path.join(reports, name + ".json")
        with open(tf) as fh:
            truth = json.load(fh)
        if truth.get("schema", "").startswith("independent.vehicle") and os.path.exists(rp):
            with open(rp) as fh:
                per[name] = sweep.score("vehicle", truth["effects"], json.load(fh).get("findings", []))
    singles = [s for s in per.values() if s["n_systematic"] == 1]
    pairs = [s for s in per.values() if s["n_systematic"] == 2]
    free = [s for s in per.values() if s["n_systematic"] == 0]
    cov = [c for s in per.values() for c in s["coverage"]]
    return {"runs": len(per), "singles_right": f"{sum(s['right'] for s in singles)}/{len(singles)}",
            "pairs_right": f"{sum(s['right'] for s in pairs)}/{len(pairs)}",
            "false_alarms": f"{sum(s['false_alarm'] for s in free)}/{len(free)}",
            "effects_covered": f"{sum(c['covered'] for c in cov)}/{len(cov)}",
            "confusion": {k: s["first"] for k, s in per.items()}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="diagnose every run of RUNS into OUT")
    r.add_argument("runs")
    r.add_argument("out")
    c = sub.add_parser("compare", help="compare two output folders")
    c.add_argument("a")
    c.add_argument("b")
    c.add_argument("--json", help="write the comparison here")
    sc = sub.add_parser("score", help="score the vehicle reports of each folder against the truth files in RUNS")
    sc.add_argument("runs")
    sc.add_argument("dirs", nargs="+")
    a = ap.parse_args(argv)
    if a.cmd == "score":
        print(json.dumps({d: score(a.runs, d) for d in a.dirs}, indent=1))
        return 0
    if a.cmd == "run":
        run(a.runs, a.out)
        return 0
    res = compare(a.a, a.b)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(res, fh, indent=1)
    print(json.dumps({k: v for k, v in res.items() if k != "series_differing"}, indent=1))
    return 0 if res["reports_equal"] == res["reports"] and not res["missing"] else 1


if __name__ == "__main__":
    sys.exit(main())
