"""The optional nonlinear suspension of the half-car: off is the linear model to the bit, on is
the independent generator's law (benchmarks/validation/gen_vehicle.py, written separately)."""

from __future__ import annotations


import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdrift.models._halfcar import (NonlinearSuspension, contact_forces, equilibrium_forces,
                                      force_driven_rhs, road_driven_rhs, spring_forces)
from jaxdrift.models._params import HalfCarParams

from benchmarks.validation import gen_vehicle

jax.config.update("jax_enable_x64", True)

P = HalfCarParams()


def _states(n, seed=0):
    rng = np.random.default_rng(seed)
    x = rng.normal(0.0, 0.02, (n, 10))
    x[:, 3] *= 2.0  # pitch [rad]
    x[:, 4:8] = rng.normal(0.0, 0.3, (n, 4))
    return jnp.asarray(x)


def test_off_is_bit_identical_to_the_linear_model():
    """None (the default) and the all-default terms give exactly the linear results."""
    xs = _states(64)
    nl0 = NonlinearSuspension()
    for x in xs:
        lin = force_driven_rhs(0.0, x, P, 3000.0, 2900.0)
        assert np.array_equal(np.asarray(force_driven_rhs(0.0, x, P, 3000.0, 2900.0, nonlinear=None)), np.asarray(lin))
        assert np.array_equal(np.asarray(force_driven_rhs(0.0, x, P, 3000.0, 2900.0, nonlinear=nl0)), np.asarray(lin))
        zeta, dz = jnp.array([0.01, -0.02]), jnp.array([0.1, 0.2])
        assert np.array_equal(np.asarray(road_driven_rhs(0.0, x[:8], P, zeta, dz, nonlinear=nl0)),
                              np.asarray(road_driven_rhs(0.0, x[:8], P, zeta, dz)))


@pytest.mark.parametrize("axle", [0, 1])
def test_nonlinear_law_matches_the_independent_generator(axle):
    """Each term against the generator's scalar law, at random travels and rates."""
    keys = dict(a=float(P.a), b=float(P.b), m1=float(P.m1), m2=float(P.m2), m3=float(P.m3), I=float(P.I),
                k1=float(P.k1), k2=float(P.k2), k3=float(P.k3), k4=float(P.k4), d1=float(P.d1),
                d2=float(P.d2), d3=float(P.d3), d4=float(P.d4), g=float(P.g))
    rho, c, kb, ub = 1.45, 900.0, 6.0e5, 0.012
    spring, damper = ("k3", "d3") if axle == 0 else ("k4", "d4")
    nl_gen = {("damper_asymmetry", damper): rho, ("progressive_spring", spring): c,
              ("bump_stop", spring): (kb, ub)}
    kw = {f"damper_ratio{axle + 3}": rho, f"cubic{axle + 3}": c, f"stop_k{axle + 3}": kb,
          f"stop_u{axle + 3}": ub}
    nl = NonlinearSuspension(**kw)
    law = gen_vehicle._suspension_law(keys, nl_gen)[axle]
    s0 = float(equilibrium_forces(P)[2 + axle]) / keys[spring]
    rng = np.random.default_rng(3)
    for _ in range(50):
        s, ds = s0 + rng.normal(0, 0.02), rng.normal(0, 0.4)
        # travel and rate of this axle from q, dq with zero pitch: s = z3 - z_i
        q = [0.0, 0.0, s, 0.0] if axle == 1 else [0.0, 0.0, s, 0.0]
        dq = [0.0, 0.0, ds, 0.0]
        f = spring_forces(jnp.array(q), jnp.array(dq), P, nonlinear=nl)[axle]
        assert float(f) == pytest.approx(law(s, ds), rel=1e-12, abs=1e-9)
    # the static state carries the linear static load: the equilibrium is unchanged
    q0 = jnp.array([0.0, 0.0, s0, 0.0])
    assert float(spring_forces(q0, jnp.zeros(4), P, nonlinear=nl)[axle]) == pytest.approx(
        float(equilibrium_forces(P)[2 + axle]), rel=1e-12)


def test_lift_off_clips_pulling_tyre_forces():
    x = jnp.zeros(8)
    f = contact_forces(x, P, jnp.array([0.01, -0.01]), jnp.zeros(2), NonlinearSuspension(lift_off=True))
    f_lin = contact_forces(x, P, jnp.array([0.01, -0.01]), jnp.zeros(2))
    assert float(f_lin[0]) < 0 and float(f[0]) == 0.0
    assert float(f[1]) == float(f_lin[1]) > 0


def test_nonlinear_rhs_jits():
    nl = NonlinearSuspension(damper_ratio4=1.5, cubic3=500.0)
    f = jax.jit(lambda x: force_driven_rhs(0.0, x, P, 3000.0, 2900.0, nonlinear=nl))
    x = _states(1)[0]
    assert np.allclose(np.asarray(f(x)), np.asarray(force_driven_rhs(0.0, x, P, 3000.0, 2900.0, nonlinear=nl)))
