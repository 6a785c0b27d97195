"""How well a diagnosis report recovers the hidden effects of a generated run.

Used by the sweeps in ``benchmarks/`` and by the slow sweep test (``tests/``); it is a rule for
scoring, not part of the library.
"""

from __future__ import annotations

from jaxdrift.diagnosis.vehicle import nonlinear_cause_names

__all__ = ["score_report"]


def _target(d: dict) -> tuple:
    return d["cause"], d.get("channel", d.get("parameter"))


_AXLE = {"k3": "front", "d3": "front", "f1": "front", "k4": "rear", "d4": "rear", "f2": "rear"}
_NONLINEAR = nonlinear_cause_names()  # the diagnosis's registry


def model_form_names(f: dict, t: tuple) -> bool:
    """Whether the ``model_form`` finding ``f`` names the hidden effect ``t`` (cause, channel or
    parameter): the nonlinear effect on its axle (what the linear model cannot explain there without
    forcing it into a candidate), or, on the body (a body that is not rigid), the degree of freedom
    the model lacks."""
    return ((t[0] in _NONLINEAR and _AXLE.get(t[1]) == f.get("axle"))
            or (t[0] == "unmodelled_mode" and f.get("axle") == "body"))


def _as_truth(f: dict, truth: set) -> tuple:
    """A finding's target; a ``model_form`` finding's the hidden effect it names (``model_form_names``)."""
    if f["cause"] == "model_form":
        for t in truth:
            if model_form_names(f, t):
                return t
    return _target(f)


def score_report(report: dict, effects) -> dict:
    """How well a diagnosis report recovers the hidden ``effects`` (tests and sweeps).

    ``first``: the systematic causes head the findings, or are named as indistinguishable from
    one of the leading findings (the report may not guess where the data cannot tell). Interval
    coverage is checked for every effect except those the report declares indistinguishable from
    another true effect (say an offset on f2 and m3 without z3): the data fix only a combination
    of them. An effect named only as an alternative is checked against the alternative's
    interval. Returns ``{"first", "covered", "total", "misses"}`` (misses: readable lines).
    """
    findings = report["findings"]
    truth = {_target(e) for e in effects if e["cause"] != "force_noise"}
    got = [_as_truth(f, truth) for f in findings]
    head = findings[: max(len(truth), 1) + 1]
    alts = {_target(a) for f in head for a in f.get("indistinguishable_from", [])}
    first = truth <= set(got[: len(truth) + 1]) | alts
    misses = [] if first else [f"order: true {sorted(truth)}, got {got}"]
    confounded = set()
    for f in findings:
        alt_t = {_target(a) for a in f.get("indistinguishable_from", [])}
        if _target(f) in truth and alt_t & truth:
            confounded |= {_target(f)} | (alt_t & truth)
    # an effect named only as an alternative of a finding (m3 behind a g finding without z3) is
    # checked against the interval the report gives that alternative
    alt_entries = [a for f in findings for a in f.get("indistinguishable_from", []) if "interval" in a]
    covered = total = 0
    for e in effects:
        if _target(e) in confounded:
            continue
        match = [f for f in findings if _target(f) == _target(e)] or \
            [a for a in alt_entries if _target(a) == _target(e)]
        total += 1
        inside = bool(match) and match[0]["interval"][0] <= e["value"] <= match[0]["interval"][1]
        covered += inside
        if not inside:
            where = (f"estimate {match[0]['estimate']:.5g} interval [{match[0]['interval'][0]:.5g}, "
                     f"{match[0]['interval'][1]:.5g}]") if match else "not reported"
            misses.append(f"{_target(e)} true {e['value']:.5g}: {where}")
    return {"first": bool(first), "covered": covered, "total": total, "misses": misses}
