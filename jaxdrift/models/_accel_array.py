"""Rigid-body motion from an array of triaxial accelerometers: the seed's section 3.1.

Sensor ``i`` at body position ``r_i`` measures, after the sensor's own gravity correction (3.3),
``a_i = S^T x_i'' + g e3 - S^T g e3`` (z down). With ``A = [a_i - a_{m+1}]`` and
``R = [r_i - r_{m+1}]``, ``M = A R^+ = S^T S'' = omega~' + omega~ omega~`` (3.4)-(3.6).

The six steps of the seed's summary (:func:`reconstruct`):

1. ``M_- = (M - M^T) / 2`` (the angular acceleration ``omega~'``),
2. ``omega_l`` by integrating ``M_-`` (cubic step averages, 4th order), optionally high-pass filtered (remark 2),
3. ``q`` by integrating ``q' = 0.5 Omega_l q`` (exponential map of the step-averaged rate),
   optionally high-pass filtering the Cardan angles afterwards (remark 2),
4. ``S = S(q)`` (3.7),
5. ``x_C''`` by the average (3.9), ``x_C`` by two integrations (same rule),
6. ``x_i = x_C + S r_i`` (3.1).

``M_+ - omega~ omega~`` (the consistency condition of (3.6)) is returned as a rigidity and
sensor-placement check. Noise on the accelerations enters ``omega_l`` as a random walk and the angles
as an integrated random walk: angle errors grow like ``t^(3/2)`` (two integrations), against
``t^(1/2)`` for measured rates (:func:`angle_error_std_closed_form`).
"""

from __future__ import annotations

import numpy as np

from ._quaternion import (
    euler_to_quat_np,
    integrate_rates_np,
    quat_to_euler_np,
    rotation_matrix_np,
    skew_np,
)

__all__ = [
    "check_positions",
    "simulate_array",
    "reconstruct",
    "consistency_residual",
    "omega_dot_noise_matrix",
    "angle_error_std_closed_form",
]

G = 9.81
E3 = np.array([0.0, 0.0, 1.0])


def check_positions(r) -> str | None:
    """``None`` if the positions make ``R`` of full rank 3 with at least 4 sensors, else the reason."""
    r = np.asarray(r, float)
    if r.ndim != 2 or r.shape[1] != 3:
        return f"positions must have shape (N, 3), got {r.shape}"
    if r.shape[0] < 4:
        return f"{r.shape[0]} sensor(s); the array needs at least 4 (m + 1 >= 4, section 3.1)"
    R = (r[:-1] - r[-1]).T
    s = np.linalg.svd(R, compute_uv=False)
    scale = max(s[0], 1e-300)
    rank = int(np.sum(s > 1e-6 * scale)) if s[0] > 0 else 0
    if rank < 3:
        what = {0: "all at one point", 1: "collinear", 2: "coplanar"}[rank]
        return (
            f"sensor positions are {what}: R = [r_i - r_N] has rank {rank} (singular values "
            f"{', '.join(f'{v:.3g}' for v in s)}), so A R^+ cannot determine S^T S'' (3.4); "
            "place at least one sensor off the plane of the others"
        )
    return None


def simulate_array(S, omega, omega_dot, xc_ddot, positions, g=G):
    """Gravity-corrected sensor readings (3.3) of a rigid body: ``(n, N, 3)``.

    Args:
        S: ``(n, 3, 3)`` body-to-global rotations; ``omega``, ``omega_dot``: ``(n, 3)`` body rates and
        their derivatives; ``xc_ddot``: ``(n, 3)`` global acceleration of the body origin; ``positions``
        ``(N, 3)`` body-frame sensor positions.
    """
    K = skew_np(omega_dot) + skew_np(omega) @ skew_np(omega)
    common = np.einsum("nji,nj->ni", S, xc_ddot - g * E3) + g * E3
    return common[:, None, :] + np.einsum("nij,kj->nki", K, np.asarray(positions, float))


def _pinv_R(positions):
    r = np.asarray(positions, float)
    msg = check_positions(r)
    if msg:
        raise ValueError(msg)
    R = (r[:-1] - r[-1]).T  # 3 x m
    return R, np.linalg.pinv(R)


def m_matrix(acc, positions):
    """``M = A R^+`` per sample, ``(n, 3, 3)`` (3.4)."""
    _, Rp = _pinv_R(positions)
    A = np.swapaxes(acc[:, :-1, :] - acc[:, -1:, :], 1, 2)  # (n, 3, m)
    return A @ Rp


def _vee(Mskew):
    return np.stack([Mskew[..., 2, 1], Mskew[..., 0, 2], Mskew[..., 1, 0]], -1)


def _highpass(x, dt, cutoff, order=2):
    from scipy.signal import butter, sosfiltfilt

    sos = butter(order, cutoff, btype="highpass", fs=1.0 / dt, output="sos")
    # even (mirror) padding over three time constants: no artificial jump at the ends, so a cut-off
    # far below 1/duration tends to removing the mean rather than to an edge transient
    padlen = int(min(x.shape[0] - 1, 3.0 / (cutoff * dt)))
    return sosfiltfilt(sos, x, axis=0, padtype="even", padlen=padlen)


def _step_average(y):
    """Average of the cubic interpolant of the samples over each step [t_k, t_k+1]: (n-1, ...).

    ``(-y_{k-1} + 13 y_k + 13 y_{k+1} - y_{k+2}) / 24`` (fourth order; the trapezoidal rule at the ends).
    """
    avg = 0.5 * (y[1:] + y[:-1])
    if len(y) >= 4:
        avg[1:-1] = (-y[:-3] + 13 * y[1:-2] + 13 * y[2:-1] - y[3:]) / 24.0
    return avg


def _cumint(y, dt, y0):
    """Cumulative integral of samples ``y`` from ``y0`` with the step averages of :func:`_step_average`."""
    out = np.empty_like(y)
    out[0] = y0
    out[1:] = y0 + np.cumsum(_step_average(y) * dt, 0)
    return out


def reconstruct(acc, positions, dt, *, q0=(1.0, 0.0, 0.0, 0.0), omega0=(0.0, 0.0, 0.0), x0=(0.0, 0.0, 0.0),
                v0=(0.0, 0.0, 0.0), g=G, highpass_omega=None, highpass_angles=None, highpass_position=None):
    """The six-step reconstruction of section 3.1 (see the module doc).

    Args:
        acc: ``(n, N, 3)`` gravity-corrected readings (3.3), N >= 4 non-coplanar sensors.
        positions: ``(N, 3)``.
        q0, omega0, x0, v0: initial attitude, body rate, position and velocity of the body origin.
        highpass_omega, highpass_angles, highpass_position: cut-off frequencies [Hz] of zero-phase
            2nd-order Butterworth high-pass filters (remarks 2 and 4); ``None``: no filter.

    Returns:
        dict with ``omega`` (n, 3), ``q`` (n, 4), ``S`` (n, 3, 3), ``angles`` (Cardan roll, pitch,
        yaw), ``xc`` (n, 3), ``x_sensors`` (n, N, 3), ``M_plus``, ``M_minus`` and ``consistency``
        (``M_+ - omega~ omega~``, (n, 3, 3)).
    """
    acc = np.asarray(acc, float)
    r = np.asarray(positions, float)
    M = m_matrix(acc, r)  # step 1
    Mm = 0.5 * (M - np.swapaxes(M, 1, 2))
    Mp = 0.5 * (M + np.swapaxes(M, 1, 2))
    omega = _cumint(_vee(Mm), dt, np.asarray(omega0, float))  # step 2
    if highpass_omega:
        omega = _highpass(omega, dt, highpass_omega)
    # step 3: exponential map of the step-averaged rate (keeps |q| = 1)
    w_step = np.concatenate([_step_average(omega), omega[-1:]], 0)
    q = integrate_rates_np(np.asarray(q0, float), w_step, dt)
    angles = quat_to_euler_np(q)
    if highpass_angles:
        ang = np.unwrap(angles, axis=0)
        ang = _highpass(ang - ang[:1], dt, highpass_angles) + ang[:1]
        angles = ang
        q = euler_to_quat_np(ang)
    S = rotation_matrix_np(q)  # step 4
    # step 5: (3.9) with S'' = S M (both from the measurements)
    xdd = np.mean(np.einsum("nab,nkb->nka", S, acc - g * E3) + g * E3 - np.einsum("nab,nbc,kc->nka", S, M, r), axis=1)
    if highpass_position:
        xdd = _highpass(xdd, dt, highpass_position)
    v = _cumint(xdd, dt, np.asarray(v0, float))
    xc = _cumint(v, dt, np.asarray(x0, float))
    x_sensors = xc[:, None, :] + np.einsum("nab,kb->nka", S, r)  # step 6
    cons = consistency_residual(Mp, omega)
    return {"omega": omega, "q": q, "S": S, "angles": angles, "xc": xc, "x_sensors": x_sensors,
            "M_plus": Mp, "M_minus": Mm, "consistency": cons}


def consistency_residual(M_plus, omega):
    """``M_+ - omega~ omega~`` of (3.6): zero for a rigid body with correctly placed sensors."""
    W = skew_np(omega) @ skew_np(omega)
    return np.asarray(M_plus) - W


def omega_dot_noise_matrix(positions):
    """Linear map ``L`` (3 x 3N) from stacked sensor noise to the angular-acceleration estimate of step 1.

    With white accelerometer noise of standard deviation ``s`` per component, the estimate of
    ``omega_l'`` has covariance ``s^2 L L^T`` per sample.
    """
    r = np.asarray(positions, float)
    N = r.shape[0]
    L = np.zeros((3, 3 * N))
    for j in range(3 * N):
        e = np.zeros((1, N, 3))
        e[0, j // 3, j % 3] = 1.0
        M = m_matrix(e, r)[0]
        L[:, j] = _vee(0.5 * (M - M.T))
    return L


def angle_error_std_closed_form(accel_noise, positions, dt, t):
    """Std of each body-axis angle error for a (nearly) non-rotating body: ``s_j sqrt(dt) t^(3/2) / sqrt(3)``.

    ``s_j^2 = accel_noise^2 (L L^T)_jj``: white angular-acceleration noise integrated twice (an
    integrated random walk, variance ``sigma^2 t^3 / 3``). Returns ``(len(t), 3)``.
    """
    L = omega_dot_noise_matrix(positions)
    s = accel_noise * np.sqrt(np.diag(L @ L.T))
    t = np.asarray(t, float)
    return s[None, :] * np.sqrt(dt) * t[:, None] ** 1.5 / np.sqrt(3.0)
