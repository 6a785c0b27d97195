"""Cost per path-step against the number of paths per call: jaxdrift and diffrax on the half-car.

Hypothesis 1: a 1 ms step is about 13 XLA kernels on ``(10, paths)`` arrays,
so a fixed cost per kernel (thunk dispatch, the hand-off of a fusion to XLA's intra-op threads)
weighs more at small batches. This script times the same study as ``benchmarks/throughput.py``
(half-car, noisy forces at 1 kHz, fixed 1 ms Dormand-Prince 5(4), pitch and heave every 0.1 s)
at several paths per call, every contender at the same paths per call:

* ``jaxdrift``: ``solve_ode(dt=...)`` float64, split over all CPU devices (``use_all_cores``, as
  ``monte_carlo`` and ``throughput.py`` do);
* ``jaxdrift-fast``: ``solve_fixed_fast`` float32 + Kahan, all devices;
* ``jaxdrift-1dev``: float64 on one device;
* ``diffrax``: ``Dopri5`` + ``ConstantStepSize`` under ``jit(vmap)``, one device.

All cases of one size run interleaved in rounds (best kept), as wall time and process CPU time
(all threads) per path-step.

Reproduce::

    python benchmarks/batch_scaling.py --sizes 128,256,1024,4096 --seconds 1 --rounds 3
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="128,256,1024,4096,16384")
    ap.add_argument("--seconds", type=float, default=1.0)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--cases", default="jaxdrift,jaxdrift-fast,jaxdrift-1dev,diffrax")
    ap.add_argument("--out", default=None, help="JSON path (default: print only)")
    a = ap.parse_args(argv)

    import jax

    import jaxdrift

    n_dev = jaxdrift.use_all_cores()
    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    from _setup import study_paths

    load0 = list(os.getloadavg())
    sp = study_paths(a.seconds)
    n_steps = sp.n_steps

    makers = {
        "jaxdrift": lambda: sp.all_devices(sp.engine),
        "jaxdrift-fast": lambda: sp.all_devices(sp.fast),
        "jaxdrift-1dev": lambda: jax.jit(jax.vmap(sp.engine)),
        "diffrax": lambda: jax.jit(jax.vmap(sp.diffrax)),
    }
    names = a.cases.split(",")
    res = {}
    for size in [int(s) for s in a.sizes.split(",")]:
        fns = {k: makers[k]() for k in names}
        idx = jnp.arange(size, dtype=jnp.int32)
        for k, f in fns.items():
            jax.block_until_ready(f(idx))
        wall = {k: float("inf") for k in fns}
        cpu = dict(wall)
        for r in range(a.rounds):
            for k, f in fns.items():
                t, c = time.perf_counter(), time.process_time()
                jax.block_until_ready(f(idx + (r + 1) * size))
                wall[k] = min(wall[k], time.perf_counter() - t)
                cpu[k] = min(cpu[k], time.process_time() - c)
        steps = size * n_steps
        res[size] = {k: {"wall_ns": wall[k] / steps * 1e9, "cpu_ns": cpu[k] / steps * 1e9} for k in fns}
        print(f"{size:6d} paths: " + "  ".join(
            f"{k} wall {v['wall_ns']:.0f} cpu {v['cpu_ns']:.0f}" for k, v in res[size].items()), flush=True)
        if "diffrax" in fns:
            print("         vs diffrax (wall): " + "  ".join(
                f"{k} {res[size]['diffrax']['wall_ns'] / v['wall_ns']:.2f}x" for k, v in res[size].items()
                if k != "diffrax"), flush=True)
    load1 = list(os.getloadavg())
    print(f"load average {load0[0]:.2f} at start, {load1[0]:.2f} at end; {n_dev} devices")
    if a.out:
        Path(a.out).write_text(json.dumps({"command": "python benchmarks/batch_scaling.py " + " ".join(
            sys.argv[1:] if argv is None else argv), "load_average_start": load0, "load_average_end": load1,
            "devices": n_dev, "seconds": a.seconds, "rounds": a.rounds, "ns_per_path_step": res}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
