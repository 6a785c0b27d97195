"""Shared setup of the benchmarks: the seed paper's half-car study (section 4) at 1 kHz.

The "virtual measurement" (step 1 of section 4.1): the road-driven model (A.4) on an ISO 8608
class D road with +-2 m hills, solved with tight tolerances, gives the contact forces f^(0) (4.3)
sampled at ``fs``. The noisy-force study adds white noise of standard deviation
``0.002 max|f^(0)|`` (the seed's sigma, about 32 N) to each force channel, drawn with
:func:`jaxdrift.path_normals`, and integrates the force-driven model (A.3) from static equilibrium.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

import jaxdrift
from jaxdrift.models._halfcar import contact_forces, force_driven_rhs, road_driven_rhs, static_equilibrium
from jaxdrift.models._params import HalfCarParams
from jaxdrift.models._road import iso8608_road

SPEED = 20.0  # m/s
ROAD_CLASS = "D"  # as jaxdrift.studies._study.StudyConfig (forces closest to the paper's Fig. 4)
ROAD_SEED = 0
NOISE_FRACTION = 0.002  # sigma = 0.002 f_max (section 4.2)


@dataclasses.dataclass
class Study:
    params: HalfCarParams
    T: float
    fs: float
    t_samples: np.ndarray  # (n,)
    f0: np.ndarray  # (n, 2) undisturbed contact forces
    sigma: float  # noise standard deviation per channel [N]
    x0: np.ndarray  # (10,) static equilibrium of the force-driven model
    xbar_ref: np.ndarray  # (n, 8) the virtual measurement

    @property
    def dt(self) -> float:
        return 1.0 / self.fs

    @property
    def n_samples(self) -> int:
        return self.t_samples.size


def paper_study(T: float = 30.0, fs: float = 1000.0, speed: float = SPEED) -> Study:
    """The virtual measurement of the seed's section 4 on ``[0, T]`` sampled at ``fs``."""
    p = HalfCarParams()
    road = iso8608_road(ROAD_CLASS, seed=ROAD_SEED)
    wheelbase = float(p.a + p.b)
    n = int(round(T * fs)) + 1
    t_s = np.arange(n) / fs

    def road_rhs(t, xbar, args):
        zeta, dzeta = road.wheel_inputs(t, speed, wheelbase)
        return road_driven_rhs(t, xbar, p, zeta, dzeta)

    xbar0 = static_equilibrium(p, "road")
    sol = jaxdrift.solve_ode(road_rhs, xbar0, 0.0, T, saveat=t_s, rtol=1e-10, atol=1e-12, max_steps=10_000_000)
    if int(sol.result) != 0:
        raise RuntimeError(f"virtual measurement failed: {jaxdrift.RESULTS[int(sol.result)]}")
    zeta, dzeta = road.wheel_inputs(jnp.asarray(t_s), speed, wheelbase)
    f0 = jax.vmap(lambda x, z, dz: contact_forces(x, p, z, dz))(sol.ys, zeta, dzeta)
    f0 = np.asarray(f0)
    sigma = NOISE_FRACTION * float(np.max(np.abs(f0)))
    x0 = np.asarray(static_equilibrium(p, "force"))
    return Study(p, float(T), float(fs), t_s, f0, sigma, x0, np.asarray(sol.ys))


def force_rhs(params):
    """``f(t, x, signal)`` of the force-driven half-car with the forces from a SampledSignal."""

    def rhs(t, x, sig):
        f = sig(t)
        return force_driven_rhs(t, x, params, f[0], f[1])

    return rhs


def force_rhs_u(params):
    """``rhs(t, x, u, args)`` with the forces as the input vector (for covariance propagation)."""

    def rhs(t, x, u, args):
        return force_driven_rhs(t, x, params, u[0], u[1])

    return rhs


def numpy_force_rhs(params):
    """The force-driven half-car (A.1)-(A.3) in plain numpy, for scipy's solve_ivp."""
    p = {k: float(v) for k, v in params.to_dict().items()}
    a, b, m1, m2, m3, I = p["a"], p["b"], p["m1"], p["m2"], p["m3"], p["I"]
    k1, k2, k3, k4, d1, d2, d3, d4, g = (p[k] for k in ("k1", "k2", "k3", "k4", "d1", "d2", "d3", "d4", "g"))

    def rhs(x, f1, f2):
        z1, z2, z3, be, dz1, dz2, dz3, dbe, ze1, ze2 = x
        s, c = np.sin(be), np.cos(be)
        f3 = k3 * (z3 - z1 - b * s) + d3 * (dz3 - dz1 - b * dbe * c)
        f4 = k4 * (z3 - z2 + a * s) + d4 * (dz3 - dz2 + a * dbe * c)
        return np.array(
            [
                dz1, dz2, dz3, dbe,
                g + (f3 - f1) / m1,
                g + (f4 - f2) / m2,
                g - (f3 + f4) / m3,
                c * (b * f3 - a * f4) / I,
                (k1 * (z1 - ze1) + d1 * dz1 - f1) / d1,
                (k2 * (z2 - ze2) + d2 * dz2 - f2) / d2,
            ]
        )

    return rhs


def study_paths(T: float):
    """The noisy-force study's path functions as the timing scripts compare them (path index ->
    pitch and heave at the 0.1 s saves): ``engine`` (``solve_ode`` fixed 1 ms, float64), ``fast``
    (``solve_fixed_fast``, float32 inputs), ``diffrax`` (Dopri5, constant 1 ms steps), and
    ``all_devices(fn)``: ``jit(vmap(fn))`` split over every JAX device. Also ``study`` and
    ``n_steps``."""
    import types

    import diffrax
    from jax.sharding import Mesh, PartitionSpec as P

    st = paper_study(T=T)
    T, dt, n = st.T, st.dt, st.n_samples
    ts = jnp.arange(0, int(round(T * 10)) + 1) / 10.0
    f0, x0, key = jnp.asarray(st.f0), jnp.asarray(st.x0), jax.random.key(0)
    rhs = force_rhs(st.params)
    n_steps = int(round(T / dt))

    def signal(i, dtype=jnp.float64):
        eps = jaxdrift.path_normals(key, i, n, 2, dtype) * jnp.asarray(st.sigma, dtype)
        return jaxdrift.SampledSignal(0.0, dt, f0.astype(dtype) + eps)

    def engine(i):
        return jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=signal(i), dt=dt).ys[:, 2:4]

    def fast(i):
        return jaxdrift.solve_fixed_fast(rhs, x0, 0.0, T, saveat=ts, args=signal(i, jnp.float32), dt=dt).ys[:, 2:4]

    def dfx(i):
        return diffrax.diffeqsolve(
            diffrax.ODETerm(rhs), diffrax.Dopri5(), 0.0, T, dt, x0, args=signal(i), saveat=diffrax.SaveAt(ts=ts),
            stepsize_controller=diffrax.ConstantStepSize(), max_steps=n_steps + 16,
        ).ys[:, 2:4]

    def all_devices(fn):
        f = jax.vmap(fn)
        if len(jax.devices()) == 1:
            return jax.jit(f)
        mesh = Mesh(np.array(jax.devices()), ("paths",))
        return jax.jit(jax.shard_map(f, mesh=mesh, in_specs=P("paths"), out_specs=P("paths"), check_vma=False))

    return types.SimpleNamespace(study=st, n_steps=n_steps, engine=engine, fast=fast, diffrax=dfx,
                                 all_devices=all_devices)
