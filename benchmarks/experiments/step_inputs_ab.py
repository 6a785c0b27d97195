"""What the carried step inputs changed in the fixed-step loop, A/B in one process, interleaved rounds.

Found (not committed as JSON; not kept,
group ``step_inputs_ab``, loaded 2-core AMD EPYC): carrying the step inputs took the engine float64
from 185 to 106 CPU ns per path-step at XLA's default vector width (load 11.8) and from 162 to 70 at
512 bits (load 4.2); the fast mode with unroll 1 to 56 and 44. Shipped (``_CARRY_STEP_ARGS``).

Variants of the half-car study (``benchmarks/_setup.py``; 1 ms Dormand-Prince 5(4), forces at
1 kHz with noise) on ``NDEV`` CPU devices (default 1), ``B`` paths a call over ``T`` seconds:

* ``carry=0 selclip=0``: the former loop: each step computes its time, input samples and
  interpolation weight from the step counter, the weight clipped with ``jnp.clip``;
* ``selclip=1``: the weight clipped with two selects (``jaxdrift.solvers._inputs._clip01``);
* ``carry=1``: the step's time and input samples carried from the previous step
  (``jaxdrift.solvers._fast._CARRY_STEP_ARGS``), so no kernel of the step reads the counter;
* fast mode (float32 + Kahan) also with ``unroll=1`` and 5 steps per loop iteration.

The switches act at trace time. Prints process CPU time and wall time per path-step (min and
median of ``R`` rounds) and the largest difference of each variant's pitch/heave from the old
loop's. Reproduce::

    NDEV=1 B=256 T=2 R=5 python benchmarks/experiments/step_inputs_ab.py
"""

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common, _setup

import jax  # noqa: E402

import jaxdrift  # noqa: E402

jaxdrift.use_all_cores(int(os.environ.get("NDEV", "1")))
jax.config.update("jax_enable_x64", True)
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from jax.sharding import Mesh, PartitionSpec as P  # noqa: E402

import jaxdrift.solvers._fast as fm  # noqa: E402
import jaxdrift.solvers._inputs as im  # noqa: E402
from _setup import force_rhs, paper_study  # noqa: E402

T = float(os.environ.get("T", "2"))
B = int(os.environ.get("B", "256"))
R = int(os.environ.get("R", "5"))
st = paper_study(T=T)
dt, n = st.dt, st.n_samples
ts = jnp.arange(0, int(round(T * 10)) + 1) / 10.0
f0, x0, key = jnp.asarray(st.f0), jnp.asarray(st.x0), jax.random.key(0)
rhs = force_rhs(st.params)
clip_new = im._clip01


def clip_old(s):
    return jnp.clip(s, 0.0, 1.0)


def make(mode, carry, newclip, unroll=5):
    def path(i):
        if mode == "engine":
            sig = jaxdrift.SampledSignal(0.0, dt, f0 + jaxdrift.path_normals(key, i, n, 2) * st.sigma)
            return jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt).ys[:, 2:4]
        u = (f0 + jaxdrift.path_normals(key, i, n, 2, jnp.float32) * st.sigma).astype(jnp.float32)
        return jaxdrift.solve_fixed_fast(rhs, x0, 0.0, T, saveat=ts, args=jaxdrift.SampledSignal(0.0, dt, u), dt=dt,
                                         unroll=unroll).ys[:, 2:4]

    f = jax.vmap(path)
    if len(jax.devices()) > 1:
        mesh = Mesh(np.array(jax.devices()), ("paths",))
        f = jax.shard_map(f, mesh=mesh, in_specs=P("paths"), out_specs=P("paths"), check_vma=False)
    f = jax.jit(f)

    def call(idx):
        fm._CARRY_STEP_ARGS, im._clip01 = carry, (clip_new if newclip else clip_old)
        try:
            return f(idx)
        finally:
            fm._CARRY_STEP_ARGS, im._clip01 = True, clip_new

    return call


variants = {}
for mode in os.environ.get("MODES", "engine,fast").split(","):
    for carry, newclip in ((False, False), (False, True), (True, True)):
        variants[f"{mode} carry={int(carry)} selclip={int(newclip)}" + (" unroll=5" if mode == "fast" else "")] = \
            make(mode, carry, newclip)
    if mode == "fast":
        for carry in (False, True):
            variants[f"fast carry={int(carry)} selclip=1 unroll=1"] = make(mode, carry, True, 1)
idx = jnp.arange(B, dtype=jnp.int32)
outs = {k: np.asarray(jax.block_until_ready(f(idx)), np.float64) for k, f in variants.items()}
load0 = os.getloadavg()[0]
wall = {k: [] for k in variants}
cpu = {k: [] for k in variants}
steps = B * int(round(T / dt))
for r in range(R):
    for k, f in variants.items():
        t, c = time.perf_counter(), time.process_time()
        jax.block_until_ready(f(idx + r + 1))
        wall[k].append((time.perf_counter() - t) / steps * 1e9)
        cpu[k].append((time.process_time() - c) / steps * 1e9)
print(f"B={B} T={T} devices={len(jax.devices())} rounds={R} load {load0:.2f} -> {os.getloadavg()[0]:.2f}; "
      f"XLA_FLAGS={os.environ.get('XLA_FLAGS', '')!r}")
for k in variants:
    ref = outs[[v for v in variants if v.startswith(k.split()[0] + " carry=0 selclip=0")][0]]
    print(f"{k:42s} CPU ns min {min(cpu[k]):5.0f} med {np.median(cpu[k]):5.0f}  wall min {min(wall[k]):5.0f} "
          f"med {np.median(wall[k]):5.0f}  max diff {np.max(np.abs(outs[k] - ref)):.1e}")
