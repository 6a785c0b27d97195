"""Joint 95 % intervals over a report's findings (vehicle and attitude reports alike).

A report that names several findings claims all of them at once. With k findings each interval is
taken at the Sidak level 0.95^(1/k), so that all k true values lie inside their intervals together
with 95 % probability; a vector finding whose interval is already a simultaneous box over its m
components (a sensor position: each component at 0.95^(1/3)) goes to 0.95^(1/(k m)) per component.
Each side is scaled about the estimate by the ratio of the normal quantiles (the chi-square noise
interval and transformed intervals are asymmetric; scaling the sides keeps that), and an interval
from 0 (an upper bound) keeps its 0.
"""

from __future__ import annotations

import scipy.stats

__all__ = ["JOINT_LEVEL", "joint_intervals"]

#: the findings' intervals hold jointly at this level
JOINT_LEVEL = 0.95


def _quantile(level: float) -> float:
    return float(scipy.stats.norm.ppf(0.5 + 0.5 * level))


def _widen_side(lo, hi, est, factor):
    lo = lo if lo == 0.0 else est - factor * (est - lo)
    return float(lo), float(est + factor * (hi - est))


def _widen(d: dict, k: int) -> dict:
    """``d`` with its interval widened to the joint level of ``k`` findings (a new dict)."""
    iv, est = d.get("interval"), d.get("estimate")
    if iv is None or est is None:
        return d
    if isinstance(est, (list, tuple)):
        m = len(est)
        factor = _quantile(JOINT_LEVEL ** (1.0 / (k * m))) / _quantile(JOINT_LEVEL ** (1.0 / m))
        sides = [_widen_side(lo, hi, e, factor) for lo, hi, e in zip(iv[0], iv[1], est)]
        return {**d, "interval": [[s[0] for s in sides], [s[1] for s in sides]]}
    factor = _quantile(JOINT_LEVEL ** (1.0 / k)) / _quantile(JOINT_LEVEL)
    return {**d, "interval": list(_widen_side(iv[0], iv[1], est, factor))}


def joint_intervals(findings: list[dict]) -> list[dict]:
    """The findings with their 95 % intervals widened so that they hold jointly (module doc), each
    recording it in its ``interval_level``: ``{"joint": 0.95, "each": 0.95^(1/k), "findings": k}``.
    Alternatives in ``indistinguishable_from`` are widened alike. New dicts; the list given is not
    changed."""
    k = sum(1 for f in findings if f.get("interval") is not None and f.get("estimate") is not None)
    if k <= 1:
        return list(findings)
    out = []
    for f in findings:
        if f.get("interval") is None or f.get("estimate") is None:
            out.append(f)
            continue
        g = _widen(f, k)
        if g.get("indistinguishable_from"):
            g["indistinguishable_from"] = [_widen(a, k) for a in g["indistinguishable_from"]]
        g["interval_level"] = {"joint": JOINT_LEVEL, "each": round(JOINT_LEVEL ** (1.0 / k), 5), "findings": k}
        out.append(g)
    return out
