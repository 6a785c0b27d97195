"""XLA's CPU fast-math flag on the engine: speed and accuracy, measured in two fresh processes.

Found (``benchmarks/results/fast-math.json``, loaded machine): the engine went from 194 to 182 CPU ns
per path-step (within this machine's noise), the fast mode got slower (170 -> 187) and its per-path
difference grew to 2.3e-3 of the ensemble spread (reassociation undoes the Kahan compensation).
Not shipped.

``XLA_FLAGS=--xla_cpu_enable_fast_math=true`` lets LLVM reassociate and contract floating-point
operations and assume no NaN/inf. This script runs the half-car study of ``benchmarks/_setup.py``
(``--paths`` paths x ``--seconds`` s, 1 ms steps, one JAX device) with jaxdrift's engine (float64)
and fast mode (float32) once without and once with the flag, each in its own process (the flag is
read when JAX starts), and compares the saved pitch and heave on the same noise: the largest
difference over the ensemble spread, and the ratio of the ensemble variances.

Reproduce::

    python benchmarks/experiments/fast_math.py           # writes benchmarks/results/fast-math.{json,md}
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # benchmarks/: _common, _setup, results/
sys.path.insert(0, str(HERE))

_CHILD = r"""
import json, sys, time
import numpy as np
import jax
jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp
sys.path.insert(0, {here!r})
import jaxdrift
from _setup import force_rhs, paper_study
st = paper_study(T={seconds})
T, dt, n = st.T, st.dt, st.n_samples
ts = jnp.arange(0, int(round(T * 10)) + 1) / 10.0
f0, x0, key = jnp.asarray(st.f0), jnp.asarray(st.x0), jax.random.key(0)
rhs = force_rhs(st.params)
def engine(i):
    sig = jaxdrift.SampledSignal(0.0, dt, f0 + jaxdrift.path_normals(key, i, n, 2) * st.sigma)
    return jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt).ys[:, 2:4]
def fast(i):
    u = (f0 + jaxdrift.path_normals(key, i, n, 2) * st.sigma).astype(jnp.float32)
    return jaxdrift.solve_fixed_fast(rhs, x0, 0.0, T, saveat=ts, args=jaxdrift.SampledSignal(0.0, dt, u), dt=dt).ys[:, 2:4]
idx = jnp.arange({paths}, dtype=jnp.int32)
out = {{}}
for name, fn in (("engine", engine), ("fast", fast)):
    f = jax.jit(jax.vmap(fn))
    ys = np.asarray(jax.block_until_ready(f(idx)), np.float64)
    best = float("inf")
    for r in range({rounds}):
        c = time.process_time(); jax.block_until_ready(f(idx)); best = min(best, time.process_time() - c)
    np.save({out!r} + "-" + name + ".npy", ys)
    out[name] = best / ({paths} * round(T / dt)) * 1e9
print(json.dumps(out))
"""


def main(argv=None):
    import argparse

    import numpy as np

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--paths", type=int, default=256)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", default="fast-math")
    a = ap.parse_args(argv)
    tmp = Path(os.environ.get("TMPDIR", "/tmp")) / "jaxdrift-fast-math"
    tmp.mkdir(exist_ok=True)
    load0 = list(os.getloadavg())
    res = {}
    for flag in (False, True):
        env = dict(os.environ)
        flags = [f for f in env.get("XLA_FLAGS", "").split() if "fast_math" not in f]
        env["XLA_FLAGS"] = " ".join(flags + [f"--xla_cpu_enable_fast_math={'true' if flag else 'false'}"])
        env["JAXDRIFT_CPU_DEVICES"] = "1"
        code = _CHILD.format(here=str(HERE), seconds=a.seconds, paths=a.paths, rounds=a.rounds,
                             out=str(tmp / ("on" if flag else "off")))
        proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        if proc.returncode != 0:
            raise SystemExit(proc.stderr[-3000:])
        res["on" if flag else "off"] = json.loads(proc.stdout.strip().splitlines()[-1])
    acc = {}
    for name in ("engine", "fast"):
        off = np.load(tmp / f"off-{name}.npy")
        on = np.load(tmp / f"on-{name}.npy")
        spread = off[:, 1:].std(axis=0)
        d = np.abs(on - off)[:, 1:]
        ratio = on[:, 1:].var(axis=0, ddof=1) / off[:, 1:].var(axis=0, ddof=1)
        acc[name] = {"max_diff_over_spread": float(np.max(d.max(axis=0) / spread)),
                     "max_abs_diff_beta": float(d[..., 1].max()),
                     "var_ratio_range": [float(ratio.min()), float(ratio.max())]}
    load1 = list(os.getloadavg())
    md = [f"Half-car, {a.paths} paths x {a.seconds:g} s, one JAX device, process CPU ns per path-step (best of "
          f"{a.rounds}); load average {load0[0]:.1f} at start, {load1[0]:.1f} at end.", "",
          "| mode | fast math off | on | largest difference / spread | variance ratio on/off |", "|---|---:|---:|---:|---|"]
    for name in ("engine", "fast"):
        r = acc[name]
        md.append(f"| {name} | {res['off'][name]:.0f} | {res['on'][name]:.0f} | {r['max_diff_over_spread']:.1e} | "
                  f"[{r['var_ratio_range'][0]:.6f}, {r['var_ratio_range'][1]:.6f}] |")
    cmd = "python benchmarks/experiments/fast_math.py " + " ".join(sys.argv[1:] if argv is None else argv)
    md += ["", f"Reproduce: `{cmd.strip()}`"]
    from _common import write_results

    write_results(a.out, {"command": cmd, "load_average_start": load0, "load_average_end": load1,
                          "cpu_ns_per_path_step": res, "accuracy": acc, "paths": a.paths, "seconds": a.seconds},
                  "\n".join(md) + "\n")
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
