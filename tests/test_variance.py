"""Analytic variances (closed forms, linearised covariance propagation) against independent oracles
and Monte-Carlo within explicit chi-square bounds (fixed keys, small sizes)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.integrate
import scipy.linalg

import jaxdrift
from jaxdrift.analysis._variance import (
    halfcar_free_mode_covariance,
    halfcar_free_modes,
    point_mass_covariance,
    point_mass_variance,
    propagate_covariance,
    quaternion_angle_variance,
    quaternion_norm_growth,
    quaternion_norm_sq_euler,
    variance_interval,
)

# A two-sided interval at this level fails by chance once in 1,000 draws: with fixed keys the
# tests are deterministic, and a changed key is very unlikely to break a correct implementation.
LEVEL = 0.999


def _inside(sample_var, n, exact, level=LEVEL):
    lo, hi = variance_interval(sample_var, n, level)
    return np.all((lo <= exact) & (exact <= hi)), (lo, hi)


# --------------------------------------------------------------------------- closed forms


def test_point_mass_eta_zero_is_2_8():
    t = np.array([0.5, 3.0, 30.0])
    vx, vv = point_mass_variance(t, sigma_m=32.0, dt=1e-3, m=750.0)
    s2 = 32.0**2 * 1e-3
    np.testing.assert_allclose(vx, s2 * t**3 / (3 * 750.0**2), rtol=1e-14)
    np.testing.assert_allclose(vv, s2 * t / 750.0**2, rtol=1e-14)


@pytest.mark.parametrize("eta", [1e-6, 0.02, 0.3, 5.0])
def test_point_mass_covariance_against_quadrature(eta):
    # Independent oracle: Ito isometry integrals of the impulse responses, by quadrature.
    m, t, s2 = 2.0, 7.0, 0.25 * 0.01
    gx = lambda u: -np.expm1(-eta * u) / eta  # response of x to a unit impulse u seconds ago
    gv = lambda u: np.exp(-eta * u)
    quad = lambda g: scipy.integrate.quad(g, 0, t, epsabs=0, epsrel=1e-13)[0]
    want = s2 / m**2 * np.array(
        [[quad(lambda u: gx(u) ** 2), quad(lambda u: gx(u) * gv(u))], [0, quad(lambda u: gv(u) ** 2)]]
    )
    want[1, 0] = want[0, 1]
    got = point_mass_covariance(t, sigma_m=0.5, dt=0.01, m=m, eta=eta)
    np.testing.assert_allclose(got, want, rtol=1e-10)


def test_point_mass_eta_continuity_and_2_11():
    # The series branch (eta t < 0.5) and the closed form (2.11) meet; eta -> 0 gives (2.8).
    c_lo = point_mass_covariance(10.0, sigma_m=1.0, dt=1.0, eta=0.05 * (1 - 1e-12))
    c_hi = point_mass_covariance(10.0, sigma_m=1.0, dt=1.0, eta=0.05)
    np.testing.assert_allclose(c_lo, c_hi, rtol=1e-10)
    eta, t = 0.8, 4.0
    vx = (t + (1 - np.exp(-2 * eta * t)) / (2 * eta) - 2 * (1 - np.exp(-eta * t)) / eta) / eta**2
    np.testing.assert_allclose(point_mass_variance(t, sigma_m=1.0, dt=1.0, eta=eta)[0], vx, rtol=1e-13)
    np.testing.assert_allclose(
        point_mass_covariance(3.0, sigma_m=1, dt=1, eta=1e-12), point_mass_covariance(3.0, sigma_m=1, dt=1), rtol=1e-9
    )


def test_quaternion_closed_forms_match_the_attitude_module():
    from jaxdrift.models import _quaternion as quat

    s, dt, t = 0.1, 1e-3, np.array([1.0, 60.0, 600.0])
    sigma = s * np.sqrt(dt)
    for n_axes in (1, 3):
        np.testing.assert_allclose(
            quaternion_norm_growth(t, sigma_m=s, dt=dt, n_axes=n_axes), quat.ito_norm_growth(sigma, t, n_axes)
        )
    np.testing.assert_allclose(quaternion_angle_variance(t, sigma_m=s, dt=dt), quat.angle_error_std(sigma, t) ** 2)
    # The seed's number: sigma = 180/pi * 0.1 * sqrt(0.001) = 0.18 deg/sqrt(s).
    assert np.degrees(np.sqrt(quaternion_angle_variance(1.0, sigma_m=0.1, dt=1e-3))) == pytest.approx(0.181, abs=1e-3)


def test_bad_arguments_raise():
    with pytest.raises(ValueError, match="sigma_m"):
        point_mass_variance(1.0, sigma_m=-1.0, dt=1e-3)
    with pytest.raises(ValueError, match="dt"):
        point_mass_variance(1.0, sigma_m=1.0, dt=0.0)
    with pytest.raises(ValueError, match="n_axes"):
        quaternion_norm_growth(1.0, sigma_m=1.0, dt=1.0, n_axes=4)
    with pytest.raises(ValueError, match="n must"):
        variance_interval(1.0, 1)


def test_variance_interval_coverage():
    # The chi-square interval covers the true variance at its nominal rate (numpy draws, fixed seed).
    rng = np.random.default_rng(3)
    n, reps = 20, 4000
    s2 = rng.normal(size=(reps, n)).var(axis=1, ddof=1)
    lo, hi = variance_interval(s2, n, 0.9)
    cover = np.mean((lo <= 1) & (1 <= hi))
    # Binomial(4000, 0.9): standard error 0.0047; 4 standard errors.
    assert abs(cover - 0.9) < 0.019


# --------------------------------------------------------------------------- propagation


def _pm_rhs(t, y, u, args):
    m, eta = args
    return jnp.stack([y[1], u[0] / m - eta * y[1]])


def test_propagated_covariance_equals_point_mass_closed_form():
    # (2.8) and (2.11) in one compiled call (vmap over the damping constant).
    ts = np.array([0.0, 1.0, 7.5, 30.0])
    etas = np.array([0.0, 0.3])

    def cov(eta):
        res = propagate_covariance(
            _pm_rhs, jnp.zeros(2), 0.0, 30.0, saveat=ts, inputs=lambda t: jnp.zeros(1),
            noise_sigma=0.5, noise_dt=1e-3, args=(2.0, eta), dt=0.01,
        )
        return res.cov, res.mean

    covs, means = jax.vmap(cov)(jnp.asarray(etas))
    for k, eta in enumerate(etas):
        want = point_mass_covariance(ts, sigma_m=0.5, dt=1e-3, m=2.0, eta=eta)
        np.testing.assert_allclose(np.asarray(covs[k]), want, rtol=1e-9, atol=1e-300)
    np.testing.assert_array_equal(np.asarray(means), 0.0)


def test_propagated_covariance_derived_quantities():
    ts = np.array([2.0, 30.0])
    res = propagate_covariance(
        _pm_rhs, jnp.zeros(2), 0.0, 30.0, saveat=ts, inputs=lambda t: jnp.zeros(1),
        noise_sigma=0.5, noise_dt=1e-3, args=(2.0, 0.3), dt=0.01,
        derived=lambda t, y, args: jnp.stack([y[0] + 2 * y[1], y[0] * y[1]]),
    )
    c = point_mass_covariance(ts, sigma_m=0.5, dt=1e-3, m=2.0, eta=0.3)
    np.testing.assert_allclose(np.asarray(res.var), np.stack([c[:, 0, 0], c[:, 1, 1]], -1), rtol=1e-9)
    j = np.array([1.0, 2.0])
    np.testing.assert_allclose(np.asarray(res.derived_var[:, 0]), j @ c @ j, rtol=1e-9)
    # d(x v) = v dx + x dv = 0 at the zero reference.
    np.testing.assert_array_equal(np.asarray(res.derived_var[:, 1]), 0.0)


def test_propagated_covariance_linear_system_against_van_loan():
    # Adaptive mode. Time-invariant linear system with a constant input: P(t) = int_0^t e^{As} B Q B^T e^{A^T s} ds,
    # computed by Van Loan's block matrix exponential; the limit solves the Lyapunov equation.
    rng = np.random.default_rng(0)
    n, m = 4, 2
    A = rng.normal(size=(n, n)) - 3.0 * np.eye(n)
    Bm = rng.normal(size=(n, m))
    u_const = np.array([0.3, -1.2])
    sig, ndt = np.array([0.7, 2.0]), np.array([1e-3, 4e-3])
    Q = np.diag(sig**2 * ndt)
    rhs = lambda t, y, u, args: jnp.asarray(A) @ y + jnp.asarray(Bm) @ u
    ts = np.array([0.1, 0.5, 2.0, 20.0])
    y0 = rng.normal(size=n)
    P0 = np.diag([0.1, 0.0, 0.2, 0.05])
    res = propagate_covariance(
        rhs, jnp.asarray(y0), 0.0, 20.0, saveat=ts, inputs=lambda t: jnp.asarray(u_const),
        noise_sigma=sig, noise_dt=ndt, P0=jnp.asarray(P0), rtol=1e-10, atol=1e-12,
    )
    W = Bm @ Q @ Bm.T
    for k, t in enumerate(ts[:3]):  # (at t = 20 the block exponential loses digits: e^{60})
        big = scipy.linalg.expm(np.block([[-A, W], [np.zeros((n, n)), A.T]]) * t)
        Phi = big[n:, n:].T
        want = Phi @ big[:n, n:] + Phi @ P0 @ Phi.T
        np.testing.assert_allclose(np.asarray(res.cov[k]), want, rtol=1e-7, atol=1e-12)
        # Reference trajectory: y(t) = e^{At} y0 + A^{-1}(e^{At} - I) B u.
        ey = scipy.linalg.expm(A * t)
        want_y = ey @ y0 + np.linalg.solve(A, (ey - np.eye(n)) @ Bm @ u_const)
        np.testing.assert_allclose(np.asarray(res.mean[k]), want_y, rtol=1e-7, atol=1e-10)
    stationary = scipy.linalg.solve_continuous_lyapunov(A, -W)
    np.testing.assert_allclose(np.asarray(res.cov[-1]), stationary, rtol=1e-6, atol=1e-12)


def test_propagate_covariance_bad_shapes():
    with pytest.raises(ValueError, match="noise_sigma"):
        propagate_covariance(
            _pm_rhs, jnp.zeros(2), 0.0, 1.0, saveat=[1.0], inputs=lambda t: jnp.zeros(1),
            noise_sigma=[1.0, 2.0], noise_dt=1e-3, args=(1.0, 0.0), dt=0.1,
        )
    with pytest.raises(ValueError, match="P0"):
        propagate_covariance(
            _pm_rhs, jnp.zeros(2), 0.0, 1.0, saveat=[1.0], inputs=lambda t: jnp.zeros(1),
            noise_sigma=1.0, noise_dt=1e-3, args=(1.0, 0.0), P0=jnp.eye(3), dt=0.1,
        )


# --------------------------------------------------------------------------- Monte-Carlo


def test_monte_carlo_point_mass_within_chi_square():
    # The seed's explicit Euler scheme on noisy force samples (2.3), i.e. Euler-Maruyama, through
    # the engine's solve_sde; noise from jaxdrift.path_normals with a fixed key; eta = 0 and 0.5.
    m, sigma_m, dt, T, n_paths = 3.0, 2.0, 0.01, 6.0, 3000
    n_steps = int(round(T / dt))
    ts = np.array([1.0, 3.0, 6.0])
    key = jax.random.key(11)
    etas = np.array([0.0, 0.5])

    def path(i, eta):
        dW = jaxdrift.path_normals(key, i, n_steps, 1) * np.sqrt(dt)
        sol = jaxdrift.solve_sde(
            lambda t, y, a: jnp.stack([y[1], -a * y[1]]),
            lambda t, y, a: jnp.array([[0.0], [sigma_m * np.sqrt(dt) / m]]),
            jnp.zeros(2), 0.0, T, dt=dt, dW=dW, saveat=ts, args=eta,
        )
        return sol.ys

    both = jax.vmap(lambda i: jax.vmap(lambda e: path(i, e))(jnp.asarray(etas)))
    ys = np.asarray(jax.jit(both)(jnp.arange(n_paths)))  # (paths, eta, save, state)
    for k, eta in enumerate(etas):
        want = point_mass_covariance(ts, sigma_m=sigma_m, dt=dt, m=m, eta=eta)
        for j in range(2):
            ok, (lo, hi) = _inside(ys[:, k, :, j].var(axis=0, ddof=1), n_paths, want[:, j, j])
            assert ok, (eta, j, lo, want[:, j, j], hi)


# --------------------------------------------------------------------------- half-car


def test_halfcar_free_modes_are_rigid_motions():
    # Independent check of R: the linearised force-driven vector field (jacfwd of the model's own
    # code) has no stiffness or damping along the rigid motions.
    from jaxdrift.models._halfcar import force_driven_rhs
    from jaxdrift.models._params import HalfCarParams

    p = HalfCarParams(a=1.3, m1=20.0)
    Mr, G, R = halfcar_free_modes(p)
    A = np.asarray(jax.jit(jax.jacfwd(lambda x: force_driven_rhs(0.0, x, p, 0.0, 0.0, linear=True)))(jnp.zeros(10)))
    # accelerations (rows 4..7) do not depend on rigid displacements or rigid velocities
    np.testing.assert_allclose(A[4:8, 0:4] @ R, 0.0, atol=1e-9)
    np.testing.assert_allclose(A[4:8, 4:8] @ R, 0.0, atol=1e-9)
    M = np.diag([20.0, 15.0, 750.0, 500.0])
    np.testing.assert_allclose(Mr, R.T @ M @ R)
    np.testing.assert_allclose(Mr[1, 1], 500.0 + 20.0 * 1.0 + 15.0 * 1.3**2)
    # Forces enter the accelerations as -1/m on z1, z2; projected: G = R^T B.
    Bf = np.asarray(jax.jit(jax.jacfwd(lambda f: force_driven_rhs(0.0, jnp.zeros(10), p, f[0], f[1], linear=True)))(jnp.zeros(2)))
    np.testing.assert_allclose(R.T @ M @ Bf[4:8], G, atol=1e-12)


def test_propagated_covariance_linear_halfcar_free_modes_exact():
    # In the linear model the mass-weighted rigid coordinates q = M_r^-1 R^T M z are exactly
    # double-integrated force noise, so the propagated covariance projected on them is the t^3 law
    # for every t (an asymmetric car, so heave and pitch are coupled through M_r).
    from jaxdrift.models._halfcar import equilibrium_forces, force_driven_rhs, static_equilibrium
    from jaxdrift.models._params import HalfCarParams

    p = HalfCarParams(a=1.3, m1=20.0)
    f1, f2, _, _ = equilibrium_forces(p)
    ts = np.array([0.5, 2.0, 6.0])
    # (The tyre rows have eigenvalue -k1/d1 = -1000 1/s, doubled in the covariance equation: a
    # fixed DOPRI5 step must stay below about 3.3 / 2000 s.)
    res = propagate_covariance(
        lambda t, x, u, args: force_driven_rhs(t, x, p, u[0], u[1], linear=True),
        static_equilibrium(p, "force", linear=True), 0.0, 6.0, saveat=ts,
        inputs=lambda t: jnp.array([f1, f2]), noise_sigma=32.0, noise_dt=1e-3, dt=1e-3,
    )
    Mr, G, R = halfcar_free_modes(p)
    L = np.linalg.solve(Mr, R.T @ np.diag([20.0, 15.0, 750.0, 500.0]))
    Pq = np.einsum("ij,tjk,lk->til", L, np.asarray(res.cov[:, :4, :4]), L)
    want = halfcar_free_mode_covariance(ts, p, sigma_m=32.0, dt=1e-3)
    np.testing.assert_allclose(Pq, want, rtol=1e-7)
    assert abs(want[0, 0, 1]) > 0.05 * np.sqrt(want[0, 0, 0] * want[0, 1, 1])  # coupled


def test_monte_carlo_halfcar_fast_mode_vs_float64_and_propagated():
    # Noisy forces around static equilibrium on the seed's (nonlinear) half-car, 1 ms DOPRI5:
    # (1) the float32 + Kahan fast mode on the same noise as the float64 engine: per-path
    #     differences far below the spread; (2) both ensembles' variances of z3 and beta contain the
    #     propagated (linearised) variance within the 99.9 % chi-square interval.
    from jaxdrift.models._halfcar import equilibrium_forces, force_driven_rhs, static_equilibrium
    from jaxdrift.models._params import HalfCarParams

    p = HalfCarParams()
    f1, f2, _, _ = equilibrium_forces(p)
    feq = jnp.array([f1, f2])
    x0 = static_equilibrium(p, "force")
    T, dt, sigma, n_paths = 2.0, 1e-3, 32.0, 200
    n = int(round(T / dt)) + 1
    ts = np.array([1.0, 2.0])
    key = jax.random.key(2024)

    def rhs(t, x, sig):
        f = sig(t)
        return force_driven_rhs(t, x, p, f[0], f[1])

    def path(i):
        u = feq + sigma * jaxdrift.path_normals(key, i, n, 2)
        y64 = jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=jaxdrift.SampledSignal(0.0, dt, u), dt=dt).ys
        sig32 = jaxdrift.SampledSignal(0.0, dt, u.astype(jnp.float32))
        y32 = jaxdrift.solve_fixed_fast(rhs, x0, 0.0, T, saveat=ts, args=sig32, dt=dt).ys
        return y64[:, 2:4], y32[:, 2:4]

    y64, y32 = (np.asarray(a, dtype=np.float64) for a in jax.jit(jax.vmap(path))(jnp.arange(n_paths)))
    spread = y64.std(axis=0)
    assert np.max(np.abs(y32 - y64) / spread) < 1e-3

    res = propagate_covariance(
        lambda t, x, u, args: force_driven_rhs(t, x, p, u[0], u[1]), x0, 0.0, T, saveat=ts,
        inputs=lambda t: feq, noise_sigma=sigma, noise_dt=dt, dt=dt,
    )
    want = np.asarray(res.var)[:, 2:4]
    for ys in (y64, y32):
        ok, (lo, hi) = _inside(ys.var(axis=0, ddof=1), n_paths, want)
        assert ok, (lo, want, hi)
    # At the static reference the free-mode law is the leading term of Var beta (elastic part small).
    free = halfcar_free_mode_covariance(ts, p, sigma_m=sigma, dt=dt)[:, 1, 1]
    np.testing.assert_allclose(want[:, 1], free, rtol=0.05)


# --------------------------------------------------------------------------- fast mode


def test_fast_mode_kahan_keeps_the_sum():
    # A constant small rate on a state of size 0.05 over 60,000 float32 steps: the plain update
    # loses the increment's low bits every step, the compensated one keeps the exact sum.
    T, dt = 60.0, 1e-3
    ts = np.array([0.0, 30.0, 60.0])
    f = lambda t, y, a: jnp.full_like(y, 1.234567e-4)
    y0 = jnp.array([0.05, 7.5e3])
    exact = np.asarray(y0, np.float64)[None] + 1.234567e-4 * ts[:, None]
    comp = np.asarray(jaxdrift.solve_fixed_fast(f, y0, 0.0, T, dt=dt, saveat=ts).ys, np.float64)
    plain = np.asarray(jaxdrift.solve_fixed_fast(f, y0, 0.0, T, dt=dt, saveat=ts, compensated=False).ys, np.float64)
    ulp = np.spacing(np.abs(exact).astype(np.float32)).astype(np.float64)
    assert np.all(np.abs(comp - exact) <= 2 * ulp)
    assert np.max(np.abs(plain - exact) / ulp) > 100


def test_fast_mode_float64_matches_engine_fixed_step():
    # Same tableau, same grid: the fast kernel in float64 reproduces solve_ode(dt=...) to rounding.
    f = lambda t, y, a: jnp.stack([y[1], -4.0 * y[0] - 0.3 * y[1] + jnp.sin(3.0 * t)])
    ts = np.linspace(0.0, 10.0, 11)
    ref = jaxdrift.solve_ode(f, jnp.array([1.0, 0.0]), 0.0, 10.0, saveat=ts, dt=0.01).ys
    got = jaxdrift.solve_fixed_fast(f, jnp.array([1.0, 0.0]), 0.0, 10.0, saveat=ts, dt=0.01, dtype=jnp.float64,
                                    compensated=False).ys
    np.testing.assert_allclose(np.asarray(got), np.asarray(ref), rtol=0, atol=1e-13)
    got32 = jaxdrift.solve_fixed_fast(f, jnp.array([1.0, 0.0]), 0.0, 10.0, saveat=ts, dt=0.01).ys
    assert got32.dtype == jnp.float32
    np.testing.assert_allclose(np.asarray(got32, np.float64), np.asarray(ref), atol=3e-6)


def test_fast_mode_rejects_off_grid_saves():
    f = lambda t, y, a: -y
    with pytest.raises(ValueError, match="step grid"):
        jaxdrift.solve_fixed_fast(f, jnp.ones(1), 0.0, 1.0, dt=0.1, saveat=[0.05, 0.55])
    with pytest.raises(ValueError, match="equally spaced"):
        jaxdrift.solve_fixed_fast(f, jnp.ones(1), 0.0, 1.0, dt=0.1, saveat=[0.1, 0.2, 0.5])
    with pytest.raises(ValueError, match="whole number"):
        jaxdrift.solve_fixed_fast(f, jnp.ones(1), 0.0, 1.05, dt=0.1, saveat=[0.1])


def test_fast_mode_inputs_on_the_grid_equal_sampled_signal():
    # inputs= (two samples read per step) gives the SampledSignal values at every stage.
    rng = np.random.default_rng(5)
    u = jnp.asarray(rng.normal(size=(201, 2)))
    f_sig = lambda t, y, sig: jnp.stack([y[1], -4.0 * y[0] + sig(t)[0] - 0.5 * sig(t)[1] * y[1]])
    f_u = lambda t, y, uu, a: jnp.stack([y[1], -4.0 * y[0] + uu[0] - 0.5 * uu[1] * y[1]])
    ts = np.linspace(0.0, 2.0, 5)
    y0 = jnp.array([1.0, 0.0])
    kw = dict(dt=0.01, saveat=ts, dtype=jnp.float64, compensated=False)
    a = jaxdrift.solve_fixed_fast(f_sig, y0, 0.0, 2.0, args=jaxdrift.SampledSignal(0.0, 0.01, u), **kw).ys
    b = jaxdrift.solve_fixed_fast(f_u, y0, 0.0, 2.0, inputs=u, **kw).ys
    np.testing.assert_allclose(np.asarray(b), np.asarray(a), rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="inputs must have shape"):
        jaxdrift.solve_fixed_fast(f_u, y0, 0.0, 2.0, inputs=u[:-1], **kw)
