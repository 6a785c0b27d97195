"""How fast can any integrator be on the half-car study? The vector field and the noise set a floor.

Found (``benchmarks/results/floor.json``, idle AMD EPYC, before the polynomial sin/cos and the
paths-last loop): float64 jaxdrift 386 ns per path-step against diffrax 902, a floor of 343 ns
(noise + six model evaluations), so at most 2.63x over diffrax with that model code; float32
(``floor-float32.json``) at most 2.89x. ``benchmarks/limit.py`` later showed how far below that
floor a compiled loop goes.

The throughput targets are ratios of path-steps per second against diffrax on the same
vector field with the same noisy inputs. Two costs are the same for every contender: drawing the
noise, and the six evaluations of the model's vector field per Dormand-Prince step (the seventh is
the next step's first, FSAL). This script measures both inside a full fixed-step run (1 ms steps,
the study of ``benchmarks/_setup.py``, 256 paths a call, float64), by running each integrator
three times:

* with the model's vector field (``force_driven_rhs``: one ``sin`` and one ``cos`` of the pitch),
* with its ``linear=True`` form (no trigonometry),
* with a trivial vector field of the same shapes (``-1e-3 x + 1e-6 f1``),

and the noise draw alone. Per path-step, ``model - trivial`` is six evaluations of the model, and
``noise + 6 evaluations`` is the cost of an integrator whose own work were free. ``diffrax /
floor`` is then the largest speed-up over diffrax that any integrator can reach on this study; it
is printed next to the target.

Reproduce (about 3 minutes on 2 idle cores)::

    python benchmarks/experiments/floor.py
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # benchmarks/: _common, _setup, results/
sys.path.insert(0, str(HERE))


def main(argv=None):
    from _common import timing_parser

    ap = timing_parser(__doc__, out="floor", seconds=10.0)
    ap.add_argument("--dtype", choices=("float64", "float32"), default="float64")
    a = ap.parse_args(argv)

    import jax

    jax.config.update("jax_enable_x64", True)
    import diffrax
    import jax.numpy as jnp

    import jaxdrift
    from _common import interleaved_best, machine_info, write_results
    from _setup import paper_study
    from jaxdrift.models._halfcar import force_driven_rhs

    st = paper_study(T=a.seconds)
    p = st.params
    T, dt, n = st.T, st.dt, st.n_samples
    dtype = jnp.dtype(a.dtype)
    ts = (jnp.arange(0, int(round(T * 10)) + 1) / 10.0).astype(dtype)
    f0 = jnp.asarray(st.f0, dtype)
    x0 = jnp.asarray(st.x0, dtype)
    key = jax.random.key(0)
    n_steps = int(round(T / dt))
    B = a.paths

    def signal(i):
        return jaxdrift.SampledSignal(0.0, dt, f0 + jaxdrift.path_normals(key, i, n, 2, dtype) * jnp.asarray(st.sigma, dtype))

    def field(kind):
        def rhs(t, x, sig):
            f = sig(t)
            if kind == "trivial":
                return -1e-3 * x + 1e-6 * f[0]
            return force_driven_rhs(t, x, p, f[0], f[1], linear=(kind == "linear"))

        return rhs

    def jd(kind):
        rhs = field(kind)
        if dtype == jnp.float64:
            return lambda i: jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=signal(i), dt=dt).ys[:, 3]
        return lambda i: jaxdrift.solve_fixed_fast(rhs, x0, 0.0, T, saveat=ts, args=signal(i), dt=dt,
                                                   dtype=dtype).ys[:, 3]

    def dfx(kind):
        term = diffrax.ODETerm(field(kind))

        def path(i):
            sol = diffrax.diffeqsolve(term, diffrax.Dopri5(), 0.0, T, dt, x0, args=signal(i),
                                      saveat=diffrax.SaveAt(ts=ts), stepsize_controller=diffrax.ConstantStepSize(),
                                      max_steps=n_steps + 16)
            return sol.ys[:, 3]

        return path

    cases = {"noise": lambda i: signal(i).values[-1, 0]}
    for kind in ("model", "linear", "trivial"):
        cases[f"jaxdrift/{kind}"] = jd(kind)
        cases[f"diffrax/{kind}"] = dfx(kind)
    fns = {k: jax.jit(jax.vmap(f)) for k, f in cases.items()}
    best, _ = interleaved_best(fns, jnp.arange(B, dtype=jnp.int32), a.rounds)
    ns = {k: v / (B * n_steps) * 1e9 for k, v in best.items()}
    ev = {kind: (ns[f"jaxdrift/{kind}"] - ns["jaxdrift/trivial"]) / 6.0 for kind in ("model", "linear")}
    ev_d = {kind: (ns[f"diffrax/{kind}"] - ns["diffrax/trivial"]) / 6.0 for kind in ("model", "linear")}
    floor = {kind: ns["noise"] + 6.0 * ev[kind] for kind in ("model", "linear")}
    out = {
        "machine": machine_info(),
        "load_average_at_end": list(os.getloadavg()),
        "config": {"paths": B, "seconds": T, "dt": dt, "dtype": a.dtype, "rounds": a.rounds},
        "ns_per_path_step": ns,
        "vector_field_eval_ns": {"jaxdrift": ev, "diffrax": ev_d},
        "floor_ns_per_path_step": floor,
        "ratio_vs_diffrax": {kind: ns[f"diffrax/{kind}"] / ns[f"jaxdrift/{kind}"] for kind in ("model", "linear", "trivial")},
        "max_ratio_vs_diffrax": {kind: ns[f"diffrax/{kind}"] / floor[kind] for kind in ("model", "linear")},
    }
    rows = [
        "| vector field | jaxdrift ns/path-step | diffrax ns/path-step | jaxdrift vs diffrax | one evaluation ns (jaxdrift / diffrax) | floor ns (noise + 6 evaluations) | largest possible vs diffrax |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for kind in ("model", "linear", "trivial"):
        e = f"{ev[kind]:.0f} / {ev_d[kind]:.0f}" if kind in ev else ""
        fl = f"{floor[kind]:.0f}" if kind in floor else ""
        mx = f"{out['max_ratio_vs_diffrax'][kind]:.2f}x" if kind in floor else ""
        rows.append(f"| {kind} | {ns[f'jaxdrift/{kind}']:.0f} | {ns[f'diffrax/{kind}']:.0f} | "
                    f"{out['ratio_vs_diffrax'][kind]:.2f}x | {e} | {fl} | {mx} |")
    md = (f"Floor of the half-car study ({a.dtype}, {B} paths x {T:g} s, fixed 1 ms DOPRI5, "
          f"{a.rounds} interleaved rounds, best kept; load average at end "
          f"{out['load_average_at_end'][0]:.1f}). Noise draw alone: {ns['noise']:.0f} ns per path-step.\n\n"
          + "\n".join(rows) + "\n\nReproduce: `python benchmarks/experiments/floor.py"
          + ("" if a.dtype == "float64" else f" --dtype {a.dtype}") + "`\n")
    jp, mp = write_results(a.out, out, md)
    print(md)
    print(f"wrote {jp} and {mp}")


if __name__ == "__main__":
    main()
