"""Does the damper ratio read high when a generator defines the asymmetric damper another way?
(issue #47, item 3). ``gen_vehicle.py``'s damper keeps the mean damping at the catalogue value
(compression 2 d / (1 + rho), rebound rho times that); ``--definition compression`` keeps
compression at the catalogue value and makes rebound rho times it, so the mean damping moves by
(1 + rho) / 2, which the diagnosis must take as a damper parameter error beside the ratio.

    python benchmarks/validation/damper_definition.py --definition compression --n 6 --out /tmp/damp

Each run: 10 s at 200 or 500 Hz, ratio 2.0 (or 0.6 every third run), on d3 or d4; prints the
diagnosis's findings beside the true ratio.
"""

from __future__ import annotations

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
from benchmarks.validation import gen_vehicle as gv  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--definition", choices=("mean", "compression"), default="compression")
    ap.add_argument("--n", type=int, default=6)
    ap.add_argument("--seed", type=int, default=9000, help="run k's generator seed is SEED + k")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    import jax

    jax.config.update("jax_enable_x64", True)
    from jaxdrift.diagnosis.vehicle import diagnose_vehicle_run
    from jaxdrift.io import load_run, read_model

    out = os.path.join(a.out, a.definition)
    os.makedirs(out, exist_ok=True)
    for k in range(a.n):
        case = {"index": k, "stratum": "single", "what": [["damper_asymmetry", "d3" if k % 2 == 0 else "d4"]],
                "seed": a.seed + k, "design": "nonlinear"}
        case = gv.make_case(case, durations=(10.0, 10.0), rates=(200, 500))
        for e in case["effects"]:
            if e["cause"] == "damper_asymmetry":
                e["value"] = 2.0 if k % 3 else 0.6
                if a.definition != "mean":
                    e["definition"] = "compression"
        p = gv.make_run(case, out, name=f"r{k}")
        model = read_model(p["model"])
        rep = diagnose_vehicle_run(load_run(p["csv"], "vehicle", model=model), model, with_simulation=False)
        found = [(f["cause"], f.get("parameter", f.get("channel")), round(f["estimate"], 4),
                  [round(x, 4) for x in f.get("interval", [])], f.get("confirmed"))
                 for f in rep["findings"] if f["cause"] != "force_noise"]
        true = [e["value"] for e in case["effects"] if e["cause"] == "damper_asymmetry"]
        print(k, case["channel_set"], case["road_class"], case["fs"], "true ratio", true, found, flush=True)


if __name__ == "__main__":
    main()
