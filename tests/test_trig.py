"""The polynomial sin/cos of the vector fields against extended-precision references."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdrift.models._trig import sincos


def _ulp_error(got, x):
    """Largest error of (sin, cos) in units of the dtype's spacing at the true value."""
    xl = np.asarray(x, dtype=np.float64).astype(np.longdouble)
    out = []
    for g, ref in zip(got, (np.sin(xl), np.cos(xl))):
        g = np.asarray(g)
        spacing = np.spacing(np.abs(ref).astype(g.dtype)).astype(np.longdouble)
        out.append(float(np.max(np.abs(g.astype(np.longdouble) - ref) / spacing)))
    return out


@pytest.mark.skipif(np.finfo(np.longdouble).eps > 1e-18, reason="needs 80-bit long double as reference")
@pytest.mark.parametrize("dtype, span, bound", [(np.float64, 1e4, 2.0), (np.float32, 1e3, 3.0)])
def test_sincos_within_a_few_ulp(dtype, span, bound):
    rng = np.random.default_rng(0)
    x = np.concatenate([
        np.linspace(-10.0, 10.0, 200_001),
        rng.uniform(-span, span, 100_000),
        np.linspace(-0.5, 0.5, 100_001),  # the pitch angles of the half-car
        np.arange(-40, 41) * (np.pi / 4),  # quadrant boundaries
    ]).astype(dtype)
    err_s, err_c = _ulp_error(jax.jit(sincos)(x), x)
    assert err_s <= bound and err_c <= bound, (err_s, err_c)
    # and far worse than that would be a wrong quadrant: the bound is tight enough to catch it
    assert np.asarray(sincos(jnp.asarray(np.pi / 2, dtype))[0]) == 1.0


def test_sincos_small_angles_absolute():
    x = np.linspace(-1.0, 1.0, 100_001)
    s, c = sincos(x)
    xl = x.astype(np.longdouble)
    assert float(np.max(np.abs(np.asarray(s) - np.sin(xl)))) < 2.3e-16
    assert float(np.max(np.abs(np.asarray(c) - np.cos(xl)))) < 2.3e-16


def test_sincos_derivatives():
    # d/dx sin = cos, d/dx cos = -sin through the polynomials (round() has derivative zero).
    x = jnp.linspace(-7.0, 7.0, 1001)
    ds = jax.vmap(jax.grad(lambda v: sincos(v)[0]))(x)
    dc = jax.vmap(jax.grad(lambda v: sincos(v)[1]))(x)
    np.testing.assert_allclose(np.asarray(ds), np.cos(np.asarray(x)), atol=1e-15, rtol=0)
    np.testing.assert_allclose(np.asarray(dc), -np.sin(np.asarray(x)), atol=1e-15, rtol=0)


def test_sincos_integer_input_is_float():
    s, c = sincos(jnp.arange(3))
    assert jnp.issubdtype(s.dtype, jnp.floating)
    np.testing.assert_allclose(np.asarray(s), np.sin(np.arange(3.0)), atol=1e-15)


def test_plain_trig_switch():
    """``plain_trig`` swaps the polynomials for jnp.sin/jnp.cos, also in a function jitted before."""
    from jaxdrift.models._trig import plain_trig

    f = jax.jit(lambda x: sincos(x)[0])
    x = jnp.linspace(-10.0, 10.0, 1001)
    poly = np.asarray(f(x))
    assert (poly != np.asarray(jnp.sin(x))).any()  # the polynomials differ in the last bits
    with plain_trig():
        np.testing.assert_array_equal(np.asarray(f(x)), np.asarray(jnp.sin(x)))
    np.testing.assert_array_equal(np.asarray(f(x)), poly)
