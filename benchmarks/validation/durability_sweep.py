"""Validation sweep of the durability analysis: stabilised damage against the true damage.

Runs from the generator (``jaxdrift.studies.make_run``: the road-driven true vehicle, whose states
give the true section forces ``f3 = k3 s1 + d3 s1'``, ``f4 = k4 s2 + d4 s2'``) over ISO 8608 road
classes B-E, sample rates 200-2000 Hz and white pitch noise of 0, 0.01 and 0.02 deg added to the
measured pitch; white force noise of ``--force-noise`` N on both wheel forces. For each case the
nominal section forces of every variant (``jaxdrift.durability.section_forces``) are counted
(rainflow, K = 5) and divided by the true damage. Also reported: the stabilised ratio with plain
central differences of the noisy pitch (no filter), and the ``measured`` variant from the true
spring travel with 1e-5 m of noise.

    python benchmarks/validation/durability_sweep.py            # writes benchmarks/results/durability-sweep.{json,md}
    python benchmarks/validation/durability_sweep.py --quick    # 4 runs, no files
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # run as a script: the repository root
from benchmarks._common import RESULTS, machine_info  # noqa: E402

ROADS = ("B", "C", "D", "E")
RATES = (200.0, 500.0, 1000.0, 2000.0)
PITCH_NOISE_DEG = (0.0, 0.01, 0.02)


def true_damage(truth, k):
    from jaxdrift.durability import load_statistics

    s, p = truth["signals"], truth["params"]
    f3 = p["k3"] * s["s1"] + p["d3"] * s["ds1"]
    f4 = p["k4"] * s["s2"] + p["d4"] * s["ds2"]
    return [load_statistics(f3, k)["damage"], load_statistics(f4, k)["damage"]]


def case(road, fs, seed, duration, force_noise, k=5.0):
    from jaxdrift.durability import load_statistics, section_forces
    from jaxdrift.studies import make_run

    speed = float(np.random.default_rng(seed).uniform(10, 25))
    cols, truth = make_run([{"cause": "force_noise", "value": force_noise}], fs=fs, road_class=road,
                           duration=duration, seed=seed, speed=speed, channels=("beta", "s1", "s2"))
    dt = true_damage(truth, k)
    p = truth["params"]
    rng = np.random.default_rng(seed + 1)
    rows = []
    s1 = cols["s1"] + 1e-5 * rng.standard_normal(cols["t"].size)
    s2 = cols["s2"] + 1e-5 * rng.standard_normal(cols["t"].size)
    for nd in PITCH_NOISE_DEG:
        beta = cols["beta"] + np.deg2rad(nd) * rng.standard_normal(cols["t"].size)
        row = {"road": road, "fs": fs, "speed": speed, "seed": seed, "pitch_noise_deg": nd}
        for filt in (True, False):
            if not filt and nd == 0:
                continue
            res = section_forces(cols["t"], cols["f1"], cols["f2"], p, beta=beta, s1=s1, s2=s2,
                                 filter_pitch=filt)
            for v, F in res["forces"].items():
                if not filt and v != "stabilised":
                    continue
                name = v if filt else "stabilised_unfiltered"
                row[name] = [load_statistics(F[:, j], k)["damage"] / dt[j] for j in range(2)]
            if filt:
                row["cutoff_hz"] = res["derivative_filter"]["cutoff_hz"]
                row["pitch_spring_torque_max"] = float(np.max(np.abs(res["pitch_spring_torque"])))
        rows.append(row)
    return rows


def markdown(rows, meta) -> str:
    out = ["# Durability validation sweep", "",
           f"{meta['n_runs']} generated runs of {meta['duration_s']} s, force noise {meta['force_noise_N']} N, "
           f"K = 5; damage ratio = computed / true pseudo-damage (f3, f4). Command: `{meta['command']}`.", "",
           "| road | Hz | pitch noise deg | cutoff Hz | stabilised f3 | f4 | unfiltered f3 | f4 | force_driven f3 | f4 | pitch_spring f3 | f4 | measured f3 | f4 |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        def c(name):
            v = r.get(name)
            return "| - | - " if v is None else f"| {v[0]:.4f} | {v[1]:.4f} "
        cut = "none" if r["cutoff_hz"] is None else f"{r['cutoff_hz']:.1f}"
        out.append(f"| {r['road']} | {r['fs']:g} | {r['pitch_noise_deg']:g} | {cut} " + c("stabilised")
                   + c("stabilised_unfiltered") + c("force_driven") + c("pitch_spring") + c("measured") + "|")
    st = np.array([r["stabilised"] for r in rows])
    out += ["", f"stabilised: worst |ratio - 1| = {np.max(np.abs(st - 1)):.4f} over {st.size} forces "
            f"(limit 0.05); median {np.median(st):.4f}."]
    return "\n".join(out) + "\n"


def main(argv=None):
    import jax

    jax.config.update("jax_enable_x64", True)
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--force-noise", type=float, default=10.0)
    ap.add_argument("--seed", type=int, default=100)
    ap.add_argument("--quick", action="store_true", help="4 runs (one per road), no files written")
    a = ap.parse_args(argv)
    grid = [(r, fs) for r in ROADS for fs in RATES]
    if a.quick:
        grid = [("B", 200.0), ("C", 500.0), ("D", 1000.0), ("E", 2000.0)]
    rows = []
    t0 = time.perf_counter()
    for i, (road, fs) in enumerate(grid):
        for r in case(road, fs, a.seed + i, a.duration, a.force_noise):
            rows.append(r)
            print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in r.items()}), flush=True)
    meta = {"n_runs": len(grid), "duration_s": a.duration, "force_noise_N": a.force_noise,
            "seconds": round(time.perf_counter() - t0, 1),
            "command": "python benchmarks/validation/durability_sweep.py" + (" --quick" if a.quick else ""),
            "machine": machine_info()}
    st = np.array([r["stabilised"] for r in rows])
    print(f"stabilised worst |ratio-1| {np.max(np.abs(st - 1)):.4f}; {meta['seconds']} s")
    if not a.quick:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "durability-sweep.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1))
        (RESULTS / "durability-sweep.md").write_text(markdown(rows, meta))


if __name__ == "__main__":
    main()
