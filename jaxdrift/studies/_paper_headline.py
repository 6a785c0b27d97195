"""The paper study's headline: drift-off times where the integration has converged.

At the paper's rtol 1e-4 a drift-off time depends on rounding (the undisturbed run drifts off
from integration error alone, and single noise samples move by seconds when the arithmetic
changes in the last bits). The headline is therefore taken at a setting where it no longer
changes with the step (``HEADLINE_SOLVER`` of ``_study.py``: fixed 1 ms Dormand-Prince at the
force sample rate), and checked three ways on the same paths and noise samples:

* **step**: the same paths at half the step (``CHECK_SOLVER``, 0.5 ms); the largest change of
  a drift-off time is reported beside the sampling spread (q90 - q10 of the noise samples);
* **rounding**: the virtual measurement and the same paths again with plain ``jnp.sin``/``jnp.cos``
  in place of the half-car's polynomials (:func:`jaxdrift.models._trig.plain_trig`);
* **sampling**: each median and quantile with a percentile-bootstrap 95 % interval over the noise
  samples (or the random models), :data:`N_BOOT` resamples from a fixed seed.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..models._trig import plain_trig
from ._paper_summary import _clean, _stats, drift_off_time

__all__ = ["N_BOOT", "bootstrap_stats", "run_headline"]

N_BOOT = 4000
LEVEL = 0.95
_QUANTILES = {"median": 0.5, "q10": 0.1, "q90": 0.9}


def bootstrap_stats(x, n_boot: int = N_BOOT, level: float = LEVEL, seed: int = 0) -> dict:
    """:func:`_stats` of ``x`` plus a percentile-bootstrap ``level`` interval for the median, q10
    and q90 (``ci_median`` etc.; ``inf`` where more than that share of resamples never drift off).

    Quantiles use ``inverted_cdf`` as in :func:`_stats`, so a resampled quantile is one of the
    samples and "never" (inf) counts as the latest time.
    """
    x = np.asarray(x, dtype=float)
    out = _stats(x)
    if x.size < 2:
        return out
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, x.size, size=(n_boot, x.size))
    res = np.sort(x[idx], axis=1)
    a = (1.0 - level) / 2.0
    for name, q in _QUANTILES.items():
        # inverted_cdf on sorted rows: the ceil(q n)-th smallest value
        k = max(int(np.ceil(q * x.size)) - 1, 0)
        col = res[:, k]
        lo, hi = np.quantile(col, [a, 1.0 - a], method="inverted_cdf")
        out[f"ci_{name}"] = [float(lo), float(hi)]
    out["bootstrap"] = dict(resamples=int(n_boot), level=level, seed=seed, method="percentile")
    return out


def _drift_offs(res, save_ts, beta_ref, thr) -> np.ndarray:
    b = np.asarray(res.ys[:, :, 1]) - beta_ref[None, :]
    return np.array([drift_off_time(save_ts, e, thr) for e in b])


def _max_change(a, b) -> dict:
    """Largest |a - b| over paths finite in both, and how many paths are finite in only one."""
    fin = np.isfinite(a) & np.isfinite(b)
    return dict(max_abs_s=float(np.max(np.abs(a[fin] - b[fin]))) if fin.any() else 0.0,
                n_finite_in_one_only=int(np.count_nonzero(np.isfinite(a) != np.isfinite(b))))


def _group_stats(d, kinds, seed) -> dict:
    out = {}
    for g in ("undisturbed", "perturbed_paper", "noisy", "perturbed_random"):
        r = np.flatnonzero(kinds == g)
        if r.size == 1:
            out[g] = float(d[r[0]])
        elif r.size:
            out[g] = bootstrap_stats(d[r], seed=seed)
    return out


def run_headline(cfg, vm, save_ts, beta_ref, kinds, run_paths: Callable, measure: Callable, solvers: tuple,
                 log: Callable, rounding_check: bool = True) -> dict:
    """Drift-off statistics at ``solvers[0]`` with the step check at ``solvers[1]`` and the rounding check.

    ``kinds``: the group of each path (undisturbed, paper-perturbed, noisy, random models), in the
    order of the main run (path ``i`` draws the noise of path ``i`` there). ``run_paths(vm,
    solver)`` runs those paths on a virtual measurement (``vm``, whose pitch at ``save_ts`` is
    ``beta_ref``); ``measure()`` makes the virtual measurement again, called under
    :func:`plain_trig` for the rounding check. Returns the
    JSON-ready ``headline`` object.
    """
    solver, check = solvers
    thr = np.radians(cfg.drift_threshold_deg)
    log(f"[headline] {len(kinds)} paths at {solver.name}, the step check at {check.name}"
        + (", the rounding check with jnp.sin/jnp.cos" if rounding_check else "") + " ...")
    d = _drift_offs(run_paths(vm, solver), save_ts, beta_ref, thr)
    d_half = _drift_offs(run_paths(vm, check), save_ts, beta_ref, thr)
    noisy = d[kinds == "noisy"]
    fin = noisy[np.isfinite(noisy)]
    spread = float(np.quantile(fin, 0.9) - np.quantile(fin, 0.1)) if fin.size > 1 else None
    out = dict(
        solver=solver.name,
        check_solver=check.name,
        drift_off_beta_s=_group_stats(d, kinds, cfg.seed),
        step_check=dict(**_max_change(d, d_half), noisy_q90_minus_q10_s=spread,
                        drift_off_beta_s=_group_stats(d_half, kinds, cfg.seed)),
        drift_off_beta_s_per_path=dict(kinds=[str(k) for k in kinds], headline=d.tolist(), half_step=d_half.tolist()),
    )
    if rounding_check:
        with plain_trig():
            vm_p = measure()
            step = int(round((save_ts[1] - save_ts[0]) * cfg.sample_rate)) if len(save_ts) > 1 else 1
            beta_p = np.asarray(vm_p.x[::step, 3])[: len(save_ts)]
            d_p = _drift_offs(run_paths(vm_p, solver), save_ts, beta_p, thr)
        out["rounding_check"] = dict(trig="jnp.sin/jnp.cos in place of the polynomials", **_max_change(d, d_p),
                                     drift_off_beta_s=_group_stats(d_p, kinds, cfg.seed))
        out["drift_off_beta_s_per_path"]["plain_trig"] = d_p.tolist()
    return _clean(out)
