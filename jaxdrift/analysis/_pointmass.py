"""Closed forms of the point mass's error variances: (2.8) for ``eta = 0``, (2.11) for ``eta > 0``,
and the exact variance of the explicit Euler recursion (2.3) they approximate."""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from ..models._params import PointMassParams

__all__ = ["pointmass_variance", "euler_variance"]


def pointmass_variance(t, sigma_m, dt, params: PointMassParams):
    """Closed-form ``(Var x(t), Var v(t))`` of the noise-driven errors: (2.8) and (2.11).

    ``sigma^2 = sigma_M^2 dt`` (2.5). For ``eta = 0``: ``Var x = sigma^2 t^3 / (3 m^2)``,
    ``Var v = sigma^2 t / m^2``. For ``eta > 0``:
    ``Var x = sigma^2/(eta^2 m^2) (t + (1 - e^{-2 eta t})/(2 eta) - 2 (1 - e^{-eta t})/eta)`` and
    ``Var v = sigma^2/(2 eta m^2) (1 - e^{-2 eta t})``. Numpy in, numpy out.
    """
    params.validate()
    t = np.asarray(t, dtype=float)
    s2 = float(sigma_m) ** 2 * float(dt)
    m, eta = float(params.m), float(params.eta)
    if eta == 0.0:
        return s2 * t**3 / (3 * m**2), s2 * t / m**2
    e1, e2 = -np.expm1(-eta * t), -np.expm1(-2 * eta * t)  # 1 - e^{-eta t}, 1 - e^{-2 eta t}
    with np.errstate(invalid="ignore", divide="ignore"):
        var_x = s2 / (eta**2 * m**2) * (t + e2 / (2 * eta) - 2 * e1 / eta)
    # for eta t << 1 the bracket cancels catastrophically: use the series of
    # int_0^t ((1 - e^{-eta u}) / eta)^2 du = t^3/3 - eta t^4/4 + 7 eta^2 t^5/60 + O(eta^3 t^6)
    series = s2 / m**2 * (t**3 / 3 - eta * t**4 / 4 + 7 * eta**2 * t**5 / 60)
    var_x = np.where(eta * t < 1e-3, series, var_x)
    var_v = s2 / (2 * eta * m**2) * e2
    return var_x, var_v


def euler_variance(t, sigma_m, dt, params: PointMassParams):
    """Exact ``(Var x, Var v)`` of the discrete Euler scheme (2.3) at grid times ``t``.

    The covariance recursion ``P_{n+1} = A P A^T + Q``, ``A = [[1, dt], [0, 1 - eta dt]]``,
    ``Q = diag(0, (sigma_M dt / m)^2)``; it tends to (2.8)/(2.11) as ``dt / t -> 0`` (the
    position variance is smaller by about ``1.5 dt / t`` without damping).
    """
    params.validate()
    t = np.atleast_1d(np.asarray(t, dtype=float))
    k = np.round(t / dt).astype(np.int64)
    if np.any(np.abs(k * dt - t) > 1e-9 * np.maximum(1.0, t)) or np.any(k < 0):
        raise ValueError("euler_variance: times must lie on the sample grid")
    m, eta = float(params.m), float(params.eta)
    a = 1.0 - eta * dt
    q = (float(sigma_m) * dt / m) ** 2
    pxx = pxv = pvv = 0.0
    out = np.zeros((k.max() + 1, 2))
    for n in range(1, k.max() + 1):
        pxx, pxv, pvv = pxx + 2 * dt * pxv + dt**2 * pvv, a * (pxv + dt * pvv), a * a * pvv + q
        out[n] = pxx, pvv
    return out[k, 0], out[k, 1]


def _check(sigma_m, dt, n_steps):
    if not (np.isfinite(sigma_m) and sigma_m >= 0):
        raise ValueError(f"sigma_M must be finite and >= 0, got {sigma_m}")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be positive, got {dt}")
    if int(n_steps) < 1:
        raise ValueError(f"n_steps must be >= 1, got {n_steps}")
