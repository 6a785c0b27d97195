"""Section forces ``f3, f4`` (seed Appendix A) of the simulation variants, in one pure JAX function.

Variants (the seed's section 3 and (4.4)/(A.5)):

* ``force_driven``: the force-driven half-car (A.3) excited by the measured forces (drifts);
* ``pitch_spring``: the same with the section-3 rotational spring-damper to ground
  (:func:`pitch_spring_rule` for its stiffness); its reaction torque is returned as well;
* ``stabilised``: (A.5), the measured pitch prescribed (filtered, see ``_derivative``), with the
  enforced moment ``lambda``;
* ``extended``: ``stabilised`` with the diagnosis's extended model: its parameters, its confirmed
  nonlinear suspension terms (``nonlinear``: a damper's asymmetry, a progressive spring, a bump
  stop), and the measured forces corrected by its ``corrections`` (``true = (measured(t + delay) -
  offset) / scale``).

The simulations reuse the paper study's :func:`~jaxdrift.simulate_forces` and
:func:`~jaxdrift.simulate_prescribed_pitch`, integrated by fixed-step Dormand-Prince 5(4) on a step
``h = dt / m`` that divides the sample step (:func:`integration_step`), so every sample time is a
step; with ``m > 1`` the measured forces are first interpolated band-limited onto that grid
(:func:`upsample_forces`), the noise draws of the Monte-Carlo band linearly. The section forces are (A.1) evaluated on the
simulated states (for the stabilised variants at the prescribed ``beta, beta'``).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..ensemble._noise import remove_input_effects, white_noise
from ..io._corrections import Corrections, unmix
from ..models._halfcar import NonlinearSuspension, pitch_spring_torque, spring_forces
from ..models._params import HalfCarParams
from ..solvers._inputs import SampledSignal
from ..analysis._force_driven import SolverSpec, simulate_forces, simulate_prescribed_pitch

__all__ = ["VARIANTS", "SIMULATED", "pitch_spring_rule", "integration_step", "SectionForces",
           "OUTPUT_COLUMNS", "SPRING_FREQUENCY_RATIO"]

VARIANTS = ("force_driven", "pitch_spring", "stabilised", "extended", "measured")
SIMULATED = ("force_driven", "pitch_spring", "stabilised", "extended")
#: columns of :class:`SectionForces`' output
OUTPUT_COLUMNS = tuple(f"{v}_{f}" for v in SIMULATED for f in ("f3", "f4")) + (
    "pitch_spring_torque", "stabilised_moment", "extended_moment")
#: the pitch spring's natural frequency on the free pitch mode, as a fraction of the body's pitch mode
SPRING_FREQUENCY_RATIO = 0.1
#: limits of the fixed step: tyre time constant d/k and the wheel-hop phase per step
STEP_WHEEL_PHASE = 0.15


def pitch_spring_rule(params: dict, k_rot: float | None = None, d_rot: float | None = None) -> dict:
    """Stiffness and damping of the section-3 rotational spring to ground (documented rule).

    Rule: the spring makes the vehicle's free pitch mode (inertia ``J = I + m1 b^2 + m2 a^2``) a
    critically damped oscillator whose frequency is ``SPRING_FREQUENCY_RATIO`` (one tenth) of the
    body's pitch mode on its suspension, ``f_pitch = sqrt((k3 b^2 + k4 a^2) / I) / (2 pi)``. A
    decade between the two keeps the spring mostly out of the band the suspension works in (on the
    seed's vehicle its stiffness is 1 % of the suspension's pitch stiffness ``k3 b^2 + k4 a^2``; with
    its damping, its impedance at ``f_pitch`` is 9 % of the suspension's) while it still stops the
    drift within a few seconds. So ``k_rot = J (2 pi 0.1 f_pitch)^2`` and ``d_rot = 2 sqrt(k_rot J)``;
    either may be given instead (``d_rot`` then defaults to critical damping of the given ``k_rot``).
    """
    p = params
    J = p["I"] + p["m1"] * p["b"] ** 2 + p["m2"] * p["a"] ** 2
    f_pitch = math.sqrt((p["k3"] * p["b"] ** 2 + p["k4"] * p["a"] ** 2) / p["I"]) / (2 * math.pi)
    rule = k_rot is None
    if k_rot is None:
        k_rot = J * (2 * math.pi * SPRING_FREQUENCY_RATIO * f_pitch) ** 2
    if d_rot is None:
        d_rot = 2.0 * math.sqrt(k_rot * J)
    return {"k_rot": float(k_rot), "d_rot": float(d_rot), "J": float(J), "f_pitch_hz": float(f_pitch),
            "f_spring_hz": float(math.sqrt(k_rot / J) / (2 * math.pi)),
            "rule": ("k_rot = J (2 pi 0.1 f_pitch)^2, d_rot = 2 sqrt(k_rot J)" if rule
                     else "given k_rot; d_rot = 2 sqrt(k_rot J) unless given")}


def integration_step(params: dict, dt: float, nonlinear: dict | None = None) -> tuple[float, int]:
    """``(h, m)``: the fixed step ``h = dt / m`` with ``m`` the fewest substeps per sample such that
    ``h`` is at most the tyre time constants ``d_i / k_i`` (the contact-point equations are stiff
    with eigenvalue ``-k_i / d_i``) and ``STEP_WHEEL_PHASE / omega_wheel``, ``omega_wheel =
    sqrt((k_i + k_{3,4}) / m_i)`` (wheel hop); with a bump stop (``nonlinear``: the report's
    ``extended_model.nonlinear``) the chassis spring's stiffness there adds the stop's."""
    p = dict(params)
    for k in ("k3", "k4"):
        p[k] = p[k] + float((nonlinear or {}).get(f"stop_{k}", 0.0))
    h_max = min(p["d1"] / p["k1"], p["d2"] / p["k2"],
                STEP_WHEEL_PHASE / math.sqrt((p["k1"] + p["k3"]) / p["m1"]),
                STEP_WHEEL_PHASE / math.sqrt((p["k2"] + p["k4"]) / p["m2"]))
    m = max(1, math.ceil(dt / h_max - 1e-9))
    return dt / m, m


class SectionForces(eqx.Module):
    """Pure per-path function: section forces of every simulated variant for one force-noise draw.

    ``__call__(key, path_index, sigma) -> ((n, 11) outputs, result code)`` with the columns
    :data:`OUTPUT_COLUMNS`; ``sigma`` [N] is the standard deviation of white noise added to both
    measured forces (path ``path_index``'s draw, ``jaxdrift.white_noise``); ``sigma = 0`` is the
    nominal run. Variants without a measured pitch (``has_pitch=False``) give NaN columns.
    Fits :func:`jaxdrift.monte_carlo`'s ``path_fn`` with the per-path model ``(index, sigma)``.
    """

    forces: jax.Array        # ((n - 1) m + 1, 2) measured forces on the integration grid
    pitch: jax.Array         # (n, 3) prescribed beta, beta', beta''
    ts: jax.Array            # (n,) sample times
    params: HalfCarParams
    params_ext: HalfCarParams
    corr: jax.Array          # (5, 2): offset, scale, delay, drift, leak per force channel (Corrections.as_rows)
    spring: jax.Array        # (2,): k_rot, d_rot
    t0: float = eqx.field(static=True)
    dt: float = eqx.field(static=True)
    h: float = eqx.field(static=True)
    m: int = eqx.field(static=True)
    span: tuple = eqx.field(static=True)
    has_pitch: bool = eqx.field(static=True)
    has_drift: bool = eqx.field(static=True, default=False)  # a correction drifts (corr[3] != 0)
    leaks: tuple = eqx.field(static=True, default=(0.0, 0.0))  # crosstalk (Corrections.leaks)
    nonlinear_ext: NonlinearSuspension | None = None  # the extended model's nonlinear terms

    def __call__(self, key, idx, sigma):
        n = self.ts.shape[0]
        noise = white_noise(key, idx, n, jnp.stack([sigma, sigma]), dtype=self.forces.dtype)
        meas = self.forces + _linear_upsample(noise, self.m)  # white per sample, linear in between
        sig = SampledSignal(self.t0, self.h, meas)
        solver = SolverSpec("durability fixed", dt=self.h)
        p = self.params

        def forces_of(ys):
            return jnp.stack(spring_forces(ys[:, 0:4].T, ys[:, 4:8].T, p), axis=1)

        sol_fd = simulate_forces(p, sig, self.ts, solver, t_span=self.span)
        sol_ps = simulate_forces(p, sig, self.ts, solver, pitch_spring=(self.spring[0], self.spring[1]),
                                 t_span=self.span)
        torque = pitch_spring_torque(sol_ps.ys, self.spring[0], self.spring[1])
        cols = [forces_of(sol_fd.ys), forces_of(sol_ps.ys)]
        code = jnp.maximum(sol_fd.result.astype(jnp.int32), sol_ps.result.astype(jnp.int32))
        if self.has_pitch:
            pitch = SampledSignal(self.t0, self.dt, self.pitch)
            b, db = self.pitch[:, 0], self.pitch[:, 1]

            def stabilised(params, signal, nl=None):
                sol, lam, _ = simulate_prescribed_pitch(params, signal, pitch, self.ts, solver, t_span=self.span,
                                                        nonlinear=nl)
                y = sol.ys
                f3, f4 = spring_forces((y[:, 0], y[:, 1], y[:, 2], b), (y[:, 3], y[:, 4], y[:, 5], db), params,
                                       nonlinear=nl)
                return jnp.stack([f3, f4], axis=1), lam, sol.result.astype(jnp.int32)

            f_st, lam_st, c_st = stabilised(p, sig)
            corrected = remove_input_effects(meas, self.h, self.corr[0], self.corr[1], self.corr[2])
            if self.has_drift:  # a scale drifting over the run (Corrections: 1 / (1 + drift (t - t_mid)))
                t_rel = jnp.arange(meas.shape[0], dtype=meas.dtype)[:, None] * self.h - 0.5 * (self.span[1] - self.span[0])
                corrected = corrected / (1.0 + self.corr[3][None, :] * t_rel)
            if any(self.leaks):  # crosstalk between the channels (Corrections.unmix)
                corrected = jnp.stack(unmix(corrected[:, 0], corrected[:, 1], *self.leaks), axis=1)
            f_ex, lam_ex, c_ex = stabilised(self.params_ext, SampledSignal(self.t0, self.h, corrected),
                                            self.nonlinear_ext)
            cols += [f_st, f_ex]
            code = jnp.maximum(code, jnp.maximum(c_st, c_ex))
        else:
            nan = jnp.full((n, 2), jnp.nan, self.forces.dtype)
            cols += [nan, nan]
            lam_st = lam_ex = jnp.full((n,), jnp.nan, self.forces.dtype)
        out = jnp.concatenate(cols + [torque[:, None], lam_st[:, None], lam_ex[:, None]], axis=1)
        return out, code


def _linear_upsample(x, m: int):
    """``(n, c)`` samples -> ``((n - 1) m + 1, c)`` by linear interpolation (``m`` static)."""
    if m == 1:
        return x
    w = (jnp.arange(m, dtype=x.dtype) / m)[None, :, None]
    inner = x[:-1, None, :] + w * (x[1:, None, :] - x[:-1, None, :])
    return jnp.concatenate([inner.reshape(-1, x.shape[1]), x[-1:]], axis=0)


def upsample_forces(forces, m: int) -> np.ndarray:
    """Measured forces ``(n, 2)`` on the integration grid ``((n - 1) m + 1, 2)``, band-limited.

    Linear interpolation between samples acts as the low-pass ``sinc^2(f / fs)``: at 200 Hz it
    passes the wheel hop (22 Hz) with 0.96, which took 7 % off the damage of the section forces
    (``docs/durability.md``). So when the integration step subdivides the sample step, the samples are
    interpolated by the polyphase FIR of ``scipy.signal.resample_poly`` (Kaiser window, flat far
    beyond the vehicle's modes; linear extrapolation as padding so the static load does not ring
    at the ends). The samples themselves are kept exactly.
    """
    forces = np.asarray(forces, float)
    if m == 1:
        return forces
    from scipy import signal

    up = signal.resample_poly(forces, m, 1, axis=0, padtype="line")[: (forces.shape[0] - 1) * m + 1]
    up[::m] = forces
    return up


def build_section_forces(t, forces, pitch, params: dict, params_ext: dict, corrections: Corrections,
                         spring: dict, h: float, nonlinear_ext: dict | None = None) -> SectionForces:
    """A :class:`SectionForces` for a run (numpy inputs; ``pitch`` (n, 3) or None)."""
    t = np.asarray(t, float)
    dt = float((t[-1] - t[0]) / (t.size - 1))
    has_pitch = pitch is not None
    # a clipped channel's bursts restored first, on the measured samples (the record's first step)
    forces = np.stack([c.restore(t, np.asarray(forces)[:, i]) for i, (_, c) in enumerate(corrections.items())], axis=1)
    corr = corrections.as_rows()
    to_p = lambda d: jax.tree_util.tree_map(  # noqa: E731
        lambda v: jnp.asarray(v, jnp.float64), HalfCarParams.from_dict(d))
    m = max(1, int(round(dt / h)))
    return SectionForces(
        forces=jnp.asarray(upsample_forces(forces, m), jnp.float64),
        pitch=jnp.asarray(pitch if has_pitch else np.zeros((t.size, 3)), jnp.float64),
        ts=jnp.asarray(t), params=to_p(params), params_ext=to_p(params_ext), corr=jnp.asarray(corr),
        spring=jnp.asarray([spring["k_rot"], spring["d_rot"]], jnp.float64),
        t0=float(t[0]), dt=dt, h=dt / m, m=m, span=(float(t[0]), float(t[-1])), has_pitch=has_pitch,
        has_drift=bool(np.any(corr[3] != 0.0)), leaks=corrections.leaks, nonlinear_ext=_nonlinear_of(nonlinear_ext))


def _nonlinear_of(d: dict | None):
    """The extended model's nonlinear terms as a pytree of float64 arrays, None where it has none."""
    nl = NonlinearSuspension.from_json(d)
    return None if nl is None else jax.tree_util.tree_map(lambda v: jnp.asarray(v, jnp.float64), nl)
