"""The campaign's consistency check on generated campaigns (issue #46, item 2): how often "X differs
between runs" is raised on campaigns of consistent runs (promised: at most 5 %), and how often a run
whose vehicle truly differs is named.

    python benchmarks/validation/campaign_false_alarms.py --consistent 100 --different 30 \
        --out /tmp/cfa --json benchmarks/results/campaign_false_alarms.json

Each campaign is drawn by ``gen_campaign.py`` (independent of jaxdrift): 4-``--max-runs`` runs of one
vehicle, 3-5 s at 200-300 Hz, several loggers, two shared parameter errors. In a "different"
campaign one run's vehicle has one of the shared parameters 8-15 % further off than the others'
(a changed load, a worn part). Found: an alarm on that parameter naming that run (an alarm that
names no run, or another, does not count).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys

import numpy as np
import scipy.stats

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
from benchmarks.validation import gen_campaign as gc  # noqa: E402


def draw(k: int, seed: int, max_runs: int, different: bool) -> tuple[dict, dict | None]:
    rng = np.random.default_rng([seed, k, int(different)])
    n = int(rng.integers(4, max_runs + 1))
    d = gc.draw_campaign(n, int(rng.integers(2**31)), durations=(3.0, 5.0), rates=(200, 250, 300))
    if not different:
        return d, None
    i = int(rng.integers(n))
    e = d["shared"][int(rng.integers(len(d["shared"])))]
    step = float(rng.uniform(0.08, 0.15)) * float(rng.choice([-1.0, 1.0]))
    for x in d["cases"][i]["effects"]:
        if x["cause"] == "parameter_error" and x["parameter"] == e["parameter"]:
            x["value"] = x["value"] * (1.0 + step)
    return d, {"run": f"run_{i:03d}", "parameter": e["parameter"], "step": step}


def run_one(d: dict, diff: dict | None, folder: str, workers: int, scheduler: str | None = None) -> dict:
    runs, out = os.path.join(folder, "runs"), os.path.join(folder, "out")
    if not os.path.isfile(os.path.join(runs, "truth.json")):
        gc.write_campaign(d, runs, progress=False)
    exe = os.path.join(os.path.dirname(sys.executable), "jaxdrift")
    p = subprocess.run([exe, "-q", "campaign", "--manifest", os.path.join(runs, "campaign.toml"), "--out", out,
                        *(["--scheduler", scheduler] if scheduler else ["--workers", str(workers)]), "--no-figures"],
                       capture_output=True, text=True)
    if p.returncode != 0:
        return {"error": p.stderr[-600:]}
    doc = json.load(open(os.path.join(out, "campaign.json")))
    return {"runs": len(d["cases"]), **judged(doc, diff), "wall_s": doc["provenance"].get("wall_s")}


def judged(doc: dict, diff: dict | None, again: bool = False) -> dict:
    """A campaign's alarms from its campaign.json (``again``: the runs' estimates judged anew by this
    checkout's test; they do not depend on it), and for a different campaign whether the run that
    differs is named and its own standard error of the parameter."""
    cons = (doc.get("joint") or {}).get("consistency", {}).get("parameters", [])
    if again:
        from jaxdrift.campaign._joint import check_consistency

        cons = [check_consistency(e, family=len(cons)) for e in cons]
    r = {"tested": [c["parameter"] for c in cons], "alarms": _alarms(cons)}
    if diff:
        r.update(different=diff, found=_found(r["alarms"], diff), different_run_se=_own_se(cons, diff))
    return r


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--consistent", type=int, default=100)
    ap.add_argument("--different", type=int, default=30)
    ap.add_argument("--seed", type=int, default=20261207)
    ap.add_argument("--max-runs", type=int, default=6)
    ap.add_argument("--out", required=True)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json")
    ap.add_argument("--scheduler", help="a running Dask scheduler's address (workers that outlive one campaign keep "
                    "their compiled functions); default: a local cluster per campaign")
    ap.add_argument("--summarise", metavar="JSON", help="only recompute the summary of a sweep's JSON (in place)")
    ap.add_argument("--rejudge", action="store_true", help="with --summarise: judge each campaign's runs again with "
                    "this checkout's consistency test (the runs' estimates in OUT/*/out/campaign.json do not depend on it)")
    a = ap.parse_args(argv)
    if a.summarise:
        doc = json.load(open(a.summarise))
        if a.rejudge:
            doc["campaigns"] = [r if "error" in r else
                                {**r, **judged(json.load(open(os.path.join(a.out, f"{r['kind'][0]}{r['campaign']:03d}",
                                                                           "out", "campaign.json"))),
                                               r.get("different"), again=True)} for r in doc["campaigns"]]
            doc["rejudged_with"] = _commit()
        doc["summary"] = summarise(doc["campaigns"])
        with open(a.summarise, "w") as fh:
            json.dump(doc, fh, indent=1)
        print(json.dumps(doc["summary"], indent=1))
        return
    # consistent and different campaigns interleaved, and the JSON rewritten after each campaign, so
    # that a sweep cut short still reports both kinds (a rerun into the same --out resumes from the
    # campaign cache)
    tasks = sorted([(k / a.consistent, "consistent", k) for k in range(a.consistent)]
                   + [(k / a.different, "different", k) for k in range(a.different)])
    res = []
    for _, kind, k in tasks:
        d, diff = draw(k, a.seed, a.max_runs, kind == "different")
        r = {"kind": kind, "campaign": k, **run_one(d, diff, os.path.join(a.out, f"{kind[0]}{k:03d}"), a.workers,
                                                    a.scheduler)}
        if diff and "error" in r:
            r.update(different=diff, found=False)
        res.append(r)
        print(f"{kind} {k}: {r.get('runs')} runs, alarms {r.get('alarms', r.get('error'))}"
              + (f"; different {diff} found {r['found']}" if diff else ""), flush=True)
        summ = summarise(res)
        if a.json:
            write(a, summ, res)
    print(json.dumps(summ, indent=1))


def _alarms(cons: list[dict]) -> list[dict]:
    return [{"parameter": c["parameter"], "p": c["p_value"], "level": c.get("level"),
             "runs": [x["run"] for x in c["disagreeing_runs"]]} for c in cons if not c["consistent"]]


def _found(alarms: list[dict], diff: dict) -> bool:
    return any(x["parameter"] == diff["parameter"] and diff["run"] in x["runs"] for x in alarms)


def _own_se(params: list[dict], diff: dict) -> float | None:
    """The different run's own standard error of the parameter that differs (None: not tested)."""
    for e in params:
        if e["parameter"] == diff["parameter"]:
            for x in e["per_run"]:
                if x["run"] == diff["run"]:
                    return x.get("own_se", x.get("se"))
    return None


def _commit() -> str:
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              cwd=os.path.dirname(os.path.abspath(__file__))).stdout.strip()
    except OSError:
        return "unknown"


def _showable(r: dict) -> bool:
    from jaxdrift.campaign._joint import DIFFERENCE_MARGIN

    se = r.get("different_run_se")
    return se is not None and abs(r["different"]["step"]) > DIFFERENCE_MARGIN + 4.0 * se


def summarise(res: list[dict]) -> dict:
    cons = [r for r in res if r["kind"] == "consistent" and "error" not in r]
    diff = [r for r in res if r["kind"] == "different" and "error" not in r]
    k = sum(bool(r["alarms"]) for r in cons)
    return {"consistent_campaigns": len(cons), "with_alarm": k,
            "with_alarm_upper_95": float(scipy.stats.beta.ppf(0.95, k + 1, max(len(cons) - k, 1))) if cons else None,
            "different_campaigns": len(diff), "different_run_found": sum(r["found"] for r in diff),
            # where the run could show the step: beyond the margin by 4 of its own standard errors
            "different_showable": sum(_showable(r) for r in diff),
            "different_showable_found": sum(r["found"] for r in diff if _showable(r)),
            # a different campaign that also names another parameter or another run: a false alarm there
            "different_with_other_alarm": sum(any((x["parameter"], rr) != (r["different"]["parameter"], r["different"]["run"])
                                                  for x in r["alarms"] for rr in (x["runs"] or [None])) for r in diff),
            "errors": sum("error" in r for r in res)}


def write(a, summ: dict, res: list[dict]) -> None:
    import jaxdrift

    with open(a.json, "w") as fh:
        json.dump({"what": "campaign_false_alarms", "seed": a.seed, "max_runs": a.max_runs,
                   "machine": platform.platform(), "python": platform.python_version(),
                   "jaxdrift": jaxdrift.__version__, "summary": summ, "campaigns": res}, fh, indent=1)

if __name__ == "__main__":
    main()
