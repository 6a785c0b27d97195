"""What each change of the fixed-step loop gave: the engine's fixed-step loop in its layouts and with either sin/cos.

Found (``benchmarks/results/engine-layouts.json``, loaded 2-core AMD EPYC, load about 10): the
engine float64 step went from 427 CPU ns per path-step (vmap, library sin/cos) to 171 (paths last,
polynomial sin/cos); the fast mode from 232 to 135; paths last alone changes nothing with the
library sin/cos (431), the polynomials alone give 261. Both are shipped.

The half-car noisy-force study of ``benchmarks/_setup.py`` (1 ms Dormand-Prince 5(4), forces at
1 kHz with noise, pitch and heave every 0.1 s), ``--paths`` paths a call (default 256) over
``--seconds`` (default 2), on one JAX device, for

* the layout: ``vmap`` batching the per-path loop (paths first, the former layout) or the
  batched loop on ``(n_state, paths)`` arrays (paths last, the default now);
* sin/cos of the pitch: ``jnp.sin``/``jnp.cos`` or the polynomials of ``jaxdrift.models._trig``
  (the default now);
* engine float64 (``solve_ode(dt=...)``: unroll 1) and fast mode float32 (``solve_fixed_fast``:
  unroll 5, and unroll 1 in the new layout).

Every variant is timed in interleaved rounds (best kept), as wall time and as process CPU time;
on a loaded machine the CPU time is the steadier measure. Results equal the default's to rounding
(the largest difference is printed).

Reproduce (a few minutes)::

    python benchmarks/experiments/engine_layouts.py        # writes benchmarks/results/engine-layouts.{json,md}
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # benchmarks/: _common, _setup, results/
sys.path.insert(0, str(HERE))


def main(argv=None):
    from _common import timing_parser

    ap = timing_parser(__doc__, out="engine-layouts", seconds=2.0, rounds=3)
    a = ap.parse_args(argv)

    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np

    import jaxdrift
    import jaxdrift.models._halfcar as hc
    import jaxdrift.solvers._fast as fast_mod
    from _common import machine_info, write_results
    from _setup import force_rhs, paper_study

    load0 = list(os.getloadavg())
    st = paper_study(T=a.seconds)
    T, dt, n = st.T, st.dt, st.n_samples
    ts = jnp.arange(0, int(round(T * 10)) + 1) / 10.0
    f0, x0, key = jnp.asarray(st.f0), jnp.asarray(st.x0), jax.random.key(0)
    rhs = force_rhs(st.params)
    poly_sin_cos = hc._sin_cos

    def lib_sin_cos(beta, linear):
        return (beta, jnp.ones_like(beta)) if linear else (jnp.sin(beta), jnp.cos(beta))

    def make(kind, paths_last, poly, unroll=5):
        def path(i):
            if kind == "engine":
                sig = jaxdrift.SampledSignal(0.0, dt, f0 + jaxdrift.path_normals(key, i, n, 2) * st.sigma)
                return jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt).ys[:, 2:4]
            u = (f0 + jaxdrift.path_normals(key, i, n, 2, jnp.float32) * st.sigma).astype(jnp.float32)
            sig = jaxdrift.SampledSignal(0.0, dt, u)
            return jaxdrift.solve_fixed_fast(rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt, unroll=unroll).ys[:, 2:4]

        jitted = jax.jit(jax.vmap(path))

        def call(idx):
            # the switches act at trace time (first call); later calls reuse the compiled code
            hc._sin_cos, fast_mod._PATHS_LAST = (poly_sin_cos if poly else lib_sin_cos), paths_last
            try:
                return jitted(idx)
            finally:
                hc._sin_cos, fast_mod._PATHS_LAST = poly_sin_cos, True

        return call

    cases = {}
    for kind in ("engine", "fast"):
        for paths_last in (False, True):
            for poly in (False, True):
                name = f"{kind} {'float64' if kind == 'engine' else 'float32'}, " \
                       f"{'paths last' if paths_last else 'vmap (paths first)'}, {'polynomial' if poly else 'library'} sin/cos"
                cases[name] = make(kind, paths_last, poly)
    cases["fast float32, paths last, polynomial sin/cos, unroll 1"] = make("fast", True, True, unroll=1)
    idx = jnp.arange(a.paths, dtype=jnp.int32)
    outs = {}
    for k, f in cases.items():
        print("compiling", k, flush=True)
        outs[k] = np.asarray(jax.block_until_ready(f(idx)), np.float64)
    wall = {k: float("inf") for k in cases}
    cpu = dict(wall)
    for r in range(a.rounds):
        for k, f in cases.items():
            t, c = time.perf_counter(), time.process_time()
            jax.block_until_ready(f(idx + (r + 1) * a.paths))
            wall[k] = min(wall[k], time.perf_counter() - t)
            cpu[k] = min(cpu[k], time.process_time() - c)
        print(f"round {r + 1} done", flush=True)
    steps = a.paths * int(round(T / dt))
    ref64 = outs["engine float64, paths last, polynomial sin/cos"]
    res = {}
    for k in cases:
        res[k] = {"wall_ns_per_path_step": wall[k] / steps * 1e9, "cpu_ns_per_path_step": cpu[k] / steps * 1e9,
                  "max_abs_diff_vs_default_engine": float(np.max(np.abs(outs[k] - ref64)))}
    load1 = list(os.getloadavg())
    md = [f"Half-car, {a.paths} paths x {a.seconds:g} s, one JAX device; load average {load0[0]:.1f} at start, "
          f"{load1[0]:.1f} at end. ns per path-step, best of {a.rounds} interleaved rounds.", "",
          "| variant | wall | CPU | max diff vs default engine |", "|---|---:|---:|---:|"]
    for k, r in res.items():
        md.append(f"| {k} | {r['wall_ns_per_path_step']:.0f} | {r['cpu_ns_per_path_step']:.0f} | "
                  f"{r['max_abs_diff_vs_default_engine']:.1e} |")
    cmd = "python benchmarks/experiments/engine_layouts.py " + " ".join(sys.argv[1:] if argv is None else argv)
    md += ["", f"Reproduce: `{cmd.strip()}`"]
    write_results(a.out, {"command": cmd, "machine": machine_info(), "load_average_start": load0,
                          "load_average_end": load1, "paths": a.paths, "seconds": a.seconds, "cases": res},
                  "\n".join(md) + "\n")
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
