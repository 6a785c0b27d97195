"""Derivatives through solve_ode: adaptive (forward mode) and fixed step (forward and reverse).

The damped oscillator y'' + 2 zeta w y' + w^2 y = 0, y(0) = 1, y'(0) = 0 has a closed form, so
d y(T) / d w is known independently of any solver; central finite differences of the solver
itself are the second reference.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxdrift

ZETA, T = 0.1, 3.0


def exact(w, t=T):
    wd = w * jnp.sqrt(1 - ZETA**2)
    return jnp.exp(-ZETA * w * t) * (jnp.cos(wd * t) + ZETA * w / wd * jnp.sin(wd * t))


def rhs(t, y, w):
    return jnp.stack([y[1], -2 * ZETA * w * y[1] - w**2 * y[0]])


def y_end(w, **kw):
    sol = jaxdrift.solve_ode(rhs, jnp.array([1.0, 0.0]), 0.0, T, saveat=np.array([T]), args=w, **kw)
    return sol.ys[-1, 0]


ADAPTIVE = dict(rtol=1e-10, atol=1e-12)
y_adaptive = jax.jit(lambda w: y_end(w, **ADAPTIVE))  # compiled once for all calls below


def test_adaptive_forward_derivative_against_closed_form_and_fd():
    w = 2.0
    d_exact = float(jax.grad(exact)(w))
    d_jvp = float(jax.jit(jax.jacfwd(y_adaptive))(w))
    eps = 1e-4
    d_fd = (float(y_adaptive(w + eps)) - float(y_adaptive(w - eps))) / (2 * eps)
    assert abs(d_jvp - d_exact) <= 1e-8 * abs(d_exact), (d_jvp, d_exact)
    # finite differences carry the tolerance over eps (1e-6) and eps^2 truncation
    assert abs(d_jvp - d_fd) <= 1e-6 * abs(d_exact), (d_jvp, d_fd)
    # and the derivative is not trivially zero or the FD of a constant
    assert abs(d_exact) > 0.1


def test_adaptive_derivative_with_respect_to_t1_and_under_vmap():
    # d y(T)/dT = y'(T): the last step ends at the differentiated t1.
    def end_at(t1):
        sol = jaxdrift.solve_ode(rhs, jnp.array([1.0, 0.0]), 0.0, t1, saveat=jnp.array([0.5]), args=2.0, **ADAPTIVE)
        return sol.ys[0, 0]

    # a save time before t1 does not depend on t1
    assert float(jax.jit(jax.jacfwd(end_at))(3.0)) == 0.0
    ws = jnp.array([1.5, 2.0, 2.5])
    d_vmap = jax.jit(jax.vmap(jax.jacfwd(y_adaptive)))(ws)
    np.testing.assert_allclose(np.asarray(d_vmap), np.asarray(jax.vmap(jax.grad(exact))(ws)), rtol=1e-8)


def test_adaptive_reverse_mode_is_refused_clearly():
    # the adaptive loop is a while_loop of unknown length: forward mode only (documented)
    with pytest.raises(ValueError, match="[Rr]everse-mode"):
        jax.grad(y_adaptive)(2.0)


@pytest.mark.parametrize("mode", ["grad", "jacfwd"])
def test_fixed_step_derivatives_both_modes(mode):
    w, dt = 2.0, 1e-3  # 3000 steps of DOPRI5: global error ~1e-13
    fn = jax.jit(lambda v: y_end(v, dt=dt))
    d = float(jax.jit((jax.grad if mode == "grad" else jax.jacfwd)(fn))(w))
    eps = 1e-5
    d_fd = (float(fn(w + eps)) - float(fn(w - eps))) / (2 * eps)
    d_exact = float(jax.grad(exact)(w))
    assert abs(d - d_exact) <= 1e-9 * abs(d_exact), (d, d_exact)
    assert abs(d - d_fd) <= 1e-8 * abs(d_exact), (d, d_fd)
    # batched (the paths-last loop) gives the same derivatives
    ws = jnp.array([1.5, 2.0])
    dv = jax.jit(jax.vmap((jax.grad if mode == "grad" else jax.jacfwd)(fn)))(ws)
    np.testing.assert_allclose(np.asarray(dv), np.asarray(jax.vmap(jax.grad(exact))(ws)), rtol=1e-9)
