"""How the way the vector field is written and the loop is unrolled change each integrator's speed.

Found (``benchmarks/results/rhs-variants.json``, idle machine): computing sin/cos once helps diffrax
most (820 -> 521 ns per path-step), the engine a little (348 -> 311) and the default fast mode not
at all (199 -> 204), so the model is left as written.

XLA's CPU compiler copies cheap elementwise producers into every consumer: the half-car's spring
forces (a ``sin`` and a ``cos`` of the pitch each) feed four output rows, so one vmapped
evaluation of ``force_driven_rhs`` computes four sines and four cosines. This script times, on the
study of ``benchmarks/_setup.py`` (fixed 1 ms DOPRI5, 256 paths, same noise for all):

* vector fields: ``model`` (``jaxdrift.force_driven_rhs`` as shipped); ``once`` (the same
  equations with the spring forces and ``cos beta`` passed through an identity contraction, which
  the CPU compiler does not fuse, so they are computed once); ``trig-once`` (only ``sin, cos``
  passed through it);
* integrators: the engine (``solve_ode(dt=...)``, float64), the fast mode (``solve_fixed_fast``,
  float32 + Kahan) with ``unroll`` 1 and 5, and diffrax ``Dopri5`` with ``ConstantStepSize``.

Every case is checked against the same integrator on ``model`` (largest difference of the pitch).

Reproduce (about 3 minutes on 2 cores)::

    python benchmarks/experiments/rhs_variants.py
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # benchmarks/: _common, _setup, results/
sys.path.insert(0, str(HERE))


def main(argv=None):
    from _common import timing_parser

    a = timing_parser(__doc__, out="rhs-variants", seconds=8.0).parse_args(argv)

    import jax

    jax.config.update("jax_enable_x64", True)
    import diffrax
    import jax.numpy as jnp

    import jaxdrift
    from _common import interleaved_best, machine_info, write_results
    from _setup import paper_study
    from jaxdrift.models._halfcar import force_driven_rhs

    st = paper_study(T=a.seconds)
    p, T, dt, n = st.params, st.T, st.dt, st.n_samples
    n_steps = int(round(T / dt))
    key = jax.random.key(0)

    def setup(dtype):
        ts = (jnp.arange(0, int(round(T * 10)) + 1) / 10.0).astype(dtype)
        f0, x0 = jnp.asarray(st.f0, dtype), jnp.asarray(st.x0, dtype)

        def signal(i):
            eps = jaxdrift.path_normals(key, i, n, 2, dtype) * jnp.asarray(st.sigma, dtype)
            return jaxdrift.SampledSignal(0.0, dt, f0 + eps)

        return ts, x0, signal

    def once(*xs):
        v = jnp.stack(xs)
        v = jnp.tensordot(jnp.eye(len(xs), dtype=v.dtype), v, axes=1)
        return tuple(v[i] for i in range(len(xs)))

    def written_out(trig_only):
        def rhs(t, x, sig):
            f1, f2 = sig(t)[0], sig(t)[1]
            s, c = jnp.sin(x[3]), jnp.cos(x[3])
            if trig_only:
                s, c = once(s, c)
            z1, z2, z3, dz1, dz2, dz3, db = x[0], x[1], x[2], x[4], x[5], x[6], x[7]
            f3 = p.k3 * (z3 - z1 - p.b * s) + p.d3 * (dz3 - dz1 - p.b * db * c)
            f4 = p.k4 * (z3 - z2 + p.a * s) + p.d4 * (dz3 - dz2 + p.a * db * c)
            if not trig_only:
                f3, f4, c = once(f3, f4, c)
            return jnp.stack([
                x[4], x[5], x[6], x[7],
                p.g + (f3 - f1) / p.m1, p.g + (f4 - f2) / p.m2, p.g - (f3 + f4) / p.m3,
                c * (p.b * f3 - p.a * f4) / p.I,
                (p.k1 * (x[0] - x[8]) + p.d1 * x[4] - f1) / p.d1,
                (p.k2 * (x[1] - x[9]) + p.d2 * x[5] - f2) / p.d2,
            ])

        return rhs

    def model(t, x, sig):
        f = sig(t)
        return force_driven_rhs(t, x, p, f[0], f[1])

    fields = {"model": model, "once": written_out(False), "trig-once": written_out(True)}

    def engine(rhs):
        ts, x0, signal = setup(jnp.float64)
        return lambda i: jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=signal(i), dt=dt).ys[:, 3]

    def fast(unroll):
        def make(rhs):
            ts, x0, signal = setup(jnp.float32)
            return lambda i: jaxdrift.solve_fixed_fast(rhs, x0, 0.0, T, saveat=ts, args=signal(i), dt=dt,
                                                       unroll=unroll).ys[:, 3].astype(jnp.float64)

        return make

    def dfx(rhs):
        ts, x0, signal = setup(jnp.float64)
        term = diffrax.ODETerm(rhs)
        return lambda i: diffrax.diffeqsolve(
            term, diffrax.Dopri5(), 0.0, T, dt, x0, args=signal(i), saveat=diffrax.SaveAt(ts=ts),
            stepsize_controller=diffrax.ConstantStepSize(), max_steps=n_steps + 16).ys[:, 3]

    solvers = {"engine float64": engine, "fast float32, unroll 1": fast(1), "fast float32, unroll 5": fast(5),
               "diffrax float64": dfx}
    fns = {(s, v): jax.jit(jax.vmap(mk(fields[v]))) for s, mk in solvers.items() for v in fields}
    best, outs = interleaved_best(fns, jnp.arange(a.paths, dtype=jnp.int32), a.rounds)
    ns = {k: v / (a.paths * n_steps) * 1e9 for k, v in best.items()}
    diff = {k: float(jnp.max(jnp.abs(outs[k] - outs[(k[0], "model")]))) for k in fns}
    rows = ["| integrator | " + " | ".join(f"{v} ns/path-step" for v in fields) + " | largest pitch difference from model |",
            "|---|" + "---:|" * len(fields) + "---:|"]
    for s in solvers:
        rows.append(f"| {s} | " + " | ".join(f"{ns[(s, v)]:.0f}" for v in fields) + " | "
                    + ", ".join(f"{diff[(s, v)]:.1e}" for v in fields if v != "model") + " |")
    md = (f"Vector-field formulations and loop unrolling, half-car study, {a.paths} paths x {T:g} s, fixed 1 ms "
          f"DOPRI5, {a.rounds} interleaved rounds, best kept; load average at end {os.getloadavg()[0]:.1f}.\n\n"
          + "\n".join(rows) + "\n\nReproduce: `python benchmarks/experiments/rhs_variants.py`\n")
    out = {"machine": machine_info(), "load_average_at_end": list(os.getloadavg()),
           "config": {"paths": a.paths, "seconds": T, "dt": dt, "rounds": a.rounds},
           "ns_per_path_step": {f"{s} / {v}": ns[(s, v)] for s, v in fns},
           "max_abs_pitch_difference_from_model": {f"{s} / {v}": diff[(s, v)] for s, v in fns}}
    jp, mp = write_results(a.out, out, md)
    print(md)
    print(f"wrote {jp} and {mp}")


if __name__ == "__main__":
    main()
