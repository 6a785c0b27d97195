"""What a Dask worker does for a campaign: diagnose one run, compute one logger group's blocks of
the joint fit, re-select one run's sensor effects against the joint vehicle, one run's durability.

Every task is a plain function of picklable arguments (paths, dicts, :class:`Cause` lists) that
reads the run itself, so it runs the same on a ``LocalCluster`` and on remote workers. A worker
keeps the residual problems it built (per process) so that the rounds of the joint fit do not
rebuild them. Results that must survive a killed worker are written atomically by the task
itself, as soon as it finishes.
"""

from __future__ import annotations

import math
import os
import time
import traceback

import numpy as np

from ..errors import InputError, UsageError

__all__ = ["diagnose_task", "blocks_task", "reselect_task", "durability_task", "load_spec"]

#: per worker process: residual problems already built, by (run key, model)
_PROBLEMS: dict = {}


def _x64():
    import jax

    jax.config.update("jax_enable_x64", True)


def load_spec(spec, model, model_given: bool):
    from ..io import load_run

    return load_run(spec.path, "vehicle", model=model if model_given else None, **spec.reading())


def _problem(spec, model: dict, model_given: bool, extra=None):
    """The run's residual problem (cached per worker process); ``extra``: the extra spring forces
    (front, rear; fine grid) of the campaign's joint nonlinear causes its model carries."""
    from ..diagnosis.vehicle import Problem as _Problem
    from ..diagnosis.vehicle import ResidualPipeline, read_signals

    key = (spec, tuple(sorted(model.items())))
    if key not in _PROBLEMS:
        if len(_PROBLEMS) > 256:
            _PROBLEMS.clear()
        run = read_signals(load_spec(spec, model, model_given))[0]  # as the single-run diagnosis reads it
        _PROBLEMS[key] = _Problem(ResidualPipeline(run), model)
    if extra is None:
        return _PROBLEMS[key]
    import hashlib

    xkey = key + (hashlib.sha1(b"".join(np.ascontiguousarray(e, float).tobytes() for e in extra)).hexdigest(),)
    if xkey not in _PROBLEMS:
        base = _PROBLEMS[key]
        _PROBLEMS[xkey] = base.with_pipe(base.pipe.with_extra(tuple(extra)))
    return _PROBLEMS[xkey]


def _write_cache(cache_file, obj) -> None:
    if cache_file is None:
        return
    from ..io._outputs import write_json

    try:
        write_json(cache_file, obj, "cache")
    except InputError:
        pass  # a cache that cannot be written costs a recomputation, never the result


def diagnose_task(spec, *, model: dict, model_given: bool, model_desc: dict, cache_file=None) -> dict:
    """The single-run diagnosis of ``spec`` (its report, with provenance), or the reason it failed.
    A finished report is written to ``cache_file`` before the task returns."""
    _x64()
    from ..diagnosis.vehicle import diagnose_vehicle_run
    from ..io import provenance

    if cache_file is not None and os.path.isfile(cache_file):
        # Dask runs a task again when the worker holding its result died before the client took
        # it: the result this task wrote then is the answer (a finished run is never recomputed)
        import json

        try:
            with open(cache_file) as fh:
                hit = json.load(fh)
            if hit.get("status") == "ok":
                return hit
        except (OSError, ValueError):
            pass
    t0 = time.monotonic()
    try:
        run = load_spec(spec, model, model_given)
        report = diagnose_vehicle_run(run, model)
        report["provenance"] = provenance("campaign", [spec.path], model=model_desc,
                                          options={"kind": "vehicle", **spec.reading()})
        report["provenance"]["reading"] = {k: v for k, v in run.info.items() if k != "quantum"}
        out = {"status": "ok", "report": report, "warnings": list(run.warnings),
               "seconds": time.monotonic() - t0}
    except (InputError, UsageError) as e:
        return {"status": "failed", "message": str(e)}
    except Exception as e:  # noqa: BLE001 - reported per run; the campaign goes on
        tb = traceback.format_exc().strip().splitlines()
        return {"status": "failed", "message": f"internal error: {type(e).__name__}: {e} ({tb[-3].strip()})"}
    _write_cache(cache_file, out)
    return out


# ------------------------------------------------------------------------ the joint fit's blocks


def _stack_eval(probs, causes, theta, scale=None):
    scale = [1.0] * len(probs) if scale is None else scale
    return [s * p.eval(causes, theta)[0] for p, s in zip(probs, scale)]


def run_scales(probs, causes, theta) -> list[float]:
    """Per run ``1 / sigma_i``: the inverse of its force-noise level ``sigma_i^2 = RSS_i / (rows_i
    - p)`` at ``theta`` (the level its sandwich variance uses). Each run's rows are multiplied by
    it, so that the stacked estimating equations weight the runs by ``1 / sigma_i^2`` (generalised
    least squares over independent runs of unequal noise); a run without residual keeps weight 1."""
    out = []
    for p in probs:
        r = p.eval(causes, theta)[0]
        s2 = float(r @ r) / max(len(r) - len(causes), 1)
        out.append(1.0 / math.sqrt(s2) if s2 > 0 and math.isfinite(s2) else 1.0)
    return out


def _fit_nuisance(probs, causes, theta, idx_n, iters: int = 5, scale=None):
    """Gauss-Newton (instrumental, as the single-run fit) over the nuisance entries ``idx_n`` of
    ``theta``, the shared entries held: one logger's sensor effects over its runs (each run's rows
    multiplied by its ``scale``)."""
    from ..diagnosis.vehicle import clip_theta as _clip_theta
    from ..diagnosis.vehicle import projected_share as _proj

    theta = np.array(theta, dtype=float)
    if not idx_n:
        return theta
    pipe = probs[0].pipe
    scale = [1.0] * len(probs) if scale is None else scale
    r = np.concatenate(_stack_eval(probs, causes, theta, scale))
    for _ in range(iters):
        N = np.vstack([s * p.jacobian(causes, theta, which=idx_n) for p, s in zip(probs, scale)])
        step, *_ = np.linalg.lstsq(N, -r, rcond=None)
        q0 = _proj(N, r)
        lam, ok = 1.0, False
        for _ in range(6):
            th = theta.copy()
            th[idx_n] += lam * step
            th = _clip_theta(causes, th, pipe)
            r_new = np.concatenate(_stack_eval(probs, causes, th, scale))
            if _proj(N, r_new) < q0:
                ok = True
                break
            lam *= 0.5
        if not ok:
            break
        moved = np.abs(th - theta)[idx_n]
        theta, r = th, r_new
        tol = np.array([1e-3 * causes[i].fd_step(pipe.h) for i in idx_n])
        if np.all(moved < tol):
            break
    return theta


def blocks_task(group, *, model: dict, model_given: bool, shared, theta_shared, extras, nuis, theta_nuis,
                final: bool = False, extra_forces=None) -> dict:
    """One logger group's share of the joint fit at the shared parameters ``theta_shared``.

    The group's sensor effects ``nuis`` are fitted first (shared held); then, per run, the
    sensitivities of the shared causes and of the ``extras`` (candidates not yet chosen), with the
    group's nuisance directions projected out: ``Z = S - N (N^+ S)``. Returned per run: ``A = Z^T
    Z``, ``b = Z^T r``, the sandwich meat of ``Z`` (noise response per unit force-noise variance),
    the RSS and the number of rows. Each run's rows (residual and sensitivities) are multiplied by
    its :func:`run_scales` at the entry ``theta``, so all of these are the run's weighted ones and
    the sums over runs are the weighted (GLS) stack. ``final``: also the run's corrections, sensor
    findings and the gain of the campaign's extended model. ``extra_forces``: per run the extra
    spring forces of the campaign's joint nonlinear causes (``_nonlinear``), or None."""
    _x64()
    extra_forces = extra_forces or [None] * len(group)
    probs = [_problem(s, model, model_given, x) for s, x in zip(group, extra_forces)]
    shared, extras, nuis = list(shared), list(extras), list(nuis)
    causes = shared + nuis
    ns, q = len(shared), len(nuis)
    idx_n = list(range(ns, ns + q))
    theta = np.concatenate([np.asarray(theta_shared, float), np.asarray(theta_nuis, float)])
    scale = run_scales(probs, causes, theta)
    theta = _fit_nuisance(probs, causes, theta, idx_n, scale=scale)
    all_c = causes + extras
    th_all = np.concatenate([theta, np.zeros(len(extras))])
    cols_s = list(range(ns)) + list(range(ns + q, ns + q + len(extras)))
    rs, Js = [], []
    for p, sc in zip(probs, scale):
        rs.append(sc * p.eval(causes, theta)[0])
        Js.append(sc * p.jacobian(all_c, th_all) if all_c else np.zeros((len(rs[-1]), 0)))
    S = np.vstack([J[:, cols_s] for J in Js])
    N = np.vstack([J[:, idx_n] for J in Js])
    Z = S - N @ np.linalg.lstsq(N, S, rcond=None)[0] if q and S.shape[1] else S
    runs, pos = [], 0
    for p, r in zip(probs, rs):
        Zi = Z[pos:pos + len(r)]
        pos += len(r)
        runs.append({"A": Zi.T @ Zi, "b": Zi.T @ r, "M": p.sandwich_meat(Zi) if Zi.shape[1] else np.zeros((0, 0)),
                     "rss": float(r @ r), "rows": len(r)})
    out = {"theta_nuis": theta[idx_n].tolist(), "runs": runs}
    if final:
        out["final"] = _final(probs, model, causes, theta, idx_n, N, rs, ns)
    return out


def _final(probs, model, causes, theta, idx_n, N, rs, ns) -> list[dict]:
    """Per run of the group: the corrections of the campaign's extended model, the sensor
    findings with their intervals (the shared parameters held at the joint estimate) and the gain."""
    from ..diagnosis.vehicle import apply_causes as _apply, finding_for as _finding_for, practical_size as _practical
    from ..io._corrections import NO_CORRECTION
    from ..diagnosis.vehicle import residual_gain

    cov = np.zeros((len(idx_n), len(idx_n)))
    if idx_n:
        NtN = np.linalg.pinv(N.T @ N)
        meat, pos = np.zeros_like(cov), 0
        for p, r in zip(probs, rs):
            Ni = N[pos:pos + len(r)]
            pos += len(r)
            sig2 = float(r @ r) / max(len(r) - len(causes), 1)
            meat += sig2 * p.sandwich_meat(Ni)
        cov = NtN @ meat @ NtN
    p_ext, corr = _apply(model, causes, theta)
    out = []
    for p in probs:
        res0 = p.pipe.with_extra(None).residuals(model, NO_CORRECTION)  # the model as given: no nonlinear term
        res1 = p.pipe.residuals(p_ext, corr)
        dynamic = sum(p.rows.values()) > 2
        findings = []
        for j, i in enumerate(idx_n):
            f = _finding_for(causes[i], theta[i], math.sqrt(max(cov[j, j], 0.0)), _practical(causes[i], p.pipe))
            findings.append(f)
        gain = residual_gain(p, res0, res1, bool(causes), corr, dynamic)
        out.append({"corrections": corr.to_json(), "sensor_findings": findings, "gain": gain})
    return out


def reselect_task(spec, *, model: dict, model_given: bool, joint_model: dict, extra_forces=None) -> dict:
    """The run's sensor effects chosen again by the single-run selection, against the campaign's
    vehicle (the joint parameters and, ``extra_forces``, its joint nonlinear causes): the
    vehicle's errors no longer stand in for sensor effects."""
    _x64()
    from ..diagnosis.vehicle import SENSOR_KINDS, candidates as _candidates
    from ..diagnosis.vehicle import Problem as _Problem
    from ..diagnosis.vehicle import ResidualPipeline, read_signals
    from ..diagnosis.vehicle import select_causes as _select

    run = read_signals(load_spec(spec, model, model_given))[0]  # as the single-run diagnosis reads it
    pipe = ResidualPipeline(run)
    if extra_forces is not None:
        pipe = pipe.with_extra(tuple(extra_forces))
    prob = _Problem(pipe, joint_model)
    sel = _select(prob, candidates=_candidates(pipe, SENSOR_KINDS))
    return {"causes": list(sel.fit.causes), "theta": [float(x) for x in sel.fit.theta]}


# ------------------------------------------------------------------------------- durability


def durability_task(spec, *, model: dict, model_given: bool, extended: dict, noise: float, paths: int,
                    seed: int, basquin_k: float, param_draws: list, cache_file=None) -> dict:
    """One run's durability (``jaxdrift durability`` with the campaign's extended model): nominal
    damage per variant and section, the force-noise Monte-Carlo damage (``paths`` draws; 0 when
    the campaign runs the Monte Carlo itself, across processes) and the extended variant's damage
    at each draw of the joint parameters."""
    _x64()
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    from ..diagnosis.vehicle import FORCE_NOISE
    from ..durability._analysis import FORCES, _nominal, durability_analysis, section_forces
    from ..durability._damage import pseudo_damage, rainflow_cycles
    from ..durability._variants import OUTPUT_COLUMNS
    from ..models._params import HalfCarParams

    try:
        run = load_spec(spec, model, model_given)
        report = {"extended_model": extended,
                  "findings": [FORCE_NOISE.finding(noise, 0.0, noise, "estimate", "")] if noise > 0 else []}
        res = durability_analysis(run, model, paths=int(paths), basquin_k=basquin_k, seed=seed, report=report,
                                  progress=False)
        ch = run.channels
        sf = section_forces(run.t, ch["f1"], ch["f2"], model, beta=ch.get("beta"), beta_rate=ch.get("beta_rate"),
                            extended=extended)["section_forces_fn"]
        col = {c: i for i, c in enumerate(OUTPUT_COLUMNS)}
        draws = []
        for pd in param_draws:
            pk = jax.tree_util.tree_map(lambda v: jnp.asarray(v, jnp.float64), HalfCarParams.from_dict(pd))
            y, code = _nominal(eqx.tree_at(lambda s: s.params_ext, sf, pk))
            y = np.asarray(y)
            if int(code) != 0 or ch.get("beta") is None:
                draws.append([math.nan, math.nan])
                continue
            draws.append([pseudo_damage(*rainflow_cycles(y[:, col[f"extended_{f}"]]), basquin_k) for f in FORCES])
    except (InputError, UsageError) as e:
        return {"status": "failed", "message": str(e)}
    s = res.summary
    out = {"status": "ok", "summary": {k: s[k] for k in ("runs", "reference", "damage_ratio_to_stabilised",
                                                            "monte_carlo", "variants_skipped", "basquin_k")},
           "mc_damage": {v: d.tolist() for v, d in (res.mc_damage or {}).items()},
           "param_damage": draws}
    _write_cache(cache_file, out)
    return out
