"""XLA CPU flags on the half-car study: jaxdrift (float64, fast mode) and diffrax, fresh processes.

Found (not committed as JSON; not kept,
group ``xla_flags``, load 9.9 -> 7.0): ``--xla_cpu_prefer_vector_width=512`` took jaxdrift float64
from 94 to 66 CPU ns per path-step and the fast mode from 59 to 42 with identical results (shipped
through ``use_all_cores``); the legacy emitters were slower (135, 88); no eigen threads changed
nothing (91, 57).

Each variant is a set of ``XLA_FLAGS`` (added to the
environment of a fresh Python process, since XLA reads them once); the variants run alternately,
``--rounds`` times each, so that a change of the machine's load hits them alike. Every process
times, after compiling, ``--reps`` calls of each case (best kept) at ``--paths`` paths per call over
``--seconds`` of the study (same setup as ``benchmarks/throughput.py``: jaxdrift on all CPU devices
via ``use_all_cores``, diffrax ``jit(vmap)`` on one), as process CPU time and wall time per
path-step, and the largest difference of its pitch/heave outputs from the first variant's (saved in
a temporary file), so a flag that changes the results shows it.

Reproduce::

    python benchmarks/experiments/xla_flags.py --variants "baseline=;vw512=--xla_cpu_prefer_vector_width=512"
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # benchmarks/: _common, _setup, results/
sys.path.insert(0, str(HERE))


def child(a):
    import jax

    import jaxdrift

    jaxdrift.use_all_cores()
    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np

    from _setup import study_paths

    sp = study_paths(a.seconds)
    n_steps = sp.n_steps

    makers = {"jaxdrift": lambda: sp.all_devices(sp.engine), "jaxdrift-fast": lambda: sp.all_devices(sp.fast),
              "diffrax": lambda: jax.jit(jax.vmap(sp.diffrax))}
    idx = jnp.arange(a.paths, dtype=jnp.int32)
    out = {}
    for name in a.cases.split(","):
        fn = makers[name]()
        ys = np.asarray(jax.block_until_ready(fn(idx)), np.float64)
        wall = cpu = float("inf")
        for _ in range(a.reps):
            t, c = time.perf_counter(), time.process_time()
            jax.block_until_ready(fn(idx))
            wall, cpu = min(wall, time.perf_counter() - t), min(cpu, time.process_time() - c)
        steps = a.paths * n_steps
        out[name] = {"wall_ns": wall / steps * 1e9, "cpu_ns": cpu / steps * 1e9, "ys": ys.tolist()}
    print("JSON" + json.dumps(out))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default="baseline=", help="'name=FLAGS;name=FLAGS' (first is the reference)")
    ap.add_argument("--cases", default="jaxdrift,jaxdrift-fast,diffrax")
    ap.add_argument("--paths", type=int, default=256)
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        child(a)
        return 0
    import numpy as np

    variants = [v.split("=", 1) for v in a.variants.split(";") if v]
    base_env = os.environ.get("XLA_FLAGS", "")
    load0 = os.getloadavg()[0]
    best = {name: {} for name, _ in variants}
    ref, diffs = {}, {name: {} for name, _ in variants}
    for r in range(a.rounds):
        for name, flags in variants:
            env = dict(os.environ, XLA_FLAGS=(base_env + " " + flags).strip())
            cmd = [sys.executable, __file__, "--child", "--cases", a.cases, "--paths", str(a.paths),
                   "--seconds", str(a.seconds), "--reps", str(a.reps)]
            p = subprocess.run(cmd, env=env, capture_output=True, text=True)
            line = [l for l in p.stdout.splitlines() if l.startswith("JSON")]
            if p.returncode or not line:
                print(f"{name}: failed\n{p.stderr[-1500:]}", flush=True)
                continue
            res = json.loads(line[0][4:])
            for case, v in res.items():
                ys = np.asarray(v.pop("ys"))
                ref.setdefault(case, ys)
                diffs[name][case] = float(np.max(np.abs(ys - ref[case])))
                b = best[name].setdefault(case, {"wall_ns": float("inf"), "cpu_ns": float("inf")})
                b["wall_ns"], b["cpu_ns"] = min(b["wall_ns"], v["wall_ns"]), min(b["cpu_ns"], v["cpu_ns"])
            print(f"round {r + 1} {name}: " + "  ".join(
                f"{c} wall {v['wall_ns']:.0f} cpu {v['cpu_ns']:.0f}" for c, v in res.items()), flush=True)
    print(f"\nbest of {a.rounds} rounds, ns per path-step (wall / CPU), max |diff| vs {variants[0][0]}; "
          f"load {load0:.2f} -> {os.getloadavg()[0]:.2f}")
    for name, flags in variants:
        print(f"{name} [{flags}]: " + "  ".join(
            f"{c} {v['wall_ns']:.0f}/{v['cpu_ns']:.0f} (diff {diffs[name].get(c, float('nan')):.1e})"
            for c, v in best[name].items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
