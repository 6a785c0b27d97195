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

    python benchmarks/independent/sweep.py --kind vehicle --n 20 --seed 1 --out /tmp/sw --jobs 2
    python benchmarks/independent/sweep.py --kind attitude --n 100 --seed 20261201 \\
        --out docs/validation --prefix before- --jobs 1
"""

from __future__ import annotations

import argparse
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
sys.path.insert(0, str(HERE))

SYSTEMATIC = {"vehicle": ("force_offset", "force_scale", "force_delay", "parameter_error"),
              "attitude": ("gyro_bias", "gyro_scale", "gyro_bias_drift", "sensor_position", "nonrigid")}
NOISE = {"vehicle": ("force_noise",), "attitude": ("gyro_noise", "accel_noise")}
#: sizing of the committed sweep (fits ~35 min of one core for 200 vehicle + 100 attitude runs)
SIZING = {"vehicle": {"durations": (10.0, 20.0), "rates": (200, 250, 300, 500, 600, 1000, 2000),
                      "max_samples": 6000},
          "attitude": {"durations": (30.0, 150.0), "rates": (100, 200, 250, 400, 500, 1000),
                       "max_samples": 60000}}


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


def score(kind: str, effects: list, findings: list) -> dict:
    """The rules of the module docstring for one run."""
    systematic = [target(e) for e in effects if e["cause"] in SYSTEMATIC[kind]]
    got = [target(f) for f in findings]
    alts = [[target(a) for a in f.get("indistinguishable_from", []) or []] for f in findings]
    first = got[0] if got else ("none", "")
    out = {"n_systematic": len(systematic), "first": label(first),
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
    cov = []
    for e in effects:
        match = [f for f in findings if target(f) == target(e)]
        est = match[0]["estimate"] if match else None
        c = {"target": label(target(e)), "true": e["value"], "estimate": est,
             "interval": match[0].get("interval") if match else None}
        c["covered"] = bool(match) and _inside(e["value"], c["interval"])
        if e["cause"] in NOISE[kind]:
            c["within_1.5x"] = bool(match) and est is not None and e["value"] > 0 and \
                1 / 1.5 <= est / e["value"] <= 1.5
        cov.append(c)
    out["coverage"] = cov
    out["all_covered"] = all(c["covered"] for c in cov) if cov else None
    return out


# ----------------------------------------------------------------------------- one run
def _trim(f: dict) -> dict:
    keep = ("cause", "channel", "parameter", "sensor", "estimate", "interval", "z", "evidence",
            "indistinguishable_from")
    return {k: f[k] for k in keep if k in f}


def run_one(kind: str, case: dict, cache: str, sizing: dict, keep_dir: str | None = None) -> dict:
    """Generate, diagnose and score one case; write its result JSON atomically into ``cache``."""
    import numpy as np  # noqa: F401  (workers start clean)

    gen = __import__("gen_vehicle" if kind == "vehicle" else "gen_attitude")
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
            report = jaxdrift.diagnose_vehicle_run(run, model, with_simulation=False)
        else:
            report = jaxdrift.run_attitude_diagnosis(paths["csv"], paths["sensors"])
        res["diag_cpu_s"] = time.process_time() - c1
        res["wall_s"] = time.time() - w0
        res["findings"] = [_trim(f) for f in report.get("findings", [])]
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
    misses = []
    for r in ok:
        s = r["score"]
        bad = (s.get("right") is False) or s.get("false_alarm") or s["all_covered"] is False
        if bad:
            truth = ", ".join(f"{c['target']}={_fmt(c['true'])}" for c in s["coverage"]) or "no effect"
            got = ", ".join(f"{label(target(f))}={_fmt(f.get('estimate'))}" for f in r["findings"][:3]) or "no finding"
            cs = r["case"]
            misses.append(f"run {r['index']} [{r['stratum']}] {_where(kind, cs)}: truth {truth}; "
                          f"reported {got}" + ("" if s.get("right", True) and not s.get("false_alarm") else
                                               " (order)" ) + ("" if s["all_covered"] is not False else " (interval)"))
    for r in errors:
        misses.append(f"run {r['index']} [{r['stratum']}]: ERROR {r['error']}")
    cpu = [r.get("gen_cpu_s", 0) + r.get("diag_cpu_s", 0) for r in ok]
    return {
        "kind": kind, **meta, "runs": len(results), "diagnosed": len(ok), "errors": len(errors),
        "single": {"n": len(singles), "right_first": sum(r["score"]["right"] for r in singles),
                   "right_first_pct": _pct(sum(r["score"]["right"] for r in singles), len(singles)),
                   "right_or_declared": sum(r["score"]["right_or_declared"] for r in singles),
                   "per_target": {k: {"right": v[0], "n": v[1]} for k, v in sorted(per_single.items())}},
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
        "misses": misses,
    }


def _fmt(v):
    if v is None:
        return "-"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(f"{x:.3g}" for x in v) + "]"
    return f"{v:.4g}"


def _where(kind, cs):
    if kind == "vehicle":
        return (f"{cs['vehicle_kind']} road {cs['road_class']} {cs['speed']:.0f} m/s {cs['fs']:g} Hz "
                f"{cs['duration']:g} s {cs['channel_set']} {cs['precision']} digits"
                + (" motion-noise" if cs["motion_noise"] else ""))
    arr = "no array" if not cs.get("n_sensors") else f"{cs['n_sensors']} sensors"
    return f"{cs['fs']:g} Hz {cs['duration']:g} s ref every {cs['reference_every']} {arr} {cs['precision']} digits"


def markdown(s: dict) -> str:
    L = [f"# Independent validation sweep: {s['kind']}", "",
         f"{s['runs']} runs (design seed {s['seed']}, generator `benchmarks/independent/gen_{s['kind']}.py`), "
         f"diagnosed by jaxdrift {s.get('jaxdrift_commit', '?')}; {s['errors']} failed with an error. "
         f"Reproduce: `{s['command']}`", "",
         "| measure | result | target (issue #13) |", "|---|---|---|",
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
         "", f"CPU: {s['cpu_s']['total']} s in all, {s['cpu_s']['mean']} s per run, at most {s['cpu_s']['max']} s.", "",
         "## Confusion: true cause (single-effect and effect-free runs) x first reported cause", ""]
    cols = sorted({c for row in s["confusion"].values() for c in row})
    L += ["| true \\ first | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for row, cnt in s["confusion"].items():
        L.append(f"| {row} | " + " | ".join(str(cnt.get(c, "")) for c in cols) + " |")
    L += ["", "## Single-effect runs per target (right first / runs)", "",
          ", ".join(f"{k} {v['right']}/{v['n']}" for k, v in s["single"]["per_target"].items()), "",
          "## Interval coverage per cause (covered / effects)", "",
          ", ".join(f"{k} {v['covered']}/{v['n']}" for k, v in s["coverage"]["per_cause"].items()), "",
          f"## Misses ({len(s['misses'])})", ""]
    L += [f"- {m}" for m in s["misses"]]
    return "\n".join(L) + "\n"


def _commit():
    import subprocess

    try:
        return subprocess.run(["git", "-C", str(HERE), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=10).stdout.strip() or "?"
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
    ap.add_argument("--prefix", default="", help="prefix of the summary files, e.g. 'before-'")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    ap.add_argument("--chunk", default="0/1", help="i/k: only the cases with index = i mod k")
    ap.add_argument("--report-only", action="store_true", help="summarise the cache, run nothing")
    ap.add_argument("--keep-runs", help="keep the generated files in this folder")
    a = ap.parse_args(argv)
    gen = __import__("gen_vehicle" if a.kind == "vehicle" else "gen_attitude")
    cache = a.cache or os.path.join(a.out, "cache", f"{a.kind}-{a.seed}")
    os.makedirs(cache, exist_ok=True)
    sizing = SIZING[a.kind]
    cases = gen.design(a.n, a.seed)
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
                show(j, run_one(a.kind, c, cache, sizing, a.keep_runs))
        else:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor, as_completed

            with ProcessPoolExecutor(a.jobs, mp_context=mp.get_context("spawn")) as ex:
                futs = [ex.submit(run_one, a.kind, c, cache, sizing, a.keep_runs) for c in todo]
                for j, f in enumerate(as_completed(futs), 1):
                    show(j, f.result())
    results = []
    for c in cases:
        p = os.path.join(cache, f"{c['index']:04d}.json")
        if os.path.exists(p):
            with open(p) as fh:
                results.append(json.load(fh))
    cmd = (f"python benchmarks/independent/sweep.py --kind {a.kind} --n {a.n} --seed {a.seed} "
           f"--out {a.out}" + (f" --prefix {a.prefix}" if a.prefix else "") + " --jobs 1")
    summ = summarise(a.kind, results, {"seed": a.seed, "n_design": a.n, "command": cmd,
                                       "sizing": sizing, "jaxdrift_commit": _commit()})
    if len(results) < len(cases):
        print(f"note: {len(cases) - len(results)} cases not yet in the cache; summary of {len(results)}")
    base = os.path.join(a.out, f"{a.prefix}{a.kind}")
    with open(base + ".json", "w") as fh:
        json.dump(summ, fh, indent=1, default=float)
    with open(base + ".md", "w") as fh:
        fh.write(markdown(summ))
    print(markdown(summ).split("## Confusion")[0])


if __name__ == "__main__":
    main()
