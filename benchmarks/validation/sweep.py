"""Sweep of ``jaxdrift diagnose`` over runs from the independent generators, scored against the truth.

For ``--n`` cases of the stratified design of ``gen_vehicle.py`` or ``gen_attitude.py`` drawn from
``--seed``, each run is generated into a scratch folder, read and diagnosed through the public API
(``jaxdrift.read_vehicle_run`` / ``read_model`` / ``diagnose_vehicle_run``, or
``jaxdrift.run_attitude_diagnosis``: the same calls ``jaxdrift diagnose`` makes), scored by the rules
below, and its result written to ``OUT/cache/<kind>-<seed>/NNNN.json``. Cached runs are skipped, so
an interrupted sweep continues where it stopped, and ``--chunk i/k`` (the cases with index = i mod k)
lets separate processes share one cache. At the end (or with ``--report-only``) all cached results of
the design are summarised into ``OUT/<prefix><kind>.json`` and ``.md``.

Scoring (from docs/measured-data.md, written for this sweep):

- systematic causes: vehicle ``force_offset, force_scale, force_delay, parameter_error``; attitude
  ``gyro_bias, gyro_scale, gyro_bias_drift, sensor_position, nonrigid``; noise causes:
  ``force_noise``, ``gyro_noise``, ``accel_noise``. A target is (cause, channel/parameter/sensor).
- single-effect run (one systematic effect, with or without noise): right if the first finding is
  the true target; "right or declared" also accepts the true target listed in the first finding's
  ``indistinguishable_from``.
- pair: both true targets among the first two findings (declared: or in their
  ``indistinguishable_from``).
- effect-free run (no systematic effect): a false alarm if the first finding is systematic.
- coverage: for every true effect (noise included) the finding with its target must exist and its
  95 % ``interval`` contain the true value (every component for a sensor position); per effect and
  per run (all effects of the run covered).
- noise level: a true noise effect whose estimate is within a factor 1.5 of the truth.

Examples::

    python benchmarks/validation/sweep.py --kind vehicle --n 20 --seed 1 --out /tmp/sw --jobs 2
    python benchmarks/validation/sweep.py --kind attitude --n 100 --seed 20261201 \\
        --out docs/validation --prefix "$(git rev-parse --short HEAD)-" --jobs 1
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import shutil
import sys
import tempfile
import time
import traceback
from collections import Counter, defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))  # run as a script: the repository root

#: nonlinear suspension causes (``gen_vehicle.design_nonlinear``) and the finding that names a
#: model-form error without a cause; ``model_form`` counts as right for a nonlinear effect when its
#: axle is the effect's (front: k3/d3/f1, rear: k4/d4/f2)
#: (both from the diagnosis's registries)
from jaxdrift.diagnosis.vehicle import VEHICLE_CAUSES, nonlinear_cause_names  # noqa: E402

from benchmarks.validation.scoring import model_form_names  # noqa: E402

NONLINEAR = nonlinear_cause_names()
FORM = ("model_form",) + NONLINEAR
SYSTEMATIC = {"vehicle": tuple(k.name for k in VEHICLE_CAUSES) + FORM + ("unmodelled_mode",),
              "attitude": ("gyro_bias", "gyro_scale", "gyro_bias_drift", "sensor_position", "nonrigid")}
NOISE = {"vehicle": ("force_noise",), "attitude": ("gyro_noise", "accel_noise")}
#: sizing of the committed sweep (fits ~35 min of one core for 200 vehicle + 100 attitude runs)
SIZING = {"vehicle": {"durations": (10.0, 40.0), "rates": (200, 250, 300, 500, 600, 1000, 1200, 2000),
                      "max_samples": 10000},
          "attitude": {"durations": (30.0, 150.0), "rates": (100, 200, 250, 400, 500, 1000),
                       "max_samples": 60000}}


#: the generators' log-uniform size ranges of each systematic effect (``size_u`` maps an effect to
#: its place in its range: 0 barely detectable ... 1 large; ``test_size_ranges`` keeps them in step)
SIZE_RANGES = {"force_offset": (1e-3, 1e-1), "force_scale": (1e-3, 1e-1), "force_delay": (1e-4, 1e-2),
               "force_gain_drift": (2e-3, 5e-2), "force_crosstalk": (2e-3, 5e-2),
               "parameter_error": (5e-3, 0.2), "gyro_bias": (3.0, 300.0), "gyro_scale": (1e-3, 5e-2),
               "gyro_bias_drift": (1e-5, 1e-3), "sensor_position": (0.005, 0.1), "nonrigid": (0.005, 0.3)}


def size_u(e: dict, case: dict) -> float:
    """Where a systematic effect's size lies in its draw range, 0..1 on a log scale."""
    import math

    c, v = e["cause"], e["value"]
    if c not in SIZE_RANGES:  # nonlinear effects: sized by their own draw (gen_vehicle.draw_effect)
        return 0.5
    if c == "force_offset":
        p = case["model"]
        share = p["a"] if e["channel"] == "f1" else p["b"]
        m = p["m1"] if e["channel"] == "f1" else p["m2"]
        x = abs(v) / (m * p["g"] + p["m3"] * p["g"] * share / (p["a"] + p["b"]))
    elif c in ("force_scale", "parameter_error", "gyro_scale"):
        x = abs(v - 1.0)
    elif c == "force_gain_drift":  # the scale's change over the run
        x = abs(v) * case["duration"]
    elif c == "gyro_bias":
        N = next((n["value"] for n in case["effects"] if n["cause"] == "gyro_noise"), math.radians(0.05) / 60)
        x = abs(v) / (N / math.sqrt(case["duration"]))
    elif c == "sensor_position":
        x = math.sqrt(sum(d * d for d in v))
    else:
        x = abs(v)
    lo, hi = SIZE_RANGES[c]
    return (math.log(x) - math.log(lo)) / (math.log(hi) - math.log(lo))


def target(d: dict) -> tuple:
    for k in ("channel", "parameter", "sensor"):
        if d.get(k) is not None:
            return d["cause"], str(d[k])
    return d["cause"], ""


def label(t: tuple) -> str:
    return t[0] + (f":{t[1]}" if t[1] else "")


def _inside(value, interval) -> bool:
    if interval is None:
        return False
    lo, hi = interval
    if isinstance(value, (list, tuple)):
        return all(l_ <= v <= h_ for v, l_, h_ in zip(value, lo, hi))
    return lo <= value <= hi


def _axle(t: tuple) -> str | None:
    return {"k3": "front", "d3": "front", "f1": "front", "k4": "rear", "d4": "rear", "f2": "rear"}.get(t[1])


def _as_truth(f: dict, systematic: list) -> tuple:
    """A finding's target; a ``model_form`` finding's the hidden effect it names
    (``scoring.model_form_names``)."""
    if f["cause"] == "model_form":
        for t in systematic:
            if model_form_names(f, t):
                return t
    return target(f)


def score(kind: str, effects: list, findings: list) -> dict:
    """The rules of the module docstring for one run."""
    systematic = [target(e) for e in effects if e["cause"] in SYSTEMATIC[kind]]
    got = [_as_truth(f, systematic) for f in findings]
    alts = [[target(a) for a in f.get("indistinguishable_from", []) or []] for f in findings]
    first = got[0] if got else ("none", "")
    out = {"n_systematic": len(systematic), "first": label(target(findings[0]) if findings else first),
           "first_is_systematic": first[0] in SYSTEMATIC[kind]}
    if len(systematic) == 1:
        out["right"] = first == systematic[0]
        out["right_or_declared"] = out["right"] or systematic[0] in (alts[0] if alts else [])
    elif len(systematic) == 2:
        head = set(got[:2])
        head_alt = head | {a for al in alts[:2] for a in al}
        out["right"] = set(systematic) <= head
        out["right_or_declared"] = set(systematic) <= head_alt
    else:
        out["false_alarm"] = out["first_is_systematic"]
    right = [f for f in findings if target(f) in systematic]
    out["right_findings"] = len(right)
    # a finding not confirmed by a check stays in the findings but out of the extended model
    out["right_all_confirmed"] = all(f.get("confirmed", True) for f in right) if right else None
    cov = []
    for e in effects:
        match = [f for f in findings if target(f) == target(e)]
        est = match[0].get("estimate") if match else None
        c = {"target": label(target(e)), "true": e["value"], "estimate": est,
             "interval": match[0].get("interval") if match else None}
        c["covered"] = bool(match) and _inside(e["value"], c["interval"])
        if e["cause"] in NOISE[kind]:
            c["estimate_kind"] = match[0].get("estimate_kind") if match else None
            c["within_1.5x"] = bool(match) and est is not None and e["value"] > 0 and \
                1 / 1.5 <= est / e["value"] <= 1.5
        cov.append(c)
    out["coverage"] = cov
    out["all_covered"] = all(c["covered"] for c in cov) if cov else None
    return out


# ----------------------------------------------------------------------------- one run
def _trim(f: dict) -> dict:
    keep = ("cause", "channel", "parameter", "sensor", "axle", "state", "estimate", "interval", "z",
            "evidence", "indistinguishable_from", "confirmed", "estimate_kind", "frequency_hz")
    return {k: f[k] for k in keep if k in f}


def _trim_gain(g: dict | None) -> dict:
    """The report's gain without the per-entry detail: the metric and its before/after, and for a
    vehicle run with the force-driven re-simulation the pitch (and heave) RMS errors before/after."""
    g = g or {}
    out = {k: g[k] for k in ("metric", "before", "after", "unit", "beta_rms_before", "beta_rms_after",
                             "beta_rms_dynamic_before", "beta_rms_dynamic_after") if k in g}
    if "z3_error" in g:
        out["z3_rms_before"] = g["z3_error"]["before"]["rms"]
        out["z3_rms_after"] = g["z3_error"]["after"]["rms"]
    return out


def run_one(kind: str, case: dict, cache: str, sizing: dict, keep_dir: str | None = None,
            with_simulation: bool = True) -> dict:
    """Generate, diagnose and score one case; write its result JSON atomically into ``cache``."""
    import numpy as np  # noqa: F401  (workers start clean)

    gen = importlib.import_module("benchmarks.validation." + ("gen_vehicle" if kind == "vehicle" else "gen_attitude"))
    res = {"index": case["index"], "kind": kind, "stratum": case["stratum"]}
    scratch = keep_dir or tempfile.mkdtemp(prefix=f"indep-{kind}-")
    try:
        c0, w0 = time.process_time(), time.time()
        full = gen.make_case(case, **sizing)
        paths = gen.make_run(full, scratch)
        res["gen_cpu_s"] = time.process_time() - c0
        res["case"] = {k: v for k, v in full.items() if k not in ("positions",)}
        res["case"]["n_sensors"] = len(full.get("positions") or [])
        res["effects"] = full["effects"]
        c1 = time.process_time()
        import jaxdrift

        if kind == "vehicle":
            run = jaxdrift.read_vehicle_run(paths["csv"])
            model = jaxdrift.read_model(paths["model"])
            report = jaxdrift.diagnose_vehicle_run(run, model, with_simulation=with_simulation)
            res["with_simulation"] = with_simulation
        else:
            report = jaxdrift.run_attitude_diagnosis(paths["csv"], paths["sensors"])
        res["diag_cpu_s"] = time.process_time() - c1
        res["wall_s"] = time.time() - w0
        res["findings"] = [_trim(f) for f in report.get("findings", [])]
        res["could_not_show"] = [nt for nt in report.get("notes", []) if nt.startswith("Could not show")]
        res["gain"] = _trim_gain(report.get("gain"))
        res["score"] = score(kind, full["effects"], report.get("findings", []))
    except Exception as e:  # noqa: BLE001 - a failing diagnosis is a result, recorded
        res["error"] = f"{type(e).__name__}: {e}"
        res["traceback"] = traceback.format_exc()[-2000:]
    finally:
        if keep_dir is None:
            shutil.rmtree(scratch, ignore_errors=True)
    path = os.path.join(cache, f"{case['index']:04d}.json")
    tmp = path + f".tmp{os.getpid()}"
    with open(tmp, "w") as fh:
        json.dump(res, fh, indent=1, default=float)
    os.replace(tmp, path)
    return res


# ----------------------------------------------------------------------------- summary
def _pct(k, n):
    return None if n == 0 else round(100.0 * k / n, 1)


#: the systematic causes whose correction the re-simulated error sees: every vehicle cause; of the
#: attitude causes only the gyro's (the array's, sensor_position and nonrigid, do not enter the
#: integrated rates; their gain is the rigidity residual, no re-simulation)
RESIMULATED_CAUSES = {"vehicle": SYSTEMATIC["vehicle"], "attitude": ("gyro_bias", "gyro_scale", "gyro_bias_drift")}
#: the margin the diagnosis itself asks of a correction in the force-driven re-simulation
#: (``_confirm.WORSE_FACTOR``): reported beside the bare after < before, not instead of it
CLEAR_FACTOR = 0.9


def resimulated(kind: str, r: dict, band: str = "full") -> tuple | None:
    """(metric, before, after) of the run's re-simulated error, or None: vehicle the force-driven
    pitch RMS error (else the heave's; ``band="dynamic"``: the pitch error above the drift band,
    ``DYNAMIC_BAND_HZ`` of the diagnosis); attitude the attitude error of the integrated corrected
    rates (the rigidity residual and the static mean rate are no re-simulation)."""
    g = r.get("gain") or {}
    if kind == "vehicle":
        for m in (("beta_rms_dynamic",) if band == "dynamic" else ()) + ("beta_rms", "z3_rms"):
            if g.get(f"{m}_before") is not None and g.get(f"{m}_after") is not None:
                return m, g[f"{m}_before"], g[f"{m}_after"]
        return None
    if g.get("metric") == "attitude_error_rms" and g.get("before") is not None and g.get("after") is not None:
        return "attitude_error_rms", g["before"], g["after"]
    return None


def gain_measure(kind: str, ok: list[dict], band: str = "full") -> dict:
    """Gains confirmed by re-simulation. Runs whose report names a systematic cause the re-simulation
    sees (``RESIMULATED_CAUSES``) and that have a re-simulated error: confirmed where the extended
    model's error is below the model's (after < before), also counted with the margin
    ``CLEAR_FACTOR``, for all of them and for the runs scored right, with the median after/before.
    Runs with no such cause reported: the re-simulated part of the extended model is the model, so
    after must equal before to rounding: 1e-6 relative (the pitch error is a small difference of two
    simulated pitches, so two solves of the same model in other batch places differ by ~1e-8 of it)."""
    def systematic(r):
        return any(f["cause"] in RESIMULATED_CAUSES[kind] for f in r.get("findings", []))

    def count(group):
        ratios = sorted(a / b if b > 0 else float("inf") for _, (_, b, a) in group)
        n, k = len(group), sum(a < b for _, (_, b, a) in group)
        return {"n": n, "confirmed": k, "confirmed_pct": _pct(k, n),
                "clear": sum(a < CLEAR_FACTOR * b for _, (_, b, a) in group),
                "median_ratio": None if not n else float(f"{(ratios[n // 2] + ratios[(n - 1) // 2]) / 2:.3g}")}

    with_sys = [(r, resimulated(kind, r, band)) for r in ok if systematic(r)]
    eligible = [(r, m) for r, m in with_sys if m is not None]
    out = {"clear_factor": CLEAR_FACTOR, "with_systematic_finding": len(with_sys),
           "metrics": dict(Counter(m[0] for _, m in eligible)), **count(eligible),
           "right": count([(r, m) for r, m in eligible if r["score"].get("right") is True])}
    out["not_confirmed"] = [
        {"index": r["index"], "stratum": r["stratum"], "metric": m[0], "before": m[1], "after": m[2],
         "truth": [f"{c['target']}={_fmt(c['true'])}" for c in r["score"]["coverage"]],
         "reported": [f"{label(target(f))}={_fmt(f.get('estimate'))}" for f in r["findings"][:3]],
         "right": r["score"].get("right"), "where": _where(kind, r["case"])}
        for r, m in eligible if not m[2] < m[1]]
    free = [(r, resimulated(kind, r, band)) for r in ok if not systematic(r)]
    free = [(r, m) for r, m in free if m is not None]
    same = {r["index"] for r, (_, b, a) in free if abs(a - b) <= 1e-6 * max(abs(b), 1e-300)}
    out["no_systematic_finding"] = {"n": len(free), "after_equals_before": len(same),
                                    "differ": [r["index"] for r, _ in free if r["index"] not in same]}
    return out


def summarise(kind: str, results: list[dict], meta: dict) -> dict:
    ok = [r for r in results if "score" in r]
    errors = [r for r in results if "error" in r]
    singles = [r for r in ok if r["score"]["n_systematic"] == 1]
    pairs = [r for r in ok if r["score"]["n_systematic"] == 2]
    free = [r for r in ok if r["score"]["n_systematic"] == 0]
    confusion = defaultdict(Counter)
    for r in singles + free:
        truth = [label(target(e)) for e in r["effects"] if e["cause"] in SYSTEMATIC[kind]]
        row = truth[0].split(":")[0] if truth else "(no systematic effect)"
        confusion[row][r["score"]["first"].split(":")[0]] += 1
    eff = [c for r in ok for c in r["score"]["coverage"]]
    noise = [c for c in eff if "within_1.5x" in c]
    per_cause = defaultdict(lambda: [0, 0])
    for c in eff:
        per_cause[c["target"].split(":")[0]][0] += c["covered"]
        per_cause[c["target"].split(":")[0]][1] += 1
    per_single = defaultdict(lambda: [0, 0])
    for r in singles:
        t = [label(target(e)) for e in r["effects"] if e["cause"] in SYSTEMATIC[kind]][0]
        per_single[t][0] += r["score"]["right"]
        per_single[t][1] += 1
    runs_cov = [r for r in ok if r["score"]["all_covered"] is not None]
    by_size = {}
    for name, group in (("single", singles), ("pair", pairs)):
        for lo, hi, tag in ((0, 1 / 3, "smallest third"), (1 / 3, 2 / 3, "middle third"), (2 / 3, 1.01, "largest third")):
            g = [r for r in group if lo <= min(size_u(e, r["case"]) for e in r["effects"]
                                               if e["cause"] in SYSTEMATIC[kind]) < hi]
            by_size[f"{name}, {tag}"] = {"right": sum(r["score"]["right"] for r in g), "n": len(g)}
    misses = []
    for r in ok:
        s = r["score"]
        bad = (s.get("right") is False) or s.get("false_alarm") or s["all_covered"] is False
        if bad:
            truth = ", ".join(f"{c['target']}={_fmt(c['true'])}" for c in s["coverage"]) or "no effect"
            got = ", ".join(f"{label(target(f))}={_fmt(f.get('estimate'))}" for f in r["findings"][:3]) or "no finding"
            cs = r["case"]
            outside = "; ".join(
                f"{c['target']} {_fmt(c['true'])} " + ("not reported" if c["estimate"] is None else
                                                       f"outside [{_fmt(c['interval'][0])}, {_fmt(c['interval'][1])}]")
                for c in s["coverage"] if not c["covered"])
            order = s.get("right") is False or s.get("false_alarm")
            misses.append(f"run {r['index']} [{r['stratum']}] {_where(kind, cs)}: truth {truth}; reported {got}"
                          + (" -- ORDER" if order else "") + (f" -- INTERVAL: {outside}" if outside else ""))
    for r in errors:
        misses.append(f"run {r['index']} [{r['stratum']}]: ERROR {r['error']}")
    cpu = [r.get("gen_cpu_s", 0) + r.get("diag_cpu_s", 0) for r in ok]
    with_right = [r for r in ok if r["score"].get("right_all_confirmed") is not None]
    noise_kind = defaultdict(lambda: [0, 0])
    for c in noise:
        noise_kind[str(c.get("estimate_kind"))][0] += c["covered"]
        noise_kind[str(c.get("estimate_kind"))][1] += 1

    def has_delay(r):
        return any(e["cause"] == "force_delay" for e in r["effects"])
    delay_single = [r for r in singles if has_delay(r)]
    delay_pair = [r for r in pairs if has_delay(r)]
    return {
        "confirmation": {
            "runs_with_right_systematic_finding": len(with_right),
            "all_right_confirmed": sum(r["score"]["right_all_confirmed"] for r in with_right),
            "all_right_confirmed_pct": _pct(sum(r["score"]["right_all_confirmed"] for r in with_right), len(with_right)),
            "not_all_confirmed": [r["index"] for r in with_right if not r["score"]["right_all_confirmed"]]},
        "delays": {"single": {"n": len(delay_single), "right": sum(r["score"]["right"] for r in delay_single)},
                   "pair": {"n": len(delay_pair), "right": sum(r["score"]["right"] for r in delay_pair)}},
        "noise_coverage_by_kind": {k: {"covered": v[0], "n": v[1]} for k, v in sorted(noise_kind.items())},
        "kind": kind, **meta, "runs": len(results), "diagnosed": len(ok), "errors": len(errors),
        "single": {"n": len(singles), "right_first": sum(r["score"]["right"] for r in singles),
                   "right_first_pct": _pct(sum(r["score"]["right"] for r in singles), len(singles)),
                   "right_or_declared": sum(r["score"]["right_or_declared"] for r in singles),
                   "per_target": {k: {"right": v[0], "n": v[1]} for k, v in sorted(per_single.items())}},
        "right_by_size": by_size,
        "pair": {"n": len(pairs), "both_in_first_two": sum(r["score"]["right"] for r in pairs),
                 "both_in_first_two_pct": _pct(sum(r["score"]["right"] for r in pairs), len(pairs)),
                 "right_or_declared": sum(r["score"]["right_or_declared"] for r in pairs)},
        "effect_free": {"n": len(free), "false_alarms": sum(r["score"]["false_alarm"] for r in free),
                        "false_alarm_pct": _pct(sum(r["score"]["false_alarm"] for r in free), len(free))},
        "coverage": {"effects": len(eff), "covered": sum(c["covered"] for c in eff),
                     "covered_pct": _pct(sum(c["covered"] for c in eff), len(eff)),
                     "runs": len(runs_cov), "runs_all_covered": sum(r["score"]["all_covered"] for r in runs_cov),
                     "runs_all_covered_pct": _pct(sum(r["score"]["all_covered"] for r in runs_cov), len(runs_cov)),
                     "per_cause": {k: {"covered": v[0], "n": v[1]} for k, v in sorted(per_cause.items())}},
        "noise_within_1.5x": {"n": len(noise), "k": sum(c["within_1.5x"] for c in noise),
                              "pct": _pct(sum(c["within_1.5x"] for c in noise), len(noise))},
        "confusion": {k: dict(v) for k, v in sorted(confusion.items())},
        "cpu_s": {"total": round(sum(cpu), 1), "mean": round(sum(cpu) / max(len(cpu), 1), 2),
                  "max": round(max(cpu, default=0.0), 1)},
        "gain_by_resimulation": gain_measure(kind, ok),
        "gain_by_resimulation_dynamic": gain_measure(kind, ok, "dynamic") if kind == "vehicle" else None,
        "misses": misses,
        "per_run": [{"index": r["index"], "stratum": r["stratum"],
                     "truth": [label(target(e)) for e in r.get("effects", [])],
                     "first_three": [label(target(f)) for f in r.get("findings", [])[:3]],
                     "right": r.get("score", {}).get("right"), "false_alarm": r.get("score", {}).get("false_alarm"),
                     "all_covered": r.get("score", {}).get("all_covered"), "error": r.get("error"),
                     "gain": r.get("gain"),
                     "cpu_s": round(r.get("gen_cpu_s", 0) + r.get("diag_cpu_s", 0), 2)} for r in results],
    }


def nonlinear_summary(results: list[dict]) -> dict:
    """The nonlinear design's measures: per run with a nonlinear effect, right (the cause, or
    ``model_form`` on its axle, first; pairs: both in the first two), else whether the report said
    it could not show the effect; also the nonlinear cause first alone (pairs too: the sensor
    effect may come later); split by whether the run measured that axle's spring travel
    (s1/s2), the channel that shows a spring law. Effect-free runs: how many got a model-form
    finding (``FORM``), and how many got one of today's causes."""
    ok = [r for r in results if "score" in r]
    rows = []
    for r in ok:
        nl = [e for e in r["effects"] if e["cause"] in NONLINEAR]
        if not nl:
            continue
        e = nl[0]
        t = target(e)
        key = f"{t[0]}[{t[1]}]"
        said = any(key in nt for nt in r.get("could_not_show", []))
        # what the note says of this cause: 'cause[target] (... would show it)' (at no usual size)
        # or 'cause[target] smaller than <limit> (...)', to set beside the true size
        said_what = next((part.strip() for nt in r.get("could_not_show", [])
                          for part in nt.split(":", 1)[-1].split(";") if key in part), None)
        axle = _axle(t)
        travel = f"s{1 if axle == 'front' else 2}"
        shows = e["cause"] == "tyre_lift_off" or travel in r["case"]["channels"]
        rows.append({"index": r["index"], "stratum": r["stratum"], "effect": label(t), "value": e["value"],
                     "right": bool(r["score"].get("right")), "could_not_show_said": said,
                     "nonlinear_first": bool(r["findings"]) and (
                         target(r["findings"][0]) == t
                         or (r["findings"][0]["cause"] == "model_form" and r["findings"][0].get("axle") == axle)),
                     "note": said_what.split(". ")[0] if said_what else None,
                     "truth": {k: v for k, v in e.items() if k in ("ratio", "share", "stiffening", "value")},
                     "travel_measured": shows, "channels": r["case"]["channel_set"],
                     "first_three": [label(target(f)) + (f"({f.get('axle')})" if f["cause"] == "model_form" else "")
                                     for f in r["findings"][:3]]})
    free = [r for r in ok if r["score"]["n_systematic"] == 0]
    form_fa = [r["index"] for r in free if any(f["cause"] in FORM for f in r["findings"])]
    today_fa = [r["index"] for r in free if any(f["cause"] in SYSTEMATIC["vehicle"] and f["cause"] not in FORM
                                                for f in r["findings"])]

    def count(g):
        right = sum(x["right"] for x in g)
        said = sum((not x["right"]) and x["could_not_show_said"] for x in g)
        # the issue's own measure: the nonlinear cause (or model_form on its axle) first, pairs too
        first = sum(x["nonlinear_first"] for x in g)
        first_said = sum((not x["nonlinear_first"]) and x["could_not_show_said"] for x in g)
        return {"n": len(g), "right": right, "right_pct": _pct(right, len(g)), "could_not_show_said": said,
                "neither": len(g) - right - said, "nonlinear_first": first,
                "nonlinear_first_pct": _pct(first, len(g)), "not_first_could_not_show_said": first_said,
                "not_first_neither": len(g) - first - first_said}

    return {"all": count(rows), "travel_measured": count([x for x in rows if x["travel_measured"]]),
            "travel_not_measured": count([x for x in rows if not x["travel_measured"]]),
            "per_cause": {c: count([x for x in rows if x["effect"].startswith(c)]) for c in NONLINEAR},
            "effect_free": {"n": len(free), "model_form_findings": len(form_fa),
                            "model_form_pct": _pct(len(form_fa), len(free)), "runs": form_fa,
                            "todays_causes_findings": len(today_fa), "todays_runs": today_fa},
            "per_run": rows}


def _fmt(v):
    if v is None:
        return "-"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(f"{x:.4g}" for x in v) + "]"
    return f"{v:.6g}"


def _where(kind, cs):
    if kind == "vehicle":
        return (f"{cs['vehicle_kind']} road {cs['road_class']} {cs['speed']:.0f} m/s {cs['fs']:g} Hz "
                f"{cs['duration']:g} s {cs['channel_set']} {cs['precision']} digits"
                + (" motion-noise" if cs["motion_noise"] else ""))
    arr = "no array" if not cs.get("n_sensors") else f"{cs['n_sensors']} sensors"
    ref = f"reference every {cs['reference_every']}" if cs["reference_every"] else "no reference"
    return f"{cs['fs']:g} Hz {cs['duration']:g} s {ref} {arr} {cs['precision']} digits"


def markdown(s: dict) -> str:
    L = [f"# Independent validation sweep: {s['kind']}", "",
         f"{s['runs']} runs (design seed {s['seed']}, generator `benchmarks/validation/gen_{s['kind']}.py`), "
         f"diagnosed by jaxdrift {s.get('jaxdrift_commit', '?')}; {s['errors']} failed with an error. "
         f"Reproduce: `{s['command']}`", "", summary_table(s), "",
         f"CPU: {s['cpu_s']['total']} s in all, {s['cpu_s']['mean']} s per run, at most {s['cpu_s']['max']} s.", "",
         "## Confusion: true cause (single-effect and effect-free runs) x first reported cause", ""]
    cols = sorted({c for row in s["confusion"].values() for c in row})
    L += ["| true \\ first | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for row, cnt in s["confusion"].items():
        L.append(f"| {row} | " + " | ".join(str(cnt.get(c, "")) for c in cols) + " |")
    L += ["", "## Single-effect runs per target (right first / runs)", "",
          ", ".join(f"{k} {v['right']}/{v['n']}" for k, v in s["single"]["per_target"].items()), "",
          "## Right first (singles) or both in the first two (pairs) by effect size", "",
          "Size: where the smaller systematic effect lies in its log-uniform draw range.", "",
          ", ".join(f"{k} {v['right']}/{v['n']}" for k, v in s["right_by_size"].items()), "",
          "## Interval coverage per cause (covered / effects)", "",
          ", ".join(f"{k} {v['covered']}/{v['n']}" for k, v in s["coverage"]["per_cause"].items()), "",
          f"## Misses ({len(s['misses'])})", ""]
    L += [f"- {m}" for m in s["misses"]]
    for key, what in (("gain_by_resimulation", ""),
                      ("gain_by_resimulation_dynamic", ", pitch error above the drift band")):
        g = s.get(key)
        if not g or not g["n"]:
            continue
        L += ["", f"## Gains not confirmed by re-simulation{what} ({len(g['not_confirmed'])} of {g['n']})", "",
              "Runs with a finding the re-simulation sees whose extended model's re-simulated RMS error is "
              "not below the model's.", ""]
        L += [f"- run {x['index']} [{x['stratum']}] {x['where']}: truth {', '.join(x['truth']) or 'no effect'}; "
              f"reported {', '.join(x['reported'])}; {x['metric']} {_fmt(x['before'])} -> {_fmt(x['after'])}"
              + (" (scored right)" if x["right"] else "") for x in g["not_confirmed"]]
    return "\n".join(L) + "\n"


def summary_table(s: dict) -> str:
    """The sweep's summary table (measure, result, target) from its JSON summary; the docs quote it
    (``benchmarks/doc_tables.py``)."""
    L = ["| measure | result | target |", "|---|---|---|",
         f"| right cause first, single-effect runs | {s['single']['right_first']}/{s['single']['n']} "
         f"({s['single']['right_first_pct']} %) | >= 95 % |",
         f"| ... or declared indistinguishable | {s['single']['right_or_declared']}/{s['single']['n']} | |",
         f"| both effects in the first two, pairs | {s['pair']['both_in_first_two']}/{s['pair']['n']} "
         f"({s['pair']['both_in_first_two_pct']} %) | >= 90 % |",
         f"| ... or declared indistinguishable | {s['pair']['right_or_declared']}/{s['pair']['n']} | |",
         f"| false alarms (systematic cause first), effect-free runs | {s['effect_free']['false_alarms']}/"
         f"{s['effect_free']['n']} ({s['effect_free']['false_alarm_pct']} %) | <= 5 % |",
         f"| true values inside the 95 % interval, per effect | {s['coverage']['covered']}/{s['coverage']['effects']} "
         f"({s['coverage']['covered_pct']} %) | |",
         f"| runs with every true value inside its interval | {s['coverage']['runs_all_covered']}/"
         f"{s['coverage']['runs']} ({s['coverage']['runs_all_covered_pct']} %) | >= 90 % |",
         f"| noise level within 1.5x of the truth | {s['noise_within_1.5x']['k']}/{s['noise_within_1.5x']['n']} "
         f"({s['noise_within_1.5x']['pct']} %) | 100 % |",
         *([f"| runs whose right systematic findings are all confirmed (in the extended model) | "
            f"{s['confirmation']['all_right_confirmed']}/{s['confirmation']['runs_with_right_systematic_finding']} "
            f"({s['confirmation']['all_right_confirmed_pct']} %) | >= 95 % |",
            f"| delays right: single-effect runs / pairs with a delay | {s['delays']['single']['right']}/"
            f"{s['delays']['single']['n']} / {s['delays']['pair']['right']}/{s['delays']['pair']['n']} | as often |",
            "| noise intervals holding the truth, by kind | " + ", ".join(
                f"{k} {v['covered']}/{v['n']}" for k, v in s["noise_coverage_by_kind"].items()) + " | all |"]
           if "confirmation" in s else []),
         *_gain_rows(s.get("gain_by_resimulation")),
         *(_gain_rows(s["gain_by_resimulation_dynamic"], " (pitch error above the drift band)")
           if s.get("gain_by_resimulation_dynamic") else [])]
    return "\n".join(L)


def _gain_rows(g: dict | None, what: str = "") -> list[str]:
    """The summary table's rows for the gains confirmed by re-simulation."""
    if not g or not g["n"]:
        return ["| gains confirmed by re-simulation | not measured (no re-simulated error: "
                "`--no-simulation` or no pitch/heave/reference) | gains confirmed by re-simulation |"]
    mets = ", ".join(f"{k} {v}" for k, v in sorted(g["metrics"].items()))
    rt, nf = g["right"], g["no_systematic_finding"]
    which = "gyro" if "attitude_error_rms" in g["metrics"] else "systematic"
    return [f"| re-simulated error{what} lower with the extended model (after < before), runs with a {which} "
            f"finding ({mets}) | {g['confirmed']}/{g['n']} ({g['confirmed_pct']} %); after < "
            f"{g['clear_factor']:g} x before in {g['clear']}; median after/before {g['median_ratio']} "
            "| gains confirmed by re-simulation |",
            f"| ... runs scored right (single: right first; pair: both in the first two) | {rt['confirmed']}/{rt['n']} ({rt['confirmed_pct']} %); after < "
            f"{g['clear_factor']:g} x before in {rt['clear']}; median after/before {rt['median_ratio']} | |",
            f"| ... no {which} finding: re-simulated error unchanged | {nf['after_equals_before']}/{nf['n']}"
            + (f" (differ: runs {', '.join(map(str, nf['differ']))})" if nf["differ"] else "") + " | |"]


def _commit():
    import subprocess

    try:
        # the last commit that changed the library: the diagnosis code that was measured
        return subprocess.run(["git", "-C", str(HERE), "log", "-1", "--format=%h", "--", "../../jaxdrift"],
                              capture_output=True, text=True, timeout=10).stdout.strip() or "?"
    except Exception:  # noqa: BLE001
        return "?"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--kind", choices=("vehicle", "attitude"), required=True)
    ap.add_argument("--n", type=int, required=True, help="number of runs of the design")
    ap.add_argument("--seed", type=int, required=True, help="design seed")
    ap.add_argument("--out", required=True, help="folder for the summary (and cache/ unless --cache)")
    ap.add_argument("--cache", help="folder of per-run results (default OUT/cache/<kind>-<seed>)")
    ap.add_argument("--prefix", default="", help="prefix of the summary files; the committed ones are named by the commit that diagnosed them, "
                    "e.g. '20e4450-'")
    ap.add_argument("--design", choices=("standard", "nonlinear", "gain_drift", "crosstalk"), default="standard",
                    help="vehicle: the stratified design of today's causes, the nonlinear suspension "
                         "design (gen_vehicle.design_nonlinear: effect-free runs, nonlinear effects alone "
                         "and paired with a sensor effect) or the gain-drift design "
                         "(gen_vehicle.design_gain_drift: effect-free runs, a drifting force gain alone "
                         "and with an offset) or the crosstalk design (gen_vehicle.design_crosstalk: a share "
                         "of one force channel read in the other, alone and with an offset or a scale)")
    ap.add_argument("--free-share", type=float, default=None,
                    help="nonlinear design: the share of effect-free runs (default 0.4; 0 for a calibration "
                         "sweep of the nonlinear causes' intervals)")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    ap.add_argument("--chunk", default="0/1", help="i/k: only the cases with index = i mod k")
    ap.add_argument("--only", default=None, metavar="CAUSE",
                    help="only the cases whose design holds this cause (e.g. bump_stop), for a question about "
                         "one kind's intervals; the summary then counts those cases only")
    ap.add_argument("--report-only", action="store_true", help="summarise the cache, run nothing")
    ap.add_argument("--keep-runs", help="keep the generated files in this folder")
    ap.add_argument("--no-simulation", action="store_true",
                    help="vehicle: diagnose with with_simulation=False (no force-driven re-simulation: "
                         "no re-simulation check of the causes and no pitch gain; faster)")
    ap.add_argument("--diagnosed-by", default=None, metavar="COMMIT",
                    help="with --report-only on a cache diagnosed by another checkout: the commit to record "
                         "as the diagnosing one (default: the last commit that changed jaxdrift/ here)")
    a = ap.parse_args(argv)
    gen = importlib.import_module("benchmarks.validation." + ("gen_vehicle" if a.kind == "vehicle" else "gen_attitude"))
    nonlinear = a.kind == "vehicle" and a.design == "nonlinear"
    design = a.design if a.kind == "vehicle" else "standard"
    cache = a.cache or os.path.join(a.out, "cache", f"{a.kind}-{'' if design == 'standard' else design + '-'}{a.seed}")
    os.makedirs(cache, exist_ok=True)
    os.makedirs(a.out, exist_ok=True)
    sizing = SIZING[a.kind]
    cases = {"standard": gen.design, "nonlinear": getattr(gen, "design_nonlinear", None),
             "gain_drift": getattr(gen, "design_gain_drift", None),
             "crosstalk": getattr(gen, "design_crosstalk", None)}[design]
    cases = cases(a.n, a.seed) if a.free_share is None else cases(a.n, a.seed, free_share=a.free_share)
    if a.only:
        cases = [c for c in cases if any(w[0] == a.only for w in c.get("what", []))]
    i, k = (int(x) for x in a.chunk.split("/"))
    todo = [c for c in cases if c["index"] % k == i
            and not os.path.exists(os.path.join(cache, f"{c['index']:04d}.json"))]
    print(f"{a.kind}: {len(cases)} cases, {len(todo)} to run in chunk {a.chunk}, cache {cache}", flush=True)
    t0 = time.time()
    if not a.report_only and todo:
        def show(j, r):
            s = r.get("score", {})
            verdict = r.get("error") or ("ok" if s.get("right", not s.get("false_alarm")) else "MISS")
            print(f"[{j}/{len(todo)} {time.time() - t0:.0f}s] run {r['index']} {r['stratum']}: {verdict}; "
                  f"first {s.get('first', '-')}; cpu {r.get('gen_cpu_s', 0) + r.get('diag_cpu_s', 0):.1f}s", flush=True)

        if a.jobs <= 1:
            for j, c in enumerate(todo, 1):
                show(j, run_one(a.kind, c, cache, sizing, a.keep_runs, not a.no_simulation))
        else:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor, as_completed

            with ProcessPoolExecutor(a.jobs, mp_context=mp.get_context("spawn")) as ex:
                futs = [ex.submit(run_one, a.kind, c, cache, sizing, a.keep_runs,
                                     not a.no_simulation) for c in todo]
                for j, f in enumerate(as_completed(futs), 1):
                    show(j, f.result())
    results = []
    for c in cases:
        p = os.path.join(cache, f"{c['index']:04d}.json")
        if os.path.exists(p):
            with open(p) as fh:
                results.append(json.load(fh))
    cmd = (f"python benchmarks/validation/sweep.py --kind {a.kind} --n {a.n} --seed {a.seed} "
           f"--out {a.out}" + (f" --prefix {a.prefix}" if a.prefix else "")
           + (" --no-simulation" if a.no_simulation and a.kind == "vehicle" else "")
           + (f" --design {design}" if design != "standard" else "")
           + (f" --free-share {a.free_share}" if a.free_share is not None else "")
           + (f" --only {a.only}" if a.only else "") + " --jobs 1")
    summ = summarise(a.kind, results, {"seed": a.seed, "n_design": a.n, "command": cmd,
                                       "sizing": sizing, "jaxdrift_commit": a.diagnosed_by or _commit()})
    if nonlinear:
        summ["nonlinear"] = nonlinear_summary(results)
    if len(results) < len(cases):
        print(f"note: {len(cases) - len(results)} cases not yet in the cache; summary of {len(results)}")
    base = os.path.join(a.out, f"{a.prefix}{a.kind}")
    with open(base + ".json", "w") as fh:
        json.dump(summ, fh, indent=1, default=float)
    with open(base + ".md", "w") as fh:
        fh.write(markdown(summ))
    print(markdown(summ).split("## Confusion")[0])
    if nonlinear:
        print(json.dumps(summ["nonlinear"], indent=1))


if __name__ == "__main__":
    main()
