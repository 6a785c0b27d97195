"""Calibrate the method component of the vehicle diagnosis' 95 % intervals on a tuning sweep.

The statistical half-width of a finding's interval (noise propagated through the fit) leaves out
the comparison's own error: the residual's signature of a cause is computed by interpolation and
finite differences on the sampled record, and the model's noise response is only as right as the
fitted parameters. That error scales with the size of the effect. This script reads the per-run
results of a sweep (``sweep.py --cache DIR``) and, per cause, finds the relative method component
``rho`` (in the cause's internal coordinate theta, 0 = no effect; for the force-noise level,
relative to the level) that, combined in quadrature with the statistical half-width,

    half = sqrt(half_stat^2 + (1.96 rho |theta|)^2),

brings the fraction of true values inside their intervals to the target (default 95 %). Only
findings that name the true cause are used (a wrong cause has no true value to cover).

Run it on a tuning seed, never on the held-out seed of the committed sweep:

    python benchmarks/validation/sweep.py --kind vehicle --n 200 --seed 31 --out /tmp/t31 \\
        --cache /tmp/t31/cache --jobs 2
    python benchmarks/validation/calibrate_intervals.py /tmp/t31/cache

With ``--rho`` the given components are applied instead, and the script reports the coverage the
sweep would have had (a check on another seed).
"""

from __future__ import annotations

import argparse
import glob
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))  # run as a script: the repository root
from benchmarks.validation import sweep  # noqa: E402

KINDS = ("force_offset", "force_scale", "force_delay", "parameter_error", "force_noise")


def _theta(kind: str, v: float) -> float:
    if kind == "force_scale":
        return 1.0 / v - 1.0
    if kind == "parameter_error":
        return v - 1.0
    return v


def samples(cache: str) -> dict:
    """Per cause: (theta_estimate, theta_truth, statistical half-width, lower bound only) rows."""
    out = {k: [] for k in KINDS}
    for path in sorted(glob.glob(os.path.join(cache, "*.json"))):
        with open(path) as fh:
            r = json.load(fh)
        if "findings" not in r:
            continue
        for e in r["effects"]:
            kind = e["cause"]
            if kind not in out:
                continue
            m = [f for f in r["findings"] if sweep.target(f) == sweep.target(e)]
            if not m or m[0].get("interval") is None:
                continue
            f = m[0]
            lo, hi = f["interval"]
            t_est, t_true = _theta(kind, f["estimate"]), _theta(kind, e["value"])
            t_lo, t_hi = sorted((_theta(kind, lo), _theta(kind, hi)))
            upper_only = kind == "force_noise" and lo == 0.0
            half = max(t_hi - t_est, t_est - t_lo)
            out[kind].append((t_est, t_true, half, upper_only))
    return out


def covered(row, rho: float) -> bool:
    t_est, t_true, half, upper_only = row
    h = math.hypot(half, 1.96 * rho * abs(t_est))
    if upper_only:
        return t_true <= t_est + h
    return abs(t_true - t_est) <= h


def needed(rows, target: float) -> float:
    """The smallest rho with the target coverage (rows needing none count at 0)."""
    need = []
    for t_est, t_true, half, upper_only in rows:
        err = (t_true - t_est) if upper_only else abs(t_true - t_est)
        extra = max(err * err - half * half, 0.0) if err > 0 else 0.0
        need.append(math.sqrt(extra) / (1.96 * max(abs(t_est), 1e-300)))
    need.sort()
    if not need:
        return 0.0
    k = min(len(need) - 1, max(0, math.ceil(target * len(need)) - 1))
    return need[k]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("cache", nargs="+", help="sweep cache folder(s) of per-run results")
    ap.add_argument("--target", type=float, default=0.95, help="coverage to calibrate to (0.95)")
    ap.add_argument("--rho", help="apply these instead, e.g. force_offset=0.01,force_noise=0.05")
    a = ap.parse_args(argv)
    rows = {k: [] for k in KINDS}
    for c in a.cache:
        for k, v in samples(c).items():
            rows[k] += v
    given = {}
    if a.rho:
        for part in a.rho.split(","):
            k, v = part.split("=")
            given[k] = float(v)
    print(f"{'cause':18s} {'n':>4s} {'covered now':>12s} {'rho needed':>11s} {'with rho':>9s}")
    for k in KINDS:
        rs = rows[k]
        if not rs:
            continue
        now = sum(covered(r, 0.0) for r in rs)
        rho = given.get(k, needed(rs, a.target)) if a.rho else needed(rs, a.target)
        after = sum(covered(r, rho) for r in rs)
        print(f"{k:18s} {len(rs):4d} {now:5d} ({100 * now / len(rs):4.1f}%) {rho:11.3g} "
              f"{after:4d} ({100 * after / len(rs):4.1f}%)")


if __name__ == "__main__":
    main()
