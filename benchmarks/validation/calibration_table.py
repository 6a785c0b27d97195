"""Calibration of the vehicle diagnosis' 95 % intervals: per kind of estimate, the share that holds
the truth, with the count.

Reads the per-run results of one or more validation sweeps (``sweep.py --cache``; any of the
designs ``standard``, ``nonlinear``, ``gain_drift``) and counts, for every true effect of every run,
whether the report gives an interval for the true target and whether it holds the true value. The
kinds: each sensor effect (offset, scale, delay, gain drift), the parameter error (and each
parameter on its own line), the force-noise level reported as an estimate and as an upper bound
(``[0, b]``), and the nonlinear causes. A true effect the report does not size is counted apart
("not sized"): that is a detection question, not an interval's.

    python benchmarks/validation/calibration_table.py /tmp/cal/std/cache/* /tmp/cal/nl/cache/* \\
        --out docs/validation/calibration.json

The JSON holds the rows and the sweeps they came from; ``benchmarks/doc_tables.py`` renders the
table in docs/explanation/validation.md.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))  # run as a script: the repository root

from benchmarks.validation import sweep  # noqa: E402

#: the share of 95 % intervals that must hold the truth, per kind
TARGET = 0.90
#: the fewest intervals per kind for the share to be judged
MIN_COUNT = 20


def _kind(effect: dict, cov: dict) -> str:
    c = effect["cause"]
    if c == "force_noise":
        return "force_noise (" + ("upper bound" if cov.get("estimate_kind") == "upper_bound" else "estimate") + ")"
    return c


def rows(caches: list[str], nonlinear_only: tuple[str, ...] = ()) -> tuple[dict, dict, list]:
    """(per kind, per parameter, sweeps) counts: intervals given, holding the truth, not sized. From
    the caches in ``nonlinear_only`` only the nonlinear causes count (a sweep run without the
    re-simulation, which the nonlinear causes' intervals do not depend on)."""
    kinds: dict = {}
    params: dict = {}
    sources = []
    for cache in list(caches) + list(nonlinear_only):
        files = sorted(glob.glob(os.path.join(cache, "*.json")))
        n_ok = 0
        for path in files:
            with open(path) as fh:
                r = json.load(fh)
            if "score" not in r:
                continue
            n_ok += 1
            for e, cov in zip(r["effects"], r["score"]["coverage"]):
                if cache in nonlinear_only and e["cause"] not in sweep.NONLINEAR:
                    continue
                k = _kind(e, cov)
                d = kinds.setdefault(k, {"intervals": 0, "covered": 0, "not_sized": 0})
                sized = cov.get("interval") is not None
                d["intervals" if sized else "not_sized"] += 1
                d["covered"] += int(bool(cov["covered"]) and sized)
                if e["cause"] == "parameter_error" and sized:
                    q = params.setdefault(e["parameter"], {"intervals": 0, "covered": 0})
                    q["intervals"] += 1
                    q["covered"] += int(bool(cov["covered"]))
        sources.append({"cache": cache, "runs": n_ok})
    for d in kinds.values():
        d["share"] = d["covered"] / d["intervals"] if d["intervals"] else None
        d["judged"] = d["intervals"] >= MIN_COUNT
        d["meets"] = (d["share"] >= TARGET) if (d["judged"] and d["share"] is not None) else None
    return kinds, params, sources


def markdown(res: dict) -> str:
    out = ["| estimate | 95 % intervals holding the truth | share | not sized |", "|---|---|---|---|"]
    for k, d in sorted(res["kinds"].items()):
        share = "-" if d["share"] is None else f"{100 * d['share']:.0f} %"
        mark = "" if d["judged"] else " (fewer than 20)"
        out.append(f"| `{k}` | {d['covered']}/{d['intervals']}{mark} | {share} | {d['not_sized']} |")
    if res["parameters"]:
        per = ", ".join(f"{p} {q['covered']}/{q['intervals']}" for p, q in sorted(res["parameters"].items()))
        out.append("")
        out.append(f"Per parameter: {per}.")
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("caches", nargs="*", help="sweep cache folders (per-run JSON files)")
    ap.add_argument("--nonlinear", nargs="*", default=(), metavar="CACHE",
                    help="caches of which only the nonlinear causes count (a sweep run with --no-simulation)")
    ap.add_argument("--out", help="write the rows here (JSON)")
    ap.add_argument("--commit", default=None, help="the commit that diagnosed the runs (recorded)")
    a = ap.parse_args(argv)
    kinds, params, sources = rows(a.caches, tuple(a.nonlinear))
    res = {"target_share": TARGET, "min_count": MIN_COUNT, "diagnosed_by": a.commit, "sweeps": sources,
           "kinds": kinds, "parameters": params}
    print(markdown(res))
    if a.out:
        with open(a.out, "w") as fh:
            json.dump(res, fh, indent=1)


if __name__ == "__main__":
    main()
