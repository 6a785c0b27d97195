"""Section 3.1: rigid-body motion from an accelerometer array (six steps, (3.3), (3.6), (3.9))."""

import numpy as np
import pytest
from scipy import stats

from jaxdrift.models._accel_array import (
    angle_error_std_closed_form,
    check_positions,
    reconstruct,
    simulate_array,
)
from jaxdrift.studies._attgen import DEFAULT_POSITIONS
from jaxdrift.models._ins import vehicle_motion
from jaxdrift.models._quaternion import (
    quat_conjugate_np,
    quat_log_np,
    quat_multiply_np,
    rotation_angle_between_np,
)


def test_check_positions():
    assert check_positions(DEFAULT_POSITIONS) is None
    assert "at least 4" in check_positions(DEFAULT_POSITIONS[:3])
    assert "collinear" in check_positions([[0, 0, 0], [1, 1, 1], [2, 2, 2], [-1, -1, -1]])
    assert "coplanar" in check_positions([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]])
    assert "coplanar" in check_positions(DEFAULT_POSITIONS[:4])  # the four floor corners alone
    with pytest.raises(ValueError, match="coplanar"):
        reconstruct(np.zeros((10, 4, 3)), DEFAULT_POSITIONS[:4], 0.01)


def _truth(seed, duration, dt):
    m = vehicle_motion(seed, duration + 1.0, road_rms_deg=1.0, curve_rate=0.3)
    t = np.arange(int(round(duration / dt)) + 1) * dt
    q = m.quaternion(t)
    S = m.rotation_matrices(t)
    w = m.body_rates(t)
    wd = m.body_angular_acceleration(t)
    x, xdd = m.position_acceleration(t)
    v = np.gradient(x, dt, axis=0)  # only for the initial velocity
    return t, q, S, w, wd, x, xdd, m, v


def test_noise_free_reconstruction_recovers_the_motion():
    """Stated error, 20 s at 500 Hz, noise-free: rates < 2e-6 rad/s, attitude < 5e-5 rad, x_C < 0.02 m.

    (Measured: 7e-7 rad/s, 1.4e-5 rad, 9 mm; the position error is the attitude error projecting
    gravity, integrated twice.)
    """
    dt = 0.002
    t, q, S, w, wd, x, xdd, m, _ = _truth(3, 20.0, dt)
    r = DEFAULT_POSITIONS
    acc = simulate_array(S, w, wd, xdd, r)
    # initial velocity: exact, from the analytic path
    yaw, yawd = m.angles(t[:1])[0][0, 2], 0.0
    s0 = m._sines(m.speed_terms, t[:1])[0][0] + m.v0
    z = m._sines(m.heave_terms, t[:1])[1][0]
    v0 = [s0 * np.cos(yaw), s0 * np.sin(yaw), z]
    out = reconstruct(acc, r, dt, q0=q[0], omega0=w[0], x0=x[0], v0=v0)
    assert np.max(np.abs(out["omega"] - w)) < 2e-6
    assert np.max(rotation_angle_between_np(out["q"], q)) < 5e-5
    assert np.max(np.linalg.norm(out["xc"] - x, axis=1)) < 0.02
    np.testing.assert_allclose(out["x_sensors"][:, 2], x + np.einsum("nab,b->na", S, r[2]), atol=0.02)
    # rigid body, correct positions: the consistency condition of (3.6) holds (M+ = w~ w~)
    assert np.max(np.abs(out["consistency"])) < 2e-6
    # a misplaced sensor breaks it (placement check)
    r_bad = r.copy()
    r_bad[1] += [0.05, 0.0, 0.0]
    out_bad = reconstruct(acc, r_bad, dt, q0=q[0], omega0=w[0], x0=x[0], v0=v0)
    assert np.sqrt(np.mean(out_bad["consistency"] ** 2)) > 100 * np.sqrt(np.mean(out["consistency"] ** 2))


def test_gravity_correction_cancels_in_relative_accelerations():
    """(3.3): a tilted body at rest reads g e3 - S^T g e3 on every sensor; M = A R^+ = 0."""
    from jaxdrift.models._accel_array import m_matrix
    from jaxdrift.models._quaternion import euler_to_quat_np, rotation_matrix_np

    S = rotation_matrix_np(euler_to_quat_np(np.array([[0.1, -0.2, 0.7]])))
    acc = simulate_array(S, np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((1, 3)), DEFAULT_POSITIONS)
    np.testing.assert_allclose(acc[0], np.broadcast_to(9.81 * (np.array([0, 0, 1.0]) - S[0].T @ [0, 0, 1.0]), (5, 3)), atol=1e-14)
    np.testing.assert_allclose(m_matrix(acc, DEFAULT_POSITIONS), 0.0, atol=1e-13)


def test_angle_error_grows_like_two_integrations():
    """White accelerometer noise, body at rest: angle errors are integrated random walks,
    Var = s_j^2 dt t^3 / 3 per axis (closed form), checked with chi-square bounds; slope 3/2."""
    dt, T, n_paths, s_a = 0.005, 10.0, 200, 0.01
    n = int(round(T / dt)) + 1
    r = DEFAULT_POSITIONS
    rng = np.random.default_rng(42)
    checks = np.array([n // 4, n // 2, n - 1])
    errs = np.empty((n_paths, len(checks), 3))
    for p in range(n_paths):
        acc = rng.normal(size=(n, r.shape[0], 3)) * s_a
        out = reconstruct(acc, r, dt)
        errs[p] = quat_log_np(out["q"][checks])
    tt = checks * dt
    sd = angle_error_std_closed_form(s_a, r, dt, tt)  # (3 times, 3 axes)
    v = np.mean(errs**2, axis=0) / sd**2  # should be ~ chi2(n_paths)/n_paths
    lo = stats.chi2.ppf(0.0005, n_paths) / n_paths
    hi = stats.chi2.ppf(0.9995, n_paths) / n_paths
    # the discrete trapezoid/midpoint integration differs from the continuous form by O(dt/t)
    assert np.all((v > lo * 0.97) & (v < hi * 1.03)), v
    slope = np.polyfit(np.log(tt), np.log(np.sqrt(np.mean(errs**2, axis=(0, 2)))), 1)[0]
    assert abs(slope - 1.5) < 0.1


def test_high_pass_cutoff_trades_drift_against_motion():
    """Remark 2: with noisy sensors a moderate cut-off removes the drift of roll/pitch, a high one the motion."""
    dt, T = 0.005, 60.0
    t, q, S, w, wd, x, xdd, m, _ = _truth(8, T, dt)
    r = DEFAULT_POSITIONS
    rng = np.random.default_rng(3)
    acc = simulate_array(S, w, wd, xdd, r) + rng.normal(size=(len(t), r.shape[0], 3)) * 0.02
    true_ang = m.angles(t)[0]

    def rp_error(**hp):
        out = reconstruct(acc, r, dt, q0=q[0], omega0=w[0], **hp)
        d = np.angle(np.exp(1j * (out["angles"][:, :2] - true_ang[:, :2])))
        return float(np.sqrt(np.mean(d**2)))

    e_none = rp_error()
    e_low = rp_error(highpass_omega=0.01, highpass_angles=0.01)
    e_mid = rp_error(highpass_omega=0.3, highpass_angles=0.3)
    e_high = rp_error(highpass_omega=3.0, highpass_angles=3.0)
    assert e_mid < 0.25 * e_none
    assert e_high > 1.5 * e_mid and e_low > 2 * e_mid
