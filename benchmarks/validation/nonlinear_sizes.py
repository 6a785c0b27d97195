"""Nonlinear sizes under sensor noise on the measured spring travel (issue #47, item 3).

Each case is one generator run (``gen_vehicle.py``, 10 s at 250 or 500 Hz, no force noise, pitch
and spring travel measured, 3e-6 rad of pitch noise) with one nonlinear effect, alternately an
asymmetric damper (ratio 0.6-1.6) and a bump stop (3-10x the spring, reached on 1-5 % of the
samples). The same run is written again with white noise of each ``--levels`` (m per sample) on
s1 and s2, and diagnosed; per level the table counts the cases whose effect is named and whose
interval holds the truth.

    python benchmarks/validation/nonlinear_sizes.py --n 12 --seed 778000 --out /tmp/nl   # ~15 min

writes ``benchmarks/results/nonlinear-sizes.json`` (``--json``). Run it from a worktree of another
commit (``PYTHONPATH`` there) for the before/after the closing notes quote.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))

from benchmarks._common import RESULTS, machine_info  # noqa: E402
from benchmarks.validation import gen_vehicle as gv  # noqa: E402

CAUSES = ("damper_asymmetry", "bump_stop")
CHANNEL_SETS = ("beta_s", "all", "beta_z3_s")


def case_for(k: int, seed: int) -> dict:
    """Case ``k``: its cause alternates over ``CAUSES``, its axle over front and rear."""
    cause = CAUSES[k % len(CAUSES)]
    target = ("d3", "d4")[k // 2 % 2] if cause == "damper_asymmetry" else ("k3", "k4")[k // 2 % 2]
    case = gv.make_case({"index": k, "stratum": "single", "what": [[cause, target]], "seed": seed + k,
                         "design": "nonlinear"}, durations=(10.0, 10.0), rates=(250, 500))
    case["channel_set"] = CHANNEL_SETS[k % len(CHANNEL_SETS)]
    case["channels"] = list(gv.CHANNEL_SETS[case["channel_set"]])
    case["effects"] = [e for e in case["effects"] if e["cause"] != "force_noise"]
    return case


def one(case: dict, level: float, out: str) -> dict:
    from jaxdrift.diagnosis.vehicle import diagnose_vehicle_run
    from jaxdrift.io import load_run, read_model

    c = json.loads(json.dumps(case))
    c["motion_noise"] = {ch: (level if ch in ("s1", "s2") else 3e-5 if ch == "beta_rate" else 3e-6)
                         for ch in c["channels"]}
    paths = gv.make_run(c, out, name=f"r{case['index']}_{level:g}")
    truth = json.load(open(paths["truth"]))
    eff = next(e for e in truth["effects"] if e["cause"] in CAUSES)
    model = read_model(paths["model"])
    rep = diagnose_vehicle_run(load_run(paths["csv"], "vehicle", model=model), model, with_simulation=False)
    f = next((g for g in rep["findings"] if g["cause"] == eff["cause"] and g.get("parameter") == eff["parameter"]), None)
    row = {"index": case["index"], "cause": eff["cause"], "parameter": eff["parameter"], "level": level,
           "fs": c["fs"], "channels": c["channel_set"], "true": eff["value"], "found": f is not None,
           "others": [[g["cause"], g.get("parameter", g.get("channel")), g["estimate"], g.get("confirmed")]
                      for g in rep["findings"] if g is not f and g["cause"] != "force_noise"]}
    if f is not None:
        row.update({"estimate": f["estimate"], "interval": f["interval"], "confirmed": f.get("confirmed"),
                    "held": f["interval"][0] <= eff["value"] <= f["interval"][1],
                    "error": f["estimate"] / eff["value"] - 1.0, "estimate_noisy_travel": f.get("estimate_noisy_travel")})
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=12, help="cases (each at every level)")
    ap.add_argument("--seed", type=int, default=778000, help="case k's generator seed is SEED + k")
    ap.add_argument("--levels", default="0,3e-5,1e-4", help="travel noise levels, m per sample")
    ap.add_argument("--out", required=True, help="folder for the generated runs")
    ap.add_argument("--json", default=os.path.join(RESULTS, "nonlinear-sizes.json"))
    a = ap.parse_args(argv)
    import jax

    jax.config.update("jax_enable_x64", True)
    levels = [float(x) for x in a.levels.split(",")]
    rows = []
    for k in range(a.n):
        case = case_for(k, a.seed)
        for lvl in levels:
            rows.append(one(case, lvl, a.out))
            r = rows[-1]
            print(f"{k:3d} {r['cause']:17s} {r['parameter']} {lvl:7.1e} {r['fs']:5.0f} Hz true {r['true']:.5g} "
                  + (f"est {r['estimate']:.5g} [{r['interval'][0]:.5g}, {r['interval'][1]:.5g}] "
                     f"{'held' if r['held'] else 'MISSED'}" if r["found"] else "not named"), flush=True)
    summary = {}
    for lvl in levels:
        for cause in CAUSES:
            sel = [r for r in rows if r["level"] == lvl and r["cause"] == cause]
            summary[f"{cause}@{lvl:g}"] = {"cases": len(sel), "named": sum(r["found"] for r in sel),
                                            "held": sum(bool(r.get("held")) for r in sel)}
    for k, v in summary.items():
        print(f"{k:28s} named {v['named']}/{v['cases']}, interval holds {v['held']}/{v['cases']}")
    doc = {"benchmark": "nonlinear_sizes", "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
           "machine": machine_info(), "args": vars(a), "summary": summary, "rows": rows}
    os.makedirs(os.path.dirname(os.path.abspath(a.json)), exist_ok=True)
    with open(a.json, "w") as fh:
        json.dump(doc, fh, indent=1)


if __name__ == "__main__":
    main()
