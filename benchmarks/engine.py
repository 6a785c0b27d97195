"""Engine throughput: jaxdrift's DOPRI5 against diffrax Dopri5 on a 10-state test model.

Reproduce:  python benchmarks/engine.py            (writes benchmarks/results/engine.{json,md})
            python benchmarks/engine.py --quick    (smaller run)

The model is "linear-ish": a damped 5-mass chain with a weak cubic spring, driven by a sampled
input signal (the engine's SampledSignal, linear interpolation), batched over paths whose input
amplitude and initial state differ. Both libraries integrate the same vector field, float64,
vmapped over paths, saving the state at 10 times. Fixed mode: both take the same 1 ms steps.
Adaptive mode: rtol 1e-6, atol 1e-8, each with its own (scipy-constant) controller; path-steps
are counted from each library's own step statistics.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

import jaxdrift  # noqa: E402
from _common import machine_info, timed, write_results  # noqa: E402

N_MASS = 5


def _chain_matrices():
    k, d = 400.0, 2.0
    K = np.zeros((N_MASS, N_MASS))
    for i in range(N_MASS):
        K[i, i] = 2 * k
        if i + 1 < N_MASS:
            K[i, i + 1] = K[i + 1, i] = -k
    return jnp.asarray(K), jnp.asarray(K * d / k)


K, D = _chain_matrices()


def vector_field(t, y, args):
    sig, amp = args
    x, v = y[:N_MASS], y[N_MASS:]
    u = amp * sig(t)[0]
    acc = -K @ x - D @ v - 50.0 * x**3
    acc = acc.at[0].add(u)
    return jnp.concatenate([v, acc])


def make_inputs(n_paths, T, dt_in, seed=0):
    rng = np.random.default_rng(seed)
    n = int(round(T / dt_in)) + 1
    t = np.arange(n) * dt_in
    base = np.sin(2 * np.pi * 1.3 * t) + 0.5 * np.sin(2 * np.pi * 4.1 * t) + 0.05 * rng.normal(size=n)
    amps = jnp.asarray(rng.uniform(0.5, 1.5, size=n_paths))
    y0 = jnp.asarray(rng.normal(scale=0.01, size=(n_paths, 2 * N_MASS)))
    return jaxdrift.SampledSignal(0.0, dt_in, base[:, None]), amps, y0


def run_jaxdrift(sig, amps, y0s, T, save, mode, dt):
    def one(y0, amp):
        kw = dict(dt=dt) if mode == "fixed" else dict(rtol=1e-6, atol=1e-8)
        sol = jaxdrift.solve_ode(vector_field, y0, 0.0, T, saveat=save, args=(sig, amp), **kw)
        return sol.ys, sol.num_accepted + sol.num_rejected

    return jax.jit(jax.vmap(one))


def run_diffrax(sig, amps, y0s, T, save, mode, dt):
    import diffrax

    term = diffrax.ODETerm(vector_field)

    def one(y0, amp):
        if mode == "fixed":
            ctrl, dt0 = diffrax.ConstantStepSize(), dt
        else:
            ctrl, dt0 = diffrax.PIDController(rtol=1e-6, atol=1e-8), None
        sol = diffrax.diffeqsolve(term, diffrax.Dopri5(), 0.0, T, dt0, y0, args=(sig, amp),
                                  saveat=diffrax.SaveAt(ts=save), stepsize_controller=ctrl,
                                  max_steps=10 * int(T / 1e-3) + 10)
        return sol.ys, sol.stats["num_steps"]

    return jax.jit(jax.vmap(one))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    ap.add_argument("--paths", type=int, default=None)
    ap.add_argument("--duration", type=float, default=None)
    a = ap.parse_args(argv)
    n_paths = a.paths or (64 if a.quick else 256)
    T = a.duration or (2.0 if a.quick else 10.0)
    dt = 1e-3
    sig, amps, y0s = make_inputs(n_paths, T, dt)
    save = jnp.linspace(0.0, T, 10)
    rows, results = [], {}
    for mode in ("fixed", "adaptive"):
        res = {}
        for lib, make in (("jaxdrift", run_jaxdrift), ("diffrax", run_diffrax)):
            fn = make(sig, amps, y0s, T, save, mode, dt)
            first, best, (ys, steps) = timed(fn, y0s, amps)
            path_steps = float(np.sum(np.asarray(steps)))
            res[lib] = {
                "compile_plus_first_run_s": first,
                "run_s": best,
                "path_steps": path_steps,
                "path_steps_per_s": path_steps / best,
                "ys_end_checksum": float(np.asarray(ys)[:, -1].sum()),
            }
        diff = abs(res["jaxdrift"]["ys_end_checksum"] - res["diffrax"]["ys_end_checksum"])
        res["max_abs_checksum_difference"] = diff
        res["ratio_jaxdrift_over_diffrax"] = res["jaxdrift"]["path_steps_per_s"] / res["diffrax"]["path_steps_per_s"]
        results[mode] = res
        rows.append(
            f"| {mode} | {res['jaxdrift']['path_steps_per_s']:.3g} | {res['diffrax']['path_steps_per_s']:.3g} "
            f"| {res['ratio_jaxdrift_over_diffrax']:.2f} | {res['jaxdrift']['compile_plus_first_run_s']:.1f} "
            f"| {res['diffrax']['compile_plus_first_run_s']:.1f} |"
        )
        print(mode, {k: (v if not isinstance(v, dict) else round(v["path_steps_per_s"])) for k, v in res.items()})
    payload = {
        "benchmark": "engine",
        "model": "10-state damped chain with cubic spring, sampled input (linear interpolation)",
        "n_paths": n_paths,
        "duration_s": T,
        "fixed_dt_s": dt,
        "adaptive": {"rtol": 1e-6, "atol": 1e-8},
        "dtype": "float64",
        "results": results,
        "machine": machine_info(),
    }
    md = (
        f"Engine benchmark ({n_paths} paths x {T:g} s, float64, {payload['machine'].get('cpu_model', '')}, "
        f"{payload['machine']['cpu_count']} cores; `python benchmarks/engine.py`)\n\n"
        "| mode | jaxdrift path-steps/s | diffrax path-steps/s | ratio | jaxdrift compile+1st run [s] | diffrax compile+1st run [s] |\n"
        "|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n"
    )
    name = "engine_quick" if a.quick else "engine"
    jp, mp = write_results(name, payload, md)
    print(md)
    print("wrote", jp, mp)


if __name__ == "__main__":
    main()
