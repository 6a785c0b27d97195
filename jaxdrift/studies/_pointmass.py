"""The seed paper's section 2: a point mass driven by a noisy measured force.

Model (2.1): ``x' = v``, ``v' = f/m - eta v`` with ``x(0) = v(0) = 0``, mass ``m > 0``, damping
``eta >= 0``. The force is observed every ``dt`` with i.i.d. Gaussian errors of standard
deviation ``sigma_M`` (2.2); integrating with the explicit Euler scheme at the observation step is
(2.3), which approximates the Ito SDE (2.4) with ``sigma^2 = sigma_M^2 dt`` (2.5). The closed
forms of the error variances are (2.8) (``eta = 0``) and (2.11) (``eta > 0``):
:func:`pointmass_variance`.

The simulation runs on the engine: :func:`jaxdrift.solve_ode` with ``method="euler"`` and a fixed
step equal to the sample period, the noisy force as a zero-order-hold
:class:`~jaxdrift.SampledSignal` (so sample ``n`` is used on ``[n dt, (n+1) dt)``: exactly (2.3)),
and :func:`jaxdrift.monte_carlo` over noise samples.
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..solvers._inputs import SampledSignal
from ..ensemble._montecarlo import monte_carlo
from ..ensemble._noise import path_normals
from ..models._params import PointMassParams
from ..solvers._solve import solve_ode
from ..models._pointmass import pointmass_rhs
from ..analysis._pointmass import _check, euler_variance, pointmass_variance

__all__ = [
    "pointmass_rhs",
    "pointmass_variance",
    "pointmass_path",
    "pointmass_monte_carlo",
    "pointmass_save_times",
    "chi2_interval",
    "euler_variance",
    "slope_loglog",
    "run_pointmass_study",
    "plot_pointmass",
]


def pointmass_path(params: PointMassParams, force, dt: float, save_ts):
    """Euler scheme (2.3) on the engine for one sampled force ``force`` (``(n_samples,)``).

    Returns ``(ys, result)`` with ``ys`` of shape ``(len(save_ts), 2)`` (``[x, v]``); ``save_ts``
    should lie on the sample grid (between grid points the engine's Euler output is the linear
    interpolant). Pure JAX: jit/vmap safe.
    """
    force = jnp.asarray(force)
    n = force.shape[0]
    sig = SampledSignal(0.0, dt, force, kind="zoh")

    def f(t, y, args):
        p, s = args
        return pointmass_rhs(t, y, p, s(t)[0])

    y0 = jnp.zeros(2, dtype=force.dtype)
    sol = solve_ode(f, y0, 0.0, n * dt, saveat=jnp.asarray(save_ts), args=(params, sig), method="euler", dt=dt)
    return sol.ys, sol.result


class _PointMassPath(eqx.Module):
    force: jax.Array  # (n,) true force samples
    sigma_m: jax.Array
    save_ts: jax.Array
    params: PointMassParams
    dt: float = eqx.field(static=True)
    error_only: bool = eqx.field(static=True, default=True)

    def __call__(self, key, idx, model):
        p = self.params if model is None else model
        n = self.force.shape[0]
        eps = self.sigma_m * path_normals(key, idx, n, 1, dtype=self.force.dtype)[:, 0]
        ys, res = pointmass_path(p, self.force + eps, self.dt, self.save_ts)
        if self.error_only:  # subtract the noise-free solution: the output is the error itself
            ys0, _ = pointmass_path(p, self.force, self.dt, self.save_ts)
            ys = ys - ys0
        return ys, res


def pointmass_save_times(duration: float, dt: float, n: int = 40):
    """About ``n`` log-spaced save times on the sample grid in ``[10 dt, duration]``."""
    k = np.unique(np.round(np.geomspace(10, round(duration / dt), n)).astype(np.int64))
    return k * dt


def pointmass_monte_carlo(
    params: PointMassParams,
    sigma_m: float,
    dt: float,
    n_steps: int,
    n_paths: int,
    *,
    seed: int = 0,
    save_ts=None,
    force=None,
    progress: bool = False,
    chunk_size: int | None = None,
):
    """Monte-Carlo of the Euler scheme (2.3) with noisy forces; returns the engine's ``MCResult``.

    Outputs per path are the errors ``[x - x_true, v - v_true]`` at ``save_ts`` (default:
    :func:`pointmass_save_times`), where the true solution uses the noise-free ``force``
    (``(n_steps,)`` samples, default zero force). Their ensemble variance is compared with
    :func:`pointmass_variance`.
    """
    params.validate()
    _check(sigma_m, dt, n_steps)
    duration = n_steps * dt
    if save_ts is None:
        save_ts = pointmass_save_times(duration, dt)
    save_ts = np.asarray(save_ts, dtype=float)
    force = np.zeros(n_steps) if force is None else np.asarray(force, dtype=float)
    if force.shape != (n_steps,):
        raise ValueError(f"force must have shape ({n_steps},) (one sample per step), got {force.shape}")
    fn = _PointMassPath(force=jnp.asarray(force), sigma_m=jnp.asarray(float(sigma_m)), save_ts=jnp.asarray(save_ts),
                        params=params, dt=float(dt), error_only=True)
    return monte_carlo(fn, n_paths, key=jax.random.key(seed), save_ts=save_ts, progress=progress,
                       chunk_size=chunk_size or min(n_paths, 1024))


def chi2_interval(n: int, level: float = 0.99):
    """Two-sided ``level`` interval for ``s^2 / sigma^2`` of ``n`` Gaussian samples (ddof = 1)."""
    from scipy.stats import chi2

    a = (1 - level) / 2
    return chi2.ppf(a, n - 1) / (n - 1), chi2.ppf(1 - a, n - 1) / (n - 1)


def slope_loglog(t, std) -> float:
    """Least-squares slope of ``log std`` against ``log t``."""
    t, std = np.asarray(t, float), np.asarray(std, float)
    return float(np.polyfit(np.log(t), np.log(std), 1)[0])


def run_pointmass_study(
    sigma_m: float = 1.0,
    dt: float = 0.01,
    duration: float = 100.0,
    n_paths: int = 2000,
    etas=(0.0, 0.5),
    mass: float = 1.0,
    seed: int = 0,
    progress: bool = True,
) -> dict:
    """Section 2 study: empirical Std of x and v against (2.8)/(2.11) for each damping.

    Returns a dict per ``eta`` with save times, empirical and closed-form standard deviations,
    the variance ratios against (2.8)/(2.11) (``fraction_inside_chi2_99``: the share of ratios at
    ``t >= 200 dt`` inside the 99 % chi-square interval) and against the exact variance of the
    discrete scheme (:func:`euler_variance`, all times), and log-log slopes.
    """
    n_steps = int(round(duration / dt))
    lo, hi = chi2_interval(n_paths)
    out = dict(sigma_m=sigma_m, dt=dt, duration=duration, n_paths=n_paths, mass=mass, sigma=math.sqrt(sigma_m**2 * dt),
               chi2_99_interval=[lo, hi], cases=[])
    for eta in etas:
        p = PointMassParams(m=mass, eta=float(eta)).validate()
        res = pointmass_monte_carlo(p, sigma_m, dt, n_steps, n_paths, seed=seed, progress=progress)
        ts = res.save_ts
        vx, vv = pointmass_variance(ts, sigma_m, dt, p)
        ex, ev = euler_variance(ts, sigma_m, dt, p)
        rx, rv = res.var[:, 0] / vx, res.var[:, 1] / vv
        rxe, rve = res.var[:, 0] / ex, res.var[:, 1] / ev
        late = ts >= ts[-1] / 10
        early = ts <= ts[-1] / 10
        resolved = ts >= 200 * dt  # the O(dt/t) discretisation bias of (2.3) is < 1 % there

        def inside(*rs):
            r = np.concatenate(rs)
            return float(np.mean((r >= lo) & (r <= hi)))

        out["cases"].append(dict(
            eta=float(eta), t=ts.tolist(),
            std_x=np.sqrt(res.var[:, 0]).tolist(), std_v=np.sqrt(res.var[:, 1]).tolist(),
            std_x_closed=np.sqrt(vx).tolist(), std_v_closed=np.sqrt(vv).tolist(),
            var_ratio_x=rx.tolist(), var_ratio_v=rv.tolist(),
            var_ratio_x_euler=rxe.tolist(), var_ratio_v_euler=rve.tolist(),
            fraction_inside_chi2_99=inside(rx[resolved], rv[resolved]),
            fraction_inside_chi2_99_euler_all_times=inside(rxe, rve),
            slope_std_x_early=slope_loglog(ts[early], np.sqrt(res.var[early, 0])),
            slope_std_v_early=slope_loglog(ts[early], np.sqrt(res.var[early, 1])),
            slope_std_x_late=slope_loglog(ts[late], np.sqrt(res.var[late, 0])),
            slope_std_v_late=slope_loglog(ts[late], np.sqrt(res.var[late, 1])),
            failed_paths=int(res.n_failed),
        ))
    return out


def plot_pointmass(study: dict, path: str, dpi: int = 90) -> None:
    """Log-log figure of empirical and closed-form Std of x and v, with t^1/2 and t^3/2 guides."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = study["cases"]
    fig, axes = plt.subplots(1, len(cases), figsize=(5.5 * len(cases), 4.2), squeeze=False)
    for ax, c in zip(axes[0], cases):
        t = np.asarray(c["t"])
        ax.loglog(t, c["std_x"], "o", ms=3, color="C0", label="Std x (Monte-Carlo)")
        ax.loglog(t, c["std_x_closed"], "-", color="C0", label="Std x closed form")
        ax.loglog(t, c["std_v"], "s", ms=3, color="C3", label="Std v (Monte-Carlo)")
        ax.loglog(t, c["std_v_closed"], "-", color="C3", label="Std v closed form")
        x0, v0 = c["std_x_closed"][0], c["std_v_closed"][0]
        ax.loglog(t, x0 * (t / t[0]) ** 1.5, ":", color="gray", label=r"$t^{3/2}$, $t^{1/2}$ slopes")
        ax.loglog(t, v0 * (t / t[0]) ** 0.5, ":", color="gray")
        eq = "(2.8)" if c["eta"] == 0 else "(2.11)"
        ax.set_title(rf"$\eta$ = {c['eta']:g}: closed form {eq}, {study['n_paths']} paths")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("standard deviation of the error")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
