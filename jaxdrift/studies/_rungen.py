"""Synthetic "true" vehicle runs with hidden effects (tests, the shipped example, benchmarks).

A run is the seed's virtual measurement (section 4.1, step 1): the road-driven half-car (A.4) of
the *true* vehicle on an ISO 8608 road with hills (``jaxdrift.models._road``), integrated by the engine
(adaptive DOPRI5 at tight tolerances), sampled at ``fs``; the contact forces (4.3) are the true
wheel forces. The sensors then apply the hidden effects in the measured-data contract's form
(``docs/measured-data.md``): ``measured(t) = scale * true(t - delay) + offset + noise``; a
a parameter error makes the true vehicle differ from the model (true = ratio x model).

:func:`draw_effects` draws hidden effects (kind, channel or parameter, size) from a seed, at
"realistic" or "small" magnitudes, restricted to what the run's channels can reveal.
"""

from __future__ import annotations

import numpy as np

from ..diagnosis.vehicle import FORCE_NOISE, VEHICLE_CAUSES, kind_named
from ..io._csvio import DEFAULT_MODEL

__all__ = ["draw_effects", "simulate_true_run", "apply_sensor_effects", "make_run", "SIZES",
           "draw_sweep_case"]

#: (low, high) magnitude of each effect kind (the kinds' ``draw_sizes``); the sign is drawn
#: separately where it matters
SIZES = {size: {k.name: k.draw_sizes[size] for k in (FORCE_NOISE, *VEHICLE_CAUSES) if size in k.draw_sizes}
         for size in ("realistic", "small")}

#: parameters a run reveals, by the channels it has (without spring travel the chassis
#: spring stiffness and damping barely change the forces the wheels pass on)
def revealed_parameters(channels) -> tuple[str, ...]:
    ch = set(channels)
    keys = []
    if "beta" in ch:
        keys += ["I", "a", "b"]
    if "z3" in ch or "beta" in ch:
        keys += ["m3"]
    if "s1" in ch:
        keys += ["k3", "d3"]
    if "s2" in ch:
        keys += ["k4", "d4"]
    # the tyre law needs the wheel positions: pitch and heave measured, and the road height
    if "beta" in ch and "z3" in ch:
        if "zeta1" in ch:
            keys += ["k1", "d1"]
        if "zeta2" in ch:
            keys += ["k2", "d2"]
    return tuple(keys)


def draw_effects(seed: int, *, n_systematic: int = 1, size: str = "realistic",
                 channels=("beta",), kinds=None, noise: bool = True) -> list[dict]:
    """Hidden effects drawn from ``seed``: ``n_systematic`` systematic ones (distinct kinds and
    targets) plus, if ``noise``, white force noise. Each is a dict ``{"cause", "value",
    "channel" | "parameter"}`` in the report's terms (scale and parameter values are ratios)."""
    rng = np.random.default_rng(seed)
    lo_hi = SIZES[size]
    params = revealed_parameters(channels)
    pool = list(kinds) if kinds is not None else [k.name for k in VEHICLE_CAUSES if k.drawn_by_default]
    pool = [k for k in pool if params or kind_named(k).target_key != "parameter"]
    out = []
    used = set()
    while len([e for e in out if e["cause"] != FORCE_NOISE.name]) < n_systematic:
        name = pool[rng.integers(len(pool))]
        kind = kind_named(name)
        lo, hi = lo_hi[name]
        mag = rng.uniform(lo, hi)
        sign = 1.0 if rng.random() < 0.5 else -1.0
        targets = params if kind.target_key == "parameter" else ("f1", "f2")
        target = targets[rng.integers(len(targets))]
        e = {"cause": name, kind.target_key: target, "value": kind.draw_value(mag, sign)}
        key = (name, target)
        # one effect per channel kind (two would add up to one); parameters may repeat kinds
        if key in used or (kind.target_key != "parameter" and any(k[0] == name for k in used)):
            continue
        used.add(key)
        out.append(e)
    if noise:
        lo, hi = lo_hi[FORCE_NOISE.name]
        out.append({"cause": FORCE_NOISE.name, "value": float(rng.uniform(lo, hi))})
    return out


def _solver():
    import equinox as eqx

    from ..models._halfcar import road_driven_rhs
    from ..solvers._solve import solve_ode

    def rhs(t, y, args):
        params, wheels = args
        zeta, dzeta = wheels(t)
        return road_driven_rhs(t, y, params, zeta, dzeta)

    @eqx.filter_jit
    def solve(params, wheels, y0, ts, t1):
        sol = solve_ode(rhs, y0, 0.0, t1, saveat=ts, args=(params, wheels), rtol=1e-9,
                        atol=1e-12, max_steps=2_000_000)
        return sol.ys, sol.result

    return solve


_SOLVE = {}


def simulate_true_run(true_params: dict, *, duration: float = 20.0, fs: float = 500.0,
                      speed: float = 15.0, road_class: str = "B", seed: int = 0,
                      hill_height: float = 2.0, extra_times=None) -> dict:
    """True signals of the road-driven vehicle at ``t = k / fs`` (and at ``extra_times``).

    Returns a dict of arrays: ``t, f1, f2, z1, z2, z3, beta, beta_rate, s1, s2, ds1, ds2, zeta1,
    zeta2`` (``ds1, ds2``: the spring travel rates, so that the true section forces are
    ``f3 = k3 s1 + d3 ds1``, ``f4 = k4 s2 + d4 ds2``) and, when ``extra_times`` is given, ``extra`` with the forces at those times.
    """
    import jax
    import jax.numpy as jnp

    from ..models._halfcar import contact_forces, spring_travel_np, static_equilibrium
    from ..models._params import HalfCarParams
    from ..models._road import iso8608_road

    n = int(round(duration * fs)) + 1
    t = np.arange(n) / fs
    extra = np.zeros(0) if extra_times is None else np.clip(np.asarray(extra_times, float), 0, t[-1])
    allt = np.concatenate([t, extra])
    order = np.argsort(allt, kind="stable")
    with jax.enable_x64(True):
        p = HalfCarParams.from_dict(true_params)
        pa = jax.tree_util.tree_map(lambda v: jnp.asarray(v, dtype=jnp.float64), p)
        road = iso8608_road(road_class, seed=seed, hill_height=hill_height)
        wb = float(true_params["a"] + true_params["b"])
        wheels = road.sampled_wheel_inputs(float(speed), wb, float(t[-1]) + 0.01, dt=2.5e-4)
        y0 = static_equilibrium(pa, "road")
        if "f" not in _SOLVE:
            _SOLVE["f"] = _solver()
        ys, code = _SOLVE["f"](pa, wheels, y0, jnp.asarray(allt[order]), float(t[-1]))
        if int(code) != 0:
            raise RuntimeError(f"true-run simulation failed (result code {int(code)})")
        ys_all = np.empty((len(allt), 8))
        ys_all[order] = np.asarray(ys)
        zeta, dzeta = road.wheel_inputs(jnp.asarray(allt), float(speed), wb)
        f = np.asarray(jax.vmap(lambda x, z, dz: contact_forces(x, pa, z, dz))(
            jnp.asarray(ys_all), zeta, dzeta))
        zeta = np.asarray(zeta)
    y = ys_all[:n]
    out = {"t": t, "f1": f[:n, 0], "f2": f[:n, 1], "z1": y[:, 0], "z2": y[:, 1], "z3": y[:, 2],
           "beta": y[:, 3], "beta_rate": y[:, 7], **spring_travel_np(y, true_params["a"], true_params["b"]),
           "zeta1": zeta[:n, 0], "zeta2": zeta[:n, 1]}
    if extra.size:
        out["extra"] = {"t": extra, "f1": f[n:, 0], "f2": f[n:, 1]}
    return out


class _Reader:
    """``read(ch)``: the true forces at the times channel ``ch`` reads them; ``read.t``: the
    sample times (what a kind's ``forward`` is given)."""

    def __init__(self, true: dict, delayed: dict | None):
        self.t = np.asarray(true["t"], dtype=float)
        self._true = {ch: np.asarray(true[ch], dtype=float) for ch in ("f1", "f2")}
        self._delayed = delayed or {}

    def __call__(self, ch: str) -> dict:
        d = self._delayed.get(ch)
        if d is None:
            return self._true
        return d if isinstance(d, dict) else {**self._true, ch: np.asarray(d, dtype=float)}


def apply_sensor_effects(true: dict, effects, seed: int, delayed: dict | None = None) -> dict:
    """Measured forces from the true ones: each effect's kind applies its forward effect
    (``forward``) in the order of the sensor's chain (``forward_stage``: reading time, crosstalk,
    gain, offset), then white noise: ``(1 + drift (t - t_mid)) scale true(t - delay) + offset +
    noise`` for the kinds of the measured-data contract.

    ``delayed``: {channel: the true forces ``{"f1", "f2"}`` (or that channel's alone) at the times
    the channel reads them} (from :func:`simulate_true_run`'s extra times); noise from
    ``numpy.random.default_rng(seed)``.
    """
    meas = {ch: np.array(true[ch], dtype=float) for ch in ("f1", "f2")}
    read = _Reader(true, delayed)
    sensor = [(kind_named(e["cause"]), e) for e in effects if e["cause"] != FORCE_NOISE.name]
    # in the chain's order; a stable sort keeps the effects' own order within a stage
    for k, e in sorted(((k, e) for k, e in sensor if k.is_sensor), key=lambda ke: ke[0].forward_stage):
        meas = k.forward(meas, e["channel"], float(e["value"]), read)
    rng = np.random.default_rng(seed)
    for e in effects:
        if e["cause"] == FORCE_NOISE.name:
            for ch in ("f1", "f2"):
                meas[ch] = meas[ch] + float(e["value"]) * rng.standard_normal(len(meas[ch]))
    return meas


def make_run(effects=(), *, model: dict | None = None, duration: float = 20.0, fs: float = 500.0,
             speed: float = 15.0, road_class: str = "B", seed: int = 0,
             channels=("beta",), hill_height: float = 2.0) -> tuple[dict, dict]:
    """A measured run with hidden ``effects`` (see :func:`draw_effects`) against ``model``.

    Returns ``(columns, truth)``: columns ``t, f1, f2`` plus the requested ``channels`` (true
    motion), ready for :func:`jaxdrift.io._csvio.write_vehicle_run`; ``truth`` holds the true
    parameters and signals.
    """
    model = dict(DEFAULT_MODEL if model is None else model)
    true_params = dict(model)
    kinds = [(kind_named(e["cause"]), e) for e in effects if e["cause"] != FORCE_NOISE.name]
    for k, e in kinds:
        if not k.is_sensor:
            true_params = k.true_model(true_params, e[k.target_key], float(e["value"]))
    n = int(round(duration * fs)) + 1
    t = np.arange(n) / fs
    shifts = [(e["channel"], k.time_shift(float(e["value"]))) for k, e in kinds if k.is_sensor]
    shifts = [(ch, d) for ch, d in shifts if d != 0.0]
    extra = np.concatenate([t - d for _, d in shifts]) if shifts else None
    true = simulate_true_run(true_params, duration=duration, fs=fs, speed=speed,
                             road_class=road_class, seed=seed, hill_height=hill_height,
                             extra_times=extra)
    delayed = {}
    for i, (ch, _) in enumerate(shifts):
        sl = slice(i * n, (i + 1) * n)
        delayed[ch] = {c: true["extra"][c][sl] for c in ("f1", "f2")}
    meas = apply_sensor_effects(true, effects, seed + 7919, delayed)
    cols = {"t": t, "f1": meas["f1"], "f2": meas["f2"]}
    for c in channels:
        cols[c] = true[c]
    return cols, {"params": true_params, "signals": true}


def draw_sweep_case(rng, channel_sets, *, noise: bool = True) -> dict:
    """One case of the seeded hidden-effect sweep (the slow test, ``benchmarks/diagnose_sweep.py``).

    Draws from ``rng`` (a ``numpy.random.Generator``), in this order: the generator seed, the
    sampling rate (200, 250, 500 or 1000 Hz), one of ``channel_sets``, the size class, 0-2
    systematic effects (:func:`draw_effects`, plus force noise if ``noise``), a speed of 8-30 m/s
    and an ISO 8608 class A-C road. Returns the keyword arguments of :func:`make_run` (without
    ``duration`` and ``model``) and ``effects``.
    """
    seed = int(rng.integers(10_000))
    fs = float(rng.choice([200.0, 250.0, 500.0, 1000.0]))
    chans = tuple(channel_sets[int(rng.integers(len(channel_sets)))])
    size = str(rng.choice(["realistic", "small"]))
    nsys = int(rng.choice([0, 1, 1, 2]))
    effects = draw_effects(seed, n_systematic=nsys, size=size, channels=chans, noise=noise)
    speed = float(rng.uniform(8, 30))
    road = str(rng.choice(["A", "B", "C"]))
    return {"effects": effects, "fs": fs, "speed": speed, "road_class": road, "seed": seed, "channels": chans}


