"""Point mass of the seed's section 2: Euler scheme (2.3) on the engine, Monte-Carlo variance
against the closed forms (2.8) and (2.11) within 99 % chi-square intervals."""

from __future__ import annotations

import numpy as np
import pytest

from jaxdrift.models._params import PointMassParams
from jaxdrift.studies._pointmass import (
    chi2_interval,
    euler_variance,
    pointmass_monte_carlo,
    pointmass_path,
    pointmass_variance,
    slope_loglog,
)


def _euler_covariance(n_steps, dt, sigma_m, m, eta):
    """Independent oracle: exact covariance of the discrete Euler recursion (2.3),
    P_{n+1} = A P A^T + Q with A = [[1, dt], [0, 1 - eta dt]], Q = diag(0, (sigma_M dt / m)^2)."""
    A = np.array([[1.0, dt], [0.0, 1.0 - eta * dt]])
    Q = np.diag([0.0, (sigma_m * dt / m) ** 2])
    P = np.zeros((2, 2))
    out = [P]
    for _ in range(n_steps):
        P = A @ P @ A.T + Q
        out.append(P)
    return np.array(out)


@pytest.mark.parametrize("eta", [0.0, 0.3, 2.0])
def test_closed_forms_are_the_limit_of_the_euler_recursion(eta):
    """(2.8)/(2.11) = the Euler scheme's exact variance as dt -> 0 (error O(dt/t))."""
    p = PointMassParams(m=2.0, eta=eta)
    T = 4.0
    errs = []
    for dt in (0.01, 0.001):
        n = int(round(T / dt))
        P = _euler_covariance(n, dt, 3.0, p.m, eta)
        vx, vv = pointmass_variance(T, 3.0, dt, p)
        errs.append((abs(P[-1, 0, 0] / vx - 1), abs(P[-1, 1, 1] / vv - 1)))
    assert errs[1][0] < 2e-3 and errs[1][1] < 2e-3
    assert errs[1][0] < errs[0][0] / 5  # first order in dt
    if eta == 0.0:
        assert errs[1][1] < 1e-12  # Var v is exact on the grid without damping


@pytest.mark.parametrize("eta", [0.0, 0.9])
def test_euler_variance_is_the_recursion(eta):
    p = PointMassParams(m=1.3, eta=eta)
    P = _euler_covariance(700, 0.01, 2.0, p.m, eta)
    vx, vv = euler_variance([0.0, 0.05, 7.0], 2.0, 0.01, p)
    np.testing.assert_allclose(vx, P[[0, 5, 700], 0, 0], rtol=1e-12)
    np.testing.assert_allclose(vv, P[[0, 5, 700], 1, 1], rtol=1e-12)
    with pytest.raises(ValueError, match="grid"):
        euler_variance([0.005], 2.0, 0.01, p)


def test_damped_limits():
    p = PointMassParams(m=1.5, eta=0.7)
    t = np.array([1e3])
    vx, vv = pointmass_variance(t, 2.0, 0.01, p)
    s2 = 4.0 * 0.01
    assert vv[0] == pytest.approx(s2 / (2 * p.eta * p.m**2))  # OU stationary variance
    assert vx[0] / t[0] == pytest.approx(s2 / (p.eta**2 * p.m**2), rel=5e-3)  # Var x ~ t
    # tiny damping -> (2.8), and the small-eta series joins the closed form continuously
    t = np.array([0.5, 2.0])
    a = pointmass_variance(t, 2.0, 0.01, PointMassParams(m=1.5, eta=1e-9))
    b = pointmass_variance(t, 2.0, 0.01, PointMassParams(m=1.5, eta=0.0))
    np.testing.assert_allclose(a, b, rtol=1e-8)
    tt = np.array([1e-3 / 0.2 * (1 - 1e-9), 1e-3 / 0.2 * (1 + 1e-9)])  # both sides of eta t = 1e-3
    vx, _ = pointmass_variance(tt, 2.0, 0.01, PointMassParams(m=1.5, eta=0.2))
    assert vx[1] / vx[0] == pytest.approx(1.0, abs=1e-6)


def test_noise_free_path_is_the_euler_recursion():
    """Constant force, no noise: v_n = n dt f/m, x_n = dt^2 f/m n (n-1)/2 (explicit Euler)."""
    import jax.numpy as jnp

    p = PointMassParams(m=2.0, eta=0.0)
    dt, n, f = 0.01, 300, 3.0
    ts = np.array([0.0, 50 * dt, 300 * dt])
    ys, res = pointmass_path(p, jnp.full(n, f), dt, ts)
    k = np.round(ts / dt)
    np.testing.assert_allclose(np.asarray(ys[:, 1]), k * dt * f / p.m, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.asarray(ys[:, 0]), dt**2 * f / p.m * k * (k - 1) / 2, rtol=1e-12, atol=1e-15)
    assert int(res) == 0


@pytest.mark.parametrize("eta", [0.0, 0.8])
def test_monte_carlo_variance_within_chi2_99(eta):
    """N = 2000 paths; at t = 2, 5, 10 s (>= 200 steps, so the O(dt/t) discretisation bias is
    < 1 %, far inside the +-8 % interval) the ratio of the empirical variance to (2.8)/(2.11) lies
    in the two-sided 99 % chi-square interval, for x and v."""
    p = PointMassParams(m=2.0, eta=eta)
    dt, sigma_m, n = 0.01, 3.0, 1000
    save_ts = np.array([0.5, 1.0, 2.0, 5.0, 10.0])
    res = pointmass_monte_carlo(p, sigma_m, dt, n, 2000, seed=7, save_ts=save_ts, force=np.sin(np.arange(n) * dt))
    assert res.n_failed == 0
    vx, vv = pointmass_variance(save_ts, sigma_m, dt, p)
    lo, hi = chi2_interval(2000, 0.99)
    assert 0.9 < lo < hi < 1.1
    late = save_ts >= 2.0
    for ratio in (res.var[late, 0] / vx[late], res.var[late, 1] / vv[late]):
        assert np.all((ratio > lo) & (ratio < hi)), (ratio, lo, hi)
    # and the errors are centred (mean within 4 standard errors)
    se = np.sqrt(res.var / 2000)
    assert np.all(np.abs(res.mean) < 4 * se)
    if eta == 0.0:  # (2.9): Std v = O(t^1/2), Std x = O(t^3/2)
        assert slope_loglog(save_ts, np.sqrt(res.var[:, 0])) == pytest.approx(1.5, abs=0.05)
        assert slope_loglog(save_ts, np.sqrt(res.var[:, 1])) == pytest.approx(0.5, abs=0.05)
    else:  # (2.14): Std v = O(1) (saturated at the OU level), Std x grows slower than t^3/2
        assert res.var[-1, 1] == pytest.approx(sigma_m**2 * dt / (2 * eta * p.m**2), rel=0.1)


def test_bad_point_mass_inputs():
    with pytest.raises(ValueError, match="'m'"):
        pointmass_variance(1.0, 1.0, 0.01, PointMassParams(m=0.0))
    with pytest.raises(ValueError, match="'eta'"):
        pointmass_variance(1.0, 1.0, 0.01, PointMassParams(eta=-0.1))
    with pytest.raises(ValueError, match="force must have shape"):
        pointmass_monte_carlo(PointMassParams(), 1.0, 0.01, 100, 10, force=np.zeros(99))
    with pytest.raises(ValueError, match="dt"):
        pointmass_monte_carlo(PointMassParams(), 1.0, 0.0, 100, 10)
    with pytest.raises(ValueError, match="sigma_M"):
        pointmass_monte_carlo(PointMassParams(), -1.0, 0.01, 100, 10)
