"""The JSON summary of the paper study: drift-off times, their statistics, the enforced moment, the
pitch-spring remedy and the solver comparison (see docs/paper-study.md for the fields).

Non-finite floats are written as ``"inf"``/``"-inf"``/``null`` so that the file is strict JSON.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np

__all__ = ["drift_off_time", "solver_agreement"]


def drift_off_time(ts, error, threshold) -> float:
    """First time in ``ts`` where ``|error| > threshold`` (or is not finite); ``inf`` if never."""
    ts, error = np.asarray(ts), np.asarray(error)
    bad = ~(np.abs(error) <= threshold)
    return float(ts[np.argmax(bad)]) if bad.any() else math.inf


def _stats(x) -> dict:
    x = np.asarray(x, dtype=float)
    fin = x[np.isfinite(x)]
    out = dict(n=int(x.size), n_never=int(np.count_nonzero(~np.isfinite(x))))
    if fin.size:
        # quantiles without interpolation, so "never" (inf) paths count as the latest times
        def q(level):
            return float(np.quantile(x, level, method="inverted_cdf"))

        out.update(min=float(fin.min()), median=q(0.5), max=float(fin.max()), q10=q(0.1), q90=q(0.9))
    else:
        out.update(min=None, median=None, max=None, q10=None, q90=None)
    return out


def solver_agreement(table: list[dict], reference: str = "dopri5 fixed 1 ms") -> list[dict]:
    """Each solver of the comparison against ``reference`` (when present), sample by sample: the
    largest |difference| of the noisy drift-off times (paths that never drift off in one of the
    two count as infinitely far), how many agree within 0.05 s, and the difference of the
    undisturbed and the paper-perturbed drift-off times."""
    ref = next((r for r in table if r["solver"] == reference), None)
    if ref is None:
        return []
    out = []

    def diff(a, b):
        a, b = float(a), float(b)
        return 0.0 if a == b else abs(a - b)  # equal infinities agree

    for r in table:
        if r is ref:
            continue
        d = [diff(a, b) for a, b in zip(r["noisy_drift_off_s"], ref["noisy_drift_off_s"])]
        out.append(dict(solver=r["solver"], reference=reference, n=len(d), noisy_max_abs_s=max(d),
                        noisy_n_within_0_05_s=int(sum(x <= 0.05 for x in d)),
                        undisturbed_abs_s=diff(r["undisturbed_drift_off_s"], ref["undisturbed_drift_off_s"]),
                        perturbed_paper_abs_s=diff(r["perturbed_paper_drift_off_s"], ref["perturbed_paper_drift_off_s"])))
    return out


def _json_float(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None if math.isnan(v) else ("inf" if v > 0 else "-inf")
    return v


def _range(x) -> dict:
    x = np.asarray(x, dtype=float)
    return dict(min=float(x.min()), max=float(x.max()), abs_max=float(np.abs(x).max()),
                rms=float(np.sqrt(np.mean(x**2))))


def _summarise(cfg, vm, save_ts, beta_ref, z3_ref, sigma, fmax, main, kinds, stab, st_kinds, comparisons, n_cmp, road):
    thr = math.radians(cfg.drift_threshold_deg)
    beta = main.ys[:, :, 1]
    z3 = main.ys[:, :, 0]
    eb = beta - beta_ref[None, :]
    ez = z3 - z3_ref[None, :]

    def doff(rows, threshold=thr, err=eb):
        return np.array([drift_off_time(save_ts, err[r], threshold) for r in rows])

    def rows(kind):
        return np.flatnonzero(kinds == kind)

    groups = ("undisturbed", "perturbed_paper", "noisy", "perturbed_random")
    drift = {}
    for g in groups:
        d = doff(rows(g))
        drift[g] = float(d[0]) if d.size == 1 else _stats(d)
    by_thr = {}
    for t_deg in (0.5, 1.0, 2.0, 5.0):
        by_thr[f"{t_deg:g}"] = {
            g: (float(doff(rows(g), math.radians(t_deg))[0]) if rows(g).size == 1
                else _stats(doff(rows(g), math.radians(t_deg))))
            for g in groups
        }
    z3_drift = {}
    for g in groups:
        d = doff(rows(g), cfg.z3_threshold, ez)
        z3_drift[g] = float(d[0]) if d.size == 1 else _stats(d)
    end_err = {
        g: dict(beta_deg_rms=float(np.degrees(np.sqrt(np.mean(eb[rows(g), -1] ** 2)))),
                z3_m_rms=float(np.sqrt(np.mean(ez[rows(g), -1] ** 2))))
        for g in groups
    }

    # stabilised: enforced moment and inertia term
    lam = stab.ys[:, :, 1]
    inertia = stab.ys[:, :, 2]
    moment = {k: _range(lam[st_kinds == k]) for k in dict.fromkeys(st_kinds)}
    moment["inertia_term"] = _range(inertia[0])

    # pitch spring (the first row, stiffness 0, is the free model on the same noise samples)
    spring = []
    n_sp = int(np.count_nonzero(kinds == f"spring_{cfg.pitch_spring_stiffness[0]:g}")) if cfg.pitch_spring_stiffness else 0
    if n_sp:
        r = rows("noisy")[:n_sp]
        e = eb[r]
        spring.append(dict(
            stiffness=0.0, damping=0.0,
            pitch_error_rms_deg=float(np.degrees(np.sqrt(np.mean(e**2)))),
            pitch_error_max_deg=float(np.degrees(np.max(np.abs(e)))),
            drift_off_s=_stats(doff(r)), reaction_torque_max=0.0, reaction_torque_rms=0.0,
        ))
    for k in cfg.pitch_spring_stiffness:
        r = rows(f"spring_{k:g}")
        e = eb[r]
        tq = main.ys[r, :, 2]
        spring.append(dict(
            stiffness=float(k), damping=float(2 * math.sqrt(k * float(cfg.params.pitch_inertia_whole))),
            pitch_error_rms_deg=float(np.degrees(np.sqrt(np.mean(e**2)))),
            pitch_error_max_deg=float(np.degrees(np.max(np.abs(e)))),
            drift_off_s=_stats(doff(r)),
            reaction_torque_max=float(np.max(np.abs(tq))),
            reaction_torque_rms=float(np.sqrt(np.mean(tq**2))),
        ))

    # solver comparison: path 0 undisturbed, 1 paper-perturbed, then the first n_cmp noise samples
    noisy_rows = rows("noisy")[:n_cmp]
    table = []
    for name, res in comparisons.items():
        b = res.ys[:, :, 1] - beta_ref[None, :]
        if res is main:
            und, per, noisy = b[rows("undisturbed")[0]], b[rows("perturbed_paper")[0]], b[noisy_rows]
        else:
            und, per, noisy = b[0], b[1], b[2:2 + n_cmp]
        table.append(dict(
            solver=name,
            undisturbed_drift_off_s=drift_off_time(save_ts, und, thr),
            undisturbed_pitch_error_end_deg=float(np.degrees(abs(und[-1]))),
            perturbed_paper_drift_off_s=drift_off_time(save_ts, per, thr),
            noisy_drift_off_s=[drift_off_time(save_ts, e, thr) for e in noisy],
            noisy_pitch_error_end_deg=[float(np.degrees(abs(e[-1]))) for e in noisy],
            failed_paths=int(res.n_failed),
        ))

    zeta = np.asarray(vm.zeta)
    summary = dict(
        config=dict(
            duration_s=cfg.duration, speed_m_s=cfg.speed, road_class=cfg.road_class, road_seed=cfg.road_seed,
            hill_height_m=cfg.hill_height, hill_wavelength_m=cfg.hill_wavelength, sample_rate_hz=cfg.sample_rate,
            noise_rel=cfg.noise_rel, n_noise=cfg.n_noise, n_models=cfg.n_models, n_compare=n_cmp, seed=cfg.seed,
            solver=dataclasses.asdict(cfg.solver), params=cfg.params.to_dict(),
            drift_threshold_deg=cfg.drift_threshold_deg, z3_threshold_m=cfg.z3_threshold, linear=cfg.linear,
        ),
        measurement=dict(
            force_min_N=float(jnp.min(vm.forces)), force_max_N=float(jnp.max(vm.forces)), f_max_N=fmax,
            sigma_N=sigma, zeta_min_m=float(zeta.min()), zeta_max_m=float(zeta.max()),
            beta_range_deg=[float(np.degrees(vm.x[:, 3].min())), float(np.degrees(vm.x[:, 3].max()))],
        ),
        drift_definition=(
            f"drift-off time = first save time where |beta_sim - beta_measured| > {cfg.drift_threshold_deg} deg "
            f"(z3: |z3_sim - z3_measured| > {cfg.z3_threshold} m); 'inf' = never within the run"
        ),
        drift_off_beta_s=drift,
        drift_off_beta_s_by_threshold_deg=by_thr,
        drift_off_z3_s=z3_drift,
        error_at_end=end_err,
        enforced_moment_Nm=moment,
        pitch_spring=spring,
        solver_comparison=table,
        solver_agreement=solver_agreement(table),
        failed_paths=dict(force=int(main.n_failed), stabilised=int(stab.n_failed)),
    )
    return _clean(summary)


def _clean(obj):
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        obj = obj.item()
    if isinstance(obj, float):
        return _json_float(obj)
    return obj
