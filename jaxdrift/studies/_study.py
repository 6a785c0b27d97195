"""The seed paper's section-4 study (steps 1-5 of section 4.1) on the engine.

1. **virtual measurement**: the road-driven half-car (A.4) on an ISO 8608 road with hills; its
   contact forces (4.3) sampled at ``sample_rate`` are the "measured" wheel forces ``f^(0)``;
2. **undisturbed forces**: the force-driven model (A.3) excited by ``f^(0)`` (linear
   interpolation between samples);
3. **noisy forces**: ``f^(0) + eps``, ``eps`` Gaussian white noise per sample with
   ``sigma = noise_rel * max|f^(0)|`` (the paper's 0.002 f_max), many samples through
   :func:`jaxdrift.monte_carlo`;
4. **perturbed models**: the paper's fixed perturbation and random factors in [0.9, 1.1] on
   ``k3, k4, d3, d4, I`` (a batch of models through :func:`jaxdrift.monte_carlo`), undisturbed
   forces;
5. **stabilised simulation**: the perturbed model with noisy forces and the pitch angle prescribed
   from the virtual measurement (A.5); the enforced moment ``lambda`` against the inertia term
   ``I beta''``.

**Drift-off time** of a simulation: the first save time at which the pitch error
``|beta_sim - beta_measured|`` exceeds ``drift_threshold_deg`` (default 1 deg), ``inf`` if never
(the same with ``z3_threshold`` metres for the vertical chassis motion ``z3``). Every simulation
starts from the static equilibrium of its own model (:func:`jaxdrift.static_equilibrium`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any, Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..models._halfcar import (
    contact_forces,
    enforced_moment,
    force_driven_rhs,
    pitch_spring_torque,
    prescribed_pitch_rhs,
    road_driven_rhs,
    static_equilibrium,
)
from ..solvers._inputs import SampledSignal
from ..ensemble._montecarlo import monte_carlo
from ..ensemble._noise import white_noise
from ..models._params import HalfCarParams, random_perturbed_models
from ..models._road import WheelInputs, iso8608_road
from ..solvers._solve import solve_ode

__all__ = [
    "SolverSpec",
    "SOLVER_LOOSE",
    "SOLVER_TIGHT",
    "SOLVER_FIXED",
    "StudyConfig",
    "VirtualMeasurement",
    "virtual_measurement",
    "simulate_forces",
    "simulate_prescribed_pitch",
    "drift_off_time",
    "run_force_paths",
    "run_pitch_paths",
    "run_paper_study",
]


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
#: Fixed-step Dormand-Prince at the force sample rate (1 ms for 1 kHz).
SOLVER_FIXED = SolverSpec("dopri5 fixed 1 ms", dt=1e-3)


@dataclasses.dataclass(frozen=True)
class StudyConfig:
    """Settings of :func:`run_paper_study`; the defaults reproduce the paper's findings.

    The road (class D, 20 m/s, +-2 m hills of 250 m wavelength) gives wheel forces of about
    -4 kN .. +13 kN and ``sigma = 0.002 f_max`` of about 25 N (the paper's Fig. 4: about
    -10 .. +16 kN, 32 N). The force-driven runs use the paper's looser tolerance (rtol 1e-4,
    atol 1e-6); ``compare_solvers`` lists the solvers of the tolerance comparison.
    """

    params: HalfCarParams = dataclasses.field(default_factory=HalfCarParams)
    duration: float = 30.0
    speed: float = 20.0
    road_class: str = "D"
    road_seed: int = 0
    hill_height: float = 2.0
    hill_wavelength: float = 250.0
    sample_rate: float = 1000.0
    noise_rel: float = 0.002
    n_noise: int = 32
    n_models: int = 32
    seed: int = 0
    save_dt: float = 0.01
    drift_threshold_deg: float = 1.0
    z3_threshold: float = 0.05
    measurement_rtol: float = 1e-9
    measurement_atol: float = 1e-11
    solver: SolverSpec = SOLVER_LOOSE
    compare_solvers: tuple[SolverSpec, ...] = (SOLVER_LOOSE, SOLVER_TIGHT, SOLVER_FIXED)
    n_compare: int = 8
    pitch_spring_stiffness: tuple[float, ...] = (1e1, 1e2, 1e3, 1e4, 1e5)
    linear: bool = False  # simulate with the small-angle form (the measurement stays nonlinear)
    n_spring: int = 4
    progress: bool = True

    def validate(self) -> "StudyConfig":
        self.params.validate()
        for name in ("duration", "speed", "sample_rate", "save_dt", "drift_threshold_deg", "z3_threshold"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"StudyConfig: {name} must be positive, got {v!r}")
        if not (np.isfinite(self.noise_rel) and self.noise_rel >= 0):
            raise ValueError(f"StudyConfig: noise_rel must be >= 0, got {self.noise_rel!r}")
        for name in ("n_noise", "n_models", "n_compare"):
            if int(getattr(self, name)) < 2:
                raise ValueError(f"StudyConfig: {name} must be >= 2, got {getattr(self, name)!r}")
        if self.save_dt < 1.0 / self.sample_rate - 1e-12:
            raise ValueError("StudyConfig: save_dt must not be shorter than the force sample period")
        if self.duration * self.sample_rate < 10:
            raise ValueError("StudyConfig: duration too short for the sample rate (fewer than 10 samples)")
        return self

    @property
    def wheelbase(self) -> float:
        return float(self.params.a + self.params.b)


# ---------------------------------------------------------------------------------------------
# step 1: virtual measurement
# ---------------------------------------------------------------------------------------------
class VirtualMeasurement(eqx.Module):
    """Result of the road-driven simulation sampled at the force sample rate.

    ``ts (n,)``; ``x (n, 8)`` road-mode states; ``zeta, dzeta (n, 2)`` road under the wheels;
    ``forces (n, 2)`` contact forces (4.3); ``ddbeta (n,)`` pitch acceleration (from (A.2)).
    """

    ts: jax.Array
    x: jax.Array
    zeta: jax.Array
    dzeta: jax.Array
    forces: jax.Array
    ddbeta: jax.Array

    @property
    def dt(self) -> float:
        return float(self.ts[1] - self.ts[0])

    def force_signal(self, noise=None) -> SampledSignal:
        """The wheel forces as a linearly interpolated :class:`SampledSignal` (plus ``noise``)."""
        v = self.forces if noise is None else self.forces + noise
        return SampledSignal(self.ts[0], self.dt, v, kind="linear")

    def pitch_signal(self) -> SampledSignal:
        """``(beta, beta', beta'')`` of the measurement, linearly interpolated (for (A.5))."""
        return SampledSignal(
            self.ts[0], self.dt, jnp.stack([self.x[:, 3], self.x[:, 7], self.ddbeta], axis=1), kind="linear"
        )


def _n_samples(duration: float, rate: float) -> int:
    n = int(round(duration * rate)) + 1
    if n < 2:
        raise ValueError(f"duration {duration} s at {rate} Hz gives fewer than 2 samples")
    return n


def virtual_measurement(
    params: HalfCarParams,
    inputs: WheelInputs | Callable,
    duration: float,
    sample_rate: float = 1000.0,
    rtol: float = 1e-9,
    atol: float = 1e-11,
) -> VirtualMeasurement:
    """Step 1: simulate the road-driven model (A.4) and sample the contact forces (4.3).

    ``inputs(t) -> (zeta (2,), dzeta (2,))`` is the road under the wheels (a
    :class:`~jaxdrift.WheelInputs` from :meth:`RoadProfile.sampled_wheel_inputs`, or any jittable
    callable/Module). The model starts from its static equilibrium on level ground.
    """
    params.validate()
    if not (np.isfinite(duration) and duration > 0 and np.isfinite(sample_rate) and sample_rate > 0):
        raise ValueError(f"virtual_measurement: need duration > 0 and sample_rate > 0, got {duration}, {sample_rate}")
    n = _n_samples(duration, sample_rate)
    ts = jnp.arange(n) / sample_rate
    t_end = getattr(inputs, "t1", None)
    if t_end is not None and float(t_end) < float(ts[-1]) - 1e-9:
        raise ValueError(
            f"virtual_measurement: the road inputs end at t = {float(t_end):g} s, before the "
            f"{duration:g} s run (mismatched lengths)"
        )

    ys, z, dz, forces, dd, result = _measure(params, inputs, ts, float(rtol), float(atol))
    if int(result) != 0:
        raise RuntimeError(f"virtual measurement failed: solver result code {int(result)}")
    return VirtualMeasurement(ts=ts, x=ys, zeta=z, dzeta=dz, forces=forces, ddbeta=dd)


def _road_vf(t, x, args):
    p, inp = args
    z, dz = inp(t)
    return road_driven_rhs(t, x, p, z, dz)


@eqx.filter_jit
def _measure(p, inp, ts, rtol, atol):
    # module-level and filter-jitted: repeated measurements with the same shapes compile once
    z0, _ = inp(jnp.asarray(0.0, ts.dtype))
    x0 = static_equilibrium(p, "road", zeta=(z0[0], z0[1]))
    sol = solve_ode(_road_vf, x0, ts[0], ts[-1], saveat=ts, args=(p, inp), rtol=rtol, atol=atol,
                    max_steps=10_000_000)
    z, dz = jax.vmap(inp)(ts)
    forces = jax.vmap(lambda x, a, b: contact_forces(x, p, a, b))(sol.ys, z, dz)
    dd = jax.vmap(lambda t, x, a, b: road_driven_rhs(t, x, p, a, b)[7])(ts, sol.ys, z, dz)
    return sol.ys, z, dz, forces, dd, sol.result


# ---------------------------------------------------------------------------------------------
# steps 2-4: force-driven simulations
# ---------------------------------------------------------------------------------------------
def _force_vf(t, x, args):
    p, sig, spring = args
    f = sig(t)
    return force_driven_rhs(t, x, p, f[0], f[1], pitch_spring=spring)


def _force_vf_linear(t, x, args):
    p, sig, spring = args
    f = sig(t)
    return force_driven_rhs(t, x, p, f[0], f[1], linear=True, pitch_spring=spring)


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
                    x0=None, t_span=None, linear: bool = False):
    """Force-driven model (A.3) excited by ``forces`` (``(2,)`` channels) from its equilibrium.

    Returns the engine's ``Solution`` (``ys`` of shape ``(len(save_ts), 10)``). Pure JAX: may be
    called under ``jit``/``vmap`` (``params`` may be a traced model); with traced ``save_ts`` give
    the concrete ``t_span=(t0, t1)``. ``pitch_spring=(k, d)`` adds the section-3 rotational
    spring-damper; ``linear=True`` integrates the small-angle form of (A.3).
    """
    _check_signal("forces", forces, 2)
    t0, t1 = _span(save_ts, t_span)
    if x0 is None:
        x0 = static_equilibrium(params, "force")
    spring = None if pitch_spring is None else tuple(pitch_spring)
    return solve_ode(
        _force_vf_linear if linear else _force_vf, x0, t0, t1, saveat=jnp.asarray(save_ts), args=(params, forces, spring), **solver.kwargs()
    )


def _pitch_vf(t, x, args):
    p, sig, pitch = args
    f = sig(t)
    b = pitch(t)
    return prescribed_pitch_rhs(t, x, p, f[0], f[1], b[0], b[1])


def _pitch_vf_linear(t, x, args):
    p, sig, pitch = args
    f = sig(t)
    b = pitch(t)
    return prescribed_pitch_rhs(t, x, p, f[0], f[1], b[0], b[1], linear=True)


def simulate_prescribed_pitch(params, forces: SampledSignal, pitch: SampledSignal, save_ts,
                              solver: SolverSpec = SOLVER_LOOSE, t_span=None, linear: bool = False):
    """Step 5: model (A.5) driven by ``forces`` (2 channels) with the pitch prescribed by ``pitch``
    (3 channels: ``beta, beta', beta''``).

    Returns ``(solution, lam, inertia)``: the engine's ``Solution`` (8 states ``z1, z2, z3, z1',
    z2', z3', zeta1, zeta2``), the enforced moment ``lambda = I beta'' - cos(beta)(b f3 - a f4)``
    (``cos(beta) = 1`` with ``linear``) and the inertia term ``I beta''`` at ``save_ts``. The
    initial state is the model's static equilibrium ``static_equilibrium(params, "pitch")``,
    whatever the prescribed pitch is at the start: a pitch that does not start at the model's
    equilibrium pitch (0 for the seed's symmetric table) gives an initial transient in ``lam``.
    ``t_span``: ``(t0, t1)``, default the first and last save time.
    """
    _check_signal("forces", forces, 2)
    _check_signal("pitch", pitch, 3)
    t0, t1 = _span(save_ts, t_span)
    save_ts = jnp.asarray(save_ts)
    x0 = static_equilibrium(params, "pitch")
    vf = _pitch_vf_linear if linear else _pitch_vf
    sol = solve_ode(vf, x0, t0, t1, saveat=save_ts, args=(params, forces, pitch), **solver.kwargs())
    b = jax.vmap(pitch)(save_ts)
    lam = enforced_moment(sol.ys, params, b[:, 0], b[:, 1], b[:, 2], linear=linear)
    return sol, lam, params.I * b[:, 2]


def drift_off_time(ts, error, threshold) -> float:
    """First time in ``ts`` where ``|error| > threshold`` (or is not finite); ``inf`` if never."""
    ts, error = np.asarray(ts), np.asarray(error)
    bad = ~(np.abs(error) <= threshold)
    return float(ts[np.argmax(bad)]) if bad.any() else math.inf



def _noisy_forces(forces, t0, dt, key, idx, sigma) -> SampledSignal:
    """Path ``idx``'s measured forces: ``forces`` plus white noise of std ``sigma`` on both channels."""
    v = forces + white_noise(key, idx, forces.shape[0], jnp.stack([sigma, sigma]), dtype=forces.dtype)
    return SampledSignal(t0, dt, v)


class _ForcePath(eqx.Module):
    """``path_fn`` of the force-driven studies (steps 2-4 and the pitch spring).

    The per-path "model" is a tuple ``(params, sigma, k_rot, d_rot)``: one compiled function runs
    undisturbed, noisy, perturbed and spring-stabilised paths side by side. Noise of path ``i`` is
    ``white_noise(key, i, ...)``: the same index gives the same noise under every solver.
    Outputs ``[z3, beta, pitch-spring torque]`` at the save times.
    """

    forces: jax.Array
    t0: jax.Array
    dt: jax.Array
    save_ts: jax.Array
    solver: SolverSpec = eqx.field(static=True)
    span: tuple = eqx.field(static=True)
    linear: bool = eqx.field(static=True, default=False)

    def __call__(self, key, idx, batch):
        p, sigma, k_rot, d_rot = batch
        sig = _noisy_forces(self.forces, self.t0, self.dt, key, idx, sigma)
        sol = simulate_forces(p, sig, self.save_ts, self.solver, pitch_spring=(k_rot, d_rot), t_span=self.span,
                              linear=self.linear)
        torque = pitch_spring_torque(sol.ys, k_rot, d_rot)
        return jnp.stack([sol.ys[:, 2], sol.ys[:, 3], torque], axis=1), sol.result.astype(jnp.int32)


class _PitchPath(eqx.Module):
    """``path_fn`` of step 5 (A.5): per path ``(params, sigma)``; outputs ``[z3, lambda, I beta'']``."""

    forces: jax.Array
    pitch: jax.Array
    t0: jax.Array
    dt: jax.Array
    save_ts: jax.Array
    solver: SolverSpec = eqx.field(static=True)
    span: tuple = eqx.field(static=True)
    linear: bool = eqx.field(static=True, default=False)

    def __call__(self, key, idx, batch):
        p, sigma = batch
        sig = _noisy_forces(self.forces, self.t0, self.dt, key, idx, sigma)
        pitch = SampledSignal(self.t0, self.dt, self.pitch)
        sol, lam, inertia = simulate_prescribed_pitch(p, sig, pitch, self.save_ts, self.solver, t_span=self.span,
                                                      linear=self.linear)
        return jnp.stack([sol.ys[:, 2], lam, inertia], axis=1), sol.result.astype(jnp.int32)


def _batch(models: list, *extra) -> tuple:
    """Stack scalar models and per-path extras into the ``models=`` pytree of monte_carlo."""
    from ..models._params import stack_models

    return (stack_models(models), *(np.asarray(e, dtype=float) for e in extra))


def _chunk(n: int) -> int:
    return max(1, min(16, n))


def run_force_paths(vm, save_ts, models, sigmas, springs=None, solver=SOLVER_LOOSE, seed=0, progress=True,
                    linear=False):
    """Run force-driven paths (``models[i]``, noise ``sigmas[i]``, spring ``springs[i]``).

    Returns the engine's ``MCResult`` with every path kept: outputs ``[z3, beta, torque]``.
    """
    n = len(models)
    springs = [(0.0, 0.0)] * n if springs is None else springs
    if len(sigmas) != n or len(springs) != n:
        raise ValueError(f"run_force_paths: {n} models but {len(sigmas)} sigmas and {len(springs)} springs")
    if n == 0:
        raise ValueError("run_force_paths: no paths")
    batch = _batch(models, sigmas, [s[0] for s in springs], [s[1] for s in springs])
    fn = _ForcePath(forces=vm.forces, t0=vm.ts[0], dt=jnp.asarray(vm.dt), save_ts=jnp.asarray(save_ts),
                    solver=solver, span=_span(save_ts, None), linear=bool(linear))
    return monte_carlo(fn, n, key=jax.random.key(seed), save_ts=np.asarray(save_ts), models=batch,
                       keep_paths=True, progress=progress, chunk_size=_chunk(n))


def run_pitch_paths(vm, save_ts, models, sigmas, solver=SOLVER_LOOSE, seed=0, progress=True, linear=False):
    """Run stabilised paths (A.5) with the measured pitch prescribed: outputs ``[z3, lambda, I beta'']``."""
    n = len(models)
    if len(sigmas) != n or n == 0:
        raise ValueError(f"run_pitch_paths: {n} models but {len(sigmas)} sigmas")
    pitch = jnp.stack([vm.x[:, 3], vm.x[:, 7], vm.ddbeta], axis=1)
    fn = _PitchPath(forces=vm.forces, pitch=pitch, t0=vm.ts[0], dt=jnp.asarray(vm.dt),
                    save_ts=jnp.asarray(save_ts), solver=solver, span=_span(save_ts, None), linear=bool(linear))
    return monte_carlo(fn, n, key=jax.random.key(seed + 1), save_ts=np.asarray(save_ts),
                       models=_batch(models, sigmas), keep_paths=True, progress=progress, chunk_size=_chunk(n))


def _unstack(models: HalfCarParams) -> list[HalfCarParams]:
    n = int(np.shape(models.k3)[0])
    names = HalfCarParams.field_names()
    return [HalfCarParams(**{k: float(np.asarray(getattr(models, k))[i]) for k in names}) for i in range(n)]


def _stats(x) -> dict:
    x = np.asarray(x, dtype=float)
    fin = x[np.isfinite(x)]
    out = dict(n=int(x.size), n_never=int(np.count_nonzero(~np.isfinite(x))))
    if fin.size:
        # quantiles without interpolation, so "never" (inf) paths count as the latest times
        def q(level):
            return float(np.quantile(x, level, method="inverted_cdf"))

        out.update(min=float(fin.min()), median=q(0.5), max=float(fin.max()), q10=q(0.1), q90=q(0.9))
    else:
        out.update(min=None, median=None, max=None, q10=None, q90=None)
    return out


def _json_float(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None if math.isnan(v) else ("inf" if v > 0 else "-inf")
    return v


def _range(x) -> dict:
    x = np.asarray(x, dtype=float)
    return dict(min=float(x.min()), max=float(x.max()), abs_max=float(np.abs(x).max()),
                rms=float(np.sqrt(np.mean(x**2))))


def run_paper_study(cfg: StudyConfig, log: Callable[[str], None] = print) -> dict:
    """Run steps 1-5 of the paper's section 4.1 and the extra studies; return all results.

    Returns a dict with the virtual measurement ``vm``, the save grids, the engine results of
    every Monte-Carlo run and a JSON-ready ``summary`` (see ``docs/paper-study.md``).
    """
    cfg.validate()
    p = cfg.params
    timings: dict[str, float] = {}
    t_start = time.perf_counter()

    def step(name):
        timings[name] = time.perf_counter() - step.t
        step.t = time.perf_counter()

    step.t = t_start

    log(f"[1/6] virtual measurement: road class {cfg.road_class}, {cfg.speed} m/s, {cfg.duration} s ...")
    road = iso8608_road(cfg.road_class, seed=cfg.road_seed, hill_height=cfg.hill_height,
                        hill_wavelength=cfg.hill_wavelength)
    inputs = road.sampled_wheel_inputs(cfg.speed, cfg.wheelbase, cfg.duration)
    vm = virtual_measurement(p, inputs, cfg.duration, cfg.sample_rate, cfg.measurement_rtol, cfg.measurement_atol)
    fmax = float(jnp.max(jnp.abs(vm.forces)))
    sigma = cfg.noise_rel * fmax
    step("virtual_measurement")

    step_idx = max(1, int(round(cfg.save_dt * cfg.sample_rate)))
    sidx = np.arange(0, vm.ts.shape[0], step_idx)
    save_ts = np.asarray(vm.ts)[sidx]
    beta_ref = np.asarray(vm.x[sidx, 3])
    z3_ref = np.asarray(vm.x[sidx, 2])

    # --- one batch of force-driven paths: steps 2-4 and the pitch-spring remedy --------------
    paper_model = p.paper_perturbed()
    random_models = _unstack(random_perturbed_models(cfg.n_models, seed=cfg.seed, base=p))
    J = float(p.pitch_inertia_whole)
    models, sigmas, springs, kinds = [], [], [], []

    def add(kind, model, sig, spring=(0.0, 0.0)):
        kinds.append(kind)
        models.append(model)
        sigmas.append(sig)
        springs.append(spring)

    add("undisturbed", p, 0.0)
    add("perturbed_paper", paper_model, 0.0)
    for _ in range(cfg.n_noise):
        add("noisy", p, sigma)
    for m in random_models:
        add("perturbed_random", m, 0.0)
    n_spring = max(1, min(cfg.n_spring, cfg.n_noise))
    for k in cfg.pitch_spring_stiffness:
        for _ in range(n_spring):
            add(f"spring_{k:g}", p, sigma, (float(k), 2.0 * math.sqrt(k * J)))
    kinds_arr = np.array(kinds)
    log(f"[2-4/6] force-driven simulations: undisturbed, {cfg.n_noise} noise samples "
        f"(sigma = {sigma:.1f} N), {cfg.n_models} perturbed models, pitch spring "
        f"({len(cfg.pitch_spring_stiffness)} stiffnesses x {n_spring}); {len(models)} paths, {cfg.solver.name}")
    main = run_force_paths(vm, save_ts, models, sigmas, springs, cfg.solver, cfg.seed, cfg.progress, cfg.linear)
    step("force_paths")
    if main.n_failed:
        log(f"warning: {main.n_failed} force-driven paths failed (solver result codes {np.unique(main.result)})")

    # --- step 5: stabilised simulation --------------------------------------------------------
    n_st = max(2, min(cfg.n_compare, cfg.n_noise))
    st_models = [p, p, paper_model] + [paper_model] * n_st
    st_sigmas = [0.0, sigma, 0.0] + [sigma] * n_st
    st_kinds = np.array(["unperturbed_undisturbed", "unperturbed_noisy", "perturbed_undisturbed"]
                        + ["perturbed_noisy"] * n_st)
    moment_ts = np.asarray(vm.ts)
    log(f"[5/6] stabilised simulation (prescribed pitch, A.5): {len(st_models)} paths ...")
    stab = run_pitch_paths(vm, moment_ts, st_models, st_sigmas, cfg.solver, cfg.seed, cfg.progress, cfg.linear)
    step("stabilised")

    # --- solver / tolerance comparison --------------------------------------------------------
    n_cmp = min(cfg.n_compare, cfg.n_noise)
    cmp_models = [p, paper_model] + [p] * n_cmp
    cmp_sigmas = [0.0, 0.0] + [sigma] * n_cmp
    comparisons = {cfg.solver.name: main}
    others = [s for s in cfg.compare_solvers if s.name != cfg.solver.name]
    for i, s in enumerate(others):
        log(f"[6/6] solver comparison {i + 1}/{len(others)}: {s.name}, undisturbed + {n_cmp} noise samples ...")
        comparisons[s.name] = run_force_paths(vm, save_ts, cmp_models, cmp_sigmas, None, s, cfg.seed, cfg.progress,
                                              cfg.linear)
    step("solver_comparison")

    summary = _summarise(cfg, vm, save_ts, beta_ref, z3_ref, sigma, fmax, main, kinds_arr, stab, st_kinds,
                         comparisons, n_cmp, road)
    timings["total"] = time.perf_counter() - t_start
    summary["timings_s"] = {k: round(v, 2) for k, v in timings.items()}
    return dict(cfg=cfg, vm=vm, save_ts=save_ts, beta_ref=beta_ref, z3_ref=z3_ref, sigma=sigma, main=main,
                kinds=kinds_arr, stab=stab, stab_kinds=st_kinds, moment_ts=moment_ts, comparisons=comparisons,
                summary=summary)


def _summarise(cfg, vm, save_ts, beta_ref, z3_ref, sigma, fmax, main, kinds, stab, st_kinds, comparisons, n_cmp, road):
    thr = math.radians(cfg.drift_threshold_deg)
    beta = main.ys[:, :, 1]
    z3 = main.ys[:, :, 0]
    eb = beta - beta_ref[None, :]
    ez = z3 - z3_ref[None, :]

    def doff(rows, threshold=thr, err=eb):
        return np.array([drift_off_time(save_ts, err[r], threshold) for r in rows])

    def rows(kind):
        return np.flatnonzero(kinds == kind)

    groups = ("undisturbed", "perturbed_paper", "noisy", "perturbed_random")
    drift = {}
    for g in groups:
        d = doff(rows(g))
        drift[g] = float(d[0]) if d.size == 1 else _stats(d)
    by_thr = {}
    for t_deg in (0.5, 1.0, 2.0, 5.0):
        by_thr[f"{t_deg:g}"] = {
            g: (float(doff(rows(g), math.radians(t_deg))[0]) if rows(g).size == 1
                else _stats(doff(rows(g), math.radians(t_deg))))
            for g in groups
        }
    z3_drift = {}
    for g in groups:
        d = doff(rows(g), cfg.z3_threshold, ez)
        z3_drift[g] = float(d[0]) if d.size == 1 else _stats(d)
    end_err = {
        g: dict(beta_deg_rms=float(np.degrees(np.sqrt(np.mean(eb[rows(g), -1] ** 2)))),
                z3_m_rms=float(np.sqrt(np.mean(ez[rows(g), -1] ** 2))))
        for g in groups
    }

    # stabilised: enforced moment and inertia term
    lam = stab.ys[:, :, 1]
    inertia = stab.ys[:, :, 2]
    moment = {k: _range(lam[st_kinds == k]) for k in dict.fromkeys(st_kinds)}
    moment["inertia_term"] = _range(inertia[0])

    # pitch spring (the first row, stiffness 0, is the free model on the same noise samples)
    spring = []
    n_sp = int(np.count_nonzero(kinds == f"spring_{cfg.pitch_spring_stiffness[0]:g}")) if cfg.pitch_spring_stiffness else 0
    if n_sp:
        r = rows("noisy")[:n_sp]
        e = eb[r]
        spring.append(dict(
            stiffness=0.0, damping=0.0,
            pitch_error_rms_deg=float(np.degrees(np.sqrt(np.mean(e**2)))),
            pitch_error_max_deg=float(np.degrees(np.max(np.abs(e)))),
            drift_off_s=_stats(doff(r)), reaction_torque_max=0.0, reaction_torque_rms=0.0,
        ))
    for k in cfg.pitch_spring_stiffness:
        r = rows(f"spring_{k:g}")
        e = eb[r]
        tq = main.ys[r, :, 2]
        spring.append(dict(
            stiffness=float(k), damping=float(2 * math.sqrt(k * float(cfg.params.pitch_inertia_whole))),
            pitch_error_rms_deg=float(np.degrees(np.sqrt(np.mean(e**2)))),
            pitch_error_max_deg=float(np.degrees(np.max(np.abs(e)))),
            drift_off_s=_stats(doff(r)),
            reaction_torque_max=float(np.max(np.abs(tq))),
            reaction_torque_rms=float(np.sqrt(np.mean(tq**2))),
        ))

    # solver comparison: path 0 undisturbed, 1 paper-perturbed, then the first n_cmp noise samples
    noisy_rows = rows("noisy")[:n_cmp]
    table = []
    for name, res in comparisons.items():
        b = res.ys[:, :, 1] - beta_ref[None, :]
        if res is main:
            und, per, noisy = b[rows("undisturbed")[0]], b[rows("perturbed_paper")[0]], b[noisy_rows]
        else:
            und, per, noisy = b[0], b[1], b[2:2 + n_cmp]
        table.append(dict(
            solver=name,
            undisturbed_drift_off_s=drift_off_time(save_ts, und, thr),
            undisturbed_pitch_error_end_deg=float(np.degrees(abs(und[-1]))),
            perturbed_paper_drift_off_s=drift_off_time(save_ts, per, thr),
            noisy_drift_off_s=[drift_off_time(save_ts, e, thr) for e in noisy],
            noisy_pitch_error_end_deg=[float(np.degrees(abs(e[-1]))) for e in noisy],
            failed_paths=int(res.n_failed),
        ))

    zeta = np.asarray(vm.zeta)
    summary = dict(
        config=dict(
            duration_s=cfg.duration, speed_m_s=cfg.speed, road_class=cfg.road_class, road_seed=cfg.road_seed,
            hill_height_m=cfg.hill_height, hill_wavelength_m=cfg.hill_wavelength, sample_rate_hz=cfg.sample_rate,
            noise_rel=cfg.noise_rel, n_noise=cfg.n_noise, n_models=cfg.n_models, n_compare=n_cmp, seed=cfg.seed,
            solver=dataclasses.asdict(cfg.solver), params=cfg.params.to_dict(),
            drift_threshold_deg=cfg.drift_threshold_deg, z3_threshold_m=cfg.z3_threshold, linear=cfg.linear,
        ),
        measurement=dict(
            force_min_N=float(jnp.min(vm.forces)), force_max_N=float(jnp.max(vm.forces)), f_max_N=fmax,
            sigma_N=sigma, zeta_min_m=float(zeta.min()), zeta_max_m=float(zeta.max()),
            beta_range_deg=[float(np.degrees(vm.x[:, 3].min())), float(np.degrees(vm.x[:, 3].max()))],
        ),
        drift_definition=(
            f"drift-off time = first save time where |beta_sim - beta_measured| > {cfg.drift_threshold_deg} deg "
            f"(z3: |z3_sim - z3_measured| > {cfg.z3_threshold} m); 'inf' = never within the run"
        ),
        drift_off_beta_s=drift,
        drift_off_beta_s_by_threshold_deg=by_thr,
        drift_off_z3_s=z3_drift,
        error_at_end=end_err,
        enforced_moment_Nm=moment,
        pitch_spring=spring,
        solver_comparison=table,
        failed_paths=dict(force=int(main.n_failed), stabilised=int(stab.n_failed)),
    )
    return _clean(summary)


def _clean(obj):
    if isinstance(obj, dict):
        return {k: _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        obj = obj.item()
    if isinstance(obj, float):
        return _json_float(obj)
    return obj


# ---------------------------------------------------------------------------------------------
# figures and files
# ---------------------------------------------------------------------------------------------
def _fmt_t(v) -> str:
    if v is None or v == "inf" or (isinstance(v, float) and not math.isfinite(v)):
        return "> run"
    return f"{v:.2f}"


def solver_table_markdown(summary: dict) -> str:
    """The solver/tolerance comparison as a markdown table."""
    thr = summary["config"]["drift_threshold_deg"]
    lines = [
        f"Drift-off time [s] of beta (|beta - beta_measured| > {thr:g} deg); '> run' = never within the run.",
        "",
        "| solver | undisturbed | pitch error at end, undisturbed [deg] | paper-perturbed model | noisy: median | noisy: each sample |",
        "|---|---|---|---|---|---|",
    ]
    for row in summary["solver_comparison"]:
        noisy = [float("inf") if v == "inf" else v for v in row["noisy_drift_off_s"]]
        med = float(np.quantile(np.asarray(noisy, dtype=float), 0.5, method="inverted_cdf"))
        lines.append(
            f"| {row['solver']} | {_fmt_t(row['undisturbed_drift_off_s'])} | "
            f"{row['undisturbed_pitch_error_end_deg']:.3f} | {_fmt_t(row['perturbed_paper_drift_off_s'])} | "
            f"{_fmt_t(med)} | {', '.join(_fmt_t(v) for v in noisy)} |"
        )
    return "\n".join(lines) + "\n"


def write_paper_outputs(res: dict, out_dir, dpi: int = 90) -> list[str]:
    """Write figures 4-8 (+ pitch spring), ``summary.json`` and ``solver_comparison.md``.

    Files are written to a temporary folder inside ``out_dir`` first and moved into place at the
    end, so an interrupted run leaves no half-written set. Returns the written file names.
    """
    import json
    import os
    import shutil
    import tempfile

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(out_dir, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix=".paper-", dir=out_dir)
    try:
        files = _write_all(res, tmp, dpi, plt)
        for name in files:
            os.replace(os.path.join(tmp, name), os.path.join(out_dir, name))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return files


def _band(ax, ts, ys, ref, color, label, n_show=8, scale=1.0):
    q05, q50, q95 = np.quantile(ys * scale, [0.05, 0.5, 0.95], axis=0)
    ax.fill_between(ts, q05, q95, color=color, alpha=0.2, lw=0, label=f"{label}: 5-95 % band")
    for i in range(min(n_show, ys.shape[0])):
        ax.plot(ts, ys[i] * scale, color=color, lw=0.6, alpha=0.7, label=f"{label}: samples" if i == 0 else None)
    ax.plot(ts, ref * scale, color="k", lw=1.2, label="virtual measurement")


def _write_all(res, d, dpi, plt):
    import json
    import os

    cfg, vm, ts = res["cfg"], res["vm"], res["save_ts"]
    s = res["summary"]
    main, kinds = res["main"], res["kinds"]
    vts = np.asarray(vm.ts)
    beta_ref, z3_ref = res["beta_ref"], res["z3_ref"]
    deg = 180.0 / np.pi
    files = []

    def save(fig, name):
        fig.tight_layout()
        fig.savefig(os.path.join(d, name), dpi=dpi)
        plt.close(fig)
        files.append(name)

    def rows(kind):
        return np.flatnonzero(kinds == kind)

    # Fig. 4: road and wheel forces
    fig, ax = plt.subplots(3, 1, figsize=(8, 7), gridspec_kw=dict(height_ratios=[2, 1.2, 2]))
    zeta = np.asarray(vm.zeta)
    ax[0].plot(vts, zeta[:, 0], lw=0.8, label=r"$\zeta_1$ (front)")
    ax[0].plot(vts, zeta[:, 1], lw=0.8, label=r"$\zeta_2$ (rear)")
    ax[0].set_ylabel(r"road $\zeta$ [m] (z down)")
    ax[0].legend(loc="upper right")
    ax[0].set_title(f"ISO 8608 class {cfg.road_class} road with hills at {cfg.speed:g} m/s")
    t_lo = min(2.0, 0.5 * float(vts[-1]))
    m = (vts >= t_lo) & (vts <= t_lo + 1.0)
    ax[1].plot(vts[m], zeta[m, 0], lw=0.8)
    ax[1].plot(vts[m], zeta[m, 1], lw=0.8)
    ax[1].set_ylabel(r"$\zeta$ [m] (detail)")
    f = np.asarray(vm.forces)
    ax[2].plot(vts, f[:, 0] / 1e3, lw=0.5, label="$f_1$")
    ax[2].plot(vts, f[:, 1] / 1e3, lw=0.5, label="$f_2$", alpha=0.8)
    ax[2].set_ylabel("wheel force [kN]")
    ax[2].legend(loc="upper right")
    for a in ax:
        a.set_xlabel("t [s]")
    save(fig, "fig4_road_forces.png")

    # Fig. 5: z3 and beta for each step
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    series = [("virtual measurement", None, "k"), ("undisturbed forces", rows("undisturbed")[0], "C0"),
              ("noisy forces (one sample)", rows("noisy")[0], "C3"),
              ("perturbed model (paper's)", rows("perturbed_paper")[0], "C2")]
    for label, r, c in series:
        z = z3_ref if r is None else main.ys[r, :, 0]
        b = beta_ref if r is None else main.ys[r, :, 1]
        ax[0].plot(ts, z, color=c, lw=1.0, label=label)
        ax[1].plot(ts, b * deg, color=c, lw=1.0, label=label)
    ax[0].set_ylabel("$z_3$ [m] (down)")
    ax[1].set_ylabel(r"$\beta$ [deg]")
    lim = max(10.0, 2.0 * np.max(np.abs(beta_ref)) * deg)
    ax[1].set_ylim(-lim, lim)
    for a in ax:
        a.set_xlabel("t [s]")
    ax[1].legend(fontsize=7, loc="upper left")
    ax[0].set_title("vertical chassis motion")
    ax[1].set_title(f"pitch (drift-off: |error| > {cfg.drift_threshold_deg:g} deg)")
    save(fig, "fig5_z3_beta.png")

    # Fig. 6 / 7: bands over noise samples and perturbed models
    for name, kind, color, title in (("fig6_noise_samples.png", "noisy", "C3", "noise samples"),
                                     ("fig7_perturbed_models.png", "perturbed_random", "C2", "perturbed models")):
        r = rows(kind)
        fig, ax = plt.subplots(1, 2, figsize=(10, 4))
        _band(ax[0], ts, main.ys[r, :, 0], z3_ref, color, title)
        _band(ax[1], ts, main.ys[r, :, 1], beta_ref, color, title, scale=deg)
        ax[0].set_ylabel("$z_3$ [m] (down)")
        ax[1].set_ylabel(r"$\beta$ [deg]")
        ax[1].set_ylim(-lim, lim)
        for a in ax:
            a.set_xlabel("t [s]")
        ax[1].legend(fontsize=7, loc="upper left")
        ax[0].set_title(f"$z_3$ over {len(r)} {title}")
        ax[1].set_title(rf"$\beta$ over {len(r)} {title}")
        save(fig, name)

    # Fig. 8: inertia term and enforced moment
    stab, sk, mts = res["stab"], res["stab_kinds"], res["moment_ts"]
    i_pn = np.flatnonzero(sk == "perturbed_noisy")[0]
    i_uu = np.flatnonzero(sk == "unperturbed_undisturbed")[0]
    fig, ax = plt.subplots(1, 2, figsize=(10, 4), sharex=True)
    ax[0].plot(mts, stab.ys[i_pn, :, 2] / 1e3, lw=0.5, color="C0")
    ax[0].set_ylabel(r"inertia term $I\ddot\beta$ [kNm]")
    ax[0].set_title(r"inertia term $I\ddot\beta$")
    ax[1].plot(mts, stab.ys[i_pn, :, 1], lw=0.5, color="C3", label="perturbed model, noisy forces")
    ax[1].plot(mts, stab.ys[i_uu, :, 1], lw=0.5, color="k", label="original model, undisturbed forces")
    ax[1].set_ylabel(r"enforced moment $\lambda$ [Nm]")
    ax[1].set_title(r"enforced moment $\lambda = I\ddot\beta - \cos\beta\,(b f_3 - a f_4)$")
    ax[1].legend(fontsize=7, loc="upper left")
    for a in ax:
        a.set_xlabel("t [s]")
    save(fig, "fig8_enforced_moment.png")

    # pitch spring trade-off
    sp = [r for r in s["pitch_spring"] if r["stiffness"] > 0]
    free = [r for r in s["pitch_spring"] if r["stiffness"] == 0]
    if sp:
        k = np.array([r["stiffness"] for r in sp])
        fig, ax = plt.subplots(1, 1, figsize=(6, 4))
        ax.loglog(k, [r["pitch_error_rms_deg"] for r in sp], "o-", color="C0", label="pitch error RMS [deg]")
        ax.loglog(k, [r["pitch_error_max_deg"] for r in sp], "s--", color="C0", alpha=0.6,
                  label="pitch error max [deg]")
        if free:
            ax.axhline(free[0]["pitch_error_rms_deg"], color="C0", lw=0.8, ls=":",
                       label="pitch error RMS without spring [deg]")
        ax.set_xlabel("rotational spring stiffness [Nm/rad] (critically damped)")
        ax.set_ylabel("pitch error [deg]", color="C0")
        ax2 = ax.twinx()
        ax2.loglog(k, [r["reaction_torque_max"] for r in sp], "^-", color="C3", label="reaction torque max [Nm]")
        ax2.set_ylabel("reaction torque max [Nm]", color="C3")
        ax.set_title("section 3, approach 1: pitch spring to ground (noisy forces)")
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper center")
        save(fig, "fig_pitch_spring.png")

    with open(os.path.join(d, "summary.json"), "w") as fh:
        json.dump(s, fh, indent=2)
    files.append("summary.json")
    with open(os.path.join(d, "solver_comparison.md"), "w") as fh:
        fh.write(solver_table_markdown(s))
    files.append("solver_comparison.md")
    return files
