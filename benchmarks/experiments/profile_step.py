"""Where the time of a half-car step goes: the model's vector field against the integrator.

Found (``benchmarks/results/profile_step.json``, loaded machine, load 3.4 -> 6.7): a fixed 1 ms step of
the fast kernel in float64 costs 2973 ns per path (512 paths) with the forces as a
``SampledSignal``, 1767 with each step's two samples read once (the ``inputs=`` option) and 1752
with the forces constant: the per-stage interpolation was about 40 % of the step, which led to
the engine reading grid-aligned inputs once per step. One nonlinear model evaluation costs
94.6 ns per path (float64, vmap layout) against 10.4 for the linear form with the batch last.

Measures, per path, the cost of one evaluation of ``force_driven_rhs`` (the nonlinear model and
its ``linear=True`` form, float32 and float64) in the layout ``vmap`` produces (state ``(paths,
10)``) and with the batch on the last axis (state ``(10, paths)``), and the cost of a whole fixed
1 ms DOPRI5 step (6 evaluations) of ``jaxdrift.solve_ode`` and of the fast mode, with the same
noisy sampled forces, and of the fast kernel with the forces held constant (no per-stage
``SampledSignal`` evaluation) and the noise generation alone. Writes ``benchmarks/results/profile_step.json``.

Reproduce (about 3 minutes on 2 cores)::

    python benchmarks/experiments/profile_step.py
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # benchmarks/: _common, _setup, results/
sys.path.insert(0, str(HERE))


def _interleaved(cases, rounds=3):
    """Best time of each ``(fn, args)`` over ``rounds`` interleaved rounds (after a warm-up call),
    so that a change of load on a shared machine hits every case alike."""
    import jax

    for fn, args in cases.values():
        jax.block_until_ready(fn(*args))
    best = {k: float("inf") for k in cases}
    for _ in range(rounds):
        for k, (fn, args) in cases.items():
            t = time.perf_counter()
            jax.block_until_ready(fn(*args))
            best[k] = min(best[k], time.perf_counter() - t)
    return best


def main():
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    import jaxdrift
    from _setup import force_rhs
    from jaxdrift.models._halfcar import equilibrium_forces, force_driven_rhs, static_equilibrium
    from jaxdrift.models._params import HalfCarParams

    p = HalfCarParams()
    n_paths, K = 1024, 2000
    out = {"paths": n_paths, "load_average_at_start": list(os.getloadavg()), "rhs_ns_per_path": {}, "step_ns_per_path": {}}
    rhs_cases = {}
    for dtype in (jnp.float32, jnp.float64):
        dn = jnp.dtype(dtype).name
        for linear in (False, True):
            for layout in ("vmap (paths, 10)", "batch-last (10, paths)"):
                x0 = jnp.asarray(static_equilibrium(p), dtype)
                if layout.startswith("vmap"):
                    x = jnp.broadcast_to(x0, (n_paths, 10))
                    f = jnp.full((n_paths, 2), 3700.0, dtype)

                    def ev(x, f, linear=linear):
                        return jax.vmap(lambda x, f: force_driven_rhs(0.0, x, p, f[0], f[1], linear=linear))(x, f)
                else:
                    x = jnp.broadcast_to(x0[:, None], (10, n_paths))
                    f = jnp.full((2, n_paths), 3700.0, dtype)

                    def ev(x, f, linear=linear):
                        return force_driven_rhs(0.0, x, p, f[0], f[1], linear=linear)

                def loop(x, f, ev=ev):
                    return jax.lax.scan(lambda x, _: (x + 1e-9 * ev(x, f), None), x, None, length=K)[0]

                key = f"{dn}, {'linear' if linear else 'nonlinear'}, {layout}"
                rhs_cases[key] = ((jax.jit(loop), (x, f)), n_paths * K)
        xs = jnp.linspace(-0.5, 0.5, n_paths * 16, dtype=dtype)
        for name, fn in (("sin", jnp.sin), ("cos", jnp.cos), ("multiply-add", lambda v: v * 1.0001 + 0.5)):
            g = jax.jit(lambda v, fn=fn: jax.lax.scan(lambda c, _: (fn(c) * 0.5, None), v, None, length=64)[0])
            rhs_cases[f"{dn}, {name} of one element"] = ((g, (xs,)), xs.size * 64)
    best = _interleaved({k: v[0] for k, v in rhs_cases.items()})
    for k, (_, count) in rhs_cases.items():
        out["rhs_ns_per_path"][k] = best[k] / count * 1e9
        print(k, f"{out['rhs_ns_per_path'][k]:.1f} ns", flush=True)

    rhs = force_rhs(p)
    T, dt = 2.0, 1e-3
    n = int(round(T / dt)) + 1
    f1, f2, _, _ = equilibrium_forces(p)
    f0 = jnp.ones((n, 2)) * jnp.array([f1, f2])
    x0 = static_equilibrium(p)
    ts = jnp.arange(0, int(T * 10) + 1) / 10.0
    key = jax.random.key(0)
    n_steps = n - 1

    def make(kind, dtype):
        def path(i):
            sig = jaxdrift.SampledSignal(0.0, dt, (f0 + 32.0 * jaxdrift.path_normals(key, i, n, 2, dtype)).astype(dtype))
            if kind == "engine":
                return jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt).ys
            if kind == "noise only":
                return sig.values
            if kind.startswith("fast, inputs on the grid"):
                def rhs_u(t, x, u, a):
                    return force_driven_rhs(t, x, p, u[0], u[1])

                return jaxdrift.solve_fixed_fast(rhs_u, x0, 0.0, T, saveat=ts, inputs=sig.values, dt=dt, dtype=dtype).ys
            if kind.startswith("fast, constant input"):
                # The same kernel without the per-stage SampledSignal evaluation (forces fixed).
                def rhs_const(t, x, a):
                    return force_driven_rhs(t, x, p, a[0], a[1])

                return jaxdrift.solve_fixed_fast(rhs_const, x0, 0.0, T, saveat=ts, args=sig.values[0], dt=dt,
                                                 dtype=dtype).ys
            return jaxdrift.solve_fixed_fast(rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt, dtype=dtype).ys

        return jax.jit(jax.vmap(path))

    idx = jnp.arange(512)
    step_cases = {}
    for kind, dtype in (("engine", jnp.float64), ("fast", jnp.float32), ("fast", jnp.float64),
                        ("fast, inputs on the grid", jnp.float64), ("fast, inputs on the grid", jnp.float32),
                        ("fast, constant input", jnp.float64), ("fast, constant input", jnp.float32),
                        ("noise only", jnp.float64), ("noise only", jnp.float32)):
        step_cases[f"{kind} {jnp.dtype(dtype).name}"] = (make(kind, dtype), (idx,))
    best = _interleaved(step_cases, rounds=2)
    for name in step_cases:
        out["step_ns_per_path"][name] = best[name] / (idx.size * n_steps) * 1e9
        print(name, f"{out['step_ns_per_path'][name]:.0f} ns per path-step", flush=True)
    out["load_average_at_end"] = list(os.getloadavg())
    path = HERE / "results" / "profile_step.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
