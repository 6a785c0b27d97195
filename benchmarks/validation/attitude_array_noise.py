"""Accelerometer noise against non-rigidity: false alarms on clean rigid arrays, and the size of
``accel_noise``, measured on runs of the independent generator (``benchmarks/validation/gen_attitude.py``).

Each of ``--n`` runs is a rigid accelerometer array (4-8 sensors on a vehicle-sized box, the
generator's ``draw_array``) with white gyro noise, a reference attitude on every row, every 10th or
100th row or none, a rate of 100-1000 Hz, 30-90 s, 6-9 significant digits, drawn by the
generator's ``make_case`` from the design seed. Even runs are clean (no effect but gyro noise);
odd runs carry white accelerometer noise of 0.002-0.1 m/s^2 (log-uniform). Nothing else. Each run
is diagnosed through ``jaxdrift.run_attitude_diagnosis``.

Scored per run: ``false_alarm`` (the first finding is systematic: gyro_bias, gyro_scale,
gyro_bias_drift, sensor_position, nonrigid), ``any_systematic`` (any finding is), ``nonrigid``
(reported at all), and for accelerometer noise runs ``accel_noise`` named, its estimate over the
truth, and whether the 95 % interval holds the truth.

With ``--bias K`` it measures instead the estimator's bias on the tuning generator
(``jaxdrift.studies._attgen``, seeds 9000..9000+K-1, 200 Hz, 20 s, the default 5-sensor array, a
reference on every row) in two regimes: accelerometer noise dominating the white residual (0.02
m/s^2, ARW 4e-4 rad/sqrt(s)) and the gyro noise's share dominating it (0.005 m/s^2 against ARW 2e-3,
whose share is about 0.008 m/s^2): mean and standard error of estimate / truth, and the coverage.

Reproduce (the numbers in docs/attitude.md; about 10 s per run on one core)::

    python benchmarks/validation/attitude_array_noise.py --seed 4242 --n 40 --json out/array_noise.json
    python benchmarks/validation/attitude_array_noise.py --bias 12
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # benchmarks/
sys.path.insert(0, str(HERE.parent))  # run as a script: the repository root

SYSTEMATIC = ("gyro_bias", "gyro_scale", "gyro_bias_drift", "sensor_position", "nonrigid")


def draw_case(i, seed):
    """Case ``i`` of the design: a rigid array, clean (even i) or with accelerometer noise (odd i)."""
    import numpy as np

    from benchmarks.validation import gen_attitude as ga

    rng = np.random.default_rng([seed, i])
    noisy = i % 2 == 1
    case = {"index": i, "stratum": "single" if noisy else "clean", "what": ["accel_noise"] if noisy else [],
            "seed": int(rng.integers(2**31))}
    full = ga.make_case(case, durations=(30.0, 90.0), rates=(100, 200, 250, 400, 500, 1000), max_samples=30000)
    if full["positions"] is None:  # the clean stratum draws an array only sometimes: always here
        full["positions"] = ga.draw_array(rng).tolist()
    # gyro noise on in every run (the clean stratum always has it; the noisy one most of the time)
    if not any(e["cause"] == "gyro_noise" for e in full["effects"]):
        full["effects"].insert(0, {"cause": "gyro_noise", "value": math.radians(float(rng.uniform(0.05, 1.0))) / 60.0})
    return full


def run_case(full, tmp):
    from benchmarks.validation import gen_attitude as ga
    import jaxdrift

    paths = ga.make_run(full, tmp, name=f"r{full['index']}")
    t0 = time.process_time()
    rep = jaxdrift.run_attitude_diagnosis(paths["csv"], paths["sensors"])
    cpu = time.process_time() - t0
    for p in paths.values():
        if p:
            os.remove(p)
    causes = [f["cause"] for f in rep["findings"]]
    truth = {e["cause"]: e["value"] for e in full["effects"]}
    row = {
        "index": full["index"], "fs": full["fs"], "duration": full["duration"], "sensors": len(full["positions"]),
        "reference_every": full["reference_every"], "precision": full["precision"],
        "gyro_noise": truth.get("gyro_noise"), "accel_noise": truth.get("accel_noise"),
        "causes": causes, "false_alarm": bool(causes) and causes[0] in SYSTEMATIC,
        "any_systematic": any(c in SYSTEMATIC for c in causes), "nonrigid": "nonrigid" in causes,
        "cpu_s": round(cpu, 1),
    }
    rr = rep["simulation_error"].get("rigidity_residual", {})
    row["rigidity_rms"] = rr.get("rms")
    row["white_rms"] = rr.get("white_rms")
    an = [f for f in rep["findings"] if f["cause"] == "accel_noise"]
    if an:
        row["accel_estimate"] = an[0]["estimate"]
        row["accel_interval"] = an[0]["interval"]
    if "accel_noise" in truth:
        row["accel_named"] = bool(an)
        if an:
            row["ratio"] = an[0]["estimate"] / truth["accel_noise"]
            lo, hi = an[0]["interval"]
            row["covered"] = bool(lo <= truth["accel_noise"] <= hi)
    return row


def summarise(rows):
    import numpy as np

    out = {}
    for name, sel in (("clean", [r for r in rows if r["accel_noise"] is None]),
                      ("accel_noise", [r for r in rows if r["accel_noise"] is not None])):
        n = len(sel)
        s = {"runs": n, "false_alarms": sum(r["false_alarm"] for r in sel),
             "any_systematic": sum(r["any_systematic"] for r in sel), "nonrigid": sum(r["nonrigid"] for r in sel)}
        if name == "accel_noise":
            ratios = np.array([r["ratio"] for r in sel if "ratio" in r])
            s["named"] = sum(r.get("accel_named", False) for r in sel)
            s["covered"] = sum(r.get("covered", False) for r in sel)
            if ratios.size:
                s["ratio_mean"] = float(ratios.mean())
                s["ratio_se"] = float(ratios.std(ddof=1) / math.sqrt(ratios.size)) if ratios.size > 1 else None
                s["ratio_min"] = float(ratios.min())
                s["ratio_max"] = float(ratios.max())
        else:
            s["accel_noise_named"] = sum("accel_noise" in r["causes"] for r in sel)
        out[name] = s
    return out


def bias_study(k):
    """estimate / truth of accel_noise on the tuning generator, two regimes, ``k`` seeds each."""
    import numpy as np

    from jaxdrift import run_attitude_diagnosis
    from jaxdrift.studies._attgen import DEFAULT_POSITIONS, make_attitude_run

    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, sigma, arw in (("accel dominates", 0.02, 4e-4), ("gyro share dominates", 0.005, 2e-3)):
            ratios, covered = [], 0
            for seed in range(9000, 9000 + k):
                tr = make_attitude_run(tmp, seed, duration=20.0, rate_hz=200.0, arw=arw, accel_noise=sigma,
                                       positions=DEFAULT_POSITIONS, name="b")
                rep = run_attitude_diagnosis(tr["paths"]["run"], tr["paths"]["sensors"])
                f = [f for f in rep["findings"] if f["cause"] == "accel_noise"]
                if f:
                    ratios.append(f[0]["estimate"] / sigma)
                    covered += f[0]["interval"][0] <= sigma <= f[0]["interval"][1]
                else:
                    ratios.append(0.0)
            r = np.array(ratios)
            out[name] = {"accel_noise": sigma, "arw": arw, "runs": k, "ratio_mean": float(r.mean()),
                         "ratio_se": float(r.std(ddof=1) / math.sqrt(k)), "ratio_min": float(r.min()),
                         "ratio_max": float(r.max()), "covered": int(covered)}
            print(name, json.dumps(out[name]), flush=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=4242, help="design seed (default 4242)")
    ap.add_argument("--n", type=int, default=40, help="number of runs (default 40)")
    ap.add_argument("--json", default=None, help="write the per-run rows and the summary here")
    ap.add_argument("--bias", type=int, default=0, metavar="K",
                    help="measure the estimator's bias on the tuning generator with K seeds per regime instead")
    a = ap.parse_args(argv)
    if a.bias:
        res = bias_study(a.bias)
        if a.json:
            Path(a.json).write_text(json.dumps(res, indent=1) + "\n")
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(a.n):
            full = draw_case(i, a.seed)
            r = run_case(full, tmp)
            rows.append(r)
            acc = (f" accel {r['accel_noise']:.3g} -> {r.get('accel_estimate', float('nan')):.3g}"
                   if r["accel_noise"] is not None else "")
            print(f"{i:3d} {r['fs']:6.0f} Hz {r['duration']:5.1f} s N={r['sensors']} ref/{r['reference_every']} "
                  f"digits {r['precision']}{acc}: {r['causes'][:4]} ({r['cpu_s']} s)", flush=True)
    summary = summarise(rows)
    print(json.dumps(summary, indent=1))
    if a.json:
        os.makedirs(os.path.dirname(os.path.abspath(a.json)), exist_ok=True)
        Path(a.json).write_text(json.dumps({"seed": a.seed, "n": a.n, "summary": summary, "runs": rows},
                                           indent=1) + "\n")


if __name__ == "__main__":
    main()
