"""The engine accuracy figures quoted in docs/engine.md, measured the way tests/test_solve.py checks them.

- ``fixed_order``: the fixed-step DOPRI5 order, the slope of log error against log step on a linear
  ODE against ``scipy.linalg.expm`` (the test asserts 5 +/- 0.2);
- ``sampled_input``: ``x'' = u(t)`` with ``u`` the linear interpolant of 300 random samples, whose
  exact solution is piecewise cubic: the error of fixed steps aligned with the samples, and of
  adaptive steps at rtol 1e-6, 1e-8 and 1e-10 (the kinks make the adaptive error exceed rtol).

    python benchmarks/validation/engine_checks.py     # ~20 s; writes benchmarks/results/engine-checks.json
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import sys

import numpy as np
import scipy.linalg

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))  # run as a script: the repository root
from benchmarks._common import RESULTS, machine_info  # noqa: E402

A_LIN = np.array([[0.0, 1.0, 0.0], [-4.0, -0.3, 1.0], [0.0, 0.0, -1.5]])


def fixed_order() -> dict:
    import jax.numpy as jnp

    import jaxdrift

    y0, T = np.array([1.0, 0.0, 2.0]), 2.0
    exact = scipy.linalg.expm(A_LIN * T) @ y0
    ns = (28, 40, 56, 80, 113)
    errs = []
    for n in ns:
        sol = jaxdrift.solve_ode(lambda t, y, a: jnp.asarray(A_LIN) @ y, y0, 0.0, T, saveat=jnp.array([T]), dt=T / n)
        errs.append(float(np.linalg.norm(np.asarray(sol.ys[-1]) - exact)))
    slope = float(np.polyfit(np.log([T / n for n in ns]), np.log(errs), 1)[0])
    return {"steps": list(ns), "errors": errs, "order": slope}


def sampled_input() -> dict:
    import jax.numpy as jnp

    import jaxdrift

    rng = np.random.default_rng(1)
    dt = 0.01
    u = rng.normal(size=301)
    x = v = 0.0
    for k in range(300):
        x, v = x + v * dt + dt**2 * (2 * u[k] + u[k + 1]) / 6, v + dt * (u[k] + u[k + 1]) / 2
    sig = jaxdrift.SampledSignal(0.0, dt, u)

    def f(t, y, s):
        return jnp.array([y[1], s(t)[0]])

    fixed = jaxdrift.solve_ode(f, jnp.zeros(2), 0.0, 3.0, saveat=np.array([3.0]), args=sig, dt=dt)
    out = {"samples": 300, "fixed_error": float(np.abs(np.asarray(fixed.ys[0]) - [x, v]).max()), "adaptive_error": {}}
    for rtol in (1e-6, 1e-8, 1e-10):
        sol = jaxdrift.solve_ode(f, jnp.zeros(2), 0.0, 3.0, saveat=np.array([3.0]), args=sig, rtol=rtol, atol=rtol * 1e-2)
        out["adaptive_error"][f"{rtol:g}"] = float(np.abs(np.asarray(sol.ys[0]) - [x, v]).max())
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(RESULTS / "engine-checks.json"))
    a = ap.parse_args(argv)
    import jax

    jax.config.update("jax_enable_x64", True)
    res = {"benchmark": "engine_checks", "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
           "fixed_order": fixed_order(), "sampled_input": sampled_input(), "machine": machine_info()}
    print(f"fixed-step order {res['fixed_order']['order']:.3f}; sampled input: fixed {res['sampled_input']['fixed_error']:.2g}, "
          f"adaptive {res['sampled_input']['adaptive_error']}")
    with open(a.out, "w") as fh:
        json.dump(res, fh, indent=2)
        fh.write("\n")
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
