"""Throughput of the half-car noisy-force study: jaxdrift against diffrax and scipy, in one process.

The study of the seed's section 4 (``benchmarks/_setup.py``): force-driven half-car (A.3), contact
forces sampled at 1 kHz with white noise (sigma = 0.002 f_max), 30 s, pitch and heave saved every
0.1 s. Every contender integrates the same vector field with the same noisy inputs (a
:class:`jaxdrift.SampledSignal`, linear between samples; the noise of path ``i`` is
``jaxdrift.path_normals(key, i, ...)``):

* fixed 1 ms Dormand-Prince 5(4) (30,000 steps a path): ``jaxdrift.solve_ode(dt=1e-3)``, the fast
  mode ``jaxdrift.solve_fixed_fast`` (float32 state, Kahan update, float32 noise), diffrax
  ``Dopri5`` with ``ConstantStepSize`` under ``jit(vmap)``, scipy ``solve_ivp(RK45)`` forced to
  the same 1 ms steps (``first_step = max_step = 1e-3``, tolerances so loose every step is
  accepted), one path at a time;
* adaptive, rtol 1e-6, atol 1e-8: ``jaxdrift.solve_ode`` (scipy's controller), diffrax ``Dopri5``
  with its ``PIDController`` (I controller), scipy ``RK45``.

Path-steps per second count each solver's own steps (accepted + rejected); compile time is
reported separately (first call minus the best warm call); the cases are timed in ``--repeats``
interleaved rounds on fresh path indices (so a change of load hits all alike), each keeping its best. scipy runs a few paths and is extrapolated linearly (its cost per step
does not depend on the number of paths). The memory case (10,000 paths x 60 s at 1 kHz, statistics
at 0.1 s, through :func:`jaxdrift.monte_carlo`) runs in a subprocess so that its peak RSS is its
own. Writes ``benchmarks/results/throughput.json`` and ``throughput.md``.

Reproduce (about 15 minutes on 2 cores; ``--quick``: about 3 minutes, 5 s paths, no memory case)::

    python benchmarks/throughput.py
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
sys.path.insert(0, str(HERE))


def _versions():
    import importlib.metadata as md

    out = {"python": platform.python_version()}
    for pkg in ("jax", "jaxlib", "equinox", "diffrax", "numpy", "scipy"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = None
    return out


def _machine():
    import jax

    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem = None
    try:
        with open("/proc/meminfo") as fh:
            mem = int(fh.readline().split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return {
        "platform": platform.platform(),
        "cpu": cpu,
        "cpu_count": os.cpu_count(),
        "memory_bytes": mem,
        "jax_backend": jax.default_backend(),
        "jax_devices": [str(d) for d in jax.devices()],
        "load_average_at_start": list(os.getloadavg()),
        "gpu_note": "the code runs unchanged on GPU (device-agnostic jax); no GPU was available to the session "
        "that produced these numbers, so no GPU figures are recorded",
    }


def _scipy_case(study, n_paths, *, fixed, rtol=1e-6, atol=1e-8, key_seed=0):
    import jax
    import numpy as np
    from scipy.integrate import solve_ivp

    import jaxdrift
    from _setup import numpy_force_rhs

    rhs_np = numpy_force_rhs(study.params)
    dt, T = study.dt, study.T
    n = study.n_samples
    ts = np.arange(0, int(round(T * 10)) + 1) / 10.0
    key = jax.random.key(key_seed)
    total_steps, wall = 0, 0.0
    for i in range(n_paths):
        f = study.f0 + study.sigma * np.asarray(jaxdrift.path_normals(key, i, n, 2))

        def fun(t, x):
            s = min(max(t / dt, 0.0), n - 1.0)
            k = min(int(s), n - 2)
            w = s - k
            u = f[k] + w * (f[k + 1] - f[k])
            return rhs_np(x, u[0], u[1])

        kw = dict(method="RK45", t_eval=ts)
        if fixed:
            # Every step accepted at exactly 1 ms: scipy's DOPRI5 as a fixed-step method.
            kw.update(first_step=dt, max_step=dt, rtol=1e3, atol=1e3)
        else:
            kw.update(rtol=rtol, atol=atol)
        t = time.perf_counter()
        sol = solve_ivp(fun, (0.0, T), study.x0, **kw)
        wall += time.perf_counter() - t
        if not sol.success:
            raise RuntimeError(f"scipy failed: {sol.message}")
        # RK45 uses 6 evaluations per step (FSAL), plus 2 for the initial step selection.
        total_steps += (sol.nfev - (0 if fixed else 2)) / 6
    return {
        "paths": n_paths,
        "compile_s": 0.0,
        "run_s": wall,
        "path_steps": total_steps,
        "steps_per_path": total_steps / n_paths,
        "path_steps_per_s": total_steps / wall,
        "paths_per_s": n_paths / wall,
        "extrapolated": True,
    }


def _jax_cases(study, n_paths, repeats, which):
    import diffrax
    import jax
    import jax.numpy as jnp
    import numpy as np

    import jaxdrift
    from _setup import force_rhs
    from jaxdrift.models._halfcar import force_driven_rhs

    p = study.params
    rhs = force_rhs(p)
    T, dt, n = study.T, study.dt, study.n_samples
    ts = jnp.arange(0, int(round(T * 10)) + 1) / 10.0
    f0 = jnp.asarray(study.f0)
    x0 = jnp.asarray(study.x0)
    sigma = study.sigma
    key = jax.random.key(0)
    n_fixed = int(round(T / dt))

    def signal(i, dtype=jnp.float64, key=key):
        eps = jaxdrift.path_normals(key, i, n, 2, dtype) * jnp.asarray(sigma, dtype)
        return jaxdrift.SampledSignal(0.0, dt, f0.astype(dtype) + eps)

    out = {}

    def sel(ys):
        return ys[:, jnp.array([2, 3])]  # z3, beta

    def jd_fixed():
        def path(i):
            sol = jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=signal(i), dt=dt)
            return sel(sol.ys), sol.stats["num_steps"]

        return jax.vmap(path)

    def fast(dtype=jnp.float32, compensated=True, key_=key):
        def make():
            def path(i):
                sol = jaxdrift.solve_fixed_fast(
                    rhs, x0, 0.0, T, saveat=ts, args=signal(i, dtype, key_), dt=dt, dtype=dtype,
                    compensated=compensated,
                )
                return sel(sol.ys), sol.stats["num_steps"]

            return jax.vmap(path)

        return make

    def fast_grid(dtype=jnp.float32):
        # The fast kernel reading the two samples of each step (inputs= on the grid) instead of
        # evaluating the SampledSignal at every stage; same samples, same values.
        def make():
            def rhs_u(t, x, u, a):
                return force_driven_rhs(t, x, p, u[0], u[1])

            def path(i):
                u = f0.astype(dtype) + jaxdrift.path_normals(key, i, n, 2, dtype) * jnp.asarray(sigma, dtype)
                sol = jaxdrift.solve_fixed_fast(rhs_u, x0, 0.0, T, saveat=ts, inputs=u, dt=dt, dtype=dtype)
                return sel(sol.ys), sol.stats["num_steps"]

            return jax.vmap(path)

        return make

    def dfx(adaptive):
        def make():
            term = diffrax.ODETerm(rhs)
            if adaptive:
                ctrl, dt0, max_steps = diffrax.PIDController(rtol=1e-6, atol=1e-8), None, 1_000_000
            else:
                ctrl, dt0, max_steps = diffrax.ConstantStepSize(), dt, n_fixed + 16

            def path(i):
                sol = diffrax.diffeqsolve(
                    term, diffrax.Dopri5(), 0.0, T, dt0, x0, args=signal(i), saveat=diffrax.SaveAt(ts=ts),
                    stepsize_controller=ctrl, max_steps=max_steps,
                )
                return sel(sol.ys), sol.stats["num_steps"]

            return jax.vmap(path)

        return make

    def jd_adaptive():
        def path(i):
            sol = jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=signal(i), rtol=1e-6, atol=1e-8)
            return sel(sol.ys), sol.stats["num_steps"]

        return jax.vmap(path)

    def all_devices(make):
        # jaxdrift's default: the paths split over every device (one per core after
        # jaxdrift.use_all_cores()), each device running its share vmapped, as monte_carlo does.
        def made():
            fn = make()
            devs = jax.devices()
            if len(devs) == 1:
                return fn
            from jax.sharding import Mesh, PartitionSpec as P

            mesh = Mesh(np.array(devs), ("paths",))
            return jax.shard_map(fn, mesh=mesh, in_specs=P("paths"), out_specs=P("paths"), check_vma=False)

        return made

    makers = {
        "fixed/jaxdrift": all_devices(jd_fixed),
        "fixed/jaxdrift-fast": all_devices(fast()),
        "fixed/jaxdrift-1dev": jd_fixed,
        "fixed/jaxdrift-fast-1dev": fast(),
        "fixed/diffrax-alldev": all_devices(dfx(False)),
        "fixed/jaxdrift-fast-rbg": fast(key_=jax.random.key(0, impl="rbg")),
        "fixed/jaxdrift-fast-grid": fast_grid(),
        "fixed/jaxdrift-float32-plain": fast(compensated=False),
        "fixed/jaxdrift-fast-float64": fast(dtype=jnp.float64, compensated=False),
        "fixed/diffrax": dfx(False),
        "adaptive/jaxdrift": all_devices(jd_adaptive),
        "adaptive/diffrax": dfx(True),
    }
    # Compile (first call) every case, then time them in interleaved rounds, so that a change of
    # load on this shared machine hits every case alike; each case keeps its best round.
    fns, first, outs = {}, {}, {}
    idx = jnp.arange(n_paths, dtype=jnp.int32)
    for name in which:
        if name not in makers:
            continue
        print(f"  compiling {name} ...", flush=True)
        fns[name] = jax.jit(makers[name]())
        t = time.perf_counter()
        jax.block_until_ready(fns[name](idx))
        first[name] = time.perf_counter() - t
    limits = {}
    if any(w.startswith("limit/") for w in which):
        import limit as limit_mod

        print("  compiling the numba limit ...", flush=True)
        for name, call in limit_mod.limit_cases(study, n_paths, threads=(1, 2), layouts=("simd",)).items():
            if "limit/" + name.removeprefix("limit-") in which:
                call()
                limits["limit/" + name.removeprefix("limit-")] = call
    best = {name: float("inf") for name in list(fns) + list(limits)}
    cpu = dict(best)
    for r in range(repeats):
        idx_r = idx + (r + 1) * n_paths
        for name, fn in fns.items():
            t, c = time.perf_counter(), time.process_time()
            o = fn(idx_r)
            jax.block_until_ready(o)
            best[name] = min(best[name], time.perf_counter() - t)
            cpu[name] = min(cpu[name], time.process_time() - c)
            outs[name] = o
            print(f"    round {r + 1}: {name} {best[name]:.1f} s", flush=True)
        for name, call in limits.items():
            (w, c), ys = call()
            best[name], cpu[name] = min(best[name], w), min(cpu[name], c)
            outs[name] = (ys, np.full(n_paths, n_fixed))
            print(f"    round {r + 1}: {name} {best[name]:.2f} s", flush=True)
    paths = {}
    for name in list(fns) + list(limits):
        ys, steps = outs[name]
        total = float(np.sum(np.asarray(steps)))
        out[name] = {
            "paths": n_paths, "compile_s": max(first.get(name, best[name]) - best[name], 0.0), "run_s": best[name],
            "cpu_s": cpu[name], "cpu_ns_per_path_step": cpu[name] / total * 1e9,
            "path_steps": total, "steps_per_path": total / n_paths, "path_steps_per_s": total / best[name],
            "paths_per_s": n_paths / best[name],
        }
        paths[name] = np.asarray(ys)
        print(f"    {name}: {out[name]['path_steps_per_s']:.3g} path-steps/s", flush=True)
    return out, paths, np.asarray(ts)


def _drift_agreement(paths, ts, level=0.95):
    """Fast mode vs float64 on independent noise streams (the fast mode draws float32 normals):
    the variance ratio of z3 and beta against its two-sided F interval (equal variances)."""
    import numpy as np
    from scipy.stats import f as fdist

    ref = paths.get("fixed/jaxdrift")
    out = {}
    for name in ("fixed/jaxdrift-fast", "fixed/jaxdrift-fast-grid", "fixed/jaxdrift-fast-rbg", "fixed/jaxdrift-float32-plain"):
        if ref is None or name not in paths:
            continue
        y = paths[name].astype(np.float64)
        n1, n2 = y.shape[0], ref.shape[0]
        lo, hi = fdist.ppf((1 - level) / 2, n1 - 1, n2 - 1), fdist.ppf((1 + level) / 2, n1 - 1, n2 - 1)
        lo3, hi3 = fdist.ppf(0.0005, n1 - 1, n2 - 1), fdist.ppf(0.9995, n1 - 1, n2 - 1)
        rows = []
        for k in range(1, ts.size, max(1, (ts.size - 1) // 6)):
            row = {"t": float(ts[k])}
            for j, q in enumerate(("z3", "beta")):
                v_ref = float(np.var(ref[:, k, j], ddof=1))
                v = float(np.var(y[:, k, j], ddof=1))
                row[q] = {"var_float64": v_ref, "var_fast": v, "ratio": v / v_ref,
                          "f_interval": [float(lo), float(hi)], "agree": bool(lo <= v / v_ref <= hi),
                          "f_interval_999": [float(lo3), float(hi3)], "agree_999": bool(lo3 <= v / v_ref <= hi3)}
            rows.append(row)
        out[name] = rows
    return out


def _same_noise_check(study, n_paths=64):
    """Fast mode (float32 + Kahan) and the float64 engine on the same noise samples: the largest
    per-path difference of z3 and beta over the paths' spread, at every save time."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    import jaxdrift
    from _setup import force_rhs

    rhs = force_rhs(study.params)
    T, dt, n = study.T, study.dt, study.n_samples
    ts = jnp.arange(0, int(round(T * 10)) + 1) / 10.0
    f0, x0 = jnp.asarray(study.f0), jnp.asarray(study.x0)
    key = jax.random.key(1)

    def path(i):
        u = f0 + study.sigma * jaxdrift.path_normals(key, i, n, 2)
        y64 = jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=jaxdrift.SampledSignal(0.0, dt, u), dt=dt).ys
        out = {"float64": y64[:, 2:4]}
        for name, comp in (("fast", True), ("float32-plain", False)):
            sig = jaxdrift.SampledSignal(0.0, dt, u.astype(jnp.float32))
            out[name] = jaxdrift.solve_fixed_fast(rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt, compensated=comp).ys[:, 2:4]
        return out

    res = jax.jit(jax.vmap(path))(jnp.arange(n_paths))
    y64 = np.asarray(res["float64"])
    spread = y64[:, 1:].std(axis=0)
    out = {"paths": n_paths}
    for name in ("fast", "float32-plain"):
        d = np.abs(np.asarray(res[name], np.float64) - y64)[:, 1:]
        rel = d.max(axis=0) / spread
        # Variance of the ensemble from the same noise: the fast mode's statistic against float64's.
        ratio = np.var(np.asarray(res[name], np.float64)[:, 1:], axis=0, ddof=1) / np.var(y64[:, 1:], axis=0, ddof=1)
        out[name] = {"max_diff_over_spread_z3": float(rel[:, 0].max()), "max_diff_over_spread_beta": float(rel[:, 1].max()),
                     "max_abs_diff_beta_rad_at_end": float(d[:, -1, 1].max()),
                     "var_ratio_range_z3": [float(ratio[:, 0].min()), float(ratio[:, 0].max())],
                     "var_ratio_range_beta": [float(ratio[:, 1].min()), float(ratio[:, 1].max())]}
    return out


def _memory_case(n_paths, T, chunk_size, mode):
    """Run inside a subprocess: the memory case through jaxdrift.monte_carlo; print JSON."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    import jaxdrift
    from _setup import force_rhs, paper_study

    study = paper_study(T=T)
    rhs = force_rhs(study.params)
    dt, n = study.dt, study.n_samples
    ts = jnp.arange(0, int(round(T * 10)) + 1) / 10.0
    f0 = jnp.asarray(study.f0)
    x0 = jnp.asarray(study.x0)
    dtype = jnp.float32 if mode == "fast" else jnp.float64

    def path_fn(key, i, model):
        eps = jaxdrift.path_normals(key, i, n, 2, dtype) * jnp.asarray(study.sigma, dtype)
        sig = jaxdrift.SampledSignal(0.0, dt, f0.astype(dtype) + eps)
        if mode == "fast":
            sol = jaxdrift.solve_fixed_fast(rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt)
        else:
            sol = jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt)
        return sol.ys[:, jnp.array([2, 3])].astype(jnp.float64), sol.result

    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    t = time.perf_counter()
    res = jaxdrift.monte_carlo(
        path_fn, n_paths, key=jax.random.key(0), save_ts=ts, chunk_size=chunk_size, progress=False
    )
    wall = time.perf_counter() - t
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(json.dumps({
        "paths": n_paths, "T": T, "mode": mode, "chunk_size": res.chunk_size, "wall_s": wall,
        "peak_rss_bytes": peak, "rss_before_run_bytes": rss_before,
        "path_steps_per_s": n_paths * round(T / dt) / wall, "count": int(res.count),
        "var_beta_end": float(res.var[-1, 1]),
    }))


def _prng_check():
    """Is a path's noise independent of the batch it is drawn in, for each PRNG implementation?

    jaxdrift's contract: sample i of path p depends only on (key, p, i). Measured by drawing paths
    0..7 under one vmap, paths 3..10 under another, and each path alone.
    """
    import jax
    import jax.numpy as jnp
    import numpy as np

    import jaxdrift

    out = {}
    for impl in ("threefry2x32", "rbg", "unsafe_rbg"):
        k = jax.random.key(0, impl=impl)
        f = jax.jit(jax.vmap(lambda i, k=k: jaxdrift.path_normals(k, i, 600, 2, jnp.float32)))
        a, c = np.asarray(f(jnp.arange(8))), np.asarray(f(jnp.arange(3, 11)))
        b = np.stack([np.asarray(jaxdrift.path_normals(k, i, 600, 2, jnp.float32)) for i in range(8)])
        out[impl] = bool(np.array_equal(a, b) and np.array_equal(a[3:], c[:5]))
    return out


def _run_memory(a, memory):
    """The memory case in a fresh subprocess (its peak RSS is its own)."""
    print(f"memory case ({a.memory_paths} paths x {a.memory_T:g} s, {memory}) in a subprocess ...", flush=True)
    cmd = [sys.executable, str(Path(__file__).resolve()), "--memory-case", "--memory", memory,
           "--memory-paths", str(a.memory_paths), "--memory-T", str(a.memory_T), "--memory-chunk", str(a.memory_chunk)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        return {"error": proc.stderr[-2000:]}
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["command"] = " ".join(["python benchmarks/throughput.py --memory-only", "--memory", memory,
                               "--memory-paths", str(a.memory_paths), "--memory-T", str(a.memory_T),
                               "--memory-chunk", str(a.memory_chunk)])
    out["load_average_at_end"] = list(os.getloadavg())
    return out


def _agree(q):
    if q["agree"]:
        return "yes"
    return "no (in 99.9 %)" if q.get("agree_999") else "**no**"


def _markdown(report):
    lines = []
    cfg = report["config"]
    lines.append(
        f"Half-car noisy-force study: {cfg['T']:g} s at 1 kHz, {cfg['paths']} paths per JAX call "
        f"(scipy: {cfg['scipy_paths']} paths, extrapolated), float64 unless noted; "
        f"{report['machine']['cpu_count']} CPU cores ({report['machine']['cpu']}), "
        f"load average at start {report['machine']['load_average_at_start'][0]:.1f}."
    )
    lines.append("")
    lines.append("| mode | solver | steps/path | path-steps/s | vs diffrax | vs scipy | of the limit | CPU ns/path-step | compile s |")
    lines.append("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, r in report["cases"].items():
        mode, solver = name.split("/", 1)
        vd = r.get("vs_diffrax")
        vs = r.get("vs_scipy")
        vl = r.get("of_limit")
        lc = r.get("limit_case")
        cn = r.get("cpu_ns_per_path_step")
        lines.append(
            f"| {mode} | {solver} | {r['steps_per_path']:.0f} | {r['path_steps_per_s']:.3g} | "
            f"{'' if vd is None else f'{vd:.2f}x'} | {'' if vs is None else f'{vs:.0f}x'} | "
            f"{'' if vl is None else f'{100 * vl:.1f} % of {lc}'} | {'' if cn is None else f'{cn:.0f}'} | "
            f"{r['compile_s']:.1f} |"
        )
    lines.append("")
    lines.append(
        f"jaxdrift, jaxdrift-fast and adaptive jaxdrift run with jaxdrift's defaults: paths split over all "
        f"{len(report['machine']['jax_devices'])} CPU devices (jaxdrift.use_all_cores); `-1dev` rows and diffrax run "
        "on one device (diffrax-alldev: diffrax split the same way). `limit/...`: the same step as a compiled loop "
        "(benchmarks/limit.py, numba, SIMD over blocks of 64 paths, `given` noise read from memory, `inline` drawn in "
        "the loop, 1 or 2 threads); the fraction compares path-steps/s with the limit of the same dtype and core "
        "count. CPU ns/path-step: process CPU time (all threads) over path-steps, less sensitive to other load.")
    for mem in (report.get("memory"), report.get("memory_float64")):
        if not mem or "peak_rss_bytes" not in mem:
            continue
        lines.append("")
        lines.append(
            f"Memory case ({mem['mode']}): {mem['paths']} paths x {mem['T']:g} s at 1 kHz, statistics every 0.1 s, "
            f"chunk {mem['chunk_size']}: peak RSS {mem['peak_rss_bytes'] / 2**30:.2f} GiB, "
            f"{mem['wall_s']:.0f} s ({mem['path_steps_per_s']:.3g} path-steps/s)"
            + (f"; reproduce: `{mem['command']}`." if mem.get("command") else ".")
        )
    agree = report.get("fast_vs_float64")
    if agree:
        lines.append("")
        lines.append("Fast mode vs float64 on independent noise streams: variance ratio fast/float64 and whether it lies "
                     "in the two-sided 95 % F interval of equal variances:")
        lines.append("")
        lines.append("| variant | t [s] | Var z3 ratio | agree | Var beta ratio | agree | F interval |")
        lines.append("|---|---:|---:|---|---:|---|---|")
        for name, rows in agree.items():
            for row in rows:
                z, b = row["z3"], row["beta"]
                lines.append(
                    f"| {name.split('/')[1]} | {row['t']:g} | {z['ratio']:.3f} | {_agree(z)} | {b['ratio']:.3f} | "
                    f"{_agree(b)} | [{z['f_interval'][0]:.2f}, {z['f_interval'][1]:.2f}] |"
                )
        lines.append("")
        lines.append("`yes`: inside the 95 % interval; `no (in 99.9 %)`: outside it but inside the 99.9 % one; rows of "
                     "one variant share their paths, and about one row in 20 misses the 95 % interval by chance. "
                     "The same-noise comparison below is the sharper test.")
    prng = report.get("prng_path_independent")
    if prng:
        lines.append("")
        lines.append(
            "PRNG: a path's noise is independent of the batch it is drawn in (jaxdrift's reproducibility contract) for "
            + ", ".join(f"{k}: {'yes' if v else '**no**'}" for k, v in prng.items())
            + ". The rbg variants are faster but break the contract, so the fast mode keeps threefry."
        )
    same = report.get("same_noise")
    if same:
        lines.append("")
        lines.append(
            f"Same noise, {same['paths']} paths: largest per-path difference from float64 over the ensemble spread: "
            f"fast (float32 + Kahan) z3 {same['fast']['max_diff_over_spread_z3']:.1e}, beta "
            f"{same['fast']['max_diff_over_spread_beta']:.1e}; float32 without compensation z3 "
            f"{same['float32-plain']['max_diff_over_spread_z3']:.1e}, beta {same['float32-plain']['max_diff_over_spread_beta']:.1e}."
        )
        fr = same["fast"]
        if "var_ratio_range_beta" in fr:
            from scipy.stats import chi2

            m = same["paths"] - 1
            lines.append(
                f"Ensemble variance from the same noise, fast/float64, over every save time: z3 "
                f"[{fr['var_ratio_range_z3'][0]:.4f}, {fr['var_ratio_range_z3'][1]:.4f}], beta "
                f"[{fr['var_ratio_range_beta'][0]:.4f}, {fr['var_ratio_range_beta'][1]:.4f}]; the 95 % Monte-Carlo "
                f"interval of a {same['paths']}-path variance is [{m / chi2.ppf(0.975, m):.2f}, {m / chi2.ppf(0.025, m):.2f}] "
                "times its estimate, so the fast mode's drift statistics agree with float64 far inside it."
            )
    lines.append("")
    lines.append(f"Reproduce: `{report['command']}`")
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="5 s paths, fewer paths, no memory case")
    ap.add_argument("--paths", type=int, default=None, help="paths per JAX call")
    ap.add_argument("--T", type=float, default=None, help="horizon [s]")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--scipy-paths", type=int, default=None)
    ap.add_argument("--cases", default="all", help="comma-separated case names, or 'all'")
    ap.add_argument("--devices", type=int, default=None,
                    help="JAX CPU devices (default: one per core, jaxdrift.use_all_cores)")
    ap.add_argument("--memory", choices=("fast", "float64", "skip"), default=None,
                    help="engine path of the memory case (default: fast; skip with --quick)")
    ap.add_argument("--memory-paths", type=int, default=10_000)
    ap.add_argument("--memory-T", type=float, default=60.0)
    ap.add_argument("--memory-chunk", type=int, default=256)
    ap.add_argument("--memory-case", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--memory-only", action="store_true",
                    help="run only the memory case (subprocess) and write results/throughput-memory.json")
    ap.add_argument("--out", default=None, help="output stem (default benchmarks/results/throughput[-quick])")
    ap.add_argument("--render-only", action="store_true",
                    help="rewrite the markdown from the JSON (adding the PRNG check and memory case if missing)")
    a = ap.parse_args(argv)
    if a.render_only:
        import jax

        jax.config.update("jax_enable_x64", True)
        stem = Path(a.out) if a.out else RESULTS / ("throughput-quick" if a.quick else "throughput")
        report = json.loads(stem.with_suffix(".json").read_text())
        report.setdefault("prng_path_independent", _prng_check())
        # The memory cases run separately (--memory-only); their JSONs are folded into the report.
        for key, fname in (("memory", "throughput-memory.json"), ("memory_float64", "throughput-memory-float64.json")):
            if (RESULTS / fname).exists():
                report[key] = json.loads((RESULTS / fname).read_text())
        stem.with_suffix(".json").write_text(json.dumps(report, indent=2) + "\n")
        stem.with_suffix(".md").write_text(_markdown(report))
        return 0
    if a.memory_case:
        import jaxdrift

        jaxdrift.use_all_cores(a.devices)  # the memory case runs with jaxdrift's defaults too
        _memory_case(a.memory_paths, a.memory_T, a.memory_chunk, a.memory or "fast")
        return 0
    if a.memory_only:
        RESULTS.mkdir(parents=True, exist_ok=True)
        mode = a.memory or "fast"
        mem = _run_memory(a, mode)
        name = "throughput-memory.json" if mode == "fast" else f"throughput-memory-{mode}.json"
        (RESULTS / name).write_text(json.dumps(mem, indent=2) + "\n")
        print(mem)
        return 0

    import jax

    import jaxdrift

    n_dev = jaxdrift.use_all_cores(a.devices)  # before the first JAX operation
    jax.config.update("jax_enable_x64", True)
    from _setup import paper_study

    T = a.T or (5.0 if a.quick else 30.0)
    n_paths = a.paths or (128 if a.quick else 256)
    scipy_paths = a.scipy_paths or (1 if a.quick else 2)
    memory = a.memory or ("skip" if a.quick else "fast")
    all_cases = [
        "fixed/jaxdrift", "fixed/jaxdrift-fast", "fixed/jaxdrift-1dev", "fixed/jaxdrift-fast-1dev",
        "fixed/diffrax", "fixed/diffrax-alldev", "fixed/scipy",
        "adaptive/jaxdrift", "adaptive/diffrax", "adaptive/scipy",
        "limit/simd-float64-given-1t", "limit/simd-float64-given-2t", "limit/simd-float32-given-1t",
        "limit/simd-float32-given-2t", "limit/simd-float64-inline-2t", "limit/simd-float32-inline-2t",
    ]
    which = all_cases if a.cases == "all" else a.cases.split(",")
    if n_dev == 1:
        which = [w for w in which if not w.endswith(("-1dev", "-alldev"))]
    report = {
        "command": "python benchmarks/throughput.py" + (" " + " ".join(sys.argv[1:]) if argv is None and sys.argv[1:] else ""),
        "machine": _machine(),
        "versions": _versions(),
        "config": {"T": T, "fs": 1000.0, "paths": n_paths, "scipy_paths": scipy_paths, "repeats": a.repeats,
                   "save_every_s": 0.1, "adaptive_rtol": 1e-6, "adaptive_atol": 1e-8},
    }
    print(f"virtual measurement ({T:g} s) ...", flush=True)
    study = paper_study(T=T)
    from _setup import ROAD_CLASS, ROAD_SEED, SPEED

    report["config"]["sigma_N"] = study.sigma
    report["config"]["road"] = f"ISO 8608 class {ROAD_CLASS}, seed {ROAD_SEED}, +-2 m hills of 250 m, {SPEED:g} m/s"
    cases, paths, ts = _jax_cases(study, n_paths, a.repeats, which)
    for name, fixed in (("fixed/scipy", True), ("adaptive/scipy", False)):
        if name in which:
            print(f"  {name} ...", flush=True)
            cases[name] = _scipy_case(study, scipy_paths, fixed=fixed)
            print(f"    {cases[name]['path_steps_per_s']:.3g} path-steps/s", flush=True)
    for name, r in cases.items():
        mode = name.split("/")[0]
        for ref, field in ((f"{mode}/diffrax", "vs_diffrax"), (f"{mode}/scipy", "vs_scipy")):
            if ref in cases and ref != name:
                r[field] = r["path_steps_per_s"] / cases[ref]["path_steps_per_s"]
                r[field.replace("vs_", "paths_vs_")] = r["paths_per_s"] / cases[ref]["paths_per_s"]
    for name, r in cases.items():
        if name.startswith("limit/") or not name.startswith("fixed/") or "scipy" in name:
            continue
        dt_ = "float32" if "fast" in name else "float64"
        th = "1t" if (name.endswith("-1dev") or (name.startswith("fixed/diffrax") and "alldev" not in name)) else "2t"
        ref = f"limit/simd-{dt_}-given-{th}"
        if ref in cases:
            r["of_limit"] = r["path_steps_per_s"] / cases[ref]["path_steps_per_s"]
            r["limit_case"] = ref.removeprefix("limit/")
    report["cases"] = cases
    report["fast_vs_float64"] = _drift_agreement(paths, ts)
    report["prng_path_independent"] = _prng_check()
    print("  same-noise check ...", flush=True)
    report["same_noise"] = _same_noise_check(study)
    report["machine"]["load_average_at_end"] = list(os.getloadavg())
    mem_file = RESULTS / "throughput-memory.json"
    if memory != "skip":
        report["memory"] = _run_memory(a, memory)
        mem_file.write_text(json.dumps(report["memory"], indent=2) + "\n")
    elif mem_file.exists() and not a.quick:
        report["memory"] = json.loads(mem_file.read_text())
    stem = Path(a.out) if a.out else RESULTS / ("throughput-quick" if a.quick else "throughput")
    stem.parent.mkdir(parents=True, exist_ok=True)
    stem.with_suffix(".json").write_text(json.dumps(report, indent=2) + "\n")
    stem.with_suffix(".md").write_text(_markdown(report))
    print(_markdown(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
