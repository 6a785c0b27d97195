"""Read the optimised HLO of the fixed-step loop: kernels per step and library sin/cos calls.

Found (``benchmarks/results/hlo-step.json``): the engine float64 step had 65 fusions and 24 sine +
24 cosine operations per step in the vmap layout with library sin/cos; paths last with polynomial
sin/cos, 13 fusions and no library call (fast mode per 5 steps: 323 fusions -> 63).

Compiles the half-car study's step loop (256 paths, 1 ms steps, as ``jax.jit(jax.vmap(path))``)
with ``jax.jit(...).lower(...).compile().as_text()`` in the layouts of
``benchmarks/experiments/engine_layouts.py`` and counts, in the body of the innermost ``while`` loop (the
steps), the fusions and other kernels, and the ``sine``/``cosine`` operations inside the fusions
it calls. Writes ``benchmarks/results/hlo-step.{json,md}`` and, with ``--dump DIR``, the HLO text.

Reproduce::

    python benchmarks/experiments/hlo_step.py
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # benchmarks/: _common, _setup, results/
sys.path.insert(0, str(HERE))


def _computations(txt):
    comps, cur = {}, None
    for line in txt.splitlines():
        m = re.match(r"^(ENTRY )?%?([\w.\-]+) .*\{$", line)
        if m and not line.startswith(" "):
            cur = m.group(2)
            comps[cur] = []
        elif cur and line.startswith("  "):
            comps[cur].append(line)
    return comps


def _ops(comps, name):
    out = {}
    for line in comps.get(name, []):
        m = re.search(r"= \S+ (\w[\w-]*)\(", line)
        if m:
            out[m.group(1)] = out.get(m.group(1), 0) + 1
        for sub in re.findall(r"calls=%?([\w.\-]+)", line):
            for k, v in _ops(comps, sub).items():
                out[k] = out.get(k, 0) + v
    return out


def step_body_stats(txt):
    """Kernels of the while body with the most fusions (the step loop) and its sin/cos count."""
    comps = _computations(txt)
    bodies = re.findall(r"while\(.*?body=%?([\w.\-]+)", txt)
    best = None
    for body in set(bodies):
        top = {}
        for line in comps.get(body, []):
            m = re.search(r"= \S+ (\w[\w-]*)\(", line)
            if m:
                top[m.group(1)] = top.get(m.group(1), 0) + 1
        if best is None or top.get("fusion", 0) > best[1].get("fusion", 0):
            best = (body, top)
    body, top = best
    inner = _ops(comps, body)
    kernels = sum(v for k, v in top.items() if k not in ("get-tuple-element", "constant", "parameter", "tuple", "bitcast"))
    return {"fusions": top.get("fusion", 0), "kernels": kernels, "copies": top.get("copy", 0),
            "concatenates_outside_fusions": top.get("concatenate", 0),
            "sine": inner.get("sine", 0), "cosine": inner.get("cosine", 0)}


def main(argv=None):
    import argparse

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--paths", type=int, default=256)
    ap.add_argument("--dump", default=None, help="directory for the HLO text of every variant")
    a = ap.parse_args(argv)

    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    import jaxdrift
    import jaxdrift.models._halfcar as hc
    import jaxdrift.solvers._fast as fast_mod
    from _common import write_results
    from _setup import force_rhs, paper_study

    st = paper_study(T=0.2)
    T, dt, n = st.T, st.dt, st.n_samples
    ts = jnp.arange(0, 3) / 10.0
    f0, x0, key = jnp.asarray(st.f0), jnp.asarray(st.x0), jax.random.key(0)
    rhs = force_rhs(st.params)
    poly = hc._sin_cos

    def lib(beta, linear):
        return (beta, jnp.ones_like(beta)) if linear else (jnp.sin(beta), jnp.cos(beta))

    res = {}
    idx = jnp.arange(a.paths, dtype=jnp.int32)
    for kind in ("engine float64", "fast float32 (5 steps per iteration)"):
        for paths_last in (False, True):
            for use_poly in (False, True):
                def path(i, kind=kind):
                    if kind.startswith("engine"):
                        sig = jaxdrift.SampledSignal(0.0, dt, f0 + jaxdrift.path_normals(key, i, n, 2) * st.sigma)
                        return jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt).ys
                    u = (f0 + jaxdrift.path_normals(key, i, n, 2, jnp.float32) * st.sigma).astype(jnp.float32)
                    return jaxdrift.solve_fixed_fast(rhs, x0, 0.0, T, saveat=ts, args=jaxdrift.SampledSignal(0.0, dt, u),
                                                     dt=dt).ys

                hc._sin_cos, fast_mod._PATHS_LAST = (poly if use_poly else lib), paths_last
                try:
                    txt = jax.jit(jax.vmap(path)).lower(idx).compile().as_text()
                finally:
                    hc._sin_cos, fast_mod._PATHS_LAST = poly, True
                name = f"{kind}, {'paths last' if paths_last else 'vmap (paths first)'}, " \
                       f"{'polynomial' if use_poly else 'library'} sin/cos"
                res[name] = step_body_stats(txt)
                if a.dump:
                    Path(a.dump).mkdir(parents=True, exist_ok=True)
                    (Path(a.dump) / (re.sub(r"[^\w]+", "_", name) + ".hlo.txt")).write_text(txt)
                print(name, res[name], flush=True)
    md = [f"Optimised HLO of the step loop, {a.paths} paths (`jax.jit(jax.vmap(path)).lower(idx).compile().as_text()`); "
          "counts in the body of the step loop (fast mode: per iteration of 5 steps).", "",
          "| variant | fusions | all kernels | sine | cosine |", "|---|---:|---:|---:|---:|"]
    md += [f"| {k} | {r['fusions']} | {r['kernels']} | {r['sine']} | {r['cosine']} |" for k, r in res.items()]
    md += ["", "`sine`/`cosine`: operations inside the fusions (each is evaluated for every element of its fusion's "
           "output rows that use it). Reproduce: `python benchmarks/experiments/hlo_step.py`"]
    write_results("hlo-step", {"paths": a.paths, "variants": res}, "\n".join(md) + "\n")
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
