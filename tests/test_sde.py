"""SDE schemes against closed forms (explicit chi-square / normal bounds, fixed keys)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import jaxdrift

N = 4000


def _paths(scheme, drift, diffusion, y0, T, dt, m, saveat, key=0):
    n_steps = int(round(T / dt))
    keys = jax.random.split(jax.random.key(key), N)

    def one(k):
        dW = jax.random.normal(k, (n_steps, m)) * jnp.sqrt(dt)
        return jaxdrift.solve_sde(drift, diffusion, y0, 0.0, T, dt=dt, dW=dW, saveat=saveat, scheme=scheme).ys

    return np.asarray(jax.jit(jax.vmap(one))(keys))


def _chi2_interval(var_exact, n, level=0.999):
    lo, hi = stats.chi2.ppf([(1 - level) / 2, (1 + level) / 2], n - 1)
    return var_exact * lo / (n - 1), var_exact * hi / (n - 1)


@pytest.mark.parametrize("scheme", ["euler_maruyama", "heun"])
def test_point_mass_variances_match_2_8(scheme):
    # Additive noise: both schemes give Var v = s^2 t / m^2, Var x = s^2 t^3 / (3 m^2) (up to O(dt)).
    m, s = 2.0, 3.0
    ts = np.array([0.5, 1.0])
    ys = _paths(scheme, lambda t, y, a: jnp.array([y[1], 0.0]), lambda t, y, a: jnp.array([[0.0], [s / m]]),
                jnp.zeros(2), 1.0, 1e-3, 1, ts)
    for j, t in enumerate(ts):
        for comp, exact in ((1, s**2 * t / m**2), (0, s**2 * t**3 / (3 * m**2))):
            lo, hi = _chi2_interval(exact, N)
            v = ys[:, j, comp].var(ddof=1)
            assert lo < v < hi, (scheme, t, comp, v, exact)


def test_ito_versus_stratonovich_geometric_brownian_motion():
    # dX = s X dW: Ito (Euler-Maruyama) E X(t) = 1; Stratonovich (Heun) E X(t) = exp(s^2 t / 2).
    s, T = 0.8, 1.0
    drift = lambda t, y, a: jnp.zeros(1)  # noqa: E731
    diff = lambda t, y, a: s * y[:, None]  # noqa: E731
    for scheme, mean_exact, var_exact in (
        ("euler_maruyama", 1.0, np.exp(s**2 * T) - 1),
        ("heun", np.exp(s**2 * T / 2), np.exp(s**2 * T) * (np.exp(s**2 * T) - 1)),
    ):
        x = _paths(scheme, drift, diff, jnp.ones(1), T, 1e-3, 1, np.array([T]), key=3)[:, 0, 0]
        se = np.sqrt(var_exact / N)
        assert abs(x.mean() - mean_exact) < 4 * se, (scheme, x.mean(), mean_exact)
    # The two differ by far more than the standard error: the test can tell them apart.
    assert np.exp(s**2 * T / 2) - 1 > 10 * np.sqrt((np.exp(s**2 * T) - 1) / N)


def test_dw_shape_is_checked():
    with pytest.raises(ValueError, match="dW must have shape"):
        jaxdrift.solve_sde(lambda t, y, a: y, lambda t, y, a: jnp.ones((1, 1)), jnp.ones(1), 0.0, 1.0, dt=0.1,
                           dW=jnp.zeros((5, 1)), saveat=np.array([1.0]))
