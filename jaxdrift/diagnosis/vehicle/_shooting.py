"""Force-driven re-simulation by multiple shooting: short windows restarted from the measured motion.

A force-driven simulation of a whole run drifts: the force noise integrates into the rigid-body
pitch and heave like Brownian motion, and a model error as small as a right correction's remainder
does the same. After the drift-off time the simulated vehicle is somewhere else (pitched by a
radian on the independent hold-out runs), and whether a correction makes its pitch better or worse
there says little about the correction. So the simulation is restarted every window (shorter than
the drift-off time of the force noise, at most ``WINDOW_MAX_S``) on the measured motion:

- the rigid-body states are moved onto the measured ones: the pitch and pitch rate (and the heave
  and its rate where the heave is measured) less the value and slope, at the window's end, of a
  straight line fitted to the window's error. A line over the whole window, not a derivative of
  the measured pitch at one instant: wheel hop and road texture put 10-20 Hz into the pitch, which
  a local derivative turns into a restart error larger than the model errors judged;
- the wheels and contact points move with the body so that no spring or tyre changes its length:
  the spring and tyre deflections and their rates carry on from the simulation, the model's own
  (stable, damped) response to the forces, which does not drift.

Each window's error is then the model's error over a time too short to drift; what the restart
leaves (a rigid-body angle and rate slightly off) grows as a straight line, which is removed per
window from the pitch and heave errors. Every variant (model, causes) is restarted by its own
error's line, so the comparison between variants is on equal terms.
"""

from __future__ import annotations

import math

import numpy as np

from ...io._csvio import VehicleRun

#: the longest window [s]: a few periods of the body modes (about 1-2 Hz)
WINDOW_MAX_S = 4.0
#: the shortest window [s], whatever the drift-off time: at least one period of the slowest body mode
WINDOW_MIN_S = 1.0


def window_samples(run: VehicleRun, drift_off_s: float | None) -> int:
    """Samples per window: the noise drift-off time, clipped to [WINDOW_MIN_S, WINDOW_MAX_S]."""
    t = WINDOW_MAX_S if drift_off_s is None or not math.isfinite(drift_off_s) else drift_off_s
    t = min(max(t, WINDOW_MIN_S), WINDOW_MAX_S)
    return max(8, round(t / run.dt))


def _line_end(err: np.ndarray, dt: float) -> tuple[float, float]:
    """Value at the last sample and slope [1/s] of a straight line fitted to ``err``."""
    x = np.arange(len(err), dtype=float)
    c1, c0 = np.polyfit(x, err, 1)
    return float(c0 + c1 * x[-1]), float(c1 / dt)


def restart_state(x: np.ndarray, p: dict, m: dict) -> np.ndarray:
    """The state ``x`` (10 force-mode states) moved rigidly to the measured motion ``m``: pitch and
    rate (and heave and rate where measured) set, wheels and contact points moved with the body so
    that the spring and tyre deflections and their rates stay as they were."""
    x = np.array(x, dtype=float)
    a, b = p["a"], p["b"]
    sb0, cb0 = math.sin(x[3]), math.cos(x[3])
    sb1, cb1 = math.sin(m["beta"]), math.cos(m["beta"])
    dz = m["z3"] - x[2] if "z3" in m else 0.0
    ddz = m["dz3"] - x[6] if "dz3" in m else 0.0
    # spring i's length: z3 - z_i -/+ lever sin(beta); keep it while beta and z3 change
    dz1 = dz - b * (sb1 - sb0)
    dz2 = dz + a * (sb1 - sb0)
    dv = m["dbeta"] * cb1 - x[7] * cb0
    x[0] += dz1
    x[1] += dz2
    x[2] += dz
    x[3] = m["beta"]
    x[4] += ddz - b * dv
    x[5] += ddz + a * dv
    x[6] += ddz
    x[7] = m["dbeta"]
    x[8] += dz1  # the contact points move with their wheels (tyre deflection kept)
    x[9] += dz2
    return x


def shooting_states(run: VehicleRun, models: list, forces: list, window: int) -> list[np.ndarray]:
    """States of the force-driven model (A.3) for several (model, forces) pairs, simulated in windows
    of ``window`` samples, each restarted on the measured motion (:func:`restart_state`); the
    first starts from the model's static equilibrium as the run does. One ``(n, 10)`` array per
    pair; the state at each window start is the restarted one."""
    import jax
    import jax.numpy as jnp

    from ...solvers._inputs import SampledSignal
    from ._extend import BATCH, _compiled_solve, batches, solve_grid

    dt, sub = solve_grid(run)
    n = run.n
    starts = list(range(0, n - 1, window))
    beta = np.asarray(run["beta"], dtype=float)
    z3 = np.asarray(run["z3"], dtype=float) if run.has("z3") else None
    out = [np.zeros((n, 10)) for _ in models]
    with jax.enable_x64(True):
        solve = _compiled_solve(window + 1, dt, sub)
        for i0, pad, ms, params, values, x in batches(models, forces, window + 1):
            restarts: list = []
            for w, s in enumerate(starts):
                if w:
                    x = np.stack([restart_state(x[j], ms[j], restarts[j]) for j in range(BATCH)])
                sig = jax.vmap(lambda v: SampledSignal(0.0, dt, v))(jnp.asarray(values[:, s:s + window + 1]))
                ys, codes = solve(params, sig, jnp.asarray(x))
                ys = np.asarray(ys)
                if np.any(np.asarray(codes) != 0):
                    raise RuntimeError(f"force-driven simulation failed (result codes {np.asarray(codes).tolist()})")
                e = min(s + window + 1, n)
                for j in range(BATCH - pad):
                    out[i0 + j][s:e] = ys[j, :e - s]
                end = min(window, n - 1 - s)
                x = ys[:, end]
                restarts = []
                for j in range(BATCH):  # each variant onto the measured motion by its own error's line
                    e_b, r_b = _line_end(ys[j, :end + 1, 3] - beta[s:s + end + 1], dt)
                    m = {"beta": x[j, 3] - e_b, "dbeta": x[j, 7] - r_b}
                    if z3 is not None:
                        e_z, r_z = _line_end(ys[j, :end + 1, 2] - z3[s:s + end + 1], dt)
                        m.update(z3=x[j, 2] - e_z, dz3=x[j, 6] - r_z)
                    restarts.append(m)
    return out


def _detrended(err: np.ndarray, window: int) -> np.ndarray:
    """``err`` less a straight line fitted per window (the restart's own error)."""
    out = np.empty_like(err)
    for s in range(0, len(err), window):
        seg = err[s:s + window]
        if len(seg) < 3:
            out[s:s + window] = seg - seg.mean()
            continue
        x = np.arange(len(seg), dtype=float)
        out[s:s + window] = seg - np.polyval(np.polyfit(x, seg, 1), x)
    return out


def channel_errors(run: VehicleRun, ys: np.ndarray, p: dict, window: int) -> dict:
    """RMS error of each measured motion channel against the windowed simulation: pitch and heave
    less their per-window straight line, spring travels as they are."""
    from ...models._halfcar import spring_travel_np

    out = {"beta": float(np.sqrt(np.mean(_detrended(ys[:, 3] - run["beta"], window) ** 2)))}
    if run.has("z3"):
        out["z3"] = float(np.sqrt(np.mean(_detrended(ys[:, 2] - run["z3"], window) ** 2)))
    travel = spring_travel_np(ys, p["a"], p["b"])
    for ch in ("s1", "s2"):
        if run.has(ch):
            out[ch] = float(np.sqrt(np.mean((travel[ch] - run[ch]) ** 2)))
    return out
