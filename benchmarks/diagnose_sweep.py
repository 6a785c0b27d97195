"""Seeded sweep of the vehicle diagnosis over hidden effects: how often the right cause comes first
and how often the true values lie inside the reported 95 % intervals.

Each draw (``jaxdrift.studies._rungen.draw_sweep_case``, the slow test's draw) picks a generator seed, a
sampling rate, a channel set, an effect size ("realistic" or "small"), 0-2 systematic effects plus
force noise, a speed of 8-30 m/s and an ISO 8608 class A-C road, makes the run with ``jaxdrift.studies._rungen.make_run`` and
diagnoses it (without the force-driven simulation, which does not change the findings), and scores
the report with ``benchmarks/validation/scoring.score_report`` (the slow test's rule). Prints every miss and a
summary line; ``--json`` writes the counts.

Examples (the numbers quoted in ``docs/diagnosis.md``)::

    python benchmarks/diagnose_sweep.py --seed 2024 --n 24
    python benchmarks/diagnose_sweep.py --seed 7 --n 16 --channels "z3;s1,s2;z3,s1,s2"
    python benchmarks/diagnose_sweep.py --seed 5 --n 16 \\
        --channels "beta,z3,zeta1,zeta2;beta,z3,s1,s2,zeta1,zeta2;beta,z3,zeta1"
    python benchmarks/diagnose_sweep.py --seed 2024 --n 24 --no-noise
    python benchmarks/diagnose_sweep.py --seed 11 --n 14 --other-vehicle
    python benchmarks/diagnose_sweep.py --seed 2024 --n 24 --motion-noise 1e-6 1e-4
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import time

import numpy as np

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: benchmarks.validation
from benchmarks.validation.scoring import score_report  # noqa: E402

#: a vehicle unlike the seed's (heavier, longer, softer), to check nothing is tuned to the default
OTHER_VEHICLE = dict(a=1.3, b=1.5, m1=40.0, m2=45.0, m3=1400.0, I=2200.0, k1=3e5, k2=3e5, k3=6e4,
                     k4=7e4, d1=300.0, d2=300.0, d3=4000.0, d4=5000.0, g=9.81)
DEFAULT_CHANNELS = "beta;beta,z3;beta,s1,s2;beta,beta_rate,z3,s1,s2"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, default=2024, help="master seed of the draws (default 2024)")
    ap.add_argument("--n", type=int, default=24, help="number of runs (default 24)")
    ap.add_argument("--channels", default=DEFAULT_CHANNELS,
                    help=f"channel sets, ';'-separated, each ','-separated (default {DEFAULT_CHANNELS!r})")
    ap.add_argument("--no-noise", action="store_true", help="runs without force noise")
    ap.add_argument("--noise-size", choices=("drawn", "realistic", "small"), default="drawn",
                    help="force noise of the drawn size class (default) or always of this one")
    ap.add_argument("--other-vehicle", action="store_true",
                    help="true vehicle and model from OTHER_VEHICLE instead of the seed's table")
    ap.add_argument("--motion-noise", type=float, nargs=2, metavar=("LO", "HI"), default=None,
                    help="add white sensor noise to the measured motion (beta, z3, s1, s2 in rad or m; "
                         "beta_rate 10x), its level drawn log-uniformly in [LO, HI] per run")
    ap.add_argument("--json", help="write the counts to this JSON file")
    a = ap.parse_args(argv)

    from jaxdrift.diagnosis.vehicle import diagnose_vehicle_run
    from jaxdrift.studies import _rungen as rg
    from jaxdrift.io._csvio import DEFAULT_MODEL, VehicleRun

    model = dict(OTHER_VEHICLE if a.other_vehicle else DEFAULT_MODEL)
    chan_sets = [tuple(c.split(",")) for c in a.channels.split(";")]
    rng = np.random.default_rng(a.seed)
    t0 = time.perf_counter()
    first_ok = covered = total = 0
    misses = []
    for k in range(a.n):
        case = rg.draw_sweep_case(rng, chan_sets, noise=not a.no_noise)
        effects, fs, chans = case["effects"], case["fs"], case["channels"]
        if a.noise_size != "drawn":
            lo, hi = rg.SIZES[a.noise_size]["force_noise"]
            for e in effects:
                if e["cause"] == "force_noise":
                    e["value"] = float(np.random.default_rng(case["seed"] + 1).uniform(lo, hi))
        cols, _ = rg.make_run(model=model, duration=10.0, **case)
        if a.motion_noise:
            mrng = np.random.default_rng(case["seed"] + 3)
            lo, hi = a.motion_noise
            level = float(np.exp(mrng.uniform(np.log(lo), np.log(hi))))
            for c in chans:
                if c in ("beta", "z3", "s1", "s2", "beta_rate"):
                    cols[c] = np.asarray(cols[c]) + (10.0 if c == "beta_rate" else 1.0) * level * \
                        mrng.standard_normal(len(cols["t"]))
        run = VehicleRun("run.csv", cols["t"], {c: np.asarray(v) for c, v in cols.items() if c != "t"})
        rep = diagnose_vehicle_run(run, model, with_simulation=False)
        sc = score_report(rep, effects)
        first_ok += sc["first"]
        covered += sc["covered"]
        total += sc["total"]
        for m in sc["misses"]:
            extra = f" motion noise {level:.1e}" if a.motion_noise else ""
            print(f"run {k}: fs={fs:g} channels={chans}{extra}: {m}", flush=True)
            misses.append({"run": k, "fs": fs, "channels": list(chans), "miss": str(m)})
    line = (f"{a.n} runs: true causes first in {first_ok}; {covered} of {total} assessable true values "
            f"inside their 95 % intervals ({100.0 * covered / max(total, 1):.0f} %)")
    print(line)
    if a.json:
        from _common import machine_info

        with open(a.json, "w") as fh:
            json.dump({"benchmark": "diagnose_sweep", "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
                       "args": vars(a), "runs": a.n, "first": first_ok, "covered": covered, "total": total, "misses": misses,
                       "wall_s": time.perf_counter() - t0, "machine": machine_info()}, fh, indent=2)
            fh.write("\n")


if __name__ == "__main__":
    main()
