"""Half-car of the seed's Appendix A: vector fields against the paper's matrix forms, equilibrium,
small-angle form, the excitation modes against each other (scipy as the integrator oracle)."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from jaxdrift.models._halfcar import (
    contact_forces,
    enforced_moment,
    equilibrium_forces,
    force_driven_rhs,
    pitch_spring_torque,
    prescribed_pitch_rhs,
    road_driven_rhs,
    spring_forces,
    static_equilibrium,
)
from jaxdrift.models._params import (
    PAPER_PERTURBATION,
    HalfCarParams,
    random_perturbed_models,
    stack_models,
)

# An asymmetric model (so the equilibrium pitch is not zero and a != b is exercised).
ASYM = HalfCarParams(a=1.3, b=0.9, m1=17.0, m2=13.0, k3=1.2e5, k4=0.8e5, d3=9e3, d4=1.1e4, I=420.0)


# ---------------------------------------------------------------------------------------------
# independent oracles: the paper's matrix forms (A.3), (A.4), (A.5), written out in numpy
# ---------------------------------------------------------------------------------------------
def _blocks(p, beta):
    c4 = np.cos(beta)
    s4 = np.sinc(beta / np.pi)  # sin(beta)/beta, = 1 at 0
    k3, k4, d3, d4, a, b = p.k3, p.k4, p.d3, p.d4, p.a, p.b
    A21 = np.array(
        [
            [-k3, 0, k3, -b * k3 * s4],
            [0, -k4, k4, a * k4 * s4],
            [k3, k4, -k3 - k4, (b * k3 - a * k4) * s4],
            [-b * k3 * c4, a * k4 * c4, (b * k3 - a * k4) * c4, (-(b**2) * k3 - a**2 * k4) * c4 * s4],
        ]
    )
    A22 = np.array(
        [
            [-d3, 0, d3, -b * d3 * c4],
            [0, -d4, d4, a * d4 * c4],
            [d3, d4, -d3 - d4, (b * d3 - a * d4) * c4],
            [-b * d3 * c4, a * d4 * c4, (b * d3 - a * d4) * c4, (-(b**2) * d3 - a**2 * d4) * c4**2],
        ]
    )
    return A21, A22


def a3_matrix_rhs(x, p, f1, f2):
    A21, A22 = _blocks(p, x[3])
    A = np.zeros((10, 10))
    A[0:4, 4:8] = np.eye(4)
    A[4:8, 0:4] = A21
    A[4:8, 4:8] = A22
    A[8:10, 0:4] = [[p.k1, 0, 0, 0], [0, p.k2, 0, 0]]
    A[8:10, 4:8] = [[p.d1, 0, 0, 0], [0, p.d2, 0, 0]]
    A[8:10, 8:10] = -np.diag([p.k1, p.k2])
    M = np.diag([1, 1, 1, 1, p.m1, p.m2, p.m3, p.I, p.d1, p.d2])
    F = np.array([0, 0, 0, 0, p.m1 * p.g - f1, p.m2 * p.g - f2, p.m3 * p.g, 0, -f1, -f2])
    return np.linalg.solve(M, A @ x + F)


def a4_matrix_rhs(x, p, zeta, dzeta):
    A21, A22 = _blocks(p, x[3])
    A21 = A21 - np.diag([p.k1, p.k2, 0, 0])
    A22 = A22 - np.diag([p.d1, p.d2, 0, 0])
    A = np.zeros((8, 8))
    A[0:4, 4:8] = np.eye(4)
    A[4:8, 0:4] = A21
    A[4:8, 4:8] = A22
    M = np.diag([1, 1, 1, 1, p.m1, p.m2, p.m3, p.I])
    F = np.array(
        [
            0,
            0,
            0,
            0,
            p.m1 * p.g + p.k1 * zeta[0] + p.d1 * dzeta[0],
            p.m2 * p.g + p.k2 * zeta[1] + p.d2 * dzeta[1],
            p.m3 * p.g,
            0,
        ]
    )
    return np.linalg.solve(M, A @ x + F)


def a5_matrix_rhs(x, p, f1, f2, beta, dbeta):
    k1, k2, k3, k4, d1, d2, d3, d4, a, b = p.k1, p.k2, p.k3, p.k4, p.d1, p.d2, p.d3, p.d4, p.a, p.b
    A = np.array(
        [
            [0, 0, 0, 1, 0, 0, 0, 0],
            [0, 0, 0, 0, 1, 0, 0, 0],
            [0, 0, 0, 0, 0, 1, 0, 0],
            [-k3, 0, k3, -d3, 0, d3, 0, 0],
            [0, -k4, k4, 0, -d4, d4, 0, 0],
            [k3, k4, -k3 - k4, d3, d4, -d3 - d4, 0, 0],
            [k1, 0, 0, d1, 0, 0, -k1, 0],
            [0, k2, 0, 0, d2, 0, 0, -k2],
        ]
    )
    sb, cb = np.sin(beta), np.cos(beta)
    F = np.array(
        [
            0,
            0,
            0,
            p.m1 * p.g - f1 - k3 * b * sb - d3 * b * dbeta * cb,
            p.m2 * p.g - f2 + k4 * a * sb + d4 * a * dbeta * cb,
            p.m3 * p.g + (k3 * b - k4 * a) * sb + (d3 * b - d4 * a) * dbeta * cb,
            -f1,
            -f2,
        ]
    )
    M = np.diag([1, 1, 1, p.m1, p.m2, p.m3, d1, d2])
    return np.linalg.solve(M, A @ x + F)


def _random_state(rng, n):
    x = rng.normal(size=n) * 0.05
    x[3] = rng.uniform(-0.6, 0.6)  # large pitch: exercises sin/cos
    return x


@pytest.mark.parametrize("p", [HalfCarParams(), ASYM], ids=["seed", "asym"])
def test_vector_fields_equal_matrix_forms(p):
    rng = np.random.default_rng(1)
    for _ in range(5):
        x = _random_state(rng, 10)
        f1, f2 = rng.normal(size=2) * 5e3 + 4e3
        got = np.asarray(force_driven_rhs(0.0, jnp.asarray(x), p, f1, f2))
        np.testing.assert_allclose(got, a3_matrix_rhs(x, p, f1, f2), rtol=1e-12, atol=1e-9)

        xb = x[:8]
        zeta, dzeta = rng.normal(size=2) * 0.1, rng.normal(size=2)
        got = np.asarray(road_driven_rhs(0.0, jnp.asarray(xb), p, jnp.asarray(zeta), jnp.asarray(dzeta)))
        np.testing.assert_allclose(got, a4_matrix_rhs(xb, p, zeta, dzeta), rtol=1e-12, atol=1e-9)

        xh = x[[0, 1, 2, 4, 5, 6, 8, 9]]
        beta, dbeta = x[3], x[7]
        got = np.asarray(prescribed_pitch_rhs(0.0, jnp.asarray(xh), p, f1, f2, beta, dbeta))
        np.testing.assert_allclose(got, a5_matrix_rhs(xh, p, f1, f2, beta, dbeta), rtol=1e-12, atol=1e-9)


def test_linear_form_is_A_at_zero():
    """linear=True is the paper's M x' = A(0) x + F (cos -> 1, sin(beta)/beta -> 1)."""
    p = ASYM
    rng = np.random.default_rng(2)
    x = _random_state(rng, 10)
    f1, f2 = 3e3, 5e3
    A21, A22 = _blocks(p, 0.0)
    A = np.zeros((10, 10))
    A[0:4, 4:8] = np.eye(4)
    A[4:8, 0:4] = A21
    A[4:8, 4:8] = A22
    A[8:10, 0:4] = [[p.k1, 0, 0, 0], [0, p.k2, 0, 0]]
    A[8:10, 4:8] = [[p.d1, 0, 0, 0], [0, p.d2, 0, 0]]
    A[8:10, 8:10] = -np.diag([p.k1, p.k2])
    M = np.diag([1, 1, 1, 1, p.m1, p.m2, p.m3, p.I, p.d1, p.d2])
    F = np.array([0, 0, 0, 0, p.m1 * p.g - f1, p.m2 * p.g - f2, p.m3 * p.g, 0, -f1, -f2])
    want = np.linalg.solve(M, A @ x + F)
    got = np.asarray(force_driven_rhs(0.0, jnp.asarray(x), p, f1, f2, linear=True))
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-9)


def test_linear_equals_nonlinear_at_small_angles():
    """The difference is second order in beta: it shrinks 100x when beta shrinks 10x."""
    p = ASYM
    rng = np.random.default_rng(3)
    x = _random_state(rng, 10)
    diffs = []
    for beta in (1e-2, 1e-3):
        x[3], x[7] = beta, 10 * beta
        xn = jnp.asarray(x)
        d = force_driven_rhs(0.0, xn, p, 4e3, 4e3) - force_driven_rhs(0.0, xn, p, 4e3, 4e3, linear=True)
        diffs.append(float(jnp.max(jnp.abs(d))))
    assert diffs[1] < diffs[0] / 50
    assert diffs[1] < 1e-3


@pytest.mark.parametrize("p", [HalfCarParams(), ASYM], ids=["seed", "asym"])
@pytest.mark.parametrize("linear", [False, True])
def test_static_equilibrium_is_at_rest(p, linear):
    f1, f2, f3, f4 = equilibrium_forces(p)
    assert f1 + f2 == pytest.approx((p.m1 + p.m2 + p.m3) * p.g, rel=1e-14)
    zeta = (0.03, -0.02)
    x = static_equilibrium(p, "force", zeta=zeta, linear=linear)
    assert x.shape == (10,)
    rhs = force_driven_rhs(0.0, x, p, f1, f2, linear=linear)
    np.testing.assert_allclose(np.asarray(rhs), 0.0, atol=1e-10)
    xb = static_equilibrium(p, "road", zeta=zeta, linear=linear)
    np.testing.assert_allclose(np.asarray(xb), np.asarray(x[:8]))
    rhs = road_driven_rhs(0.0, xb, p, jnp.asarray(zeta), jnp.zeros(2), linear=linear)
    np.testing.assert_allclose(np.asarray(rhs), 0.0, atol=1e-10)
    np.testing.assert_allclose(np.asarray(contact_forces(xb, p, jnp.asarray(zeta), jnp.zeros(2))), [f1, f2], rtol=1e-12)
    xh = static_equilibrium(p, "pitch", zeta=zeta, linear=linear)
    rhs = prescribed_pitch_rhs(0.0, xh, p, f1, f2, x[3], 0.0, linear=linear)
    np.testing.assert_allclose(np.asarray(rhs), 0.0, atol=1e-10)
    lam = enforced_moment(xh, p, x[3], 0.0, 0.0, linear=linear)
    assert abs(float(lam)) < 1e-8
    if p is ASYM:
        assert abs(float(x[3])) > 1e-3  # the asymmetric model really sits pitched


def test_static_equilibrium_signs_seed():
    """z points down: the loaded wheels sit below the road contact (z1 > zeta1), spring forces
    are compressive m3 g / 2 each, pitch is zero for the symmetric seed model."""
    p = HalfCarParams()
    x = np.asarray(static_equilibrium(p))
    assert x[0] == pytest.approx((p.m1 * p.g + p.m3 * p.g / 2) / p.k1)
    assert x[3] == 0.0
    f3, f4 = spring_forces(x[0:4], x[4:8], p)
    assert float(f3) == pytest.approx(p.m3 * p.g / 2) and float(f4) == pytest.approx(p.m3 * p.g / 2)


def test_enforced_moment_formula_and_pitch_spring():
    p = ASYM
    rng = np.random.default_rng(4)
    x = _random_state(rng, 10)
    xh = x[[0, 1, 2, 4, 5, 6, 8, 9]]
    f3, f4 = spring_forces(x[0:4], x[4:8], p)
    want = p.I * 2.5 - np.cos(x[3]) * (p.b * float(f3) - p.a * float(f4))
    got = float(enforced_moment(jnp.asarray(xh), p, x[3], x[7], 2.5))
    assert got == pytest.approx(want, rel=1e-12)
    # the free model's beta'' makes lambda vanish (consistency of A.3 and the lambda formula)
    ddbeta = float(force_driven_rhs(0.0, jnp.asarray(x), p, 1e3, 2e3)[7])
    assert abs(float(enforced_moment(jnp.asarray(xh), p, x[3], x[7], ddbeta))) < 1e-8
    # the pitch spring adds -(k beta + d beta') / I to beta'' and nothing else
    k, d = 3e4, 2e3
    diff = force_driven_rhs(0.0, jnp.asarray(x), p, 1e3, 2e3, pitch_spring=(k, d)) - force_driven_rhs(
        0.0, jnp.asarray(x), p, 1e3, 2e3
    )
    want = np.zeros(10)
    want[7] = -(k * x[3] + d * x[7]) / p.I
    np.testing.assert_allclose(np.asarray(diff), want, atol=1e-12)
    assert float(pitch_spring_torque(jnp.asarray(x), k, d)) == pytest.approx(k * x[3] + d * x[7])


def test_jit_and_vmap_over_batched_params():
    models = random_perturbed_models(7, seed=3)
    x0 = static_equilibrium(models)  # batched params -> (7, 10)
    assert x0.shape == (7, 10)
    f = jax.jit(jax.vmap(lambda x, p: force_driven_rhs(0.0, x, p, 4e3, 4e3)))
    out = f(x0, models)
    assert out.shape == (7, 10)
    for i in (0, 6):
        pi = HalfCarParams(**{n: float(getattr(models, n)[i]) for n in HalfCarParams.field_names()})
        np.testing.assert_allclose(np.asarray(out[i]), a3_matrix_rhs(np.asarray(x0[i]), pi, 4e3, 4e3), atol=1e-9)


# ---------------------------------------------------------------------------------------------
# parameters
# ---------------------------------------------------------------------------------------------
def test_params_defaults_are_the_seed_table():
    p = HalfCarParams()
    assert p.to_dict() == {
        "a": 1.0, "b": 1.0, "m1": 15.0, "m2": 15.0, "m3": 750.0, "I": 500.0,
        "k1": 2e5, "k2": 2e5, "k3": 1e5, "k4": 1e5,
        "d1": 200.0, "d2": 200.0, "d3": 1e4, "d4": 1e4, "g": 9.81,
    }  # fmt: skip
    assert HalfCarParams.from_dict(p.to_dict()) == p
    q = p.paper_perturbed()
    for k, f in PAPER_PERTURBATION.items():
        assert getattr(q, k) == pytest.approx(getattr(p, k) * f)
    assert q.m3 == p.m3


@pytest.mark.parametrize("key", ["m1", "m3", "I", "k3", "k1", "d4", "a"])
@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan")])
def test_bad_params_name_the_key(key, bad):
    with pytest.raises(ValueError, match=repr(key)):
        HalfCarParams.from_dict({key: bad})
    with pytest.raises(ValueError, match=repr(key)):
        dataclasses.replace(HalfCarParams(), **{key: bad}).validate()


def test_params_unknown_and_non_numeric():
    with pytest.raises(ValueError, match="'k5'"):
        HalfCarParams.from_dict({"k5": 1.0})
    with pytest.raises(ValueError, match="'m1'.*not a number"):
        HalfCarParams.from_dict({"m1": "heavy"})
    with pytest.raises(ValueError, match="'k3'"):
        random_perturbed_models(4, base=HalfCarParams(k3=-1.0)).validate()


def test_random_perturbed_models_range_and_reproducible():
    m = random_perturbed_models(500, seed=11)
    base = HalfCarParams()
    for k in ("k3", "k4", "d3", "d4", "I"):
        r = np.asarray(getattr(m, k)) / getattr(base, k)
        assert r.min() >= 0.9 and r.max() <= 1.1
        assert r.min() < 0.91 and r.max() > 1.09  # really spread over the interval
    np.testing.assert_array_equal(np.asarray(m.m1), 15.0)
    m2 = random_perturbed_models(500, seed=11)
    np.testing.assert_array_equal(np.asarray(m2.k3), np.asarray(m.k3))
    s = stack_models([base, base.paper_perturbed()])
    assert np.asarray(s.k3).tolist() == [1e5, 1.05e5]


# ---------------------------------------------------------------------------------------------
# excitation modes against each other, scipy DOP853 as the integrator
# ---------------------------------------------------------------------------------------------
def _smooth_road(t, xp=np):
    """A smooth test road under wheel 1 and wheel 2 (z-down), starting flat at t = 0."""
    w = 1.0 - xp.exp(-((t / 0.3) ** 2))
    dw = 2 * t / 0.3**2 * xp.exp(-((t / 0.3) ** 2))
    z1 = 0.02 * xp.sin(9.0 * t) + 0.01 * xp.sin(23.0 * t + 1.0)
    dz1 = 0.18 * xp.cos(9.0 * t) + 0.23 * xp.cos(23.0 * t + 1.0)
    z2 = 0.015 * xp.sin(7.0 * t + 0.5) - 0.01 * xp.sin(31.0 * t)
    dz2 = 0.105 * xp.cos(7.0 * t + 0.5) - 0.31 * xp.cos(31.0 * t)
    zeta = xp.stack([w * z1, w * z2])
    dzeta = xp.stack([dw * z1 + w * dz1, dw * z2 + w * dz2])
    return zeta, dzeta


def test_force_mode_driven_by_road_contact_forces_reproduces_road_motion():
    """Virtual measurement (A.4) -> its contact forces (4.3) -> force mode (A.3) gives the same
    motion (undisturbed forces, short horizon); prescribed pitch (A.5) gives lambda ~ 0."""
    p = ASYM

    @jax.jit
    def road_rhs(t, x):
        z, dz = _smooth_road(t, jnp)
        return road_driven_rhs(t, x, p, z, dz)

    @jax.jit
    def road_forces(t, xb):
        z, dz = _smooth_road(t, jnp)
        return contact_forces(xb, p, z, dz)

    force_rhs = jax.jit(lambda t, x, f: force_driven_rhs(t, x, p, f[0], f[1]))
    pitch_rhs = jax.jit(lambda t, x, f, b, db: prescribed_pitch_rhs(t, x, p, f[0], f[1], b, db))

    def fr(t, x):
        return np.asarray(road_rhs(t, x))

    T = 0.5
    ts = np.linspace(0, T, 51)
    tol = dict(method="DOP853", rtol=1e-10, atol=1e-12, dense_output=True)
    road = solve_ivp(fr, (0, T), np.asarray(static_equilibrium(p, "road")), t_eval=ts, **tol)
    assert road.success

    def ff(t, x):
        return np.asarray(force_rhs(t, x, road_forces(t, road.sol(t))))

    force = solve_ivp(ff, (0, T), np.asarray(static_equilibrium(p, "force")), t_eval=ts, **tol)
    assert force.success
    # the road moves the car by centimetres; force mode reproduces it to ~1e-7 (tolerance-limited)
    assert np.ptp(road.y[2]) > 5e-3 and np.ptp(road.y[3]) > 1e-3
    np.testing.assert_allclose(force.y[:8], road.y, atol=1e-7)
    # the contact states reconstruct the road itself
    zeta = np.array([_smooth_road(t)[0] for t in ts]).T
    np.testing.assert_allclose(force.y[8:10], zeta, atol=1e-7)

    def fp(t, x):
        xb = road.sol(t)
        return np.asarray(pitch_rhs(t, x, road_forces(t, xb), xb[3], xb[7]))

    pitch = solve_ivp(fp, (0, T), np.asarray(static_equilibrium(p, "pitch")), t_eval=ts, **tol)
    assert pitch.success
    ddbeta = np.array([fr(t, road.sol(t))[7] for t in ts])
    lam = np.asarray(enforced_moment(jnp.asarray(pitch.y.T), p, road.y[3], road.y[7], ddbeta))
    inertia = p.I * ddbeta
    assert np.max(np.abs(inertia)) > 50.0  # the pitch really moves
    assert np.max(np.abs(lam)) < 1e-5 * np.max(np.abs(inertia))
