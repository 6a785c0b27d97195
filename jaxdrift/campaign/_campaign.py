"""``jaxdrift.campaign``: diagnose every run of a campaign on Dask, fit the vehicle jointly over
them, optionally their durability, and write ``campaign.json``, the runs' reports, ``summary.md``
and the figures into one folder (``docs/campaign.md``)."""

from __future__ import annotations

import datetime
import hashlib
import json
import os
import time

import numpy as np

from ..errors import UsageError
from ..io._csvio import DEFAULT_MODEL, MODEL_KEYS
from ..io._provenance import jaxdrift_version
from ._joint import CONSISTENCY_LEVEL, check_consistency
from ._manifest import RunSpec, cache_key, code_digest, read_manifest, run_specs

__all__ = ["campaign", "SCHEMA"]

SCHEMA = "jaxdrift.campaign/1"
#: bump when the joint fit changes what it returns for the same inputs (part of its cache key)
JOINT_VERSION = 3


def _read_cache(path):
    try:
        with open(path) as fh:
            return json.load(fh)
    except (OSError, ValueError):
        return None


def _report_names(specs) -> list[str]:
    names, seen = [], {}
    for s in specs:
        n = s.name
        seen[n] = seen.get(n, 0) + 1
        names.append(n if seen[n] == 1 else f"{n}_{seen[n]}")
    return names


def _diagnose_all(client, specs, model, model_given, model_desc, cache_dir, progress, log):
    from ._executor import map_tasks

    results = [None] * len(specs)
    todo = []
    for i, s in enumerate(specs):
        key = cache_key(s, model, {"stage": "diagnose"}, "diagnose")
        f = os.path.join(cache_dir, f"diagnose-{key}.json")
        hit = _read_cache(f)
        if hit is not None and hit.get("status") == "ok":
            results[i] = {**hit, "cached": True}
        else:
            todo.append((i, s, f))
    log.append(f"{len(specs) - len(todo)} of {len(specs)} runs' diagnoses from the cache")
    for (i, _, f), res in zip(todo, map_tasks(
            client, _diag_call, [(s, f) for _, s, f in todo], desc="diagnosing runs", progress=progress,
            record_failures=True, model=model, model_given=model_given, model_desc=model_desc)):
        results[i] = {**res, "cached": False}
    return results


def _diag_call(item, **kw):
    from ._tasks import diagnose_task

    spec, cache_file = item
    return diagnose_task(spec, cache_file=cache_file, **kw)


def _groups(specs, ok):
    order, groups = [], {}
    for i in ok:
        lid = specs[i].logger_id
        if lid not in groups:
            groups[lid] = []
            order.append(lid)
        groups[lid].append(i)
    return order, [groups[k] for k in order]


def _joint(client, specs, results, names, model, model_given, progress, log):
    """The joint fit over the runs that were diagnosed; its result as plain JSON-able data."""
    from ..diagnosis.vehicle import PARAMETER_ERROR, candidates as _candidates
    from ._joint import JointFit, _merge, consistency, sensor_causes_of

    ok = [i for i, r in enumerate(results) if r["status"] == "ok"]
    if not ok:
        return None
    lids, groups = _groups(specs, ok)
    start = [_merge([sensor_causes_of(results[i]["report"]) for i in g]) for g in groups]
    cands = _candidates(None, (PARAMETER_ERROR,))
    specs_g = [[specs[i] for i in g] for g in groups]
    fit = JointFit(client, specs_g, model, model_given, cands, start, progress=progress, log=log)
    shared, theta, _ = fit.select()
    fit.reselect(specs_g, shared, theta)
    shared, theta, state = fit.select(shared, theta)
    # the linear parameters chosen again on the model carrying the joint nonlinear causes
    nl_findings, nl_corr, shared, theta = _joint_nonlinear(client, fit, specs, results, names, groups, specs_g,
                                                           shared, theta, model, model_given, progress, log)
    order, A, b, M, outs = fit._blocks(shared, theta, final=True)
    state = (order, A, b, M, outs, theta)
    cov = fit.covariance(state, len(shared))
    run_names = [names[i] for g in groups for i in g]
    p_of = [len(shared) + len(n) for n in fit.nuis]
    cons = consistency(shared, theta, state, JointFit.sigma2, run_names, p_of)
    left = {n: x for n, x in zip(run_names, fit.not_carried) if x}
    for e in cons:  # a run that lacks a law of the vehicle cannot be compared with the others
        e["per_run"] = [r for r in e["per_run"] if r["run"] not in left]
        if left:
            e["left_out"] = [{"run": n, "why": f"the joint {', '.join(x)} could not be carried into it"}
                             for n, x in left.items()]
    from ..diagnosis.vehicle import apply_causes as _apply

    p_joint, _ = _apply(model, shared, theta)
    per_run = {}
    for g, o in zip(groups, outs):
        for i, fin in zip(g, o["final"]):
            per_run[i] = fin
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0)) if len(shared) else np.zeros(0)
    corr = (cov / np.outer(sd, sd)).tolist() if len(shared) and np.all(sd > 0) else []
    return {
        "extended_model": {"parameters": {k: float(p_joint[k]) for k in MODEL_KEYS},
                           "runs": {names[i]: per_run[i]["corrections"] for i in ok},
                           **({"nonlinear": nl_corr} if nl_corr else {})},
        "nonlinear_findings": nl_findings,
        "consistency": {"parameters": cons},
        "covariance": {"parameters": [c.target for c in shared], "theta": [float(x) for x in theta],
                       "theta_covariance": cov.tolist(), "correlation": corr,
                       "theta_definition": "true parameter = (1 + theta) x model"},
        "per_run": {names[i]: {"gain": per_run[i]["gain"], "sensor_findings": per_run[i]["sensor_findings"],
                               "logger": lids[gi]}
                    for gi, g in enumerate(groups) for i in g},
        "log": list(log), "rounds": fit.rounds,
    }


def _joint_nonlinear(client, fit, specs, results, names, groups, specs_g, shared, theta, model, model_given,
                     progress, log):
    """The nonlinear causes the single runs confirmed, fitted jointly (``_nonlinear``), and the linear
    parameters chosen again on the model carrying them. Returns the joint findings, the extended
    model's nonlinear terms (empty without any) and the shared causes with their theta."""
    from ..diagnosis.vehicle import apply_causes as _apply
    from ._nonlinear import JointNonlinear, _joint_setting, fit_nonlinear, named_terms, nonlinear_findings

    flat = [i for g in groups for i in g]
    terms = named_terms([results[i] for i in flat], [names[i] for i in flat])
    if not terms:
        return [], {}, shared, theta
    jn = JointNonlinear(client, [specs[i] for i in flat], [names[i] for i in flat], model, model_given, terms,
                        progress=progress, log=log)
    # a law is first sized without the stiffness and damper rate of its axle where they may stand in
    # for it (:func:`_stand_ins`): its force is solved at the travels of the model it is sized on
    stand = _stand_ins(terms, {names[i]: results[i] for i in flat})
    keep = [j for j, c in enumerate(shared) if c.target not in stand]
    shared0, theta0 = [shared[j] for j in keep], np.asarray(theta, float)[keep]
    comb, extra = fit_nonlinear(jn, fit, shared0, theta0, _apply(model, shared0, theta0)[0])
    if extra is not None:
        fit.carry(extra)
        shared, theta, _ = fit.select()
        fit.reselect(specs_g, shared, theta)
        shared, theta, _ = fit.select(shared, theta)
        comb, extra = fit_nonlinear(jn, fit, shared, theta, _apply(model, shared, theta)[0], joint=_joint_setting(comb))
        fit.carry(extra)
    return (*nonlinear_findings(jn, comb, _apply(model, shared, theta)[0], fit.not_carried), shared, theta)


def _stand_ins(terms: list[dict], results: dict) -> set:
    """The stiffness and damper rate of each law's axle (``k3``/``d3`` or ``k4``/``d4``) that no run
    naming a law there (the term or a rival) confirms beside it. Chosen on the model without the law
    they may stand in for it (a progressive front spring read as k3 x1.105; with the law sized beside
    it and its force solved at that stand-in's travels, the parameters chosen again took m1 x1.019
    in two pitch-only runs and "m1 differs" followed); a run that names the law and still confirms
    the parameter shows a true error of it (a front spring 6.6 % stiff beside a front stop, confirmed
    in every run: without it the stop took the spring's error)."""
    out = set()
    for t in terms:
        beside = {f["parameter"] for e in [t, *t.get("rivals", [])] for r in e["runs"]
                  for f in results[r["run"]]["report"].get("findings", [])
                  if f.get("cause") == "parameter_error" and f.get("confirmed")}
        out |= {k + t["parameter"][1] for k in "kd"} - beside
    return out


def _findings(joint: dict, results) -> list[dict]:
    """The joint findings from the fit (estimate, covariance, consistency)."""
    from ..diagnosis.vehicle import PARAMETER_ERROR, Cause
    from ._joint import joint_findings

    ok = [r for r in results if r["status"] == "ok"]
    named: dict = {}
    for r in ok:
        for f in r["report"].get("findings", []):
            if f.get("cause") == PARAMETER_ERROR.name:
                named[f["parameter"]] = named.get(f["parameter"], 0) + 1
    cov = joint["covariance"]
    shared = [Cause(PARAMETER_ERROR, p) for p in cov["parameters"]]
    return joint_findings(shared, np.asarray(cov["theta"], float), np.asarray(cov["theta_covariance"], float).reshape(
        len(shared), len(shared)), len(ok), named, joint["consistency"]["parameters"])


def consistency_summary(cons):
    return {"level": CONSISTENCY_LEVEL, "method": (
        "each run's own estimate of the parameter (the run's sensor effects projected out; "
        "estimate: the other shared parameters held at the joint values, whose inverse-variance "
        "mean is the joint finding's estimate and interval, meta; own_estimate: every shared "
        "parameter the run resolves free, which the test compares) with its single-run interval "
        "(sandwich variance and the resolution floor); chi-square of the own estimates' scatter "
        "about their mean, and each run's distance from the others', each deviation shrunk by the "
        "0.5 % difference margin (a difference within it is one vehicle); family-wise: the campaign's alarms, over every parameter and every "
        "run, stay within the level (Bonferroni: each scatter test at level / (2 x parameters), "
        "each run's at that over the runs)"),
        "parameters": cons}


def _inputs_key(specs, results, model) -> str:
    h = hashlib.sha256()
    for s, r in zip(specs, results):
        h.update(json.dumps([s.path, s.logger_id, r["status"], r.get("report", {}).get("provenance", {})
                             .get("inputs", [{}])[0].get("sha256")], default=str).encode())
    h.update(json.dumps({"model": model, "version": jaxdrift_version(), "code": code_digest(),
                         "joint": JOINT_VERSION}, sort_keys=True).encode())
    return h.hexdigest()


def campaign(runs=(), *, model=None, out, manifest=None, workers: int | None = None,
             scheduler: str | None = None, durability: bool = False, paths: int = 64, seed: int = 0,
             basquin_k: float = 5.0, param_draws: int = 32, reading: dict | None = None,
             figures: bool = True, progress: bool = True, write: bool = True) -> dict:
    """Diagnose a campaign of vehicle runs jointly; returns the ``campaign.json`` dict (schema
    ``jaxdrift.campaign/1``) and writes it into ``out`` with the runs' reports, ``summary.md`` and
    the figures. ``runs``: paths (or :class:`RunSpec`); ``manifest``: a TOML manifest instead;
    ``model``: a MODEL.json path or a dict (default: the manifest's, else the seed's table);
    ``workers``/``scheduler``: the Dask cluster (default: a LocalCluster with one worker per core);
    ``durability``: also the campaign damage (``paths`` force-noise draws per run, ``param_draws``
    draws of the joint parameters). ``write=False``: compute only (the other processes of a
    campaign started under ``jax.distributed``; process 0 writes)."""
    from ..io import check_outputs, read_model
    from ._executor import dask_client
    from ._outputs import OUTPUT_FILES, write_campaign

    started = datetime.datetime.now(datetime.timezone.utc)
    t0 = time.monotonic()
    model_path = None
    if manifest is not None:
        if runs:
            raise UsageError("give the runs either on the command line or in --manifest, not both")
        specs, model_path = read_manifest(manifest)
    else:
        specs = [r if isinstance(r, RunSpec) else None for r in runs]
        if any(s is None for s in specs):
            specs = run_specs([str(r) for r in runs], **(reading or {}))
    if not specs:
        raise UsageError("no runs: give RUN files or --manifest campaign.toml")
    if isinstance(model, dict):
        model_dict, model_given, model_desc = dict(model), True, {"parameters": dict(model)}
    else:
        model_path = model if model is not None else model_path
        model_given = model_path is not None
        model_dict = read_model(model_path) if model_given else dict(DEFAULT_MODEL)
        model_desc = {"file": os.path.basename(model_path)} if model_given else {"default": "the seed's table"}
        model_desc["parameters"] = model_dict
    if paths < 0 or param_draws < 0:
        raise UsageError(f"--paths and --param-draws must be >= 0, got {paths} and {param_draws}")
    check_outputs([("--out", out, "dir", OUTPUT_FILES)], [s.path for s in specs] + [model_path, manifest])
    cache_dir = os.path.join(out, "cache")
    os.makedirs(cache_dir, exist_ok=True)
    names = _report_names(specs)
    log: list[str] = []
    with dask_client(workers=workers, scheduler=scheduler) as (client, executor):
        results = _diagnose_all(client, specs, model_dict, model_given, model_desc, cache_dir, progress, log)
        jkey = _inputs_key(specs, results, model_dict)
        jfile = os.path.join(cache_dir, f"joint-{jkey}.json")
        joint = _read_cache(jfile)
        if joint is None:
            joint = _joint(client, specs, results, names, model_dict, model_given, progress, log)
            if joint is not None:
                from ._tasks import _write_cache

                _write_cache(jfile, joint)
        if joint is not None:  # what the fit implies, from the fit (cached or new)
            params = joint["consistency"]["parameters"]
            joint["consistency"] = consistency_summary([check_consistency(e, family=len(params)) for e in params])
            lin = _findings(joint, results)
            # a parameter the stacked fit chose but the runs' own estimates do not show (their mean's
            # interval holds "no error", or it is within the single-run confirmation margin, 1 %)
            # is no finding, and there is nothing to check between runs
            from ..diagnosis.vehicle import PARAMETER_ERROR

            weak = [f["parameter"] for f in lin
                    if not f["z"] >= 1.96 or abs(f["estimate"] - 1.0) <= PARAMETER_ERROR.confirm_margin]
            if weak:
                params = [e for e in params if e["parameter"] not in weak]
                joint["consistency"] = consistency_summary([check_consistency(e, family=len(params)) for e in params])
                joint["consistency"]["not_shown"] = weak
                lin = [f for f in lin if f["parameter"] not in weak]
            joint["findings"] = joint.get("nonlinear_findings", []) + lin
        dur = None
        if durability and joint is not None:
            from ._damage import campaign_durability

            dur = campaign_durability(client, specs, results, names, joint, model_dict, model_given, cache_dir,
                                      paths=paths, seed=seed, basquin_k=basquin_k, n_draws=param_draws,
                                      progress=progress)
    doc = {
        "schema": SCHEMA,
        "joint": None if joint is None else {k: joint[k] for k in ("findings", "extended_model", "consistency",
                                                                   "covariance")},
        "runs": [_run_entry(s, n, r, joint) for s, n, r in zip(specs, names, results)],
        "durability": dur,
        "provenance": {"jaxdrift_version": jaxdrift_version(), "command": "campaign",
                       "model": model_desc, "manifest": None if manifest is None else os.path.abspath(manifest),
                       "executor": executor, "started_utc": started.isoformat(timespec="seconds"),
                       "wall_s": round(time.monotonic() - t0, 1), "cached_runs": sum(bool(r.get("cached")) for r in results),
                       "joint_rounds": None if joint is None else joint.get("rounds"),
                       "log": log if joint is None else joint.get("log", log),
                       "options": {"durability": durability, "paths": paths, "seed": seed, "basquin_k": basquin_k,
                                   "param_draws": param_draws}},
    }
    if write:
        doc = write_campaign(out, doc, results, names, figures=figures)
    return doc


def _run_entry(spec, name, res, joint) -> dict:
    e = {"run": spec.path, "name": name, "logger": spec.logger, "repetitions": spec.repetitions,
         "status": res["status"]}
    if res["status"] != "ok":
        e["message"] = res.get("message")
        return e
    e["report"] = f"runs/{name}.json"
    e["findings"] = res["report"]["findings"]
    e["gain"] = res["report"].get("gain")
    if joint is not None and name in joint["per_run"]:
        e["campaign"] = joint["per_run"][name]
    return e
