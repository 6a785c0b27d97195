"""Does the confirmation gate accept the truth? The vehicle diagnosis' two checks of its corrections
(``_confirm.confirm_corrections``: the halves check on the residual channel; and
``confirm_by_resimulation``: the force-driven re-simulation) are given the *true* corrections of
each generated run and must keep every one of them. A run where a check drops a true correction is
a defect of the check, not of the data.

Runs come from the independent generator ``gen_vehicle.py`` (designs ``standard``, ``nonlinear``,
``gain_drift``), sized as the validation sweep sizes them. Each run is read through the public API;
the problem is set up as ``diagnose_vehicle_run`` sets it up (in a run with a nonlinear effect,
``select_with_form``: the nonlinear force the adequacy test finds is carried, as in a diagnosis);
then the selection is replaced by the
true linear causes at their true sizes and both checks run on it. Only runs with at least one
linear systematic effect (offset, scale, delay, gain drift, parameter) count.

    python benchmarks/validation/gate_truth.py --design standard --n 120 --seed 20261210 --out /tmp/gate
    python benchmarks/validation/gate_truth.py --report-only --out /tmp/gate

Per run a JSON line is appended to ``OUT/gate-<design>-<seed>.jsonl`` (runs already there are
skipped); the summary prints per design the runs whose true corrections were all kept.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import shutil
import sys
import tempfile
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))  # run as a script: the repository root

from benchmarks.validation import gen_vehicle, sweep

LINEAR = ("force_offset", "force_scale", "force_delay", "force_gain_drift", "parameter_error")


def true_selection(prob, effects):
    """A selection whose fit holds the true linear causes at their true sizes."""
    import numpy as np

    from jaxdrift.diagnosis.vehicle._causes import Cause
    from jaxdrift.diagnosis.vehicle._problem import Fit
    from jaxdrift.diagnosis.vehicle._select import Selection, _covariance

    causes, theta = [], []
    for e in effects:
        if e["cause"] not in LINEAR:
            continue
        c = Cause(e["cause"], e.get("channel") or e.get("parameter"))
        causes.append(c)
        theta.append(c.kind.to_theta(float(e["value"])))
    theta = np.asarray(theta, dtype=float)
    r, res = prob.eval(causes, theta)
    X = prob.jacobian(causes, theta)
    fit = Fit(causes, theta, r, res, float(r @ r), X)
    sigma2 = fit.rss / max(len(r) - len(causes), 1)
    cov = _covariance(prob, X, sigma2)
    z = theta / np.sqrt(np.maximum(np.diag(cov), 1e-300))
    return Selection(fit, cov, float(np.sqrt(sigma2)), z, {}, [], {}, fit.rss, [fit.rss])


def run_one(case: dict, out_path: str, sizing: dict) -> dict:
    import jaxdrift
    from jaxdrift.diagnosis.vehicle._confirm import (
        confirm_by_resimulation,
        confirm_corrections,
    )
    from jaxdrift.diagnosis.vehicle._pipeline import select_with_form
    from jaxdrift.diagnosis.vehicle._problem import _Problem
    from jaxdrift.diagnosis.vehicle._residuals import ResidualPipeline

    res = {"index": case["index"], "design": case.get("design", "standard"), "stratum": case["stratum"],
           "commit": sweep._commit()}
    scratch = tempfile.mkdtemp(prefix="gate-")
    try:
        w0 = time.time()
        full = gen_vehicle.make_case(case, **sizing)
        paths = gen_vehicle.make_run(full, scratch)
        res["effects"] = full["effects"]
        res["case"] = {k: full[k] for k in ("fs", "duration", "channels", "road_class", "speed") if k in full}
        lin = [e for e in full["effects"] if e["cause"] in LINEAR]
        res["n_true"] = len(lin)
        if lin:
            run = jaxdrift.read_vehicle_run(paths["csv"])
            model = jaxdrift.read_model(paths["model"])
            prob = _Problem(ResidualPipeline(run), model)
            if any(e["cause"] in sweep.NONLINEAR for e in full["effects"]):
                prob, _, _ = select_with_form(prob)  # carries the nonlinear force the test finds
            sel = true_selection(prob, full["effects"])
            log: list = []
            _, held = confirm_corrections(prob, sel, log)
            _, resim = confirm_by_resimulation(prob, sel, log)
            res["dropped_halves"] = [c.label for c, *_ in held]
            res["dropped_resim"] = [c.label for c, *_ in resim]
            res["log"] = log
        res["wall_s"] = time.time() - w0
    except Exception as e:  # noqa: BLE001 - a failure is a result, recorded
        res["error"] = f"{type(e).__name__}: {e}"
        res["traceback"] = traceback.format_exc()[-2000:]
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    with open(out_path, "a") as fh:
        fh.write(json.dumps(res, default=float) + "\n")
    return res


def summarise(out: str) -> dict:
    paths = sorted(glob.glob(os.path.join(out, "gate-*.jsonl")))
    rows = {}
    for path in paths:
        with open(path) as fh:  # one row per run (a resumed sweep may have written one twice)
            rows.update({(path, r["index"]): r for r in map(json.loads, filter(str.strip, fh))})
    rows = list(rows.values())
    summary = {}
    for r in rows:
        d = summary.setdefault(r["design"], {"runs": 0, "kept_all": 0, "errors": 0, "drops": []})
        if r.get("error"):
            d["errors"] += 1
            continue
        if not r.get("n_true"):
            continue
        d["runs"] += 1
        dropped = r.get("dropped_halves", []) + r.get("dropped_resim", [])
        if dropped:
            d["drops"].append({"index": r["index"], "halves": r.get("dropped_halves"),
                               "resim": r.get("dropped_resim"), "case": r.get("case"),
                               "effects": [sweep.label(sweep.target(e)) + f"={e['value']:.4g}" for e in r["effects"]]})
        else:
            d["kept_all"] += 1
    commits = sorted({r.get("commit") for r in rows if r.get("commit")})
    files = [os.path.basename(p)[len("gate-"):-len(".jsonl")] for p in paths]
    return {"designs": summary, "files": files, "diagnosed_by": commits}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--design", choices=("standard", "nonlinear", "gain_drift"), default="standard")
    ap.add_argument("--n", type=int, default=0, help="cases of the design")
    ap.add_argument("--seed", type=int, default=0, help="design seed")
    ap.add_argument("--out", required=True, help="folder for the per-run JSON lines")
    ap.add_argument("--long", action="store_true",
                    help="runs of 20-60 s up to 30,000 samples (the sweep's are 10-40 s up to 10,000), where a "
                         "force-driven simulation drifts further")
    ap.add_argument("--report-only", action="store_true")
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    if not a.report_only:
        make = {"standard": gen_vehicle.design, "nonlinear": gen_vehicle.design_nonlinear,
                "gain_drift": gen_vehicle.design_gain_drift}[a.design]
        cases = make(a.n, a.seed)
        path = os.path.join(a.out, f"gate-{a.design}{'-long' if a.long else ''}-{a.seed}.jsonl")
        done = set()
        if os.path.exists(path):
            with open(path) as fh:
                done = {json.loads(line)["index"] for line in fh if line.strip()}
        for case in cases:
            if case["index"] in done or case["stratum"] in ("clean", "noise"):
                continue  # an effect-free run has no correction to keep
            case.setdefault("design", a.design)
            sizing = dict(sweep.SIZING["vehicle"])
            if a.long:
                sizing.update(durations=(20.0, 60.0), max_samples=30000)
            r = run_one(case, path, sizing)
            flag = r.get("error") or (r.get("dropped_halves", []) + r.get("dropped_resim", [])) or "ok"
            print(f"{case['index']:4d} {case['stratum']:7s} true={r.get('n_true')} {flag} {r.get('wall_s', 0):.1f}s",
                  flush=True)
    s = summarise(a.out)
    for design, d in s["designs"].items():
        print(f"{design}: true corrections all kept in {d['kept_all']}/{d['runs']} runs ({d['errors']} errors)")
        for x in d["drops"]:
            print("   ", x)
    with open(os.path.join(a.out, "summary.json"), "w") as fh:
        json.dump(s, fh, indent=1)


if __name__ == "__main__":
    main()
