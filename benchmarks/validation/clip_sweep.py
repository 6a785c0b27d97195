"""force_clipping on fresh runs: each case of the independent generator's standard design
(``gen_vehicle.design``) is written twice, once as drawn and once with f1 or f2 clipped on 0.2-2 %
of its samples (``gen_vehicle.draw_effect``), and both are diagnosed (no re-simulation). Scored:
the clipping named on the right channel, its range equal to the truth within the run's printed
digits, the other systematic findings equal to those of the unclipped twin, and the force-noise
interval holding the truth.

    python benchmarks/validation/clip_sweep.py --n 12 --seed 20261501 --out OUT [--jobs 2]

Writes ``OUT/clip-sweep-seedSEED.json`` (per run: truth and findings of both) and prints one line
per run and the totals.
"""

from __future__ import annotations

import argparse
import copy
import json
import os
import sys
from multiprocessing import Pool

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", ".."))

NOISE = "force_noise"
_ARGS = {}


def _one(i: int) -> dict:
    import jaxdrift
    from benchmarks.validation import gen_vehicle as gen

    n, seed, out_dir = _ARGS["n"], _ARGS["seed"], _ARGS["out"]
    case = gen.make_case(gen.design(n, seed)[i], durations=(10.0, 30.0), max_samples=15000)
    rng = np.random.default_rng(seed * 1000 + i)
    ch = ("f1", "f2")[int(rng.integers(2))]
    clipped = copy.deepcopy(case)
    clipped["effects"].append(gen.draw_effect(rng, "force_clipping", ch, None))
    out = {"index": i, "vehicle": case["vehicle_kind"], "fs": case["fs"], "precision": case["precision"]}
    for tag, c in (("clipped", clipped), ("twin", case)):
        paths = gen.make_run(c, out_dir, f"{tag}{i:02d}")
        with open(paths["truth"]) as fh:
            truth = json.load(fh)
        run = jaxdrift.read_vehicle_run(paths["csv"])
        rep = jaxdrift.diagnose_vehicle_run(run, jaxdrift.read_model(paths["model"]), with_simulation=False)
        out[tag] = {"truth": truth["effects"], "samples": rep["run"]["samples"],
                    "findings": [{k: f.get(k) for k in ("cause", "channel", "parameter", "estimate", "interval",
                                                        "estimate_kind")} for f in rep["findings"]]}
    return out


def _systematic(rep: dict) -> list:
    return sorted({(f["cause"], f.get("channel") or f.get("parameter")) for f in rep["findings"]
                   if f["cause"] not in (NOISE, "none", "force_clipping")})


def score(res: list[dict]) -> dict:
    rows, named, exact, same, noise_ok, noise_n = [], 0, 0, 0, 0, 0
    for r in res:
        c, t = r["clipped"], r["twin"]
        clip = next(e for e in c["truth"] if e["cause"] == "force_clipping")
        fc = [f for f in c["findings"] if f["cause"] == "force_clipping"]
        ok = bool(fc) and fc[0]["channel"] == clip["channel"]
        # the range as the CSV printed it (the run's significant digits)
        ex = ok and float(f"{clip['value']:.{r['precision']}g}") == fc[0]["estimate"]
        s_c, s_t = _systematic(c), _systematic(t)
        nt = next((e["value"] for e in c["truth"] if e["cause"] == NOISE), 0.0)
        nf = [f for f in c["findings"] if f["cause"] == NOISE]
        held = None
        if nf:
            lo, hi = nf[0]["interval"]
            held = lo <= nt <= hi
            noise_n += 1
            noise_ok += held
        named, exact, same = named + ok, exact + ex, same + (s_c == s_t)
        rows.append({"index": r["index"], "vehicle": r["vehicle"], "fs": r["fs"], "channel": clip["channel"],
                     "share": clip["share"], "named": ok, "range_exact": ex, "truth": sorted(
                         (e["cause"], e.get("channel") or e.get("parameter")) for e in c["truth"]
                         if e["cause"] not in (NOISE, "force_clipping")),
                     "clipped": s_c, "twin": s_t, "noise_true": nt,
                     "noise_interval": nf[0]["interval"] if nf else None, "noise_held": held})
    return {"runs": len(res), "named": named, "range_exact": exact, "systematic_as_twin": same,
            "noise_held": noise_ok, "noise_intervals": noise_n, "rows": rows}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=12)
    ap.add_argument("--seed", type=int, default=20261501)
    ap.add_argument("--out", required=True)
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    _ARGS.update(n=a.n, seed=a.seed, out=a.out)
    with Pool(a.jobs) as p:
        res = p.map(_one, range(a.n))
    sc = score(res)
    for r in sc["rows"]:
        print(f"{r['index']:3d} {r['vehicle']:9s} {r['fs']:6.0f} Hz {r['channel']} {100 * r['share']:.2f} % "
              f"{'named' if r['named'] else 'MISSED'} {'exact' if r['range_exact'] else ''} | truth {r['truth']} "
              f"| clipped {r['clipped']} | twin {r['twin']} | noise {r['noise_true']:.3g} in "
              f"{r['noise_interval']}: {r['noise_held']}")
    print(f"named {sc['named']}/{sc['runs']}, range exact {sc['range_exact']}, other findings as the unclipped "
          f"twin's {sc['systematic_as_twin']}/{sc['runs']}, noise interval holds the truth "
          f"{sc['noise_held']}/{sc['noise_intervals']}")
    with open(os.path.join(a.out, f"clip-sweep-seed{a.seed}.json"), "w") as fh:
        json.dump({"seed": a.seed, "n": a.n, "score": sc, "runs": res}, fh, indent=1)


if __name__ == "__main__":
    main()
