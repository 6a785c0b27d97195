"""The seed paper's half-car (Fig. 3, Appendix A) as pure JAX vector fields.

Conventions (as in the paper): z points **down**, gravity acts as ``+g``; wheel 1 sits at distance
``b`` from the chassis centre of mass, wheel 2 at distance ``a``; ``beta`` is the chassis pitch.
Spring forces (A.1)::

    f_i = k_i (z_i - zeta_i) + d_i (z_i' - zeta_i')                          i = 1, 2  (tyres)
    f_3 = k_3 (z_3 - z_1 - b sin beta) + d_3 (z_3' - z_1' - b beta' cos beta)
    f_4 = k_4 (z_3 - z_2 + a sin beta) + d_4 (z_3' - z_2' + a beta' cos beta)

and equations of motion (A.2)::

    m_1 z_1'' = m_1 g + f_3 - f_1        m_2 z_2'' = m_2 g + f_4 - f_2
    m_3 z_3'' = m_3 g - f_3 - f_4        I beta''  = cos beta (b f_3 - a f_4)

Three excitation modes:

* force-driven (A.3), 10 states ``x = [z1, z2, z3, beta, z1', z2', z3', beta', zeta1, zeta2]``:
  the contact points ``zeta`` follow from the tyre force law ``d_i zeta_i' = k_i (z_i - zeta_i)
  + d_i z_i' - f_i``; see :func:`force_driven_rhs`;
* road-driven (A.4), 8 states ``xbar = x[:8]``, contact forces (4.3) from the road ``zeta``; see
  :func:`road_driven_rhs` and :func:`contact_forces`;
* force-driven with prescribed pitch (A.5), 8 states ``xhat = [z1, z2, z3, z1', z2', z3', zeta1,
  zeta2]``; the enforced moment ``lambda = I beta'' - cos beta (b f3 - a f4)``; see
  :func:`prescribed_pitch_rhs` and :func:`enforced_moment`.

``linear=True`` gives the paper's small-angle form ``M x' = A(0) x + F`` (``cos beta -> 1``,
``sin beta -> beta``). All functions are written from (A.1)-(A.2) directly (the tests check them
against the matrix forms (A.3)-(A.5)); they are pure, jit/vmap safe, and accept a batched
:class:`~jaxdrift.HalfCarParams` under ``vmap``. The ``t`` argument is unused; it is there so the
functions slot into the engine's ``f(t, y, args)`` convention.

Optional nonlinear suspension (``nonlinear=`` a :class:`NonlinearSuspension`; ``None``, the
default, is the linear law above, computed by the same expressions, so results are bit-identical):
per axle an asymmetric damper (rebound/compression ratio ``rho`` with the model's mean damping:
``2 d / (1 + rho)`` in compression, ``rho`` times that in rebound), a progressive spring
(``k (u + c u^3)`` with ``u`` the travel from the static one), a bump stop (``k_b max(u - u_b, 0)``
added in compression) and tyre lift-off (road-driven contact forces cannot pull: ``max(f, 0)``).
All terms vanish at the static state, so the static equilibrium is the linear one.

The section-3 remedy (approach 1, "a rotational spring between the vehicle body and ground") is the
optional ``pitch_spring=(k_rot, d_rot)`` of :func:`force_driven_rhs`: a torque
``-(k_rot beta + d_rot beta')`` on the chassis, whose size :func:`pitch_spring_torque` reports.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from typing import NamedTuple

from ._params import HalfCarParams
from ._trig import sincos

__all__ = [
    "FORCE_STATE_NAMES",
    "ROAD_STATE_NAMES",
    "PITCH_STATE_NAMES",
    "spring_forces",
    "contact_forces",
    "force_driven_rhs",
    "force_driven_mount_rhs",
    "MountedMass",
    "road_driven_rhs",
    "prescribed_pitch_rhs",
    "enforced_moment",
    "pitch_spring_torque",
    "static_equilibrium",
    "pitch_states_from_force_states",
    "spring_travel_np",
    "NonlinearSuspension",
]

FORCE_STATE_NAMES = ("z1", "z2", "z3", "beta", "dz1", "dz2", "dz3", "dbeta", "zeta1", "zeta2")
ROAD_STATE_NAMES = FORCE_STATE_NAMES[:8]
PITCH_STATE_NAMES = ("z1", "z2", "z3", "dz1", "dz2", "dz3", "zeta1", "zeta2")


def _sin_cos(beta, linear: bool):
    if linear:
        return beta, jnp.ones_like(beta)
    # Polynomials instead of jnp.sin/jnp.cos: within 2 ulp, and 1.6-2.6x faster half-car steps on
    # CPU, where XLA computes the library sin/cos once per output row (docs/performance.md).
    return sincos(beta)


class NonlinearSuspension(NamedTuple):
    """Nonlinear terms of the chassis springs and dampers, per axle (3: front, 4: rear), and tyre
    lift-off; the defaults are the linear model. A pytree (jit/vmap safe)."""

    damper_ratio3: float = 1.0   # rebound / compression damping ratio, mean damping kept
    damper_ratio4: float = 1.0
    cubic3: float = 0.0          # c [1/m^2]: spring force k (u + c u^3), u = travel - static travel
    cubic4: float = 0.0
    stop_k3: float = 0.0         # bump-stop stiffness k_b [N/m] beyond the travel u_b [m] (compression)
    stop_k4: float = 0.0
    stop_u3: float = 0.0
    stop_u4: float = 0.0
    lift_off: bool = False       # road-driven tyre forces cannot pull

    @classmethod
    def from_json(cls, d: dict | None) -> "NonlinearSuspension | None":
        """The chassis terms of a report's ``extended_model.nonlinear`` (``damper_ratio3``,
        ``cubic4``, ``stop_k3``/``stop_u3``, ...); None where it has none (tyre lift-off alone acts
        on road-driven tyre forces only, never on a force-driven model)."""
        keys = [k for k in (d or {}) if k in cls._fields and k != "lift_off"]
        if not keys:
            return None
        return cls(**{k: float(d[k]) for k in keys})


def _nonlinear_law(k, d, s, ds, s0, rho, cubic, stop_k, stop_u):
    """One chassis spring-damper with the nonlinear terms (see :class:`NonlinearSuspension`)."""
    dc = 2.0 * d / (1.0 + rho)
    u = s - s0
    return (k * s + jnp.where(ds > 0.0, dc, rho * dc) * ds + k * cubic * u * u * u
            + stop_k * jnp.maximum(u - stop_u, 0.0))


def spring_forces(q, dq, params: HalfCarParams, linear: bool = False, nonlinear=None):
    """Chassis spring forces ``(f3, f4)`` of (A.1).

    ``q = [z1, z2, z3, beta]`` and ``dq = [z1', z2', z3', beta']`` (arrays whose last axis has
    length 4, or any sequence of four scalars). Returns a tuple of two scalars. ``nonlinear``: a
    :class:`NonlinearSuspension` (``None``: the linear law).
    """
    p = params
    z1, z2, z3, beta = q[0], q[1], q[2], q[3]
    dz1, dz2, dz3, dbeta = dq[0], dq[1], dq[2], dq[3]
    s, c = _sin_cos(beta, linear)
    if nonlinear is None:
        f3 = p.k3 * (z3 - z1 - p.b * s) + p.d3 * (dz3 - dz1 - p.b * dbeta * c)
        f4 = p.k4 * (z3 - z2 + p.a * s) + p.d4 * (dz3 - dz2 + p.a * dbeta * c)
        return f3, f4
    n = nonlinear
    _, _, f3s, f4s = equilibrium_forces(p)
    f3 = _nonlinear_law(p.k3, p.d3, z3 - z1 - p.b * s, dz3 - dz1 - p.b * dbeta * c, f3s / p.k3,
                        n.damper_ratio3, n.cubic3, n.stop_k3, n.stop_u3)
    f4 = _nonlinear_law(p.k4, p.d4, z3 - z2 + p.a * s, dz3 - dz2 + p.a * dbeta * c, f4s / p.k4,
                        n.damper_ratio4, n.cubic4, n.stop_k4, n.stop_u4)
    return f3, f4


def contact_forces(xbar, params: HalfCarParams, zeta, dzeta, nonlinear=None):
    """Tyre (contact) forces ``[f1, f2]`` of (4.3) for the road ``zeta = [zeta1, zeta2]``.

    ``xbar`` is the 8-state road-mode vector (the first 8 entries of a 10-state vector work too):
    ``f_i = k_i (z_i - zeta_i) + d_i (z_i' - zeta_i')``. Positive ``f_i`` pushes the wheel up.
    ``nonlinear.lift_off``: the tyre cannot pull (``max(f_i, 0)``).
    """
    p = params
    f1 = p.k1 * (xbar[0] - zeta[0]) + p.d1 * (xbar[4] - dzeta[0])
    f2 = p.k2 * (xbar[1] - zeta[1]) + p.d2 * (xbar[5] - dzeta[1])
    if nonlinear is not None and nonlinear.lift_off:
        f1, f2 = jnp.maximum(f1, 0.0), jnp.maximum(f2, 0.0)
    return jnp.stack([f1, f2])


def _accelerations(q, dq, params, f1, f2, linear, torque=0.0, nonlinear=None):
    """(z1'', z2'', z3'', beta'') of (A.2) given the tyre forces; ``torque`` acts on beta."""
    p = params
    f3, f4 = spring_forces(q, dq, p, linear, nonlinear)
    _, c = _sin_cos(q[3], linear)
    ddz1 = p.g + (f3 - f1) / p.m1
    ddz2 = p.g + (f4 - f2) / p.m2
    ddz3 = p.g - (f3 + f4) / p.m3
    ddbeta = (c * (p.b * f3 - p.a * f4) + torque) / p.I
    return ddz1, ddz2, ddz3, ddbeta


def pitch_spring_torque(x, k_rot, d_rot):
    """Reaction torque ``k_rot beta + d_rot beta'`` of the section-3 rotational spring-damper.

    This is the torque the ground spring exerts *against* the pitch (the model feels
    ``-pitch_spring_torque``); its size is the paper's measure of validity of approach 1.
    ``x`` is a force-mode state (beta = x[3], beta' = x[7]); works on a trajectory ``(n, 10)``
    via ``x[..., 3]`` broadcasting.
    """
    x = jnp.asarray(x)
    return k_rot * x[..., 3] + d_rot * x[..., 7]


def force_driven_rhs(t, x, params: HalfCarParams, f1, f2, linear: bool = False, pitch_spring=None,
                     nonlinear=None):
    """Right-hand side ``x'`` of the force-driven half-car (A.3), 10 states.

    ``x = [z1, z2, z3, beta, z1', z2', z3', beta', zeta1, zeta2]``; ``f1, f2`` are the (measured)
    contact forces at time ``t`` (scalars). The contact points obey the tyre law
    ``d_i zeta_i' = k_i (z_i - zeta_i) + d_i z_i' - f_i`` (rows 9-10 of (A.3)).
    ``pitch_spring=(k_rot, d_rot)`` adds the section-3 rotational spring-damper to ground
    (torque ``-(k_rot beta + d_rot beta')`` on the chassis); ``None`` is the free model.
    ``nonlinear``: a :class:`NonlinearSuspension` for the chassis springs (``None``: linear).
    """
    p = params
    q, dq = x[0:4], x[4:8]
    torque = 0.0
    if pitch_spring is not None:
        k_rot, d_rot = pitch_spring
        torque = -(k_rot * x[3] + d_rot * x[7])
    ddz1, ddz2, ddz3, ddbeta = _accelerations(q, dq, p, f1, f2, linear, torque, nonlinear)
    dzeta1, dzeta2 = _contact_rates(x, p, f1, f2)
    return jnp.stack([x[4], x[5], x[6], x[7], ddz1, ddz2, ddz3, ddbeta, dzeta1, dzeta2])


def _contact_rates(x, p: HalfCarParams, f1, f2):
    """The contact points' rates of (A.3), rows 9-10: ``d_i zeta_i' = k_i (z_i - zeta_i) + d_i z_i' - f_i``."""
    return ((p.k1 * (x[0] - x[8]) + p.d1 * x[4] - f1) / p.d1,
            (p.k2 * (x[1] - x[9]) + p.d2 * x[5] - f2) / p.d2)


class MountedMass(NamedTuple):
    """A mass on a vertical spring-damper inside the chassis (an engine on its mounts, a seat):
    ``mass`` [kg] at ``x`` [m ahead of the centre of mass], stiffness ``k`` [N/m], damping ``d``
    [N s/m]. The model's ``m3`` and ``I`` stay those of the rigid whole (the mass included, fixed
    at ``x``), as a diagnosis's ``extended_model.unmodelled_mode`` gives it. A pytree."""

    mass: float
    x: float
    k: float
    d: float

    @classmethod
    def from_json(cls, d: dict | None) -> "MountedMass | None":
        """From a report's ``extended_model.unmodelled_mode`` (None where there is none)."""
        if not d:
            return None
        return cls(float(d["mass_kg"]), float(d["x_m"]), float(d["stiffness_n_per_m"]), float(d["damping_n_s_per_m"]))


def force_driven_mount_rhs(t, x, params: HalfCarParams, f1, f2, mount: MountedMass, linear: bool = False,
                           nonlinear=None):
    """Right-hand side of the force-driven half-car (A.3) carrying ``mount``: 12 states, the 10 of
    :func:`force_driven_rhs` (``z3``, ``beta`` those of the rigid whole's centre of mass) and the
    mass's travel ``y`` below its static place under the chassis point ``x`` and its rate.

    The whole system's momentum and angular momentum give ``m3 z3'' + m y'' = m3 g - f3 - f4`` and
    ``I beta'' - x cos(beta) m y'' = cos(beta) (b f3 - a f4)``; the mass's own law
    ``m (y'' + z_p'') = -(k y + d y')`` with ``z_p = z3 - x sin(beta)``. Solved for the three
    accelerations in closed form; with ``mount.mass = 0`` the first 10 states are (A.3)'s."""
    p, mt = params, mount
    q, dq = x[0:4], x[4:8]
    y, dy = x[10], x[11]
    r1, r2, r3, rb = _accelerations(q, dq, p, f1, f2, linear, 0.0, nonlinear)  # the rigid whole's
    s, c = _sin_cos(q[3], linear)
    rel = -(mt.k * y + mt.d * dy) / jnp.maximum(mt.mass, 1e-30) * (mt.mass > 0) - mt.x * s * dq[3] ** 2
    ddy = (rel - r3 + mt.x * c * rb) / (1.0 - mt.mass / p.m3 - (mt.x * c) ** 2 * mt.mass / p.I)
    ddz3 = r3 - mt.mass / p.m3 * ddy
    ddbeta = rb + mt.x * c * mt.mass / p.I * ddy
    dzeta1, dzeta2 = _contact_rates(x, p, f1, f2)
    return jnp.stack([x[4], x[5], x[6], x[7], r1, r2, ddz3, ddbeta, dzeta1, dzeta2, dy, ddy])


def road_driven_rhs(t, xbar, params: HalfCarParams, zeta, dzeta, linear: bool = False, nonlinear=None):
    """Right-hand side of the road-driven half-car (A.4), 8 states.

    ``xbar = [z1, z2, z3, beta, z1', z2', z3', beta']``; ``zeta = [zeta1, zeta2]`` and
    ``dzeta = [zeta1', zeta2']`` are the road under each wheel at time ``t`` (z-down, so a hill of
    height h is ``zeta = -h``). The contact forces are (4.3), see :func:`contact_forces`.
    ``nonlinear``: a :class:`NonlinearSuspension` (``None``: linear springs, tyres that can pull).
    """
    f = contact_forces(xbar, params, zeta, dzeta, nonlinear)
    ddz1, ddz2, ddz3, ddbeta = _accelerations(xbar[0:4], xbar[4:8], params, f[0], f[1], linear,
                                              nonlinear=nonlinear)
    return jnp.stack([xbar[4], xbar[5], xbar[6], xbar[7], ddz1, ddz2, ddz3, ddbeta])


def prescribed_pitch_rhs(
    t, xhat, params: HalfCarParams, f1, f2, beta, dbeta, linear: bool = False, nonlinear=None
):
    """Right-hand side of the force-driven half-car with prescribed pitch (A.5), 8 states.

    ``xhat = [z1, z2, z3, z1', z2', z3', zeta1, zeta2]``; ``beta, dbeta`` are the prescribed pitch
    angle and rate at ``t``, ``f1, f2`` the contact forces. The system is linear in ``xhat``
    (with ``nonlinear``, a :class:`NonlinearSuspension`, it is not).
    """
    p = params
    q = jnp.stack([xhat[0], xhat[1], xhat[2], jnp.asarray(beta, dtype=xhat.dtype)])
    dq = jnp.stack([xhat[3], xhat[4], xhat[5], jnp.asarray(dbeta, dtype=xhat.dtype)])
    ddz1, ddz2, ddz3, _ = _accelerations(q, dq, p, f1, f2, linear, nonlinear=nonlinear)
    dzeta1 = (p.k1 * (xhat[0] - xhat[6]) + p.d1 * xhat[3] - f1) / p.d1
    dzeta2 = (p.k2 * (xhat[1] - xhat[7]) + p.d2 * xhat[4] - f2) / p.d2
    return jnp.stack([xhat[3], xhat[4], xhat[5], ddz1, ddz2, ddz3, dzeta1, dzeta2])


def enforced_moment(xhat, params: HalfCarParams, beta, dbeta, ddbeta, linear: bool = False, nonlinear=None):
    """Enforced moment ``lambda = I beta'' - cos(beta) (b f3 - a f4)`` of the prescribed pitch.

    ``xhat`` is an A.5 state (or a trajectory ``(n, 8)`` with ``beta, dbeta, ddbeta`` of shape
    ``(n,)``); ``f3, f4`` are the chassis spring forces (A.1) at the prescribed ``beta, dbeta``.
    Zero when the prescribed motion is consistent with the forces and the model.
    """
    p = params
    xhat = jnp.asarray(xhat)
    q = (xhat[..., 0], xhat[..., 1], xhat[..., 2], beta)
    dq = (xhat[..., 3], xhat[..., 4], xhat[..., 5], dbeta)
    f3, f4 = spring_forces(q, dq, p, linear, nonlinear)
    _, c = _sin_cos(jnp.asarray(beta), linear)
    return p.I * ddbeta - c * (p.b * f3 - p.a * f4)


def static_equilibrium(params: HalfCarParams, mode: str = "force", zeta=(0.0, 0.0), linear: bool = False):
    """Static equilibrium state: the default initial state of every mode.

    ``mode``: ``"force"`` (10 states of A.3), ``"road"`` (8 states of A.4) or ``"pitch"``
    (8 states of A.5; start the prescribed pitch at the equilibrium pitch
    ``static_equilibrium(params, "road")[3]``, which is 0 for the seed's symmetric data).
    ``zeta`` is the road height under the wheels at rest (z-down).

    At rest all velocities vanish and (A.2) gives ``b f3 = a f4``, ``f3 + f4 = m3 g``, so
    ``f3 = a m3 g / (a + b)``, ``f4 = b m3 g / (a + b)``, ``f1 = m1 g + f3``, ``f2 = m2 g + f4``
    (so ``f1 + f2 = (m1 + m2 + m3) g``); then ``z_i = zeta_i + f_i / k_i`` and the chassis position
    and pitch follow from (A.1). Works with a batched ``params`` (a trailing state axis is added).
    """
    p = params
    if mode not in ("force", "road", "pitch"):
        raise ValueError(f"static_equilibrium: mode must be 'force', 'road' or 'pitch', got {mode!r}")
    zeta1, zeta2 = zeta
    f1, f2, f3, f4 = equilibrium_forces(p)
    z1 = zeta1 + f1 / p.k1
    z2 = zeta2 + f2 / p.k2
    sin_beta = ((z2 + f4 / p.k4) - (z1 + f3 / p.k3)) / (p.a + p.b)
    beta = sin_beta if linear else jnp.arcsin(sin_beta)
    z3 = z1 + f3 / p.k3 + p.b * sin_beta
    zero = jnp.zeros_like(jnp.asarray(z3 + z1 + z2, dtype=float))
    z1, z2, z3, beta = (zero + v for v in (z1, z2, z3, beta))
    zeta1, zeta2 = zero + zeta1, zero + zeta2
    if mode == "force":
        parts = [z1, z2, z3, beta, zero, zero, zero, zero, zeta1, zeta2]
    elif mode == "road":
        parts = [z1, z2, z3, beta, zero, zero, zero, zero]
    else:
        parts = [z1, z2, z3, zero, zero, zero, zeta1, zeta2]
    return jnp.stack(parts, axis=-1)


def equilibrium_forces(params: HalfCarParams):
    """Static forces ``(f1, f2, f3, f4)``: tyres carry ``(m1+m2+m3) g``, springs ``m3 g``."""
    p = params
    f3 = p.a * p.m3 * p.g / (p.a + p.b)
    f4 = p.b * p.m3 * p.g / (p.a + p.b)
    return p.m1 * p.g + f3, p.m2 * p.g + f4, f3, f4


def spring_travel_np(x, a: float, b: float) -> dict:
    """The spring compressions of the data contract and their rates from force-mode states
    ``(..., >= 8)`` (numpy): ``s1 = z3 - z1 - b sin(beta)``, ``s2 = z3 - z2 + a sin(beta)`` (zero
    for the unloaded spring), ``ds1``, ``ds2``."""
    x = np.asarray(x)
    sb = np.sin(x[..., 3])
    cb_rate = np.cos(x[..., 3]) * x[..., 7]
    return {"s1": x[..., 2] - x[..., 0] - b * sb, "s2": x[..., 2] - x[..., 1] + a * sb,
            "ds1": x[..., 6] - x[..., 4] - b * cb_rate, "ds2": x[..., 6] - x[..., 5] + a * cb_rate}


def pitch_states_from_force_states(x):
    """Map force-mode states ``(..., 10)`` to A.5 states ``(..., 8)`` (drop beta, beta')."""
    x = jnp.asarray(x)
    idx = np.array([0, 1, 2, 4, 5, 6, 8, 9])
    return x[..., idx]
