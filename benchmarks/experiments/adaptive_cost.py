"""Where an adaptive step's time goes on the half-car study: the loop, and the sampled input.

Found (``benchmarks/results/adaptive-cost.json``, idle 2-core AMD EPYC): the adaptive mode costs
956 ns per path-step on the sampled forces against 427 for the fixed 1 ms step (2.2x); with the
forces held constant 561 ns, and the fixed step forced to interpolate at every stage 656 ns: the
per-stage interpolation of the sampled forces (a per-path gather) is most of the difference.

The adaptive mode costs about twice the fixed mode per step (``benchmarks/results/throughput-idle.md``).
This script times ``jaxdrift.solve_ode`` on the study of ``benchmarks/_setup.py`` (256 paths,
float64) four ways, in ns per path-step:

* adaptive (rtol 1e-6, atol 1e-8) on the noisy forces as a ``SampledSignal``;
* adaptive with the forces held constant (no per-stage interpolation; far fewer steps, but the
  per-step cost is what matters here);
* fixed 1 ms on the noisy forces (the engine reads each step's two samples once);
* fixed 1 ms with the signal's ``t0`` traced, which hides the grid alignment, so the signal is
  interpolated at every stage as in the adaptive mode.

Under ``vmap`` the adaptive paths sit at different times, so each stage's interpolation is a gather
with a per-path index; in the fixed mode all paths share the index.

Reproduce (about a minute)::

    python benchmarks/experiments/adaptive_cost.py
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # benchmarks/: _common, _setup, results/
sys.path.insert(0, str(HERE))


def main(argv=None):
    from _common import timing_parser

    a = timing_parser(__doc__, out="adaptive-cost", seconds=5.0).parse_args(argv)

    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    import jaxdrift
    from _common import interleaved_best, machine_info, write_results
    from _setup import force_rhs, paper_study
    from jaxdrift.models._halfcar import force_driven_rhs

    st = paper_study(T=a.seconds)
    p, T, dt, n = st.params, st.T, st.dt, st.n_samples
    key = jax.random.key(0)
    ts = jnp.arange(0, int(round(T * 10)) + 1) / 10.0
    f0, x0 = jnp.asarray(st.f0), jnp.asarray(st.x0)
    rhs = force_rhs(p)

    def noisy(i, t0=0.0):
        return jaxdrift.SampledSignal(t0, dt, f0 + st.sigma * jaxdrift.path_normals(key, i, n, 2))

    def adaptive(i):
        sol = jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=noisy(i), rtol=1e-6, atol=1e-8)
        return sol.ys[:, 3], sol.stats["num_steps"]

    def adaptive_const(i):
        force = f0[0] + 0.0 * i
        sol = jaxdrift.solve_ode(lambda t, x, u: force_driven_rhs(t, x, p, u[0], u[1]), x0, 0.0, T, saveat=ts,
                                 args=force, rtol=1e-6, atol=1e-8)
        return sol.ys[:, 3], sol.stats["num_steps"]

    def fixed(i):
        sol = jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=noisy(i), dt=dt)
        return sol.ys[:, 3], sol.stats["num_steps"]

    def fixed_per_stage(i):
        sol = jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=noisy(i, 0.0 * i), dt=dt)
        return sol.ys[:, 3], sol.stats["num_steps"]

    cases = {"adaptive, sampled forces": adaptive, "adaptive, constant forces": adaptive_const,
             "fixed 1 ms, sampled forces": fixed, "fixed 1 ms, forces interpolated per stage": fixed_per_stage}
    fns = {k: jax.jit(jax.vmap(f)) for k, f in cases.items()}
    best, outs = interleaved_best(fns, jnp.arange(a.paths), a.rounds)
    steps = {k: float(jnp.sum(outs[k][1])) for k in fns}
    ns = {k: best[k] / steps[k] * 1e9 for k in fns}
    rows = ["| case | ns per path-step | steps per path |", "|---|---:|---:|"]
    rows += [f"| {k} | {ns[k]:.0f} | {steps[k] / a.paths:.0f} |" for k in fns]
    md = (f"Cost per step of jaxdrift's modes, half-car study, {a.paths} paths x {T:g} s, float64, {a.rounds} "
          f"interleaved rounds, best kept; load average at end {os.getloadavg()[0]:.1f}.\n\n" + "\n".join(rows)
          + "\n\nReproduce: `python benchmarks/experiments/adaptive_cost.py`\n")
    out = {"machine": machine_info(), "load_average_at_end": list(os.getloadavg()),
           "config": {"paths": a.paths, "seconds": T, "rounds": a.rounds},
           "ns_per_path_step": ns, "steps_per_path": {k: steps[k] / a.paths for k in fns}}
    jp, mp = write_results(a.out, out, md)
    print(md)
    print(f"wrote {jp} and {mp}")


if __name__ == "__main__":
    main()
