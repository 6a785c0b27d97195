"""The extended model by re-simulation: the force-driven half-car (A.3) on the engine, before
and after the corrections, and the noise-only pitch envelope it is judged against."""

from __future__ import annotations

import math

import numpy as np
import scipy.signal

from ...io._csvio import VehicleRun
from ._causes import FORCE_CHANNELS
from ._discretise import _discretise
from ._residuals import rms as _rms

#: pitch error at which the force-driven simulation is said to have drifted off (0.5 deg)
DRIFT_THRESHOLD_RAD = math.radians(0.5)
#: the pitch error's dynamic band starts here [Hz]: below it the force-driven pitch drifts (force
#: noise integrates like Brownian motion, its error spectrum growing as 1/f^2 and faster towards
#: 0 Hz), above it lie the body's bounce and pitch modes (about 1-2 Hz) where a model error shows
DYNAMIC_BAND_HZ = 0.5


def _dynamic_rms(err: np.ndarray, dt: float) -> float:
    """RMS of the error above DYNAMIC_BAND_HZ (zero-phase 4th-order Butterworth high-pass), without
    the first and last 5 % (the filter's ends)."""
    n = len(err)
    if n < 64 or DYNAMIC_BAND_HZ >= 0.45 / dt:
        return _rms(err)
    sos = scipy.signal.butter(4, DYNAMIC_BAND_HZ, btype="highpass", fs=1.0 / dt, output="sos")
    k = n // 20
    return _rms(scipy.signal.sosfiltfilt(sos, err)[k:n - k])


#: the simulations are run in batches of this many (model, forces) pairs, the last one padded, so
#: that one compiled solve serves every call on a run (the re-simulation check's all-causes and
#: leave-one-out variants, its refits, and the report's before/after)
BATCH = 4
#: compiled solves kept (one per sample interval and length bucket; a sweep reuses them across runs)
CACHE_SIZE = 64


def _bucket(n: int) -> int:
    """The length the simulation is padded to: the next of 256 x 2^(j/4) samples (at most 19 %
    more), so that runs of one rate and similar length share a compiled solve."""
    j = max(0, math.ceil(4 * math.log2(n / 256) - 1e-9))
    return max(n, int(math.ceil(256 * 2 ** (j / 4))))


def _force_driven_pitch(run: VehicleRun, models: list, forces: list, nonlinear: list | None = None,
                        mounts: list | None = None) -> list:
    """States of the force-driven model (A.3) driven by ``forces``, from each model's static
    equilibrium, for several (model, forces) pairs at once (vmapped).

    The engine's DOPRI5 with a fixed step: the sample interval, halved until it is at most
    1 ms. The measured forces are linear between samples, so steps on the sample grid never
    straddle a kink; 1 ms keeps the stiffest mode (the wheel on its damper, about -700 1/s)
    well inside the method's stability region. Returns one ``(n, 10)`` array per pair, the states
    at the samples of the uniform grid the forces are read on.

    Compiling is most of the cost (1.5-5 s of CPU against 0.1-0.2 s for the solve of a few
    thousand samples), so the solve is compiled for a sample interval (the run's, to 9 significant
    digits) and a length bucket (``_bucket``; the forces held at their last value past the run's
    end, which the states at the run's samples do not see) and called in batches of ``BATCH``.
    ``nonlinear``: per pair, the chassis suspension's nonlinear terms
    (:class:`~jaxdrift.models.NonlinearSuspension`; None for all: the linear law, compiled without
    them). ``mounts``: per pair, a :class:`~jaxdrift.models.MountedMass` (one of zero mass for a
    model without; None for all: compiled without), the states then 12.
    """
    import jax
    import jax.numpy as jnp

    from ...solvers._inputs import SampledSignal

    dt, sub = solve_grid(run)
    n, nb = run.n, _bucket(run.n)
    out, codes = [], []
    if mounts is not None and nonlinear is None:
        from ...models._halfcar import NonlinearSuspension

        nonlinear = [NonlinearSuspension()] * len(models)

    def stacked(items, i0, pad):
        chunk = list(items[i0:i0 + BATCH])
        chunk += [chunk[-1]] * pad
        return jax.tree_util.tree_map(lambda *x: jnp.asarray(x, dtype=jnp.float64), *chunk)

    with jax.enable_x64(True):
        solve = _compiled_solve(nb, dt, sub, nonlinear is not None, mounts is not None)
        for i0, pad, _, params, values, y0 in batches(models, forces, nb - n):
            sig = jax.vmap(lambda v: SampledSignal(0.0, dt, v))(jnp.asarray(values))  # a batch of signals
            if mounts is not None:
                y0 = np.concatenate([y0, np.zeros((y0.shape[0], 2))], axis=1)
                ys, c = solve(params, sig, jnp.asarray(y0), stacked(nonlinear, i0, pad), stacked(mounts, i0, pad))
            elif nonlinear is None:
                ys, c = solve(params, sig, jnp.asarray(y0))
            else:
                ys, c = solve(params, sig, jnp.asarray(y0), stacked(nonlinear, i0, pad))
            out += list(np.asarray(ys)[:BATCH - pad, :n])
            codes += np.asarray(c)[:BATCH - pad].tolist()
    if np.any(np.asarray(codes) != 0):
        raise RuntimeError(f"force-driven simulation failed (result codes {codes})")
    return out


def solve_grid(run: VehicleRun) -> tuple[float, int]:
    """The sample interval the solves are compiled for (the run's, to 9 significant digits) and the
    fixed steps per sample (halved until at most 1 ms)."""
    dt = float(f"{run.dt:.9g}")
    return dt, int(math.ceil(dt / 1e-3 - 1e-9))


def batches(models: list, forces: list, extra: int):
    """The (model, forces) pairs in batches of ``BATCH`` (the last padded with its last pair), each
    as ``(i0, pad, models, params, values, y0)``: stacked float64 parameters, the forces
    ``(BATCH, n + extra, 2)`` held at their last value for ``extra`` samples past the end, and each
    model's static equilibrium (numpy)."""
    import jax
    import jax.numpy as jnp

    from ...models._halfcar import static_equilibrium
    from ...models._params import HalfCarParams

    for i0 in range(0, len(models), BATCH):
        ms, fs = list(models[i0:i0 + BATCH]), list(forces[i0:i0 + BATCH])
        pad = BATCH - len(ms)
        ms, fs = ms + [ms[-1]] * pad, fs + [fs[-1]] * pad
        ps = [jax.tree_util.tree_map(lambda v: jnp.asarray(v, dtype=jnp.float64), HalfCarParams.from_dict(m))
              for m in ms]
        params = jax.tree_util.tree_map(lambda *x: jnp.stack(x), *ps)
        values = np.stack([np.stack([np.asarray(f["f1"], dtype=np.float64),
                                     np.asarray(f["f2"], dtype=np.float64)], axis=1) for f in fs])
        values = np.concatenate([values, np.repeat(values[:, -1:], extra, axis=1)], axis=1)
        y0 = np.asarray(jax.vmap(lambda q: static_equilibrium(q, "force"))(params))
        yield i0, pad, ms, params, values, y0


#: compiled solves by (samples, sample interval, steps per sample), least recently used first
_JIT_CACHE: dict = {}


def _compiled_solve(n: int, dt: float, sub: int, nonlinear: bool = False, mount: bool = False):
    """The jitted, vmapped force-driven solve of ``n`` samples ``dt`` apart with ``sub`` steps per
    sample, saving at the samples. The save times are concrete (closed over), so the engine takes
    its fixed-step path for saves on the step grid (a scan over save intervals), which also
    compiles in about half the time of the general one. ``nonlinear``: the solve takes a batch of
    :class:`~jaxdrift.models.NonlinearSuspension` as its fourth argument; ``mount``: a batch of
    :class:`~jaxdrift.models.MountedMass` as its fifth."""
    import jax

    from ...analysis._force_driven import SolverSpec, simulate_forces

    key = (n, dt, sub, nonlinear, mount)
    f = _JIT_CACHE.pop(key, None)
    if f is None:
        tau = np.arange(n) * dt
        t1, h = float(tau[-1]), dt / sub

        def one(p, sg, y, nl=None, mt=None):
            sol = simulate_forces(p, sg, tau, SolverSpec("fixed", dt=h), x0=y, t_span=(0.0, t1), nonlinear=nl,
                                  mount=mt)
            return sol.ys, sol.result

        f = jax.jit(jax.vmap(one))
        while len(_JIT_CACHE) >= CACHE_SIZE:
            _JIT_CACHE.pop(next(iter(_JIT_CACHE)))
    _JIT_CACHE[key] = f
    return f


def _linear_force_system(p: dict):
    """Linearised force-driven half-car (A.3 without the contact points, which do not feed
    back): states [z1, z2, z3, beta, rates], inputs [f1, f2]."""
    m1, m2, m3, I = p["m1"], p["m2"], p["m3"], p["I"]
    k3, k4, d3, d4, a, b = p["k3"], p["k4"], p["d3"], p["d4"], p["a"], p["b"]
    # f3 = K3 q + D3 q', f4 = K4 q + D4 q'
    K3 = np.array([-k3, 0, k3, -b * k3])
    D3 = np.array([-d3, 0, d3, -b * d3])
    K4 = np.array([0, -k4, k4, a * k4])
    D4 = np.array([0, -d4, d4, a * d4])
    A = np.zeros((8, 8))
    A[:4, 4:] = np.eye(4)
    rows = [(K3 / m1, D3 / m1), (K4 / m2, D4 / m2), (-(K3 + K4) / m3, -(D3 + D4) / m3),
            ((b * K3 - a * K4) / I, (b * D3 - a * D4) / I)]
    for i, (K, D) in enumerate(rows):
        A[4 + i, :4] = K
        A[4 + i, 4:] = D
    B = np.zeros((8, 2))
    B[4, 0] = -1 / m1
    B[5, 1] = -1 / m2
    return A, B


def noise_pitch_std(p: dict, h: float, n: int) -> np.ndarray:
    """Standard deviation of the force-driven pitch error per unit force-noise sigma at the
    samples: propagated covariance of the linearised model, each noise sample held over its
    interval (exact for the linear model). Shape (n,)."""
    A, B = _linear_force_system(p)
    Phi, G = _discretise(A, B, h)
    Gam = G[0]
    var = np.zeros(n)
    acc = 0.0
    x = Gam.copy()  # response one step after a unit sample, both channels (8, 2)
    for k in range(1, n):
        acc += float(x[3, 0] ** 2 + x[3, 1] ** 2)
        var[k] = acc
        x = Phi @ x
    return np.sqrt(var)



def noise_pitch_dynamic_rms(p: dict, h: float) -> float:
    """RMS of the force-driven pitch error in the dynamic band (above ``DYNAMIC_BAND_HZ``, the
    zero-phase high-pass of ``_dynamic_rms``) per unit force-noise sigma: the linearised model's
    response to white samples on both forces (each held over its interval), integrated over
    frequency with the high-pass applied forward and backward. The drift below the band, which
    grows without bound, does not enter; what is left is stationary."""
    fs = 1.0 / h
    if DYNAMIC_BAND_HZ >= 0.45 * fs:
        return float("nan")
    A, B = _linear_force_system(p)
    Phi, G = _discretise(A, B, h)
    Gam = G[0]
    f = np.unique(np.concatenate([np.geomspace(DYNAMIC_BAND_HZ / 20, fs / 2, 1500),
                                  np.linspace(DYNAMIC_BAND_HZ / 20, fs / 2, 1500)]))
    z = np.exp(2j * np.pi * f * h)
    # (z I - Phi)^-1 Gam at every frequency in one batched solve; row 3 is the pitch: (nf, 2)
    H = np.linalg.solve(z[:, None, None] * np.eye(Phi.shape[0]) - Phi, Gam)[:, 3, :]
    sos = scipy.signal.butter(4, DYNAMIC_BAND_HZ, btype="highpass", fs=fs, output="sos")
    _, hp = scipy.signal.sosfreqz(sos, worN=f, fs=fs)
    power = np.sum(np.abs(H) ** 2, axis=1) * np.abs(hp) ** 4
    # variance of a discrete-time process: (1/pi) int_0^pi S(w) dw = 2 h int_0^{fs/2} S df
    return float(math.sqrt(2.0 * h * np.trapezoid(power, f)))



def resimulate(pipe, model: dict, p_ext: dict, corr_ext: dict, sigma: float, sim_err: dict,
               gain: dict, nonlinear: dict | None = None, mount: dict | None = None) -> tuple[dict, dict, dict]:
    """Run the force-driven model (A.3) before (model, measured forces) and after (extended model,
    corrected forces, and the confirmed nonlinear causes' terms ``nonlinear``, the report's
    ``extended_model.nonlinear``). Returns ``(sims, sim_err, gain)``: the simulations and the unit
    noise-only pitch envelope, and copies of ``sim_err`` and ``gain`` with the measured pitch/heave errors
    added (before; before/after). ``mount``: the report's ``extended_model.unmodelled_mode`` (the
    extended model then carries that mass on its spring)."""
    from ...models._halfcar import MountedMass, NonlinearSuspension

    run = pipe.run
    sim_err, gain = dict(sim_err), dict(gain)
    forces0 = {ch: run[ch] for ch in FORCE_CHANNELS}
    forces1 = {ch: v[::pipe.U] for ch, v in pipe.corrected_forces(corr_ext).items()}
    nl = NonlinearSuspension.from_json(nonlinear)
    mt = MountedMass.from_json(mount)
    y0, y1 = _force_driven_pitch(run, [model, p_ext], [forces0, forces1],
                                 None if nl is None else [NonlinearSuspension(), nl],
                                 None if mt is None else [MountedMass(0.0, 0.0, 0.0, 0.0), mt])
    sims = {"before": y0, "after": y1}
    env_unit = noise_pitch_std(model, run.dt, run.n)
    sims["pitch_std_unit"] = env_unit
    env = 1.96 * sigma * env_unit
    for label, ys in (("before", y0), ("after", y1)):
        if run.has("beta"):
            err = ys[:, 3] - run["beta"]
            above = np.flatnonzero(np.abs(err) > DRIFT_THRESHOLD_RAD)
            entry = {"rms": _rms(err), "rms_dynamic": _dynamic_rms(err, run.dt),
                     "dynamic_band_hz": DYNAMIC_BAND_HZ, "max_abs": float(np.max(np.abs(err))),
                     "drift_off_time_s": float(run.t[above[0]] - run.t[0]) if above.size else None,
                     "drift_threshold_rad": DRIFT_THRESHOLD_RAD,
                     "outside_noise_envelope_fraction": float(np.mean(np.abs(err) > env))}
            if label == "before":
                sim_err["beta"] = entry
            else:
                gain["beta_error"] = {"before": sim_err["beta"], "after": entry}
        if run.has("z3"):
            ez = ys[:, 2] - run["z3"]
            entry = {"rms": _rms(ez), "max_abs": float(np.max(np.abs(ez)))}
            if label == "before":
                sim_err["z3"] = entry
            else:
                gain["z3_error"] = {"before": sim_err["z3"], "after": entry}
    if run.has("beta"):
        gain["beta_rms_before"] = gain["beta_error"]["before"]["rms"]
        gain["beta_rms_after"] = gain["beta_error"]["after"]["rms"]
        gain["beta_rms_dynamic_before"] = gain["beta_error"]["before"]["rms_dynamic"]
        gain["beta_rms_dynamic_after"] = gain["beta_error"]["after"]["rms_dynamic"]
    return sims, sim_err, gain
