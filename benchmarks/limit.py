"""The machine's limit for the half-car study: the same step as a compiled loop over paths (numba).

jaxdrift's throughput is measured against other libraries (``throughput.py``); this script says
what the machine itself can do with the same work. It integrates the force-driven half-car (A.3)
of ``benchmarks/_setup.py`` with the fixed 1 ms Dormand-Prince 5(4) step (6 stages, FSAL, forces
linear between the 1 kHz samples, the same tableau as jaxdrift), pitch and heave saved every
0.1 s, as a loop over paths compiled by numba: one path's 10 states live in registers, ``sin``
and ``cos`` of the pitch are computed once per evaluation, nothing is written to memory inside a
step. Variants:

* ``float64`` and ``float32`` (float32 state with the Kahan-compensated update of jaxdrift's fast
  mode);
* ``noise="inline"``: each step draws its two force-noise samples with numba's generator
  (per-thread state): the cost of a study that needs no reproducible per-path streams;
  ``noise="given"``: the noise is read from an array (jaxdrift's ``path_normals``, the same
  samples jaxdrift integrates), which is how the trajectory is checked;
* 1 or 2 threads (``prange`` over paths).

The check: on the same noise, pitch and heave of the float64 loop equal ``jaxdrift.solve_ode``'s
fixed-step solution to rounding (the largest difference is printed and stored).

numba is a benchmark dependency only (the ``bench`` extra), never needed by jaxdrift.

Reproduce (about a minute)::

    python benchmarks/limit.py              # writes benchmarks/results/limit.{json,md}
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

_KERNEL = """
def kernel(f0, noise, sigma, x0, out, n_steps, stride, seed):
    n_paths = out.shape[0]
    h = F({dt!r})
    for p in prange(n_paths):
        if INLINE:
            np.random.seed(seed + p)
        z1, z2, z3, be, dz1, dz2, dz3, dbe, ze1, ze2 = (F(x0[0]), F(x0[1]), F(x0[2]), F(x0[3]), F(x0[4]),
                                                        F(x0[5]), F(x0[6]), F(x0[7]), F(x0[8]), F(x0[9]))
        c1 = c2 = c3 = c4 = c5 = c6 = c7 = c8 = c9 = c10 = F(0.0)
        if INLINE:
            ua = F(f0[0, 0] + sigma * np.random.standard_normal())
            ub = F(f0[0, 1] + sigma * np.random.standard_normal())
        else:
            ua = F(f0[0, 0] + sigma * noise[p, 0, 0])
            ub = F(f0[0, 1] + sigma * noise[p, 0, 1])
        k = rhs(z1, z2, z3, be, dz1, dz2, dz3, dbe, ze1, ze2, ua, ub)
        out[p, 0, 0] = z3
        out[p, 0, 1] = be
        for i in range(n_steps):
            if INLINE:
                va = F(f0[i + 1, 0] + sigma * np.random.standard_normal())
                vb = F(f0[i + 1, 1] + sigma * np.random.standard_normal())
            else:
                va = F(f0[i + 1, 0] + sigma * noise[p, i + 1, 0])
                vb = F(f0[i + 1, 1] + sigma * noise[p, i + 1, 1])
            da = va - ua
            db = vb - ub
{stages}
            ua = va
            ub = vb
            if (i + 1) % stride == 0:
                out[p, (i + 1) // stride, 0] = z3
                out[p, (i + 1) // stride, 1] = be
"""


_KERNEL_SIMD = """
def kernel(f0, noise, sigma, x0, out, n_steps, stride, seed):
    n_paths = out.shape[0]
    n_blocks = n_paths // BLK
    h = F({dt!r})
    for blk in prange(n_blocks):
        p0 = blk * BLK
        if INLINE:
            np.random.seed(seed + blk)
        Y = np.empty((10, BLK), F)
        Cc = np.zeros((10, BLK), F)
        K = np.empty((7, 10, BLK), F)
        S = np.empty((10, BLK), F)
        ua = np.empty(BLK, F)
        ub = np.empty(BLK, F)
        va = np.empty(BLK, F)
        vb = np.empty(BLK, F)
        for q in range(BLK):
            for r in range(10):
                Y[r, q] = F(x0[r])
            if INLINE:
                ua[q] = F(f0[0, 0] + sigma * np.random.standard_normal())
                ub[q] = F(f0[0, 1] + sigma * np.random.standard_normal())
            else:
                ua[q] = F(f0[0, 0] + sigma * noise[0, 0, p0 + q])
                ub[q] = F(f0[0, 1] + sigma * noise[0, 1, p0 + q])
        rhs_rows(Y, ua, ub, F(0.0), ua, ub, K[0])
        for q in range(BLK):
            out[p0 + q, 0, 0] = Y[2, q]
            out[p0 + q, 0, 1] = Y[3, q]
        for i in range(n_steps):
            if INLINE:
                for q in range(BLK):
                    va[q] = F(f0[i + 1, 0] + sigma * np.random.standard_normal())
                    vb[q] = F(f0[i + 1, 1] + sigma * np.random.standard_normal())
            else:
                for q in range(BLK):
                    va[q] = F(f0[i + 1, 0] + sigma * noise[i + 1, 0, p0 + q])
                    vb[q] = F(f0[i + 1, 1] + sigma * noise[i + 1, 1, p0 + q])
{stages}
            for q in range(BLK):
                ua[q] = va[q]
                ub[q] = vb[q]
            if (i + 1) % stride == 0:
                for q in range(BLK):
                    out[p0 + q, (i + 1) // stride, 0] = Y[2, q]
                    out[p0 + q, (i + 1) // stride, 1] = Y[3, q]
"""


def _source_simd(compensated: bool) -> str:
    """Stages on (10, BLK) blocks: each stage is one loop over the block (vectorised by LLVM)."""
    from jaxdrift.solvers._tableau import DOPRI5

    a, b, c = DOPRI5.a, DOPRI5.b, DOPRI5.c
    ind = " " * 12
    lines = []
    for j in range(1, 6):
        terms = " + ".join(f"F({float(a[j, m])!r}) * K[{m}, r, q]" for m in range(j) if a[j, m] != 0.0)
        lines += [ind + "for r in range(10):", ind + "    for q in range(BLK):",
                  ind + f"        S[r, q] = Y[r, q] + h * ({terms})",
                  ind + f"rhs_rows(S, ua, ub, F({float(c[j])!r}), va, vb, K[{j}])"]
    terms = " + ".join(f"F({float(b[m])!r}) * K[{m}, r, q]" for m in range(6) if b[m] != 0.0)
    lines += [ind + "for r in range(10):", ind + "    for q in range(BLK):"]
    if compensated:
        lines += [ind + f"        d_ = h * ({terms}) - Cc[r, q]", ind + "        y_ = Y[r, q] + d_",
                  ind + "        Cc[r, q] = (y_ - Y[r, q]) - d_", ind + "        Y[r, q] = y_"]
    else:
        lines += [ind + f"        Y[r, q] = Y[r, q] + h * ({terms})"]
    lines += [ind + "rhs_rows(Y, va, vb, F(1.0), va, vb, K[6])", ind + "K[0, :, :] = K[6]"]
    return "\n".join(lines)


def _source(dt: float, compensated: bool) -> str:
    """The stage code of one DOPRI5 step on the 10 scalar states (k1 = FSAL value ``k``)."""
    from jaxdrift.solvers._tableau import DOPRI5

    a, b, c = DOPRI5.a, DOPRI5.b, DOPRI5.c
    names = ["z1", "z2", "z3", "be", "dz1", "dz2", "dz3", "dbe", "ze1", "ze2"]
    ind = " " * 12
    lines = [ind + "k0 = k"]
    for j in range(1, 6):
        args = []
        for r, nm in enumerate(names):
            terms = " + ".join(f"F({float(a[j, m])!r}) * k{m}[{r}]" for m in range(j) if a[j, m] != 0.0)
            args.append(f"{nm} + h * ({terms})")
        u = f"ua + F({float(c[j])!r}) * da, ub + F({float(c[j])!r}) * db"
        lines.append(ind + f"k{j} = rhs(" + ", ".join(args) + f", {u})")
    for r, nm in enumerate(names):
        terms = " + ".join(f"F({float(b[m])!r}) * k{m}[{r}]" for m in range(6) if b[m] != 0.0)
        if compensated:
            cn = f"c{r + 1}"
            lines.append(ind + f"d_ = h * ({terms}) - {cn}")
            lines.append(ind + f"y_ = {nm} + d_")
            lines.append(ind + f"{cn} = (y_ - {nm}) - d_")
            lines.append(ind + f"{nm} = y_")
        else:
            lines.append(ind + f"{nm} = {nm} + h * ({terms})")
    lines.append(ind + "k = rhs(z1, z2, z3, be, dz1, dz2, dz3, dbe, ze1, ze2, va, vb)")
    return "\n".join(lines)


def build_kernel(params, dt: float, dtype: str, *, noise: str, compensated: bool | None = None,
                 layout: str = "scalar", block: int = 64):
    """A numba-compiled ``kernel(f0, noise, sigma, x0, out, n_steps, stride, seed)``.

    ``layout="scalar"``: one path at a time, states in registers, library ``sin``/``cos``; noise
    ``(paths, samples, 2)``. ``layout="simd"``: blocks of ``block`` paths, each stage one loop over
    the block that LLVM vectorises, ``sin``/``cos`` by jaxdrift's polynomials
    (``jaxdrift.models._trig``); noise ``(samples, 2, paths)``.
    """
    import numba

    F = np.float32 if dtype == "float32" else np.float64
    if compensated is None:
        compensated = dtype == "float32"
    p = {k: F(v) for k, v in params.to_dict().items()}
    a_, b_, m1, m2, m3, I_ = p["a"], p["b"], p["m1"], p["m2"], p["m3"], p["I"]
    k1, k2, k3, k4, d1, d2, d3, d4, g = (p[k] for k in ("k1", "k2", "k3", "k4", "d1", "d2", "d3", "d4", "g"))

    @numba.njit(inline="always", fastmath=False)
    def rhs(z1, z2, z3, be, dz1, dz2, dz3, dbe, ze1, ze2, f1, f2):
        s = F(math.sin(be))
        c = F(math.cos(be))
        f3 = k3 * (z3 - z1 - b_ * s) + d3 * (dz3 - dz1 - b_ * dbe * c)
        f4 = k4 * (z3 - z2 + a_ * s) + d4 * (dz3 - dz2 + a_ * dbe * c)
        # the same operations as jaxdrift.models.force_driven_rhs (divisions included)
        return (dz1, dz2, dz3, dbe, g + (f3 - f1) / m1, g + (f4 - f2) / m2,
                g - (f3 + f4) / m3, c * (b_ * f3 - a_ * f4) / I_,
                (k1 * (z1 - ze1) + d1 * dz1 - f1) / d1, (k2 * (z2 - ze2) + d2 * dz2 - f2) / d2)

    ns = {"F": F, "rhs": rhs, "np": np, "prange": numba.prange, "INLINE": noise == "inline", "BLK": block}
    if layout == "simd":
        from jaxdrift.models._trig import _PIO2, _TERMS

        pio2 = tuple(F(v) for v in _PIO2[np.dtype(F)])
        n_sin, n_cos = _TERMS[np.dtype(F)]
        cs = tuple(F((-1) ** j / math.factorial(2 * j + 1)) for j in range(n_sin))
        cc = tuple(F((-1) ** j / math.factorial(2 * j)) for j in range(n_cos))
        two_over_pi = F(2.0 / math.pi)

        @numba.njit(inline="always", fastmath=False)
        def sincos(x):
            k = np.round(x * two_over_pi)
            r = x
            for part in pio2:
                r = r - k * part
            r2 = r * r
            ps = cs[n_sin - 1]
            for j in range(n_sin - 2, -1, -1):
                ps = cs[j] + r2 * ps
            ps = r * ps
            pc = cc[n_cos - 1]
            for j in range(n_cos - 2, -1, -1):
                pc = cc[j] + r2 * pc
            qd = np.int32(k) & 3
            sn = pc if (qd & 1) == 1 else ps
            cn = ps if (qd & 1) == 1 else pc
            sn = -sn if qd >= 2 else sn
            cn = -cn if (qd == 1 or qd == 2) else cn
            return sn, cn

        @numba.njit(inline="always", fastmath=False)
        def rhs_rows(S, ua, ub, c_, va, vb, Kout):
            for q in range(S.shape[1]):
                f1 = ua[q] + c_ * (va[q] - ua[q])
                f2 = ub[q] + c_ * (vb[q] - ub[q])
                z1, z2, z3, be, dz1, dz2, dz3, dbe, ze1, ze2 = (S[0, q], S[1, q], S[2, q], S[3, q], S[4, q],
                                                                S[5, q], S[6, q], S[7, q], S[8, q], S[9, q])
                s, c = sincos(be)
                f3 = k3 * (z3 - z1 - b_ * s) + d3 * (dz3 - dz1 - b_ * dbe * c)
                f4 = k4 * (z3 - z2 + a_ * s) + d4 * (dz3 - dz2 + a_ * dbe * c)
                Kout[0, q] = dz1
                Kout[1, q] = dz2
                Kout[2, q] = dz3
                Kout[3, q] = dbe
                Kout[4, q] = g + (f3 - f1) / m1
                Kout[5, q] = g + (f4 - f2) / m2
                Kout[6, q] = g - (f3 + f4) / m3
                Kout[7, q] = c * (b_ * f3 - a_ * f4) / I_
                Kout[8, q] = (k1 * (z1 - ze1) + d1 * dz1 - f1) / d1
                Kout[9, q] = (k2 * (z2 - ze2) + d2 * dz2 - f2) / d2

        ns["rhs_rows"] = rhs_rows
        src = _KERNEL_SIMD.format(dt=float(dt), stages=_source_simd(compensated))
    else:
        src = _KERNEL.format(dt=float(dt), stages=_source(dt, compensated))
    exec(compile(src, f"<limit kernel {dtype} {noise}>", "exec"), ns)
    return numba.njit(parallel=True, fastmath=False)(ns["kernel"])


def run_kernel(kern, study, n_paths: int, *, dtype: str, noise_arr=None, threads: int = 1, seed: int = 0,
               layout: str = "scalar"):
    """Run ``kern`` on ``n_paths`` paths; returns ``((wall s, CPU s), out (paths, saves, [z3, beta]))``."""
    import numba

    F = np.float32 if dtype == "float32" else np.float64
    n_steps = int(round(study.T / study.dt))
    stride = int(round(0.1 / study.dt))
    out = np.zeros((n_paths, n_steps // stride + 1, 2), F)
    f0 = np.ascontiguousarray(study.f0, dtype=F)
    if noise_arr is None:
        noise = np.zeros((1, 1, 2), F)
    elif layout == "simd":
        noise = np.ascontiguousarray(np.moveaxis(np.asarray(noise_arr, F), 0, -1))  # (samples, 2, paths)
    else:
        noise = np.ascontiguousarray(noise_arr, dtype=F)
    numba.set_num_threads(threads)
    t, c = time.perf_counter(), time.process_time()
    kern(f0, noise, F(study.sigma), np.asarray(study.x0, F), out, n_steps, stride, seed)
    return (time.perf_counter() - t, time.process_time() - c), out


def jaxdrift_paths(study, idx, dtype="float64"):
    """jaxdrift's fixed-step solution of the same paths, and the noise it used ``(paths, n, 2)``."""
    import jax
    import jax.numpy as jnp

    import jaxdrift
    from _setup import force_rhs

    key = jax.random.key(0)
    n, T, dt = study.n_samples, study.T, study.dt
    ts = jnp.arange(0, int(round(T * 10)) + 1) / 10.0
    dt_ = jnp.dtype(dtype)
    f0 = jnp.asarray(study.f0, dt_)
    rhs = force_rhs(study.params)
    noise = jax.vmap(lambda i: jaxdrift.path_normals(key, i, n, 2, dt_))(jnp.asarray(idx, jnp.int32))

    def path(z):
        sig = jaxdrift.SampledSignal(0.0, dt, f0 + z * jnp.asarray(study.sigma, dt_))
        if dtype == "float64":
            sol = jaxdrift.solve_ode(rhs, jnp.asarray(study.x0), 0.0, T, saveat=ts, args=sig, dt=dt)
        else:
            sol = jaxdrift.solve_fixed_fast(rhs, jnp.asarray(study.x0), 0.0, T, saveat=ts, args=sig, dt=dt)
        return sol.ys[:, jnp.array([2, 3])]

    return np.asarray(jax.jit(jax.vmap(path))(noise)), np.asarray(noise)


def trajectory_check(study, n_paths: int = 8) -> dict:
    """Largest difference between the loop's and jaxdrift's pitch and heave on the same noise."""
    out = {}
    for dtype in ("float64", "float32"):
        ref, noise = jaxdrift_paths(study, np.arange(n_paths), dtype)
        for layout in ("scalar", "simd"):
            kern = build_kernel(study.params, study.dt, dtype, noise="given", layout=layout, block=n_paths)
            _, got = run_kernel(kern, study, n_paths, dtype=dtype, noise_arr=noise, layout=layout)
            diff = np.abs(got.astype(np.float64) - ref.astype(np.float64))
            spread = np.std(ref.astype(np.float64), axis=0) + 1e-300
            out[f"{dtype}-{layout}"] = {
                "paths": n_paths,
                "max_abs_diff_z3": float(diff[..., 0].max()),
                "max_abs_diff_beta": float(diff[..., 1].max()),
                "max_diff_over_spread": float(np.max(diff[:, 1:] / spread[1:])),
                "max_abs_value_beta": float(np.abs(ref[..., 1]).max()),
            }
    return out


def limit_cases(study, n_paths: int, threads=(1, 2), layouts=("scalar", "simd")):
    """``{name: callable() -> (seconds, out)}`` for every variant, compiled (first call done)."""
    cases = {}
    arr = np.random.default_rng(0).standard_normal((n_paths, study.n_samples, 2))
    for layout in layouts:
        for dtype in ("float64", "float32"):
            for noise in ("inline", "given"):
                kern = build_kernel(study.params, study.dt, dtype, noise=noise, layout=layout)
                for th in threads:
                    name = f"limit-{layout}-{dtype}-{noise}-{th}t"

                    def call(kern=kern, th=th, dtype=dtype, noise=noise, layout=layout):
                        return run_kernel(kern, study, n_paths, dtype=dtype, threads=th, layout=layout,
                                          noise_arr=arr if noise == "given" else None)

                    cases[name] = call
    return cases


def main(argv=None):
    import argparse
    import json

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--paths", type=int, default=256)
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", default="limit")
    a = ap.parse_args(argv)

    import jax

    jax.config.update("jax_enable_x64", True)
    from _common import machine_info, write_results
    from _setup import paper_study

    load0 = list(os.getloadavg())
    study = paper_study(T=a.seconds)
    check = trajectory_check(paper_study(T=min(a.seconds, 5.0)))
    cases = limit_cases(study, a.paths)
    for f in cases.values():
        f()  # compile
    best = {k: float("inf") for k in cases}
    cpu = dict(best)
    for _ in range(a.rounds):
        for k, f in cases.items():
            (w, c), _ = f()
            best[k], cpu[k] = min(best[k], w), min(cpu[k], c)
    steps = a.paths * int(round(study.T / study.dt))
    res = {k: {"s": v, "ns_per_path_step": v / steps * 1e9, "cpu_ns_per_path_step": cpu[k] / steps * 1e9,
               "path_steps_per_s": steps / v} for k, v in best.items()}
    payload = {"command": "python benchmarks/limit.py " + " ".join(sys.argv[1:] if argv is None else argv),
               "machine": machine_info(), "load_average_start": load0, "load_average_end": list(os.getloadavg()),
               "paths": a.paths, "seconds": a.seconds, "cases": res, "trajectory_check": check}
    md = ["| variant | wall ns / path-step | CPU ns / path-step | path-steps / s |", "|---|---:|---:|---:|"]
    md += [f"| {k} | {r['ns_per_path_step']:.1f} | {r['cpu_ns_per_path_step']:.1f} | {r['path_steps_per_s']:.3g} |"
           for k, r in res.items()]
    md.append("")
    for k, c in check.items():
        md.append(f"Same noise as jaxdrift ({k}, {c['paths']} paths x 5 s): largest difference z3 "
                  f"{c['max_abs_diff_z3']:.2e} m, beta {c['max_abs_diff_beta']:.2e} rad, "
                  f"{c['max_diff_over_spread']:.2e} of the spread.")
    md.append(f"Load average {load0[0]:.1f} at start, {os.getloadavg()[0]:.1f} at end. Reproduce: `{payload['command'].strip()}`")
    write_results(a.out, payload, "\n".join(md) + "\n")
    print("\n".join(md))
    print(json.dumps(check, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
