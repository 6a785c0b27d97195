"""Quaternion kinematics of the seed's section 3.2: S(q) (3.7), Omega_l (3.8), B_j (3.12).

Conventions (the seed's): ``q = [q1, q2, q3, q4]`` scalar first, ``S(q)`` maps body (local)
coordinates to global ones, ``omega_l`` is the angular rate in the body frame, so that
``S' = S skew(omega_l)`` and ``q' = 0.5 Omega_l(omega_l) q``. ``Omega_l(w) q`` is the Hamilton
product ``q (x) [0, w]``, and ``B_j = Omega_l(e_j)``.

Integrators of (3.8) on sampled rates (``omega[k]`` held over ``[t_k, t_k + dt)``):

- ``"euler"``: ``q + 0.5 dt Omega q``; ``|q|^2`` grows by exactly ``1 + |omega|^2 dt^2 / 4`` per
  step (the Ito growth of (3.14) when the rates carry white noise),
- ``"expmap"``: ``q (x) exp(omega dt / 2)``, exact for a rate constant over the step, keeps ``|q|``,
- ``"dopri5"``: the engine's :func:`jaxdrift.solve_ode` on the linearly interpolated rates (the
  paper's DOPRI(4,5) reconstruction).

SDE (3.11)/(3.13) paths: Euler-Maruyama (Ito, the explicit Euler scheme on noisy samples), stochastic
Heun (Stratonovich) through the engine's :func:`jaxdrift.solve_sde`, and the exponential map of the
noisy increments (Stratonovich, norm-preserving). Closed forms for the studies are here too.

JAX functions take and return ``jnp`` arrays and batch with ``vmap``; the ``*_np`` helpers are plain
numpy for data processing (long measured runs) and do not depend on the x64 flag.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

__all__ = [
    "B_MATRICES",
    "skew",
    "rotation_matrix",
    "omega_matrix",
    "quat_multiply",
    "quat_conjugate",
    "quat_exp",
    "euler_step",
    "expmap_step",
    "quat_to_euler",
    "euler_to_quat",
    "rotation_angle_between",
    "ito_norm_growth",
    "euler_norm_growth",
    "angle_error_std",
]

# (3.12): the imaginary units, B_j = Omega_l(e_j); B_j^2 = -I_4 (3.15).
B_MATRICES = np.array(
    [
        [[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 0, 1], [0, 0, -1, 0]],
        [[0, 0, -1, 0], [0, 0, 0, -1], [1, 0, 0, 0], [0, 1, 0, 0]],
        [[0, 0, 0, -1], [0, 0, 1, 0], [0, -1, 0, 0], [1, 0, 0, 0]],
    ],
    dtype=float,
)


# --------------------------------------------------------------------------- JAX kinematics


def skew(w):
    """The skew-symmetric matrix ``w~`` of (3.5): ``skew(w) @ v = cross(w, v)``. Batches over leading axes."""
    w = jnp.asarray(w)
    z = jnp.zeros_like(w[..., 0])
    return jnp.stack(
        [
            jnp.stack([z, -w[..., 2], w[..., 1]], -1),
            jnp.stack([w[..., 2], z, -w[..., 0]], -1),
            jnp.stack([-w[..., 1], w[..., 0], z], -1),
        ],
        -2,
    )


def rotation_matrix(q):
    """``S(q)`` of (3.7), body to global; ``q`` scalar first (need not be normalised, as in (3.7))."""
    q = jnp.asarray(q)
    q1, q2, q3, q4 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return jnp.stack(
        [
            jnp.stack([q1**2 + q2**2 - q3**2 - q4**2, 2 * (q2 * q3 - q1 * q4), 2 * (q2 * q4 + q1 * q3)], -1),
            jnp.stack([2 * (q2 * q3 + q1 * q4), q1**2 - q2**2 + q3**2 - q4**2, 2 * (q3 * q4 - q1 * q2)], -1),
            jnp.stack([2 * (q2 * q4 - q1 * q3), 2 * (q3 * q4 + q1 * q2), q1**2 - q2**2 - q3**2 + q4**2], -1),
        ],
        -2,
    )


def omega_matrix(w):
    """``Omega_l`` of (3.8): ``[[0, -w^T], [w, -skew(w)]]``, so that ``q' = 0.5 Omega_l q``."""
    w = jnp.asarray(w)
    top = jnp.concatenate([jnp.zeros_like(w[..., :1]), -w], -1)[..., None, :]
    bottom = jnp.concatenate([w[..., :, None], -skew(w)], -1)
    return jnp.concatenate([top, bottom], -2)


def quat_multiply(p, q):
    """Hamilton product ``p (x) q`` (scalar first); ``S(p (x) q) = S(p) S(q)``."""
    p, q = jnp.asarray(p), jnp.asarray(q)
    pw, pv = p[..., :1], p[..., 1:]
    qw, qv = q[..., :1], q[..., 1:]
    w = pw * qw - jnp.sum(pv * qv, -1, keepdims=True)
    v = pw * qv + qw * pv + jnp.cross(pv, qv)
    return jnp.concatenate([w, v], -1)


def quat_conjugate(q):
    q = jnp.asarray(q)
    return q * jnp.array([1.0, -1.0, -1.0, -1.0], dtype=q.dtype)


def quat_exp(v):
    """Unit quaternion of the rotation vector ``v`` (angle ``|v|`` about ``v/|v|``): ``[cos(|v|/2), sin(|v|/2) v/|v|]``."""
    v = jnp.asarray(v)
    a = jnp.sqrt(jnp.sum(v * v, -1, keepdims=True))
    half = 0.5 * a
    # sin(a/2)/a, with its series near 0 (the double-where keeps gradients finite)
    safe = jnp.where(a > 1e-8, a, 1.0)
    sinc = jnp.where(a > 1e-8, jnp.sin(0.5 * safe) / safe, 0.5 - a * a / 48.0)
    return jnp.concatenate([jnp.cos(half), sinc * v], -1)


def euler_step(q, w, dt):
    """One explicit Euler step of (3.8): ``q + 0.5 dt Omega_l(w) q``."""
    return q + 0.5 * dt * (omega_matrix(w) @ q[..., None])[..., 0]


def expmap_step(q, w, dt):
    """One exponential-map step ``expm(0.5 dt Omega_l(w)) q = q (x) exp(w dt)``: exact for constant ``w``."""
    return quat_multiply(q, quat_exp(w * dt))


def quat_to_euler(q):
    """Cardan angles ``(roll, pitch, yaw)`` of ``S(q) = Rz(yaw) Ry(pitch) Rx(roll)`` (q normalised first)."""
    q = jnp.asarray(q)
    q = q / jnp.linalg.norm(q, axis=-1, keepdims=True)
    S = rotation_matrix(q)
    roll = jnp.arctan2(S[..., 2, 1], S[..., 2, 2])
    pitch = jnp.arcsin(jnp.clip(-S[..., 2, 0], -1.0, 1.0))
    yaw = jnp.arctan2(S[..., 1, 0], S[..., 0, 0])
    return jnp.stack([roll, pitch, yaw], -1)


def euler_to_quat(angles):
    """Inverse of :func:`quat_to_euler`: ``q = qz(yaw) (x) qy(pitch) (x) qx(roll)``."""
    a = jnp.asarray(angles)
    z = jnp.zeros_like(a[..., 0])
    qx = quat_exp(jnp.stack([a[..., 0], z, z], -1))
    qy = quat_exp(jnp.stack([z, a[..., 1], z], -1))
    qz = quat_exp(jnp.stack([z, z, a[..., 2]], -1))
    return quat_multiply(qz, quat_multiply(qy, qx))


def rotation_angle_between(q_a, q_b):
    """Angle [rad] of the rotation ``S(q_a)^T S(q_b)`` (both normalised first), in ``[0, pi]``."""
    q_a = jnp.asarray(q_a)
    q_b = jnp.asarray(q_b)
    q_a = q_a / jnp.linalg.norm(q_a, axis=-1, keepdims=True)
    q_b = q_b / jnp.linalg.norm(q_b, axis=-1, keepdims=True)
    d = quat_multiply(quat_conjugate(q_a), q_b)
    return 2.0 * jnp.arctan2(jnp.linalg.norm(d[..., 1:], axis=-1), jnp.abs(d[..., 0]))


# --------------------------------------------------------------------------- closed forms


def ito_norm_growth(sigma, t, n_axes: int = 1):
    """``|q(t)|`` of the Ito SDE (3.11)/(3.13) with ``n_axes`` noisy axes: ``exp(n_axes sigma^2 t / 8)``.

    For one axis this is the prefactor of (3.14); with three, ``d|q|^2 = (3 sigma^2/4) |q|^2 dt``
    (the ``B_j q`` are orthogonal to ``q`` and to each other), so the growth is deterministic.
    """
    return np.exp(n_axes * np.asarray(sigma) ** 2 * np.asarray(t) / 8.0)


def euler_norm_growth(sigma, dt, n_steps, n_axes: int = 1):
    """``E |q_n|^2`` of Euler-Maruyama on (3.13): exactly ``(1 + n_axes sigma^2 dt / 4)^n``.

    (Each step multiplies ``|q|^2`` by ``1 + sigma^2 |dW|^2 / 4``.) Tends to ``exp(n_axes sigma^2 t/4)``.
    """
    return (1.0 + n_axes * sigma**2 * dt / 4.0) ** np.asarray(n_steps)


def angle_error_std(sigma, t):
    """Standard deviation of the spurious rotation angle about a noisy axis: ``sigma sqrt(t)`` (3.16).

    ``sigma`` is the Brownian intensity of the rate noise; for white samples of standard deviation
    ``sigma_M`` at interval ``dt`` it is ``sigma_M sqrt(dt)`` (2.5).
    """
    return sigma * np.sqrt(np.asarray(t))


# --------------------------------------------------------------------------- numpy helpers


def skew_np(w):
    w = np.asarray(w, float)
    z = np.zeros_like(w[..., 0])
    return np.stack(
        [
            np.stack([z, -w[..., 2], w[..., 1]], -1),
            np.stack([w[..., 2], z, -w[..., 0]], -1),
            np.stack([-w[..., 1], w[..., 0], z], -1),
        ],
        -2,
    )


def quat_multiply_np(p, q):
    p = np.asarray(p, float)
    q = np.asarray(q, float)
    p0, p1, p2, p3 = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
            p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
            p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
            p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0,
        ],
        -1,
    )


def quat_conjugate_np(q):
    return np.asarray(q, float) * np.array([1.0, -1.0, -1.0, -1.0])


def quat_exp_np(v):
    v = np.asarray(v, float)
    a = np.sqrt(np.sum(v * v, -1, keepdims=True))
    with np.errstate(invalid="ignore", divide="ignore"):
        sinc = np.where(a > 1e-8, np.sin(0.5 * a) / np.where(a > 0, a, 1.0), 0.5 - a * a / 48.0)
    return np.concatenate([np.cos(0.5 * a), sinc * v], -1)


def quat_log_np(q):
    """Rotation vector of a unit quaternion (the shorter rotation: sign of ``q`` ignored)."""
    q = np.asarray(q, float)
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
    vn = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    ang = 2.0 * np.arctan2(vn, q[..., :1])
    with np.errstate(invalid="ignore", divide="ignore"):
        f = np.where(vn > 1e-12, ang / np.where(vn > 0, vn, 1.0), 2.0 / np.maximum(q[..., :1], 1e-300))
    return f * q[..., 1:]


def rotation_matrix_np(q):
    q = np.asarray(q, float)
    q1, q2, q3, q4 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            np.stack([q1**2 + q2**2 - q3**2 - q4**2, 2 * (q2 * q3 - q1 * q4), 2 * (q2 * q4 + q1 * q3)], -1),
            np.stack([2 * (q2 * q3 + q1 * q4), q1**2 - q2**2 + q3**2 - q4**2, 2 * (q3 * q4 - q1 * q2)], -1),
            np.stack([2 * (q2 * q4 - q1 * q3), 2 * (q3 * q4 + q1 * q2), q1**2 - q2**2 - q3**2 + q4**2], -1),
        ],
        -2,
    )


def cumulative_quat_product_np(d):
    """Prefix products ``P[k] = d[0] (x) d[1] (x) ... (x) d[k]`` by log-depth doubling (numpy, O(n log n))."""
    P = np.array(d, float, copy=True)
    n = P.shape[0]
    s = 1
    while s < n:
        P[s:] = quat_multiply_np(P[:-s], P[s:])
        s *= 2
    return P


def integrate_rates_np(q0, omega, dt):
    """Exponential-map integration (rate held over each step) in numpy: ``(n, 4)``, ``q[0] = q0``.

    ``q[k] = q0 (x) exp(omega_0 dt) (x) ... (x) exp(omega_{k-1} dt)``; the prefix product is computed
    by doubling, so a 600,000-sample run takes well under a second. Renormalised at the end.
    """
    omega = np.asarray(omega, float)
    d = quat_exp_np(omega[:-1] * dt)
    P = cumulative_quat_product_np(np.concatenate([np.asarray(q0, float)[None], d], 0))
    return P / np.linalg.norm(P, axis=-1, keepdims=True)


def rotation_angle_between_np(q_a, q_b):
    q_a = np.asarray(q_a, float)
    q_b = np.asarray(q_b, float)
    q_a = q_a / np.linalg.norm(q_a, axis=-1, keepdims=True)
    q_b = q_b / np.linalg.norm(q_b, axis=-1, keepdims=True)
    d = quat_multiply_np(quat_conjugate_np(q_a), q_b)
    return 2.0 * np.arctan2(np.linalg.norm(d[..., 1:], axis=-1), np.abs(d[..., 0]))


def quat_to_euler_np(q):
    q = np.asarray(q, float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    S = rotation_matrix_np(q)
    return np.stack(
        [np.arctan2(S[..., 2, 1], S[..., 2, 2]), np.arcsin(np.clip(-S[..., 2, 0], -1, 1)), np.arctan2(S[..., 1, 0], S[..., 0, 0])],
        -1,
    )


def euler_to_quat_np(angles):
    a = np.asarray(angles, float)
    z = np.zeros_like(a[..., 0])
    qx = quat_exp_np(np.stack([a[..., 0], z, z], -1))
    qy = quat_exp_np(np.stack([z, a[..., 1], z], -1))
    qz = quat_exp_np(np.stack([z, z, a[..., 2]], -1))
    return quat_multiply_np(qz, quat_multiply_np(qy, qx))

