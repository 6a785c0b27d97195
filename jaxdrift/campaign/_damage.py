"""Campaign durability: each run's section-force damage (``jaxdrift durability`` with the campaign's
extended model) times its repetitions in the test schedule, summed over the runs, with
Monte-Carlo error bars from the force noise and from the joint parameter intervals.

The force-noise draws of different runs are independent, so draw ``j`` of the campaign is the
repetition-weighted sum of draw ``j`` of every run. The joint parameters are one vehicle's: each
parameter draw is used in every run at once (the runs' damages move together). Under
``jax.distributed`` (several processes, ``docs/campaign.md``) the force-noise Monte Carlo runs in
the campaign's own processes, its paths spread over all of their devices.
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from ..diagnosis.vehicle import FORCE_NOISE
from ..durability._analysis import FORCES, QUANTILES
from ._manifest import cache_key

__all__ = ["campaign_durability", "param_draws"]


def param_draws(joint: dict, model: dict, n: int, seed: int) -> list[dict]:
    """``n`` vehicles drawn from the joint fit's normal approximation (theta and its covariance)."""
    cov = joint["covariance"]
    keys = cov["parameters"]
    if not keys or n <= 0:
        return []
    rng = np.random.default_rng(seed)
    th = rng.multivariate_normal(np.asarray(cov["theta"]), np.asarray(cov["theta_covariance"]), size=n,
                                 method="eigh")
    base = joint["extended_model"]["parameters"]
    out = []
    for row in th:
        p = dict(base)
        for k, t in zip(keys, row):
            p[k] = float(model[k] * (1.0 + t))
        out.append(p)
    return out


def _noise_of(report: dict) -> float:
    level = FORCE_NOISE.level_in(report.get("findings"))
    return 0.0 if level is None else level


def _distributed_jax() -> bool:
    import jax

    return jax.process_count() > 1


def _client_mc(spec, model, model_given, extended, noise, paths, seed, basquin_k):
    """The force-noise Monte Carlo of one run in this process (across all processes' devices)."""
    from ..durability._analysis import monte_carlo_damage, section_forces
    from ..durability._variants import SIMULATED
    from ._tasks import _x64, load_spec

    _x64()
    run = load_spec(spec, model, model_given)
    ch = run.channels
    nom = section_forces(run.t, ch["f1"], ch["f2"], model, beta=ch.get("beta"), beta_rate=ch.get("beta_rate"),
                         s1=ch.get("s1"), s2=ch.get("s2"), extended=extended)
    variants = [v for v in SIMULATED if v in nom["forces"]]
    d = monte_carlo_damage(nom["section_forces_fn"], noise, paths, variants=variants, basquin_k=basquin_k,
                           seed=seed, progress=False)
    return {v: d[:, i, :].tolist() for i, v in enumerate(variants)}


def _q(x):
    x = np.asarray(x, float)
    x = x[np.isfinite(x)]
    return [float(v) for v in np.quantile(x, QUANTILES)] if x.size else None


def _run_extended(joint: dict, name: str) -> dict:
    """One run's extended model from the campaign's: the joint parameters, the run's logger's
    corrections and the joint nonlinear laws where there are any."""
    em = joint["extended_model"]
    return {"parameters": em["parameters"], "corrections": em["runs"][name],
            **({"nonlinear": em["nonlinear"]} if em.get("nonlinear") else {})}


def campaign_durability(client, specs, results, names, joint, model, model_given, cache_dir, *, paths, seed,
                        basquin_k, n_draws, progress=True) -> dict:
    from ._executor import map_tasks
    from ._tasks import durability_task

    ok = [i for i, r in enumerate(results) if r["status"] == "ok"]
    draws = param_draws(joint, model, n_draws, seed + 1)
    on_client = paths > 0 and _distributed_jax()
    items, outs = [], {}
    for i in ok:
        ext = _run_extended(joint, names[i])
        noise = _noise_of(results[i]["report"])
        opts = {"extended": ext, "noise": noise, "paths": 0 if on_client else paths, "seed": seed,
                "basquin_k": basquin_k, "draws": draws}
        f = os.path.join(cache_dir, f"durability-{cache_key(specs[i], model, opts, 'durability')}.json")
        try:
            with open(f) as fh:
                outs[i] = json.load(fh)
            continue
        except (OSError, ValueError):
            items.append((i, f, ext, noise))
    res = map_tasks(client, _dur_call, [(specs[i], f, ext, noise) for i, f, ext, noise in items],
                    desc="durability of runs", progress=progress, record_failures=True, model=model,
                    model_given=model_given, paths=0 if on_client else paths, seed=seed, basquin_k=basquin_k,
                    param_draws=draws)
    for (i, *_), r in zip(items, res):
        outs[i] = r
    if on_client:
        for i in ok:
            if outs[i].get("status") == "ok" and not outs[i]["mc_damage"]:
                ext = _run_extended(joint, names[i])
                outs[i]["mc_damage"] = _client_mc(specs[i], model, model_given, ext, _noise_of(results[i]["report"]),
                                                  paths, seed, basquin_k)
    return _combine(specs, names, ok, outs, paths, len(draws), basquin_k, on_client)


def _dur_call(item, **kw):
    from ._tasks import durability_task

    spec, f, ext, noise = item
    return durability_task(spec, extended=ext, noise=noise, cache_file=f, **kw)


def _combine(specs, names, ok, outs, paths, n_draws, basquin_k, on_client) -> dict:
    """Per run and section damage x repetitions, the campaign sums and their error bars."""
    per_run, failed = [], []
    total: dict = {}
    mc_tot: dict = {}
    par_tot = np.zeros((n_draws, 2))
    par_ok = n_draws > 0
    for i in ok:
        o = outs[i]
        if o.get("status") != "ok":
            failed.append({"run": names[i], "message": o.get("message")})
            continue
        rep = specs[i].repetitions
        s = o["summary"]
        dmg = {v: [s["runs"][v].get(f, {}).get("damage", math.nan) for f in FORCES] for v in s["runs"]}
        per_run.append({"run": names[i], "repetitions": rep, "damage": dmg,
                        "damage_x_repetitions": {v: [rep * x for x in d] for v, d in dmg.items()}})
        for v, d in dmg.items():
            total.setdefault(v, np.zeros(2))
            total[v] = total[v] + rep * np.nan_to_num(np.asarray(d, float))
        for v, d in (o.get("mc_damage") or {}).items():
            d = np.asarray(d, float)
            mc_tot[v] = mc_tot.get(v, 0.0) + rep * d
        pd = np.asarray(o.get("param_damage") or [], float)
        if pd.size and np.all(np.isfinite(pd)):
            par_tot = par_tot + rep * pd
    ref = "stabilised" if "stabilised" in total else None
    out = {
        "basquin_k": basquin_k,
        "damage_definition": "sum over runs of repetitions x sum n_i S_i^K (rainflow, ASTM E1049-85), S in N",
        "sections": list(FORCES),
        "per_run": per_run,
        "failed": failed,
        "campaign_damage": {v: d.tolist() for v, d in total.items()},
        "reference": ref,
        "damage_ratio_to_stabilised": ({v: float(d.sum() / total[ref].sum()) for v, d in total.items() if v != ref}
                                       if ref and total[ref].sum() > 0 else {}),
        "quantile_levels": list(QUANTILES),
        FORCE_NOISE.name: {"paths": paths, "computed_in": "campaign processes (jax.distributed)" if on_client
                        else "dask workers (one run per task)",
                        "damage_quantiles": {v: [_q(d[:, j]) for j in range(2)] for v, d in mc_tot.items()}},
        "joint_parameters": {"draws": n_draws, "variant": "extended",
                             "damage_quantiles": [_q(par_tot[:, j]) for j in range(2)] if par_ok else None},
    }
    if ref in mc_tot:
        r = mc_tot[ref].sum(axis=1)
        out[FORCE_NOISE.name]["damage_ratio_quantiles"] = {v: _q(d.sum(axis=1) / r) for v, d in mc_tot.items() if v != ref}
    if par_ok and ref and total[ref].sum() > 0:
        out["joint_parameters"]["extended_ratio_quantiles"] = _q(par_tot.sum(axis=1) / total[ref].sum())
    return out
