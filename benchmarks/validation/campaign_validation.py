"""Score a campaign against the truth of ``benchmarks/validation/gen_campaign.py``.

    python benchmarks/validation/gen_campaign.py --n 40 --seed S --out DIR
    jaxdrift campaign --manifest DIR/campaign.toml --out OUT --workers 2
    python benchmarks/validation/campaign_validation.py DIR OUT [--json benchmarks/results/campaign_validation.json]

Per shared parameter: the joint estimate and interval, whether it holds the truth, the single-run
intervals that name it (their median width) and the narrowing; the stacked fit's value and
whether the same interval centred on it holds the truth; the joint half-width's terms (the
meta-analytic standard error over the runs' single-run error budgets, the over-dispersion, the
joint-level factor, the effective number of runs) and the runs' own estimates (``joint.consistency``) against the
truth: their scatter about it in units of their sandwich standard errors, alone and for the runs
more precise than the single-run floor, and their inverse-variance mean. Per run: whether its logger's sensor
effect (or its absence) is named right by the single-run diagnosis and by the campaign (the
sensor effects against the joint vehicle). Named right: a finding of the true cause on the true
channel, and no other sensor finding; for an effect-free logger, no sensor finding at all.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import statistics
import sys

import scipy.stats

SENSOR = ("force_offset", "force_scale", "force_delay")


def _named_right(findings, effect) -> bool:
    sens = [(f["cause"], f.get("channel")) for f in findings if f.get("cause") in SENSOR]
    if effect is None:
        return not sens
    return sens == [(effect["cause"], effect["channel"])]


def _terms(f: dict, cov: dict, cons: dict | None) -> dict:
    """The joint half-width's terms: ``half = factor x 1.96 sqrt(d) x meta_se``, ``meta_se = 1 /
    sqrt(sum w_i)`` over the runs' single-run error budgets ``w_i = 1 / (se_i^2 + (floor /
    1.96)^2)``; beside it what the runs' sandwich errors alone would give (``1 / sqrt(sum 1 /
    se_i^2)``) and the stacked fit's sandwich standard error."""
    j = cov["parameters"].index(f["parameter"])
    k = len(cov["parameters"])
    se = math.sqrt(max(cov["theta_covariance"][j][j] if isinstance(cov["theta_covariance"][0], list)
                       else cov["theta_covariance"][j * k + j], 0.0))
    d = f.get("overdispersion", 1.0)
    each = f.get("interval_level", {}).get("each", 0.95)
    factor = float(scipy.stats.norm.ppf(0.5 + 0.5 * each) / scipy.stats.norm.ppf(0.975))
    half = 0.5 * (f["interval"][1] - f["interval"][0])
    meta = (cons or {}).get("meta") or {}
    pr = (cons or {}).get("per_run") or []
    return {"stacked_sandwich_se": se, "overdispersion": d, "meta_se": meta.get("se"),
            "meta_se_without_floor": (1.0 / math.sqrt(sum(1.0 / r["se"] ** 2 for r in pr))) if pr else None,
            "statistical_half": 1.96 * meta["se"] * math.sqrt(d) if meta else None,
            "effective_runs": f.get("effective_runs"), "largest_weight_share": meta.get("largest_weight_share"),
            "runs_informing": f.get("runs_informing"), "joint_level_factor": factor, "half": half}


def _own_vs_truth(entry: dict, true: float, floor_se: float) -> dict:
    """The runs' own estimates of a shared parameter against the truth."""
    pr = entry["per_run"]
    z = [(r["estimate"] - true) / r["se"] for r in pr]
    w = [1.0 / r["se"] ** 2 for r in pr]
    prec = [zi for zi, r in zip(z, pr) if r["se"] < floor_se]
    return {"runs": len(pr), "chi2_about_truth": sum(zi * zi for zi in z),
            "se_min": min(r["se"] for r in pr), "se_median": statistics.median(r["se"] for r in pr),
            "se_max": max(r["se"] for r in pr),
            "precise_runs": len(prec), "precise_rms_z": math.sqrt(sum(x * x for x in prec) / len(prec)) if prec else None,
            "precise_max_abs_z": max(abs(x) for x in prec) if prec else None,
            "precise_median_abs_error": statistics.median(abs(r["estimate"] - true) for r in pr if r["se"] < floor_se)
            if prec else None,
            "inverse_variance_mean_error": sum(wi * (r["estimate"] - true) for wi, r in zip(w, pr)) / sum(w),
            "inverse_variance_se": 1.0 / math.sqrt(sum(w)),
            # the largest share of one run in the joint estimate's weights (where the campaign records them)
            "largest_weight_share": (max(r["weight"] for r in pr) / sum(r["weight"] for r in pr)
                                     if all("weight" in r for r in pr) else None)}


def score(truth_dir: str, out_dir: str, floor: float = 2e-4) -> dict:
    truth = json.load(open(os.path.join(truth_dir, "truth.json")))
    doc = json.load(open(os.path.join(out_dir, "campaign.json")))
    loggers = {lg["id"]: lg["effect"] for lg in truth["loggers"]}
    # the shared parameter errors (a joint nonlinear cause names its parameter too: scored by
    # campaign_nonlinear.score)
    joint = {f["parameter"]: f for f in doc["joint"]["findings"] if f.get("cause", "parameter_error") == "parameter_error"}
    params = []
    for e in truth["shared"]:
        if e.get("cause", "parameter_error") != "parameter_error":
            continue
        p, true = e["parameter"], e["value"]
        f = joint.get(p)
        singles = [fd["interval"] for r in doc["runs"] if r["status"] == "ok" for fd in r["findings"]
                   if fd.get("cause") == "parameter_error" and fd.get("parameter") == p]
        s_cover = sum(lo <= true <= hi for lo, hi in singles)
        med = statistics.median(hi - lo for lo, hi in singles) if singles else None
        row = {"parameter": p, "true": true, "named_by_single_runs": len(singles), "single_runs_covering": s_cover,
               "median_single_width": med}
        if f is None:
            row.update({"joint": None, "contains_truth": False})
        else:
            w = f["interval"][1] - f["interval"][0]
            cons = next((c for c in doc["joint"]["consistency"]["parameters"] if c["parameter"] == p), None)
            st = f.get("stacked_estimate")
            row.update({"joint": f["estimate"], "joint_interval": f["interval"], "joint_width": w,
                        "contains_truth": f["interval"][0] <= true <= f["interval"][1],
                        "narrowing": (med / w) if med else None,
                        "narrower_than_every_single": all(w < hi - lo for lo, hi in singles),
                        # the stacked fit's value, and the same interval centred on it
                        "stacked_estimate": st,
                        "stacked_centred_contains_truth": None if st is None else abs(true - st) <= 0.5 * w,
                        "error_in_half_widths": abs(f["estimate"] - true) / (0.5 * w),
                        "stacked_error_in_half_widths": None if st is None else abs(st - true) / (0.5 * w),
                        "half_width_terms": _terms(f, doc["joint"]["covariance"], cons)})
            if cons and cons.get("per_run"):
                row["own_estimates_vs_truth"] = _own_vs_truth(cons, true, floor / 1.96)
        params.append(row)
    extra = [p for p in joint if p not in {e["parameter"] for e in truth["shared"]
                                           if e.get("cause", "parameter_error") == "parameter_error"}]
    cases = {c["index"]: c for c in truth["cases"]}
    runs, n_single, n_camp = [], 0, 0
    for r in doc["runs"]:
        if r["status"] != "ok":
            runs.append({"run": r["name"], "status": r["status"], "message": r.get("message")})
            continue
        idx = int(r["name"].split("_")[-1])
        eff = loggers[cases[idx]["logger"]]
        s = _named_right(r["findings"], eff)
        c = _named_right(r["campaign"]["sensor_findings"], eff)
        n_single += s
        n_camp += c
        runs.append({"run": r["name"], "logger": cases[idx]["logger"], "effect": eff, "single_right": s,
                     "campaign_right": c, "channels": cases[idx]["channel_set"], "fs": cases[idx]["fs"],
                     "duration": cases[idx]["duration"]})
    return {"truth": truth_dir, "campaign": out_dir, "seed": truth["seed"], "runs": len(doc["runs"]),
            "shared": params, "joint_parameters_not_in_truth": extra,
            "sensor_named_right": {"single_run": n_single, "campaign": n_camp},
            "consistency": [{k: c[k] for k in ("parameter", "chi2", "dof", "p_value", "consistent")}
                            | {"disagreeing": [d["run"] for d in c["disagreeing_runs"]]}
                            for c in doc["joint"]["consistency"]["parameters"]],
            "wall_s": doc["provenance"]["wall_s"], "executor": doc["provenance"]["executor"],
            "per_run": runs}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("truth_dir")
    ap.add_argument("out_dir")
    ap.add_argument("--json", help="write the score here")
    a = ap.parse_args(argv)
    res = score(a.truth_dir, a.out_dir)
    res["machine"] = {"platform": platform.platform(), "python": sys.version.split()[0], "cpus": os.cpu_count(),
                      "load_average": os.getloadavg()}
    for p in res["shared"]:
        print(f"{p['parameter']}: true {p['true']:.5f} joint {p.get('joint')} {p.get('joint_interval')} "
              f"contains {p['contains_truth']}; named by {p['named_by_single_runs']} runs, median single width "
              f"{p['median_single_width']}, narrowing x{p.get('narrowing')}")
        if "half_width_terms" in p:
            t = p["half_width_terms"]
            print(f"   half {t['half']:.4g} = {t['joint_level_factor']:.4f} x 1.96 x meta se {t['meta_se']:.4g} x "
                  f"sqrt(d {t['overdispersion']:.3g}) (without the floor {t['meta_se_without_floor']:.4g}; the "
                  f"stack's sandwich se {t['stacked_sandwich_se']:.4g}); effective runs {t['effective_runs']:.3g}, "
                  f"largest weight share {t['largest_weight_share']:.3g}; stacked value {p['stacked_estimate']} "
                  f"holds the truth with this interval: {p['stacked_centred_contains_truth']}")
        if "own_estimates_vs_truth" in p:
            o = p["own_estimates_vs_truth"]
            print(f"   runs' own estimates: chi2 about the truth {o['chi2_about_truth']:.3g} on {o['runs']}; "
                  f"{o['precise_runs']} runs with se below the floor: rms z {o['precise_rms_z']}, max |z| "
                  f"{o['precise_max_abs_z']}; inverse-variance mean error {o['inverse_variance_mean_error']:.3g} "
                  f"+- {o['inverse_variance_se']:.3g}")
    print("extra joint parameters:", res["joint_parameters_not_in_truth"])
    print("sensor effect named right: single-run", res["sensor_named_right"]["single_run"], "campaign",
          res["sensor_named_right"]["campaign"], "of", sum(1 for r in res["per_run"] if "single_right" in r))
    print("consistency:", res["consistency"])
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(res, fh, indent=1)


if __name__ == "__main__":
    main()
