"""Analytic variances of the drift: the seed's closed forms and linearised covariance propagation.

Closed forms (all with the Brownian intensity ``sigma^2 = sigma_M^2 dt`` of (2.5): white samples of
standard deviation ``sigma_M`` at interval ``dt``):

* point mass (2.1): (2.8) for ``eta = 0``, (2.11) for ``eta > 0``, plus ``Cov(x, v)``
  (:func:`point_mass_covariance`);
* quaternion SDE (3.11)/(3.13): the Ito norm growth ``|q(t)| = exp(n sigma^2 t / 8)`` of (3.14) and
  the spurious rotation angle about each noisy axis, a Brownian motion of variance ``sigma^2 t``
  (3.16) (:func:`quaternion_norm_growth`, :func:`quaternion_angle_variance`);
* the free (rigid-body) modes of the force-driven half-car (A.3): heave and pitch are
  double-integrated noise with the generalised inertia ``M_r = R^T M R`` and noise gain
  ``G = R^T B`` (:func:`halfcar_free_modes`, :func:`halfcar_free_mode_covariance`; the derivation
  is in ``docs/variance.md``).

For any model of the engine, :func:`propagate_covariance` linearises the vector field around the
noise-free reference trajectory (``jax.jacfwd``) and integrates the reference state together with
the covariance ``P' = A(t) P + P A(t)^T + B(t) Q B(t)^T`` with :func:`jaxdrift.solve_ode`. Unlike the
closed forms it holds along any reference trajectory, as long as the deviations stay small enough
for the linearisation (see ``docs/variance.md`` for where that fails).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..solvers._solve import solve_ode

__all__ = [
    "brownian_intensity",
    "variance_interval",
    "point_mass_variance",
    "point_mass_covariance",
    "quaternion_norm_growth",
    "quaternion_norm_sq_euler",
    "quaternion_angle_variance",
    "halfcar_free_modes",
    "halfcar_free_mode_covariance",
    "CovarianceResult",
    "propagate_covariance",
]


def _nonneg(name, value):
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
    return arr


def _positive(name, value):
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return arr


def brownian_intensity(sigma_m, dt):
    """``sigma^2 = sigma_M^2 dt`` (2.5): the Brownian intensity of white samples at interval ``dt``."""
    return _nonneg("sigma_m", sigma_m) ** 2 * _positive("dt", dt)


def variance_interval(sample_var, n, level=0.95):
    """Two-sided chi-square confidence interval of a variance from ``n`` independent Gaussian paths.

    ``(n - 1) s^2 / sigma^2 ~ chi2(n - 1)``, so the interval is
    ``((n-1) s^2 / chi2.ppf(1 - alpha/2), (n-1) s^2 / chi2.ppf(alpha/2))`` with ``alpha = 1 - level``.
    ``sample_var`` is the unbiased sample variance (``ddof=1``), array-like.
    """
    from scipy.stats import chi2

    if not isinstance(n, (int, np.integer)) or n < 2:
        raise ValueError(f"n must be an int >= 2, got {n!r}")
    if not 0 < level < 1:
        raise ValueError(f"level must lie in (0, 1), got {level!r}")
    s2 = _nonneg("sample_var", sample_var)
    alpha = 1.0 - level
    k = n - 1
    return k * s2 / chi2.ppf(1 - alpha / 2, k), k * s2 / chi2.ppf(alpha / 2, k)


# --------------------------------------------------------------------------- point mass


def _x_series(eta, t, n_terms=20):
    """``sum_{k>=3} c_k eta^(k-3) t^k`` with ``c_k = (-1)^k (2 - 2^(k-1)) / k!``: the bracket of
    (2.11) divided by ``eta^3``, free of the cancellation the closed form suffers for small ``eta t``.
    """
    out = np.zeros(np.broadcast(eta, t).shape)
    fact = 2.0  # 2!
    for k in range(3, 3 + n_terms):
        fact *= k
        out = out + (-1.0) ** k * (2.0 - 2.0 ** (k - 1)) / fact * eta ** (k - 3) * t**k
    return out


def point_mass_covariance(t, *, sigma_m, dt, m=1.0, eta=0.0):
    """Covariance of ``(x, v)`` of the point mass (2.4) driven by noisy force samples.

    ``Var x``, ``Var v`` are (2.8) (``eta = 0``) and (2.11) (``eta > 0``); the cross term is
    ``Cov(x, v) = sigma^2 / (2 m^2) ((1 - exp(-eta t)) / eta)^2`` (``sigma^2 t^2 / (2 m^2)`` at
    ``eta = 0``), from the Ito isometry like (2.12)-(2.13).

    Args:
        t: times (array-like, >= 0).
        sigma_m: standard deviation of the force samples [N].
        dt: their sampling interval [s] (so ``sigma^2 = sigma_m^2 dt``).
        m: mass [kg]; eta: damping constant [1/s] (>= 0).

    Returns:
        numpy array of shape ``t.shape + (2, 2)``.
    """
    t = _nonneg("t", t)
    m = _positive("m", m)
    eta = _nonneg("eta", eta)
    s2 = brownian_intensity(sigma_m, dt) / m**2
    u = eta * t
    small = u < 0.5
    with np.errstate(divide="ignore", invalid="ignore"):
        eta_safe = np.where(eta > 0, eta, 1.0)
        # (2.11); below eta t = 0.5 its bracket is summed as a series (no cancellation).
        closed_x = (t + (-np.expm1(-2 * u)) / (2 * eta_safe) - 2 * (-np.expm1(-u)) / eta_safe) / eta_safe**2
        var_x = np.where(small, _x_series(eta, t), closed_x)
        var_v = np.where(eta > 0, -np.expm1(-2 * u) / (2 * eta_safe), t)
        g = np.where(eta > 0, -np.expm1(-u) / eta_safe, t)  # (1 - e^{-eta t}) / eta
    cov_xv = 0.5 * g**2
    out = np.stack([np.stack([var_x, cov_xv], -1), np.stack([cov_xv, var_v], -1)], -2)
    return s2[..., None, None] * out if np.ndim(s2) else s2 * out


def point_mass_variance(t, *, sigma_m, dt, m=1.0, eta=0.0):
    """``(Var x(t), Var v(t))`` of (2.8) / (2.11); see :func:`point_mass_covariance`."""
    c = point_mass_covariance(t, sigma_m=sigma_m, dt=dt, m=m, eta=eta)
    return c[..., 0, 0], c[..., 1, 1]


# --------------------------------------------------------------------------- quaternion


def quaternion_norm_growth(t, *, sigma_m, dt, n_axes: int = 1):
    """``|q(t)|`` of the Ito quaternion SDE (3.11)/(3.13): ``exp(n_axes sigma^2 t / 8)`` (3.14).

    With ``n_axes`` noisy rate channels, ``d|q|^2 = (n_axes sigma^2 / 4) |q|^2 dt`` exactly (each
    ``B_j q`` is orthogonal to ``q`` and to the others), so the growth is deterministic; it is the
    limit of the explicit Euler scheme on noisy samples (see :func:`quaternion_norm_sq_euler`).
    """
    if n_axes not in (1, 2, 3):
        raise ValueError(f"n_axes must be 1, 2 or 3, got {n_axes!r}")
    return np.exp(n_axes * brownian_intensity(sigma_m, dt) * _nonneg("t", t) / 8.0)


def quaternion_norm_sq_euler(n_steps, *, sigma_m, dt, n_axes: int = 1, omega_sq=0.0):
    """``E |q_n|^2`` after ``n_steps`` explicit Euler steps of ``q' = 0.5 Omega(omega) q``.

    Each step multiplies ``|q|^2`` by exactly ``1 + |omega|^2 dt^2 / 4``; with white samples of
    standard deviation ``sigma_m`` on ``n_axes`` channels around a true rate of squared norm
    ``omega_sq`` the mean factor is ``1 + (omega_sq + n_axes sigma_m^2) dt^2 / 4``.
    """
    _nonneg("omega_sq", omega_sq)
    factor = 1.0 + (omega_sq + n_axes * _nonneg("sigma_m", sigma_m) ** 2) * _positive("dt", dt) ** 2 / 4.0
    return factor ** np.asarray(n_steps, dtype=float)


def quaternion_angle_variance(t, *, sigma_m, dt):
    """Variance [rad^2] of the spurious rotation angle about one noisy axis: ``sigma^2 t`` (3.16).

    The angle is ``2 theta = sigma W(t)``, a Brownian motion; for small errors the same holds for
    each component of the attitude-error vector with independent noise on all three axes.
    """
    return brownian_intensity(sigma_m, dt) * _nonneg("t", t)


# --------------------------------------------------------------------------- half-car free modes


def halfcar_free_modes(params):
    """Generalised inertia and noise gain of the free (rigid-body) modes of the half-car (A.3).

    With the tyre forces ``f1, f2`` prescribed, nothing ties the body to the ground: the linear
    stiffness and damping of (A.3) (coordinates ``z = [z1, z2, z3, beta]``, small angles) vanish on
    the rigid motions ``R = [[1, -b], [1, a], [1, 0], [0, 1]]`` (columns: heave ``h``, pitch
    ``beta``; the suspension springs stay unstretched). Splitting ``z = R q + e`` with the elastic
    part mass-orthogonal to ``R`` (``R^T M e = 0``) and projecting the equations of motion with
    ``R^T`` gives exactly::

        M_r q'' = R^T M g + G [f1, f2]^T,    M_r = R^T M R,    G = R^T B = [[-1, -1], [b, -a]]

    (``B``: the tyre forces act with ``-1`` on ``z1``, ``z2``). So ``q`` is double-integrated force
    noise, whatever the suspension does.

    Returns:
        ``(M_r, G, R)`` as numpy arrays (2x2, 2x2, 4x2).
    """
    p = params
    a, b = float(p.a), float(p.b)
    R = np.array([[1.0, -b], [1.0, a], [1.0, 0.0], [0.0, 1.0]])
    M = np.diag([float(p.m1), float(p.m2), float(p.m3), float(p.I)])
    B = np.array([[-1.0, 0.0], [0.0, -1.0], [0.0, 0.0], [0.0, 0.0]])
    return R.T @ M @ R, R.T @ B, R


def halfcar_free_mode_covariance(t, params, *, sigma_m, dt):
    """Covariance of the rigid coordinates ``(h, beta)`` of the force-driven half-car under noise.

    ``Cov q(t) = M_r^-1 G S G^T M_r^-T t^3 / 3`` with ``S = diag(sigma_m^2 dt)`` (one entry per
    tyre-force channel; ``sigma_m`` a scalar or a pair). For the seed's symmetric car
    (``m1 b = m2 a``) heave and pitch decouple and
    ``Var beta = (a^2 + b^2) sigma^2 t^3 / (3 J^2)``, ``J = I + m1 b^2 + m2 a^2``;
    ``Var h = 2 sigma^2 t^3 / (3 (m1 + m2 + m3)^2)``.

    This is the leading term of ``Var z3`` and ``Var beta`` of the *linear* model (the elastic part
    adds a bounded term); along a reference trajectory with non-small pitch, or when the model is
    nonlinear in the deviation, it holds only for the first seconds (``docs/variance.md``).

    Returns:
        numpy array ``t.shape + (2, 2)`` (order: heave, pitch).
    """
    t = _nonneg("t", t)
    s2 = np.broadcast_to(brownian_intensity(sigma_m, dt), (2,))
    Mr, G, _ = halfcar_free_modes(params)
    Minv = np.linalg.inv(Mr)
    C = Minv @ G @ np.diag(s2) @ G.T @ Minv.T
    return (t**3 / 3.0)[..., None, None] * C


# --------------------------------------------------------------------------- propagation


class CovarianceResult(eqx.Module):
    """Linearised covariance along the reference trajectory at the save times.

    ``ts (n_save,)``, ``mean (n_save, n)`` (the noise-free reference), ``cov (n_save, n, n)``;
    with ``derived``: ``derived_mean (n_save, k)`` and ``derived_cov (n_save, k, k)``.
    """

    ts: jax.Array
    mean: jax.Array
    cov: jax.Array
    derived_mean: jax.Array | None
    derived_cov: jax.Array | None
    result: jax.Array

    @property
    def var(self):
        return jnp.diagonal(self.cov, axis1=-2, axis2=-1)

    @property
    def derived_var(self):
        if self.derived_cov is None:
            raise ValueError("no derived quantities were requested")
        return jnp.diagonal(self.derived_cov, axis1=-2, axis2=-1)


def propagate_covariance(
    rhs: Callable[[Any, jax.Array, jax.Array, Any], jax.Array],
    y0,
    t0,
    t1,
    *,
    saveat,
    inputs: Callable[[Any], jax.Array],
    noise_sigma,
    noise_dt,
    args: Any = None,
    P0=None,
    derived: Callable[[Any, jax.Array, Any], jax.Array] | None = None,
    dt=None,
    rtol=1e-8,
    atol=1e-10,
    cov_atol=None,
    max_steps: int = 4_000_000,
) -> CovarianceResult:
    """Covariance of a model driven by noisy inputs, linearised around its noise-free trajectory.

    The model is ``y' = rhs(t, y, u, args)`` with the measured input ``u = inputs(t) + eps``, where
    ``eps`` is white noise on each channel ``c``: samples of standard deviation ``noise_sigma[c]``
    at interval ``noise_dt[c]``, i.e. Brownian intensity ``Q_cc = noise_sigma[c]^2 noise_dt[c]``
    (2.5). With ``A = d rhs / dy`` and ``B = d rhs / du`` (``jax.jacfwd``) at the reference
    ``(t, y_ref(t), inputs(t))``, the augmented system::

        y_ref' = rhs(t, y_ref, inputs(t), args)
        P'     = A P + P A^T + B Q B^T,     P(t0) = P0 (default 0)

    is integrated by :func:`jaxdrift.solve_ode` (adaptive DOPRI5 with ``rtol``/``atol``, or fixed
    step ``dt``: use the input sampling interval, or a divisor of it, so that steps end on the
    kinks of an interpolated input). The reference is the deterministic trajectory, not the mean of
    the noisy paths; the two differ at second order in the noise.

    Args:
        rhs: ``rhs(t, y, u, args) -> y'`` (pure JAX; ``u`` is the ``(m,)`` input vector).
        y0: initial state ``(n,)``.
        inputs: ``t -> (m,)`` noise-free input (e.g. a :class:`jaxdrift.SampledSignal`).
        noise_sigma: ``(m,)`` (or scalar) standard deviations of the input samples.
        noise_dt: scalar or ``(m,)`` sampling intervals of the input channels.
        P0: initial covariance ``(n, n)``.
        derived: optional ``g(t, y, args) -> (k,)``; its covariance ``J P J^T`` (``J = dg/dy``) and
            its reference value are returned as well.
        dt: fixed step (None: adaptive).
        rtol, atol: tolerances; ``atol`` applies to the state, ``cov_atol`` to the entries of ``P``
            (default: ``rtol * 1e-6 * max|diag(B Q B^T)| * (t1 - t0)``, i.e. essentially relative
            control of ``P``, which starts at zero and grows).

    Returns:
        A :class:`CovarianceResult`.
    """
    y0 = jnp.asarray(y0)
    if y0.ndim != 1:
        raise ValueError(f"y0 must be a 1-D state vector, got shape {y0.shape}")
    n = y0.shape[0]
    dtype = y0.dtype
    u0 = jnp.asarray(inputs(t0))
    if u0.ndim != 1:
        raise ValueError(f"inputs(t) must return a 1-D vector, got shape {u0.shape}")
    m = u0.shape[0]
    if np.shape(noise_sigma) not in ((), (m,)):
        raise ValueError(f"noise_sigma must be a scalar or of shape ({m},), got shape {np.shape(noise_sigma)}")
    sig = np.broadcast_to(_nonneg("noise_sigma", noise_sigma), (m,))
    ndt = np.asarray(noise_dt, dtype=float)
    if ndt.shape not in ((), (m,)):
        raise ValueError(f"noise_dt must be a scalar or of shape ({m},), got shape {ndt.shape}")
    Q = jnp.asarray(np.diag(brownian_intensity(sig, np.broadcast_to(ndt, (m,)))), dtype)
    if P0 is None:
        P0 = jnp.zeros((n, n), dtype)
    P0 = jnp.asarray(P0, dtype)
    if P0.shape != (n, n):
        raise ValueError(f"P0 must have shape ({n}, {n}), got {P0.shape}")
    if rhs(t0, y0, u0, args).shape != (n,):
        raise ValueError(f"rhs must return shape ({n},), got {rhs(t0, y0, u0, args).shape}")

    def linearise(t, y):
        u = jnp.asarray(inputs(t), dtype)
        A = jax.jacfwd(rhs, argnums=1)(t, y, u, args)
        B = jax.jacfwd(rhs, argnums=2)(t, y, u, args)
        return rhs(t, y, u, args), A, B

    def aug(t, z, _):
        y, P = z[:n], z[n:].reshape(n, n)
        dy, A, B = linearise(t, y)
        AP = A @ P
        dP = AP + AP.T + B @ Q @ B.T
        return jnp.concatenate([dy, dP.reshape(-1)])

    z0 = jnp.concatenate([y0, P0.reshape(-1)])
    if dt is None:
        if cov_atol is None:
            _, _, B0 = linearise(jnp.asarray(t0, dtype), y0)
            qscale = float(jnp.max(jnp.abs(jnp.diagonal(B0 @ Q @ B0.T))))
            span = float(np.asarray(t1, float) - np.asarray(t0, float))
            cov_atol = max(float(rtol) * 1e-6 * qscale * span, np.finfo(np.dtype(dtype)).tiny * 1e10)
        atol_vec = jnp.concatenate(
            [jnp.broadcast_to(jnp.asarray(atol, dtype), (n,)), jnp.full((n * n,), cov_atol, dtype)]
        )
        sol = solve_ode(aug, z0, t0, t1, saveat=saveat, rtol=rtol, atol=atol_vec, max_steps=max_steps)
    else:
        sol = solve_ode(aug, z0, t0, t1, saveat=saveat, dt=dt)
    ys = sol.ys[:, :n]
    P = sol.ys[:, n:].reshape(-1, n, n)
    P = 0.5 * (P + jnp.swapaxes(P, -1, -2))
    d_mean = d_cov = None
    if derived is not None:

        def one(t, y, P):
            J = jax.jacfwd(derived, argnums=1)(t, y, args)
            return derived(t, y, args), J @ P @ J.T

        d_mean, d_cov = jax.vmap(one)(sol.ts, ys, P)
    return CovarianceResult(ts=sol.ts, mean=ys, cov=P, derived_mean=d_mean, derived_cov=d_cov, result=sol.result)
