"""Score a campaign against the truth of ``benchmarks/validation/gen_campaign.py``.

    python benchmarks/validation/gen_campaign.py --n 40 --seed S --out DIR
    jaxdrift campaign --manifest DIR/campaign.toml --out OUT --workers 2
    python benchmarks/validation/campaign_validation.py DIR OUT [--json benchmarks/results/campaign_validation.json]

Per shared parameter: the joint estimate and interval, whether it holds the truth, the single-run
intervals that name it (their median width) and the narrowing. Per run: whether its logger's sensor
effect (or its absence) is named right by the single-run diagnosis and by the campaign (the
sensor effects against the joint vehicle). Named right: a finding of the true cause on the true
channel, and no other sensor finding; for an effect-free logger, no sensor finding at all.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys

SENSOR = ("force_offset", "force_scale", "force_delay")


def _named_right(findings, effect) -> bool:
    sens = [(f["cause"], f.get("channel")) for f in findings if f.get("cause") in SENSOR]
    if effect is None:
        return not sens
    return sens == [(effect["cause"], effect["channel"])]


def score(truth_dir: str, out_dir: str) -> dict:
    truth = json.load(open(os.path.join(truth_dir, "truth.json")))
    doc = json.load(open(os.path.join(out_dir, "campaign.json")))
    loggers = {lg["id"]: lg["effect"] for lg in truth["loggers"]}
    joint = {f["parameter"]: f for f in doc["joint"]["findings"]}
    params = []
    for e in truth["shared"]:
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
            row.update({"joint": f["estimate"], "joint_interval": f["interval"], "joint_width": w,
                        "contains_truth": f["interval"][0] <= true <= f["interval"][1],
                        "narrowing": (med / w) if med else None,
                        "narrower_than_every_single": all(w < hi - lo for lo, hi in singles)})
        params.append(row)
    extra = [p for p in joint if p not in {e["parameter"] for e in truth["shared"]}]
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
    print("extra joint parameters:", res["joint_parameters_not_in_truth"])
    print("sensor effect named right: single-run", res["sensor_named_right"]["single_run"], "campaign",
          res["sensor_named_right"]["campaign"], "of", sum(1 for r in res["per_run"] if "single_right" in r))
    print("consistency:", res["consistency"])
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(res, fh, indent=1)


if __name__ == "__main__":
    main()
