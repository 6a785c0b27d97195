"""Two sweeps of the same design and seed, diagnosed by two commits, side by side.

    python benchmarks/validation/compare_sweeps.py BEFORE.json AFTER.json --json OUT.json

``BEFORE.json`` and ``AFTER.json`` are summaries written by ``sweep.py`` (same ``--kind``,
``--design``, ``--n`` and ``--seed``, e.g. one run from a checkout of the older commit with
``PYTHONPATH`` pointing at it). Written: each summary's headline measures (singles, pairs,
effect-free runs, interval coverage per cause and, for the nonlinear design, its measures) under
``before`` and ``after``, and the runs whose first three findings differ, with both lists.
"""

from __future__ import annotations

import argparse
import json
import sys


def _headline(s: dict) -> dict:
    out = {"commit": s.get("jaxdrift_commit"), "runs": s.get("runs"), "errors": s.get("errors"),
           "single": {k: v for k, v in s.get("single", {}).items() if k != "per_target"},
           "pair": s.get("pair"), "effect_free": s.get("effect_free"),
           "coverage_per_cause": s.get("coverage", {}).get("per_cause"), "cpu_s": s.get("cpu_s")}
    nl = s.get("nonlinear")
    if nl:
        out["nonlinear"] = {k: v for k, v in nl.items() if k != "per_run"}
    return out


def compare(before: dict, after: dict) -> dict:
    for k in ("kind", "seed", "n_design"):
        if before.get(k) != after.get(k):
            raise SystemExit(f"the two sweeps differ in {k}: {before.get(k)!r} and {after.get(k)!r}")
    b = {r["index"]: r for r in before["per_run"]}
    changed = []
    for r in after["per_run"]:
        o = b.get(r["index"])
        if o is not None and o["first_three"] != r["first_three"]:
            changed.append({"index": r["index"], "stratum": r["stratum"], "truth": r["truth"],
                            "before": o["first_three"], "after": r["first_three"]})
    return {"kind": after.get("kind"), "seed": after.get("seed"), "runs": len(after["per_run"]),
            "before": _headline(before), "after": _headline(after),
            "first_three_changed": len(changed),
            "first_three_same": len(after["per_run"]) - len(changed), "changed": changed}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", help="summary JSON of the older commit's sweep")
    ap.add_argument("after", help="summary JSON of the newer commit's sweep")
    ap.add_argument("--json", required=True, help="where to write the comparison")
    args = ap.parse_args(argv)
    with open(args.before) as fb, open(args.after) as fa:
        res = compare(json.load(fb), json.load(fa))
    with open(args.json, "w") as f:
        json.dump(res, f, indent=1)
    print(f"{res['runs']} runs, first three findings changed in {res['first_three_changed']}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
