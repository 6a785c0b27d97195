"""Drive the half-car with measured forces: the force-driven model (A.3) and the model with the
pitch prescribed (A.5), integrated by our Dormand-Prince as a :class:`SolverSpec` says; pure JAX
(``jit``/``vmap``-able). The one simulation module under the paper study, the diagnosis's extended
model and re-simulation, the series output and durability.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from ..models._halfcar import (enforced_moment, force_driven_mount_rhs, force_driven_rhs, prescribed_pitch_rhs,
                               static_equilibrium)
from ..solvers._inputs import SampledSignal
from ..solvers._solve import solve_ode

__all__ = ["SolverSpec", "SOLVER_LOOSE", "SOLVER_TIGHT", "SOLVER_FIXED", "SOLVER_FIXED_HALF", "simulate_forces",
           "simulate_prescribed_pitch", "force_driven_states"]


@dataclasses.dataclass(frozen=True)
class SolverSpec:
    """How the force-driven simulations are integrated by :func:`jaxdrift.solve_ode`.

    ``dt=None``: adaptive Dormand-Prince with ``rtol``/``atol``; a float ``dt``: fixed steps of
    ``method`` (``"dopri5"`` or ``"euler"``).
    """

    name: str = "dopri5 rtol 1e-4"
    method: str = "dopri5"
    rtol: float = 1e-4
    atol: float = 1e-6
    dt: float | None = None
    max_steps: int = 2_000_000

    def kwargs(self) -> dict[str, Any]:
        kw: dict[str, Any] = dict(method=self.method, max_steps=self.max_steps)
        if self.dt is None:
            kw.update(rtol=self.rtol, atol=self.atol)
        else:
            kw.update(dt=self.dt)
        return kw


#: The seed's looser MATLAB setting (tol_rel 1e-4, tol_abs 1e-6): the study's default.
SOLVER_LOOSE = SolverSpec("dopri5 rtol 1e-4", rtol=1e-4, atol=1e-6)
#: The seed's tight setting (tol_rel 1e-8, tol_abs 1e-10).
SOLVER_TIGHT = SolverSpec("dopri5 rtol 1e-8", rtol=1e-8, atol=1e-10)
#: Fixed-step Dormand-Prince at the force sample rate (1 ms for 1 kHz): the headline's setting.
SOLVER_FIXED = SolverSpec("dopri5 fixed 1 ms", dt=1e-3)
#: Half of SOLVER_FIXED's step: the headline's convergence check.
SOLVER_FIXED_HALF = SolverSpec("dopri5 fixed 0.5 ms", dt=5e-4)


def _force_vf(t, x, args):
    p, sig, spring, nl = args
    f = sig(t)
    return force_driven_rhs(t, x, p, f[0], f[1], pitch_spring=spring, nonlinear=nl)


def _force_vf_linear(t, x, args):
    p, sig, spring, nl = args
    f = sig(t)
    return force_driven_rhs(t, x, p, f[0], f[1], linear=True, pitch_spring=spring, nonlinear=nl)


def _mount_vf(t, x, args):
    p, sig, mount, nl = args
    f = sig(t)
    return force_driven_mount_rhs(t, x, p, f[0], f[1], mount, nonlinear=nl)


def _mount_vf_linear(t, x, args):
    p, sig, mount, nl = args
    f = sig(t)
    return force_driven_mount_rhs(t, x, p, f[0], f[1], mount, linear=True, nonlinear=nl)


def _check_signal(name, sig, channels):
    shape = getattr(getattr(sig, "values", None), "shape", None)
    if shape is None or len(shape) != 2 or shape[1] != channels:
        raise ValueError(f"{name} must be a SampledSignal with {channels} channels, got values of shape {shape}")


def _span(save_ts, t_span):
    if t_span is not None:
        return float(t_span[0]), float(t_span[1])
    ts = np.asarray(save_ts)  # needs concrete save times (fixed steps need a concrete span)
    return float(ts[0]), float(ts[-1])


def simulate_forces(params, forces: SampledSignal, save_ts, solver: SolverSpec = SOLVER_LOOSE, pitch_spring=None,
                    x0=None, t_span=None, linear: bool = False, nonlinear=None, mount=None):
    """Force-driven model (A.3) excited by ``forces`` (``(2,)`` channels) from its equilibrium.

    Returns the engine's ``Solution`` (``ys`` of shape ``(len(save_ts), 10)``). Pure JAX: may be
    called under ``jit``/``vmap`` (``params`` may be a traced model); with traced ``save_ts`` give
    the concrete ``t_span=(t0, t1)``. ``pitch_spring=(k, d)`` adds the section-3 rotational
    spring-damper; ``linear=True`` integrates the small-angle form of (A.3); ``nonlinear`` (a
    :class:`~jaxdrift.models.NonlinearSuspension`) the chassis springs' and dampers' nonlinear
    terms (its defaults: the linear law). ``mount`` (a :class:`~jaxdrift.models.MountedMass`, not
    with ``pitch_spring``): the model carries a mass on its own spring-damper; ``ys`` then has 12
    states, the last two its travel and rate (:func:`~jaxdrift.models.force_driven_mount_rhs`).
    """
    _check_signal("forces", forces, 2)
    t0, t1 = _span(save_ts, t_span)
    if mount is not None and pitch_spring is not None:
        raise ValueError("simulate_forces: a mounted mass and a pitch spring together are not supported")
    if x0 is None:
        x0 = static_equilibrium(params, "force")
        if mount is not None:  # the mass at rest in its static place
            x0 = jnp.concatenate([x0, jnp.zeros(x0.shape[:-1] + (2,), dtype=x0.dtype)], axis=-1)
    if mount is not None:
        vf, extra = (_mount_vf_linear if linear else _mount_vf), mount
    else:
        vf, extra = (_force_vf_linear if linear else _force_vf), None if pitch_spring is None else tuple(pitch_spring)
    return solve_ode(
        vf, x0, t0, t1,
        # numpy save times stay numpy: the engine then knows them exactly at trace time
        saveat=save_ts if isinstance(save_ts, np.ndarray) else jnp.asarray(save_ts),
        args=(params, forces, extra, nonlinear), **solver.kwargs()
    )


def _pitch_vf(t, x, args):
    p, sig, pitch, nl = args
    f = sig(t)
    b = pitch(t)
    return prescribed_pitch_rhs(t, x, p, f[0], f[1], b[0], b[1], nonlinear=nl)


def _pitch_vf_linear(t, x, args):
    p, sig, pitch, nl = args
    f = sig(t)
    b = pitch(t)
    return prescribed_pitch_rhs(t, x, p, f[0], f[1], b[0], b[1], linear=True, nonlinear=nl)


def simulate_prescribed_pitch(params, forces: SampledSignal, pitch: SampledSignal, save_ts,
                              solver: SolverSpec = SOLVER_LOOSE, t_span=None, linear: bool = False, nonlinear=None):
    """Step 5: model (A.5) driven by ``forces`` (2 channels) with the pitch prescribed by ``pitch``
    (3 channels: ``beta, beta', beta''``).

    Returns ``(solution, lam, inertia)``: the engine's ``Solution`` (8 states ``z1, z2, z3, z1',
    z2', z3', zeta1, zeta2``), the enforced moment ``lambda = I beta'' - cos(beta)(b f3 - a f4)``
    (``cos(beta) = 1`` with ``linear``) and the inertia term ``I beta''`` at ``save_ts``. The
    initial state is the model's static equilibrium ``static_equilibrium(params, "pitch")``,
    whatever the prescribed pitch is at the start: a pitch that does not start at the model's
    equilibrium pitch (0 for the seed's symmetric table) gives an initial transient in ``lam``.
    ``t_span``: ``(t0, t1)``, default the first and last save time. ``nonlinear``: the chassis
    springs' and dampers' nonlinear terms (:class:`~jaxdrift.models.NonlinearSuspension`).
    """
    _check_signal("forces", forces, 2)
    _check_signal("pitch", pitch, 3)
    t0, t1 = _span(save_ts, t_span)
    save_ts = jnp.asarray(save_ts)
    x0 = static_equilibrium(params, "pitch")
    vf = _pitch_vf_linear if linear else _pitch_vf
    sol = solve_ode(vf, x0, t0, t1, saveat=save_ts, args=(params, forces, pitch, nonlinear), **solver.kwargs())
    b = jax.vmap(pitch)(save_ts)
    lam = enforced_moment(sol.ys, params, b[:, 0], b[:, 1], b[:, 2], linear=linear, nonlinear=nonlinear)
    return sol, lam, params.I * b[:, 2]


def force_driven_states(t, models: list[dict], forces: list[dict], dt: float | None = None,
                        nonlinear: list | None = None) -> list[np.ndarray]:
    """States ``(n, 10)`` of (A.3) on the samples ``t`` (uniform) for each (model dict, forces
    ``{"f1", "f2"}`` on ``t``) pair, from each model's static equilibrium; fixed-step DOPRI5 at the
    sample interval (``dt``, default from ``t``) halved until at most 1 ms. Numpy in and out (x64
    inside). ``nonlinear``: per pair, a :class:`~jaxdrift.models.NonlinearSuspension` or None (the
    linear law; all None by default)."""
    import math

    from ..models._params import HalfCarParams

    t = np.asarray(t, dtype=float)
    dt = float((t[-1] - t[0]) / (len(t) - 1)) if dt is None else dt
    sub = int(math.ceil(dt / 1e-3 - 1e-9))
    tau = t - t[0]
    out = []
    with jax.enable_x64(True):
        for m, f, nl in zip(models, forces, nonlinear or [None] * len(models)):
            p = jax.tree_util.tree_map(lambda v: jnp.asarray(v, dtype=jnp.float64), HalfCarParams.from_dict(m))
            sig = SampledSignal(0.0, dt, jnp.stack([jnp.asarray(f["f1"]), jnp.asarray(f["f2"])], axis=1))
            sol = simulate_forces(p, sig, jnp.asarray(tau), SolverSpec("fixed", dt=dt / sub),
                                  t_span=(0.0, float(tau[-1])), nonlinear=nl)
            if int(sol.result) != 0:
                raise RuntimeError(f"force-driven simulation failed (result code {int(sol.result)})")
            out.append(np.asarray(sol.ys))
    return out
