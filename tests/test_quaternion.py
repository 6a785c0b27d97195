"""Quaternion kinematics (3.7), (3.8), (3.12) and the SDE (3.11)/(3.13) against closed forms."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg
from scipy import stats
from scipy.spatial.transform import Rotation

from jaxdrift.models import _quaternion as Q
from jaxdrift.analysis._attitude_paths import integrate_rates, quaternion_sde_paths

RNG = np.random.default_rng(20261122)


def _unit_quats(n):
    q = RNG.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_rotation_matrix_matches_scipy_and_is_orthonormal():
    q = _unit_quats(50)
    S = np.asarray(Q.rotation_matrix(q))
    S_ref = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()  # scipy: scalar last, active, body->global
    np.testing.assert_allclose(S, S_ref, atol=1e-14)
    np.testing.assert_allclose(S @ np.swapaxes(S, 1, 2), np.broadcast_to(np.eye(3), S.shape), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(S), 1.0, atol=1e-13)
    np.testing.assert_allclose(Q.rotation_matrix_np(q), S, atol=1e-15)


def test_omega_matrix_is_right_product_and_B_are_imaginary_units():
    q = _unit_quats(10)
    w = RNG.normal(size=(10, 3))
    lhs = np.einsum("nab,nb->na", np.asarray(Q.omega_matrix(w)), q)
    rhs = np.asarray(Q.quat_multiply(q, np.concatenate([np.zeros((10, 1)), w], 1)))
    np.testing.assert_allclose(lhs, rhs, atol=1e-14)
    Om = np.asarray(Q.omega_matrix(w))
    np.testing.assert_allclose(Om, -np.swapaxes(Om, 1, 2), atol=0)  # skew: |q| is kept by (3.8)
    for j in range(3):
        B = Q.B_MATRICES[j]
        np.testing.assert_array_equal(np.asarray(Q.omega_matrix(np.eye(3)[j])), B)
        np.testing.assert_array_equal(B @ B, -np.eye(4))  # (3.15)
        lam = 0.37
        np.testing.assert_allclose(scipy.linalg.expm(lam * B), np.cos(lam) * np.eye(4) + np.sin(lam) * B, atol=1e-14)
    # B_i q, B_j q, q mutually orthogonal (basis of the Ito norm growth)
    q0 = q[0]
    V = np.stack([q0] + [Q.B_MATRICES[j] @ q0 for j in range(3)])
    np.testing.assert_allclose(V @ V.T, np.eye(4), atol=1e-14)


def test_quaternion_ode_reproduces_S_dot_equals_S_skew_omega():
    """(3.5)/(3.8): along q' = 0.5 Omega q, S(q)' = S(q) skew(omega) (central differences)."""
    q = _unit_quats(1)[0]
    w = np.array([0.4, -1.3, 0.8])
    h = 1e-5
    qp = np.asarray(Q.expmap_step(q, w, h))
    qm = np.asarray(Q.expmap_step(q, w, -h))
    Sdot = (Q.rotation_matrix_np(qp) - Q.rotation_matrix_np(qm)) / (2 * h)
    np.testing.assert_allclose(Sdot, Q.rotation_matrix_np(q) @ Q.skew_np(w), atol=1e-9)


def test_expmap_exact_euler_first_order_dopri_accurate():
    q0 = _unit_quats(1)[0]
    w = np.array([0.7, -0.2, 1.1])
    T = 2.0
    exact = scipy.linalg.expm(0.5 * T * np.asarray(Q.omega_matrix(w))) @ q0
    n = 200
    qs = np.asarray(integrate_rates(q0, np.tile(w, (n + 1, 1)), T / n, method="expmap"))
    np.testing.assert_allclose(qs[-1], exact, atol=1e-13)
    np.testing.assert_allclose(np.linalg.norm(qs, axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(Q.integrate_rates_np(q0, np.tile(w, (n + 1, 1)), T / n)[-1], exact, atol=1e-12)
    # Euler: |q|^2 grows by exactly (1 + |w|^2 dt^2 / 4) per step (FIELD-NOTES), error O(dt)
    errs = []
    for n in (100, 200, 400):
        dt = T / n
        qe = np.asarray(integrate_rates(q0, np.tile(w, (n + 1, 1)), dt, method="euler"))
        np.testing.assert_allclose(np.sum(qe[-1] ** 2), (1 + w @ w * dt**2 / 4) ** n, rtol=1e-12)
        errs.append(np.linalg.norm(qe[-1] - exact))
    qr = np.asarray(integrate_rates(q0, np.tile(w, (401, 1)), T / 400, method="euler", renormalize=True))
    np.testing.assert_allclose(np.linalg.norm(qr, axis=1), 1.0, atol=1e-14)
    slope = np.polyfit(np.log([100, 200, 400]), np.log(errs), 1)[0]
    assert -1.1 < slope < -0.9
    qd = np.asarray(integrate_rates(q0, np.tile(w, (201, 1)), T / 200, method="dopri5", rtol=1e-10, atol=1e-12))
    np.testing.assert_allclose(qd[-1], exact, atol=1e-8)


def test_numpy_helpers_agree_with_jax():
    q = _unit_quats(20)
    p = _unit_quats(20)
    np.testing.assert_allclose(Q.quat_multiply_np(p, q), np.asarray(Q.quat_multiply(p, q)), atol=1e-15)
    v = RNG.normal(size=(20, 3))
    np.testing.assert_allclose(Q.quat_exp_np(v), np.asarray(Q.quat_exp(v)), atol=1e-15)
    np.testing.assert_allclose(Q.quat_log_np(Q.quat_exp_np(v * 0.5)), v * 0.5, atol=1e-12)
    ang = np.stack([RNG.uniform(-3, 3, 20), RNG.uniform(-1.5, 1.5, 20), RNG.uniform(-3, 3, 20)], 1)
    np.testing.assert_allclose(Q.quat_to_euler_np(Q.euler_to_quat_np(ang)), ang, atol=1e-12)
    np.testing.assert_allclose(np.asarray(Q.quat_to_euler(Q.euler_to_quat(ang))), ang, atol=1e-12)
    # the doubling prefix product equals the sequential scan
    w = RNG.normal(size=(1000, 3))
    np.testing.assert_allclose(Q.integrate_rates_np(q[0], w, 1e-3), np.asarray(integrate_rates(q[0], w, 1e-3)), atol=1e-13)
    a = np.asarray(Q.rotation_angle_between(q, p))
    np.testing.assert_allclose(a, Q.rotation_angle_between_np(q, p), atol=1e-14)
    ref = (Rotation.from_quat(q[:, [1, 2, 3, 0]]).inv() * Rotation.from_quat(p[:, [1, 2, 3, 0]])).magnitude()
    np.testing.assert_allclose(a, ref, atol=1e-12)


SIG, T1, DT, NP = 0.5, 2.0, 0.004, 400


@pytest.fixture(scope="module")
def single_axis_paths():
    key = jax.random.key(7)
    out = {}
    for scheme in ("euler_maruyama", "heun", "expmap"):
        out[scheme] = quaternion_sde_paths(key, NP, T1, DT, SIG, scheme=scheme, axes=(0,), n_save=11)
    return out


def test_ito_norm_growth_under_euler_maruyama(single_axis_paths):
    """(3.14): Euler-Maruyama on (3.13) grows |q| like exp(sigma^2 t / 8); paths follow (3.14)."""
    ts, qs, W = (np.asarray(a) for a in single_axis_paths["euler_maruyama"])
    n2 = np.sum(qs[:, -1] ** 2, -1)
    n_steps = int(round(T1 / DT))
    exact_mean = Q.euler_norm_growth(SIG, DT, n_steps)  # E|q_n|^2, exact for the scheme
    se = n2.std(ddof=1) / np.sqrt(NP)
    assert abs(n2.mean() - exact_mean) < 4 * se
    # the scheme's growth is the Ito one up to O(dt): exp(sigma^2 t/4) for |q|^2
    assert abs(exact_mean / Q.ito_norm_growth(SIG, T1) ** 2 - 1) < 1e-3
    # and it is far from 1 (the test can fail if the scheme kept the norm)
    assert n2.mean() - 1 > 20 * se
    # path by path against the closed form (3.14) (strong error O(sqrt dt))
    th = 0.5 * SIG * W[:, :, 0]
    closed = Q.ito_norm_growth(SIG, ts)[None, :, None] * np.stack([np.cos(th), np.sin(th), 0 * th, 0 * th], -1)
    assert np.mean(np.abs(qs - closed)) < 0.01


def test_stratonovich_schemes_keep_the_norm(single_axis_paths):
    ts, qs, W = (np.asarray(a) for a in single_axis_paths["expmap"])
    np.testing.assert_allclose(np.linalg.norm(qs, axis=-1), 1.0, atol=1e-12)
    th = 0.5 * SIG * W[:, :, 0]
    np.testing.assert_allclose(qs, np.stack([np.cos(th), np.sin(th), 0 * th, 0 * th], -1), atol=1e-10)
    ts, qh, Wh = (np.asarray(a) for a in single_axis_paths["heun"])
    # Heun multiplies |q|^2 by 1 + a^4/4, a = sigma dW/2: E growth 3 sigma^4 t dt / 64 -> 0 with dt
    growth = np.mean(np.sum(qh[:, -1] ** 2, -1)) - 1
    assert 0 < growth < 3 * 3 * SIG**4 * T1 * DT / 64
    th = 0.5 * SIG * Wh[:, :, 0]
    assert np.max(np.abs(qh - np.stack([np.cos(th), np.sin(th), 0 * th, 0 * th], -1))) < 5e-3


def test_angle_error_std_grows_like_sigma_sqrt_t():
    """Three noisy axes, moving body (3.11): each axis' error angle ~ sigma W(t), chi-square bounds."""
    sig, t1, dt, n_paths = 0.02, 4.0, 0.01, 500
    n_steps = int(round(t1 / dt))
    tt = np.arange(n_steps) * dt
    omega = np.stack([0.3 * np.sin(2 * tt), 0.2 * np.cos(3 * tt), 0.5 + 0.0 * tt], 1)
    key = jax.random.key(11)
    ts, qs, _ = quaternion_sde_paths(key, n_paths, t1, dt, sig, scheme="expmap", omega=omega, n_save=5)
    _, q_true, _ = quaternion_sde_paths(key, 1, t1, dt, 0.0, scheme="expmap", omega=omega, n_save=5)
    qs = np.asarray(qs)
    q_true = np.asarray(q_true)[0]
    # error rotation in the body frame: S_true^T S_noisy
    err = Q.quat_log_np(Q.quat_multiply_np(Q.quat_conjugate_np(q_true)[None], qs))
    lo = stats.chi2.ppf(0.0005, n_paths) / n_paths
    hi = stats.chi2.ppf(0.9995, n_paths) / n_paths
    for k in (2, 4):
        v = np.mean(err[:, k] ** 2, axis=0) / Q.angle_error_std(sig, ts[k]) ** 2
        assert np.all((lo < v) & (v < hi)), (k, v, lo, hi)
