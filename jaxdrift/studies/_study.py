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

This module holds the configuration and the simulations; the JSON summary is built in
``_paper_summary.py`` and the figures and files are written by ``_paper_plots.py``.
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..models._halfcar import (
    contact_forces,
    pitch_spring_torque,
    road_driven_rhs,
    static_equilibrium,
)
from ..solvers._inputs import SampledSignal
from ..ensemble._montecarlo import monte_carlo
from ..ensemble._noise import white_noise
from ..models._params import HalfCarParams, random_perturbed_models
from ..models._road import WheelInputs, iso8608_road
from ..solvers._solve import solve_ode
from ..analysis._force_driven import (SOLVER_FIXED, SOLVER_FIXED_HALF, SOLVER_LOOSE, SOLVER_TIGHT, SolverSpec,
                                      _span, simulate_forces, simulate_prescribed_pitch)
from ._paper_plots import solver_table_markdown, write_paper_outputs
from ._paper_headline import run_headline
from ._paper_summary import _summarise, drift_off_time

__all__ = [
    "SolverSpec",
    "SOLVER_LOOSE",
    "SOLVER_TIGHT",
    "SOLVER_FIXED",
    "SOLVER_FIXED_HALF",
    "StudyConfig",
    "VirtualMeasurement",
    "virtual_measurement",
    "simulate_forces",
    "simulate_prescribed_pitch",
    "drift_off_time",
    "run_force_paths",
    "run_pitch_paths",
    "run_paper_study",
    "write_paper_outputs",  # from _paper_plots
    "solver_table_markdown",  # from _paper_plots
]


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
    headline_solvers: tuple[SolverSpec, SolverSpec] | None = (SOLVER_FIXED, SOLVER_FIXED_HALF)
    rounding_check: bool = True
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


def run_paper_study(cfg: StudyConfig, log: Callable[[str], None] = print) -> dict:
    """Run steps 1-5 of the paper's section 4.1 and the extra studies; return all results.

    Returns a dict with the virtual measurement ``vm``, the save grids, the engine results of
    every Monte-Carlo run and a JSON-ready ``summary`` (see ``docs/paper-study.md``).
    """
    cfg.validate()
    p = cfg.params
    timings: dict[str, float] = {}
    t_start = time.perf_counter()

    last = [t_start]

    def step(name):
        now = time.perf_counter()
        timings[name] = now - last[0]
        last[0] = now

    log(f"[1/6] virtual measurement: road class {cfg.road_class}, {cfg.speed} m/s, {cfg.duration} s ...")
    road = iso8608_road(cfg.road_class, seed=cfg.road_seed, hill_height=cfg.hill_height,
                        hill_wavelength=cfg.hill_wavelength)
    inputs = road.sampled_wheel_inputs(cfg.speed, cfg.wheelbase, cfg.duration)

    def measure():
        return virtual_measurement(p, inputs, cfg.duration, cfg.sample_rate, cfg.measurement_rtol, cfg.measurement_atol)

    vm = measure()
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
    if cfg.headline_solvers:  # last: the rounding check clears JAX's compilation caches
        hl = np.flatnonzero(np.isin(kinds_arr, ("undisturbed", "perturbed_paper", "noisy", "perturbed_random")))
        assert (hl == np.arange(hl.size)).all()  # the first paths of the main run: same noise indices
        hl_models, hl_sigmas = [models[i] for i in hl], [sigmas[i] for i in hl]
        summary = {"headline": run_headline(
            cfg, vm, save_ts, beta_ref, kinds_arr[hl],
            lambda v, s: run_force_paths(v, save_ts, hl_models, hl_sigmas, None, s, cfg.seed, cfg.progress, cfg.linear),
            measure, cfg.headline_solvers, log, cfg.rounding_check), **summary}
        step("headline")
    timings["total"] = time.perf_counter() - t_start
    summary["timings_s"] = {k: round(v, 2) for k, v in timings.items()}
    return dict(cfg=cfg, vm=vm, save_ts=save_ts, beta_ref=beta_ref, z3_ref=z3_ref, sigma=sigma, main=main,
                kinds=kinds_arr, stab=stab, stab_kinds=st_kinds, moment_ts=moment_ts, comparisons=comparisons,
                summary=summary)
