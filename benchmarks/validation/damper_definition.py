"""Does the damper ratio read high when a generator defines the asymmetric damper another way?
(issue #47, item 3). ``gen_vehicle.py``'s damper keeps the mean damping at the catalogue value
(compression 2 d / (1 + rho), rebound rho times that); the habit tried here keeps compression at the
catalogue value and makes rebound rho times it, so the mean damping moves by (1 + rho) / 2.

    python benchmarks/validation/damper_definition.py compression 6

writes the runs under /work/scratch/damp/<definition>/ (or $DAMP_OUT) and prints each run's findings.
"""
import copy  # noqa: F401
import json  # noqa: F401
import os
import sys
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
from benchmarks.validation import gen_vehicle as gv
import jax; jax.config.update("jax_enable_x64", True)
from jaxdrift.io import load_run, read_model
from jaxdrift.diagnosis.vehicle import diagnose_vehicle_run
defn = sys.argv[1]; n = int(sys.argv[2]); out = os.path.join(os.environ.get('DAMP_OUT', '/tmp/damp'), defn)
os.makedirs(out, exist_ok=True)
for k in range(n):
    case = {"index": k, "stratum": "single", "what": [["damper_asymmetry", "d3" if k % 2 == 0 else "d4"]], "seed": 9000 + k, "design": "nonlinear"}
    case = gv.make_case(case, durations=(10.0, 10.0), rates=(200, 500))
    for e in case["effects"]:
        if e["cause"] == "damper_asymmetry":
            e["value"] = 2.0 if k % 3 else 0.6
            if defn != "mean": e["definition"] = "compression"
    p = gv.make_run(case, out, name=f"r{k}")
    run = load_run(p["csv"], "vehicle", model=read_model(p["model"]))
    rep = diagnose_vehicle_run(run, read_model(p["model"]), with_simulation=False)
    fs = [(f["cause"], f.get("parameter", f.get("channel")), round(f["estimate"], 4), [round(x, 4) for x in f.get("interval", [])], f.get("confirmed")) for f in rep["findings"] if f["cause"] != "force_noise"]
    print(k, case["channel_set"], case["road_class"], case["fs"], [e["value"] for e in case["effects"] if e["cause"] == "damper_asymmetry"], fs, flush=True)
