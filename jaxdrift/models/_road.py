"""Road profiles: ISO 8608 random roughness plus long hills, and the wheelbase delay.

A profile is a smooth function ``zeta(s)`` of the distance ``s`` [m] travelled, given in the
half-car's coordinates: **z points down**, so ``zeta`` is minus the road elevation (the paper's
Fig. 4 plots ``zeta``). It is a sum of cosines (random-phase roughness, closed-form derivative)
plus long hills, multiplied by a smooth ramp that makes the road start flat at level zero
(``zeta = zeta' = zeta'' = 0`` for ``s <= 0``), so a car at rest in static equilibrium on level
ground is a consistent initial state.

Roughness follows ISO 8608: one-sided displacement PSD ``Gd(n) = Gd(n0) (n / n0)^-2`` with
``n0 = 0.1`` cycles/m and ``Gd(n0)`` from :data:`ISO8608_GD0` (classes A-H, the geometric means of
the class bands: 16e-6 ... 262144e-6 m^3; values quoted per rad/m are 16x smaller and must not be
mixed in). The random-phase sum uses log-spaced frequency bins ``[n_k, n_{k+1}]`` with amplitude
``sqrt(2 Gd(n_c) dn)`` at the bin's centre, phases uniform from ``numpy.random.default_rng(seed)``,
so the same seed gives the same road.

Wheel 1 (distance ``b`` from the chassis centre of mass) is the front wheel; wheel 2 follows on the
same track delayed by the wheelbase ``(a + b) / speed``.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

__all__ = [
    "ISO8608_GD0",
    "ISO8608_N0",
    "RoadProfile",
    "WheelInputs",
    "iso8608_road",
    "iso8608_psd",
    "iso8608_variance",
]

#: Reference spatial frequency of ISO 8608 [cycles/m].
ISO8608_N0 = 0.1
#: ``Gd(n0)`` [m^3] for ISO 8608 road classes A-H (geometric mean of each class band).
ISO8608_GD0: dict[str, float] = {
    c: v * 1e-6
    for c, v in zip("ABCDEFGH", (16.0, 64.0, 256.0, 1024.0, 4096.0, 16384.0, 65536.0, 262144.0))
}


def _gd0(road_class: str) -> float:
    key = str(road_class).upper()
    if key not in ISO8608_GD0:
        raise ValueError(f"road class must be one of A-H, got {road_class!r}")
    return ISO8608_GD0[key]


def iso8608_psd(n, road_class: str = "C"):
    """One-sided displacement PSD ``Gd(n)`` [m^3] of an ISO 8608 class at ``n`` [cycles/m]."""
    n = np.asarray(n, dtype=float)
    return _gd0(road_class) * (n / ISO8608_N0) ** -2


def iso8608_variance(road_class: str, n_min: float, n_max: float) -> float:
    """Exact variance ``int_{n_min}^{n_max} Gd(n) dn = Gd(n0) n0^2 (1/n_min - 1/n_max)`` [m^2]."""
    return _gd0(road_class) * ISO8608_N0**2 * (1.0 / n_min - 1.0 / n_max)


def _smoothstep(u):
    """C2 ramp 0 -> 1 on [0, 1] (quintic 6u^5 - 15u^4 + 10u^3) and its derivative in u."""
    u = jnp.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u**2), 30.0 * u**2 * (1.0 - u) ** 2


class RoadProfile(eqx.Module):
    """A smooth road ``zeta(s)`` [m, z-down] as a sum of cosines times a start ramp.

    ``zeta(s) = w(s) * sum_k amp_k cos(2 pi n_k s + phase_k)`` for ``s >= 0`` and 0 before, with
    ``w`` the C2 ramp from 0 to 1 over ``[0, ramp_length]`` (``w = 1`` everywhere when
    ``ramp_length == 0``). Build one with :func:`iso8608_road`. jit/vmap safe; arrays of ``s``
    broadcast.
    """

    n: jax.Array  # spatial frequencies [cycles/m]
    amp: jax.Array  # amplitudes [m]
    phase: jax.Array  # phases [rad]
    ramp_length: float = eqx.field(static=True, default=10.0)

    def _sum(self, s):
        s = jnp.asarray(s)
        arg = 2 * jnp.pi * self.n * s[..., None] + self.phase
        val = jnp.sum(self.amp * jnp.cos(arg), axis=-1)
        der = -jnp.sum(2 * jnp.pi * self.n * self.amp * jnp.sin(arg), axis=-1)
        return val, der

    def zeta_and_slope(self, s):
        """``(zeta(s), d zeta / ds)``."""
        s = jnp.asarray(s)
        val, der = self._sum(s)
        if self.ramp_length > 0:
            w, dw = _smoothstep(s / self.ramp_length)
            dw = dw / self.ramp_length
        else:
            w, dw = jnp.ones_like(s), jnp.zeros_like(s)
        z = w * val
        dz = dw * val + w * der
        before = s < 0
        return jnp.where(before, 0.0, z), jnp.where(before, 0.0, dz)

    def __call__(self, s):
        return self.zeta_and_slope(s)[0]

    def wheel_inputs(self, t, speed, wheelbase):
        """Road under both wheels at time ``t`` for a car at constant ``speed`` [m/s].

        Returns ``(zeta, dzeta)``, each of shape ``t.shape + (2,)``: wheel 1 (front) at
        ``s = speed t``, wheel 2 (rear) at ``s = speed (t - wheelbase / speed)``; ``dzeta`` are time
        derivatives (``speed * d zeta / ds``).
        """
        t = jnp.asarray(t)
        s1 = speed * t
        s2 = s1 - wheelbase
        z1, d1 = self.zeta_and_slope(s1)
        z2, d2 = self.zeta_and_slope(s2)
        return jnp.stack([z1, z2], axis=-1), speed * jnp.stack([d1, d2], axis=-1)

    def sampled_wheel_inputs(self, speed, wheelbase, t1, dt=5e-4) -> "WheelInputs":
        """The wheel inputs on ``[0, t1]`` tabulated every ``dt`` for fast evaluation.

        Evaluating the sum of cosines costs a few hundred transcendentals per call; inside an ODE
        solver that dominates everything. The tabulated :class:`WheelInputs` interpolates
        ``zeta`` by cubic Hermite from the exact values and slopes at the nodes (error at most
        ``dt^4 max|zeta^(4)| / 384``, about 3e-6 of the amplitude of a 57 Hz component at
        ``dt = 0.5 ms``) and returns its derivative as ``dzeta``, so the pair stays consistent.
        """
        if not (np.isfinite(speed) and speed > 0):
            raise ValueError(f"speed must be positive, got {speed}")
        if not (np.isfinite(t1) and t1 > 0 and np.isfinite(dt) and dt > 0):
            raise ValueError(f"need t1 > 0 and dt > 0, got t1={t1}, dt={dt}")
        n = int(np.ceil(t1 / dt - 1e-9)) + 1
        ts = np.arange(n) * dt
        fn = jax.jit(lambda road, t: road.wheel_inputs(t, speed, wheelbase))
        block = 4096  # bounded memory: (block, n_components) intermediates
        pad = (-n) % block
        tp = np.concatenate([ts, np.full(pad, ts[-1])]).reshape(-1, block)
        parts = [fn(self, jnp.asarray(row)) for row in tp]
        z = np.concatenate([np.asarray(q[0]) for q in parts])[:n]
        dz = np.concatenate([np.asarray(q[1]) for q in parts])[:n]
        return WheelInputs(t0=0.0, dt=float(dt), zeta=z, dzeta=dz)


class WheelInputs(eqx.Module):
    """Road under both wheels tabulated on a uniform time grid, cubic Hermite interpolation.

    ``inputs(t)`` returns ``(zeta, dzeta)`` of shape ``(2,)`` each; outside the table the end
    values are held (``dzeta`` then holds too). jit/vmap safe.
    """

    zeta: jax.Array  # (n, 2) values at the nodes
    dzeta: jax.Array  # (n, 2) time derivatives at the nodes
    t0: float
    dt: float

    def __check_init__(self):
        zs, ds = np.shape(self.zeta), np.shape(self.dzeta)
        if zs != ds or len(zs) != 2 or zs[0] < 2:
            raise ValueError(f"zeta and dzeta must both have shape (n >= 2, channels), got {zs}, {ds}")

    @property
    def t1(self):
        return self.t0 + (self.zeta.shape[0] - 1) * self.dt

    def __call__(self, t):
        n = self.zeta.shape[0]
        s = jnp.clip((t - self.t0) / self.dt, 0.0, n - 1.0)
        i = jnp.clip(jnp.floor(s), 0, n - 2).astype(jnp.int32)
        u = s - i
        zeta, dzeta = jnp.asarray(self.zeta), jnp.asarray(self.dzeta)
        z0, z1 = zeta[i], zeta[i + 1]
        m0, m1 = dzeta[i] * self.dt, dzeta[i + 1] * self.dt
        u2, u3 = u * u, u * u * u
        h00, h10, h01, h11 = 2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2
        d00, d10, d01, d11 = 6 * u2 - 6 * u, 3 * u2 - 4 * u + 1, -6 * u2 + 6 * u, 3 * u2 - 2 * u
        val = h00 * z0 + h10 * m0 + h01 * z1 + h11 * m1
        der = (d00 * z0 + d10 * m0 + d01 * z1 + d11 * m1) / self.dt
        return val, der


def iso8608_road(
    road_class: str = "C",
    *,
    seed: int = 0,
    n_min: float = 0.011,
    n_max: float = 2.83,
    n_components: int = 256,
    hill_height: float = 2.0,
    hill_wavelength: float = 250.0,
    ramp_length: float = 10.0,
    roughness: bool = True,
) -> RoadProfile:
    """An ISO 8608 road of the given class with long hills (the seed paper's Fig. 4 road).

    Args:
        road_class: ``"A"``-``"H"``.
        seed: seed of the random phases (numpy ``default_rng``): the same seed, the same road.
        n_min, n_max: band of spatial frequencies [cycles/m] (ISO 8608's 0.011-2.83 by default).
        n_components: number of log-spaced frequency bins of the random-phase sum.
        hill_height: amplitude [m] of the hills, ``-hill_height sin(2 pi s / wavelength)`` added
            to ``zeta`` (the road starts level at zero, first climbs, and spans ``-h .. +h``);
            0 for no hills.
        hill_wavelength: wavelength of the hills [m].
        ramp_length: length [m] of the C2 ramp at the start (road flat and level for ``s <= 0``).
        roughness: False gives the hills alone.

    Raises:
        ValueError: unknown class, or a non-positive / inverted band, or no components at all.
    """
    gd0 = _gd0(road_class)
    if not (np.isfinite(n_min) and np.isfinite(n_max) and 0 < n_min < n_max):
        raise ValueError(f"need 0 < n_min < n_max, got n_min={n_min}, n_max={n_max}")
    if int(n_components) < 1:
        raise ValueError(f"n_components must be >= 1, got {n_components}")
    if hill_height != 0 and not (np.isfinite(hill_wavelength) and hill_wavelength > 0):
        raise ValueError(f"hill_wavelength must be positive, got {hill_wavelength}")
    if not (np.isfinite(ramp_length) and ramp_length >= 0):
        raise ValueError(f"ramp_length must be >= 0, got {ramp_length}")
    ns, amps, phases = [], [], []
    if roughness:
        edges = np.geomspace(n_min, n_max, int(n_components) + 1)
        nc = np.sqrt(edges[:-1] * edges[1:])
        dn = np.diff(edges)
        rng = np.random.default_rng(seed)
        ns.append(nc)
        amps.append(np.sqrt(2.0 * gd0 * (nc / ISO8608_N0) ** -2 * dn))
        phases.append(rng.uniform(0.0, 2 * np.pi, size=nc.shape))
    if hill_height != 0:
        ns.append(np.array([1.0 / hill_wavelength]))
        amps.append(np.array([float(hill_height)]))
        phases.append(np.array([np.pi / 2]))  # h cos(x + pi/2) = -h sin(x): starts at 0, climbs
    if not ns:
        raise ValueError("empty road: no roughness and no hills")
    return RoadProfile(
        n=np.concatenate(ns), amp=np.concatenate(amps), phase=np.concatenate(phases), ramp_length=float(ramp_length)
    )
