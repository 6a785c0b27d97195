"""A plausible vehicle attitude history and gyro error models (the seed's section 3.2, Figs. 1-2).

The seed's Figs. 1-2 use 10 minutes of recorded INS data at 1000 Hz; we have none, so
:func:`vehicle_motion` makes a plausible one: road-induced pitch and roll (a sum of random
sinusoids at body-mode frequencies, 0.5-3 Hz, about half a degree RMS), roll and pitch leaning with
the lateral and longitudinal accelerations, and curves in yaw (smooth yaw-rate bumps of random sign,
a few seconds long, separated by straights). Everything is analytic in ``t``: Cardan angles, their
rates, the body rates (exact, not differentiated numerically), the reference point's position and
acceleration, so generated data have an exact truth.

Gyro error model (IEEE Std 952 terms), :func:`gyro_errors`:
``measured = scale * true + bias + b_rw(t) + b_inst(t) + white``, with white noise of angle random
walk ``N`` [rad/sqrt(s)] (sample standard deviation ``N / sqrt(dt)``), a constant bias, a rate random
walk of intensity ``K`` [rad/s/sqrt(s)] and bias instability ``B`` [rad/s] (a first-order
Gauss-Markov process with correlation time ``tau_c``, the usual stand-in for flicker noise).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ._quaternion import euler_to_quat_np, rotation_matrix_np

__all__ = ["SmoothMotion", "vehicle_motion", "gyro_errors"]


def _bump(t, t_c, w):
    """Raised-cosine bump of height 1 and half-width ``w`` centred at ``t_c``, and its integral."""
    u = np.clip((t - t_c) / w, -1.0, 1.0)
    f = 0.5 * (1.0 + np.cos(np.pi * u))
    F = 0.5 * w * (u + 1.0 + np.sin(np.pi * u) / np.pi)
    return f, F


@dataclasses.dataclass(frozen=True)
class SmoothMotion:
    """Analytic rigid-body motion: Cardan angles ``(roll, pitch, yaw)`` and reference-point path.

    ``roll`` and ``pitch`` are sums of sinusoids (amplitude, angular frequency, phase arrays);
    ``yaw`` is ``yaw0 + sum_c A_c * integral(bump)`` (curves). The reference point C moves with
    speed ``v(t) = v0 + sum of sinusoids`` along the heading, plus a vertical heave (sinusoids);
    z points down (gravity +g), as in the seed.
    """

    roll_terms: np.ndarray  # (k, 3): amplitude [rad], omega [rad/s], phase
    pitch_terms: np.ndarray
    curves: np.ndarray  # (c, 3): yaw-rate amplitude [rad/s], centre [s], half-width [s]
    yaw0: float
    v0: float
    speed_terms: np.ndarray  # (k, 3) for the speed [m/s]
    heave_terms: np.ndarray  # (k, 3) for the vertical position [m]

    @staticmethod
    def _sines(terms, t):
        a, w, p = terms[:, 0:1], terms[:, 1:2], terms[:, 2:3]
        ph = w * t[None] + p
        return (a * np.sin(ph)).sum(0), (a * w * np.cos(ph)).sum(0), (-a * w * w * np.sin(ph)).sum(0)

    def angles(self, t):
        """``(n, 3)`` roll, pitch, yaw and ``(n, 3)`` their time derivatives."""
        t = np.asarray(t, float)
        r, rd, _ = self._sines(self.roll_terms, t)
        p, pd, _ = self._sines(self.pitch_terms, t)
        y = np.full_like(t, self.yaw0)
        yd = np.zeros_like(t)
        for A, tc, w in self.curves:
            f, F = _bump(t, tc, w)
            y = y + A * F
            yd = yd + A * f
        return np.stack([r, p, y], 1), np.stack([rd, pd, yd], 1)

    def quaternion(self, t):
        return euler_to_quat_np(self.angles(t)[0])

    def body_rates(self, t):
        """Exact body-frame angular rate of ``S = Rz(yaw) Ry(pitch) Rx(roll)``."""
        (r, p, _), (rd, pd, yd) = (a.T for a in self.angles(t))
        return np.stack(
            [rd - yd * np.sin(p), pd * np.cos(r) + yd * np.cos(p) * np.sin(r), -pd * np.sin(r) + yd * np.cos(p) * np.cos(r)], 1
        )

    def body_angular_acceleration(self, t, h=1e-4):
        """``omega_l'`` by a 4th-order central difference of the analytic rates (error ~ h^4)."""
        t = np.asarray(t, float)
        w = [self.body_rates(t + k * h) for k in (-2, -1, 1, 2)]
        return (w[0] - 8 * w[1] + 8 * w[2] - w[3]) / (12 * h)

    def position_acceleration(self, t):
        """Global position ``x_C`` and acceleration ``x_C''`` of the reference point (heading-following path).

        The path is ``x' = v(t) [cos yaw, sin yaw, 0] + heave'``; its position is integrated by the
        trapezoidal rule on the given (fine) grid, the acceleration is exact.
        """
        t = np.asarray(t, float)
        (_, _, yaw), (_, _, yawd) = (a.T for a in self.angles(t))
        s, sd, _ = self._sines(self.speed_terms, t)
        v = self.v0 + s
        z, zd, zdd = self._sines(self.heave_terms, t)
        vel = np.stack([v * np.cos(yaw), v * np.sin(yaw), zd], 1)
        acc = np.stack(
            [sd * np.cos(yaw) - v * yawd * np.sin(yaw), sd * np.sin(yaw) + v * yawd * np.cos(yaw), zdd], 1
        )
        pos = np.zeros_like(vel)
        dt = np.diff(t)[:, None]
        pos[1:] = np.cumsum(0.5 * (vel[1:] + vel[:-1]) * dt, 0)
        pos[:, 2] = z
        return pos, acc

    def rotation_matrices(self, t):
        return rotation_matrix_np(self.quaternion(t))


def vehicle_motion(seed: int, duration: float = 600.0, *, road_rms_deg: float = 0.5, n_curves=None, speed=15.0,
                   curve_rate=0.15, static_until: float = 0.0) -> SmoothMotion:
    """A random plausible vehicle attitude history of ``duration`` seconds (see module doc).

    Args:
        seed: numpy seed.
        road_rms_deg: RMS of the road-induced pitch and roll [deg] each.
        n_curves: number of curves (default one per 30 s).
        speed: mean forward speed [m/s] (roll in curves ~ lateral acceleration v * yaw rate).
        curve_rate: typical peak yaw rate of a curve [rad/s].
        static_until: the vehicle stands still (no motion at all) before this time [s]; the motion
            fades in over 2 s after it (all terms are multiplied by a smooth ramp).
    """
    rng = np.random.default_rng(seed)
    k = 12

    def terms(rms, f_lo, f_hi):
        w = 2 * np.pi * rng.uniform(f_lo, f_hi, k)
        a = rng.normal(size=k)
        a *= rms * np.sqrt(2.0) / np.sqrt(np.sum(a**2))
        return np.stack([a, w, rng.uniform(0, 2 * np.pi, k)], 1)

    rms = np.deg2rad(road_rms_deg)
    nc = int(n_curves if n_curves is not None else max(1, duration // 30))
    t_start = static_until + 2.0
    centres = np.sort(rng.uniform(t_start + 5.0, max(t_start + 6.0, duration - 5.0), nc))
    widths = rng.uniform(2.0, 5.0, nc)
    amps = curve_rate * rng.uniform(0.4, 1.0, nc) * rng.choice([-1.0, 1.0], nc)
    # roll leans with lateral acceleration v * yaw rate; add it as slow sinusoids of the curve scale
    roll = np.concatenate([terms(rms, 0.8, 3.0), terms(0.3 * rms, 0.05, 0.3)])
    pitch = np.concatenate([terms(rms, 0.6, 2.5), terms(0.3 * rms, 0.05, 0.3)])
    motion = SmoothMotion(
        roll_terms=roll,
        pitch_terms=pitch,
        curves=np.stack([amps, centres, widths], 1),
        yaw0=float(rng.uniform(-np.pi, np.pi)),
        v0=float(speed),
        speed_terms=terms(0.1 * speed, 0.005, 0.03),
        heave_terms=terms(0.01, 0.8, 2.0),
    )
    if static_until > 0:
        return _Faded(motion, static_until)
    return motion


@dataclasses.dataclass(frozen=True)
class _Faded:
    """A motion frozen before ``t_s`` and faded in with a smooth ramp (C1) over 2 s (angles only)."""

    base: SmoothMotion
    t_s: float

    def _ramp(self, t):
        u = np.clip((np.asarray(t, float) - self.t_s) / 2.0, 0.0, 1.0)
        return u * u * (3 - 2 * u), 6 * u * (1 - u) / 2.0

    def angles(self, t):
        t = np.asarray(t, float)
        a, ad = self.base.angles(t)
        a0, _ = self.base.angles(np.array([self.t_s]))
        r, rd = self._ramp(t)
        # angles = a0 + r (a - a0): static at a0 before t_s, the base motion after t_s + 2
        ang = a0 + r[:, None] * (a - a0)
        dang = rd[:, None] * (a - a0) + r[:, None] * ad
        return ang, dang

    quaternion = SmoothMotion.quaternion
    body_rates = SmoothMotion.body_rates
    body_angular_acceleration = SmoothMotion.body_angular_acceleration
    rotation_matrices = SmoothMotion.rotation_matrices

    def position_acceleration(self, t):
        raise NotImplementedError("a faded-in (static start) motion models the attitude only")


def gyro_errors(rng, n, dt, *, arw=0.0, bias=(0.0, 0.0, 0.0), rrw=(0.0, 0.0, 0.0), bias_instability=0.0, tau_c=100.0):
    """Additive gyro errors ``(n, 3)`` [rad/s] (scale is applied by the caller).

    Args:
        rng: numpy Generator.
        arw: angle random walk N [rad/sqrt(s)] (white samples of std ``N / sqrt(dt)``).
        bias: constant bias per axis [rad/s].
        rrw: rate random walk K per axis [rad/s/sqrt(s)]: ``b(t_k) = K W(t_k)``, ``W(0) = 0``.
        bias_instability: B [rad/s]: Gauss-Markov of standard deviation B and correlation time tau_c.
    """
    e = np.broadcast_to(np.asarray(bias, float), (n, 3)).copy()
    if arw:
        e += rng.normal(size=(n, 3)) * (arw / np.sqrt(dt))
    rrw = np.asarray(rrw, float)
    if np.any(rrw):
        steps = rng.normal(size=(n, 3)) * np.sqrt(dt)
        steps[0] = 0.0
        e += np.cumsum(steps, 0) * rrw
    if bias_instability:
        phi = np.exp(-dt / tau_c)
        drive = rng.normal(size=(n, 3)) * bias_instability * np.sqrt(1 - phi**2)
        from scipy.signal import lfilter

        x0 = rng.normal(size=3) * bias_instability
        gm = lfilter([1.0], [1.0, -phi], drive, axis=0, zi=(phi * x0)[None])[0]
        e += gm
    return e


