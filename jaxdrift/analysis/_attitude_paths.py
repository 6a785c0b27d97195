"""Integration of the quaternion kinematics (3.8) over sampled rates and the SDE (3.11)/(3.13).

The equations live in :mod:`jaxdrift.models._quaternion`; this module drives them with the
engine (Euler / exponential map per step, our Dormand-Prince, Euler-Maruyama, stochastic Heun).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..models._quaternion import B_MATRICES, euler_step, expmap_step, omega_matrix, quat_exp, quat_multiply
from ..solvers._inputs import SampledSignal
from ..solvers._sde import solve_sde
from ..solvers._solve import solve_ode

__all__ = ["integrate_rates", "quaternion_sde_paths"]


def integrate_rates(q0, omega, dt, method: str = "expmap", renormalize: bool = False, rtol=1e-8, atol=1e-10):
    """Integrate (3.8) over sampled body rates.

    Args:
        q0: initial quaternion ``(4,)``.
        omega: ``(n, 3)`` body rates, ``omega[k]`` at ``t_k = k dt``.
        dt: sample interval.
        method: ``"expmap"`` / ``"euler"`` (rate held over each step) or ``"dopri5"`` (adaptive, on
            the linear interpolant of the rates, through :func:`jaxdrift.solve_ode`).
        renormalize: divide by ``|q|`` after every step (Euler/expmap only).

    Returns:
        ``(n, 4)`` quaternions at ``t_0 .. t_{n-1}`` (``q[0] = q0``).
    """
    q0 = jnp.asarray(q0)
    omega = jnp.asarray(omega, q0.dtype)
    if method == "dopri5":
        n = omega.shape[0]
        sig = SampledSignal(0.0, dt, omega, kind="linear")
        ts = jnp.arange(n, dtype=q0.dtype) * dt

        def f(t, q, args):
            return 0.5 * omega_matrix(args(t)) @ q

        sol = solve_ode(f, q0, 0.0, ts[-1], saveat=ts, args=sig, method="dopri5", rtol=rtol, atol=atol)
        return sol.ys
    if method not in ("euler", "expmap"):
        raise ValueError(f"method must be 'euler', 'expmap' or 'dopri5', got {method!r}")
    step = euler_step if method == "euler" else expmap_step

    def body(q, w):
        q_new = step(q, w, dt)
        if renormalize:
            q_new = q_new / jnp.linalg.norm(q_new)
        return q_new, q

    _, qs = jax.lax.scan(body, q0, omega)
    return qs


def quaternion_sde_paths(
    key,
    n_paths: int,
    t1: float,
    dt: float,
    sigma: float,
    *,
    scheme: str = "euler_maruyama",
    axes=(0, 1, 2),
    omega=None,
    q0=None,
    n_save: int = 101,
):
    """Monte-Carlo paths of the quaternion SDE (3.11) (or (3.13) with one axis, ``omega=None``).

    ``dq = 0.5 Omega_l(omega(t)) q dt + (sigma/2) sum_j B_j q dW_j`` for ``j`` in ``axes``.

    Args:
        key: PRNG key; path ``p`` uses ``fold_in(key, p)`` so paths do not depend on ``n_paths``.
        scheme: ``"euler_maruyama"`` (Ito), ``"heun"`` (stochastic Heun, Stratonovich), both through
            :func:`jaxdrift.solve_sde`; or ``"expmap"``: ``q (x) exp(omega dt + sigma dW)`` (``quat_exp`` halves the angle),
            the exponential map of each noisy increment (Stratonovich, keeps ``|q| = 1``).
        omega: optional ``(n_steps, 3)`` true body rates held over each step (``None``: no rotation).
        n_save: number of equally spaced save times in ``[0, t1]``.

    Returns:
        ``(ts, qs, W)``: ``ts (n_save,)``, ``qs (n_paths, n_save, 4)``, and the Brownian motions
        ``W (n_paths, n_save, 3)`` at the save times (zero on axes without noise), so that closed
        forms such as (3.14) can be evaluated path by path.
    """
    n_steps = int(round(t1 / dt))
    if abs(n_steps * dt - t1) > 1e-9 * max(1.0, t1):
        raise ValueError(f"t1={t1} must be a whole number of steps dt={dt}")
    if (n_steps % (n_save - 1)) != 0:
        raise ValueError(f"n_steps={n_steps} must be a multiple of n_save-1={n_save - 1}")
    axes = tuple(int(a) for a in axes)
    dtype = jnp.result_type(float)
    q0 = jnp.array([1.0, 0.0, 0.0, 0.0], dtype) if q0 is None else jnp.asarray(q0, dtype)
    om = jnp.zeros((n_steps, 3), dtype) if omega is None else jnp.asarray(omega, dtype)
    mask = jnp.zeros(3, dtype).at[jnp.array(axes)].set(1.0)
    Bm = jnp.asarray(B_MATRICES, dtype)
    ts = jnp.linspace(0.0, t1, n_save, dtype=dtype)
    stride = n_steps // (n_save - 1)

    def one(p):
        dW = jax.random.normal(jax.random.fold_in(key, p), (n_steps, 3), dtype) * jnp.sqrt(dt) * mask
        W = jnp.concatenate([jnp.zeros((1, 3), dtype), jnp.cumsum(dW, 0)[stride - 1 :: stride]], 0)
        if scheme == "expmap":

            def body(q, inp):
                w, dw = inp
                return quat_multiply(q, quat_exp(w * dt + sigma * dw)), q

            qT, qs = jax.lax.scan(body, q0, (om, dW))
            qs = jnp.concatenate([qs[::stride], qT[None]], 0)
            return qs, W

        def drift(t, q, args):
            k = jnp.clip(jnp.floor(t / dt + 1e-9).astype(jnp.int32), 0, n_steps - 1)
            return 0.5 * omega_matrix(om[k]) @ q

        def diffusion(t, q, args):
            return 0.5 * sigma * jnp.einsum("jab,b->aj", Bm, q)

        sol = solve_sde(drift, diffusion, q0, 0.0, t1, dt=dt, dW=dW, saveat=ts, scheme=scheme)
        return sol.ys, W

    if scheme not in ("euler_maruyama", "heun", "expmap"):
        raise ValueError(f"scheme must be 'euler_maruyama', 'heun' or 'expmap', got {scheme!r}")
    qs, W = jax.vmap(one)(jnp.arange(n_paths))
    return ts, qs, W
