"""Does a Gaussian moment closure follow the half-car's drift further than the linearised covariance?

Found (``benchmarks/results/moment-closure.json``): on the class D study road the cubature closure
leaves the Monte-Carlo interval of the pitch variance at 15 s (standard deviation ratio 0.80),
earlier than the linearised covariance (20 s, 1.16), and collapses after (0.026 at 30 s); heave
agrees for both over all 30 s. Not offered in the library.

``jaxdrift.propagate_covariance`` linearises the model around the noise-free reference. On the
study's class D road its pitch variance leaves the Monte-Carlo interval after 15 s
(``benchmarks/results/variance.md``), when the noisy pitch spreads over radians. The usual
next step in filtering is an assumed-Gaussian closure: propagate the mean ``m`` and covariance
``P`` with the expectations taken over the Gaussian ``N(m, P)`` by a spherical cubature rule
(the 2n points ``m +- sqrt(n) S e_i``, ``S S^T = P``)::

    m' = E f(x, u(t)),    P' = E[(x - m) f^T] + E[f (x - m)^T] + E[B Q B^T]

This script integrates both (fixed 1 ms DOPRI5, the study of ``benchmarks/_setup.py``) and sets them
against the Monte-Carlo variances recorded in ``benchmarks/results/variance.json`` (1000 paths, same
road, noise and steps). It answers the question by measurement; the closure is not part of the
library because it does worse (see ``docs/variance.md``).

Reproduce (about a minute; needs ``benchmarks/results/variance.json`` from ``benchmarks/variance.py``)::

    python benchmarks/experiments/moment_closure.py
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # benchmarks/: _common, _setup, results/
sys.path.insert(0, str(HERE))


def cubature_moments(rhs, inputs, Q, n):
    """Right-hand side of the assumed-Gaussian moment equations on the state ``[m, vec(P)]``."""
    import jax
    import jax.numpy as jnp

    def sqrt_psd(P):
        # Symmetric square root; P starts at zero, where a Cholesky factor does not exist.
        w, V = jnp.linalg.eigh(0.5 * (P + P.T))
        return V * jnp.sqrt(jnp.clip(w, 0.0))

    def aug(t, z, _):
        m, P = z[:n], z[n:].reshape(n, n)
        u = inputs(t)
        S = sqrt_psd(P) * jnp.sqrt(n)
        X = jnp.concatenate([m[None] + S.T, m[None] - S.T])
        F = jax.vmap(lambda x: rhs(t, x, u, None))(X)
        Bs = jax.vmap(lambda x: jax.jacfwd(rhs, argnums=2)(t, x, u, None))(X)
        fm = F.mean(0)
        C = ((X - m).T @ (F - fm)) / (2 * n)
        dP = C + C.T + jnp.mean(Bs @ Q @ jnp.swapaxes(Bs, 1, 2), 0)
        return jnp.concatenate([fm, dP.reshape(-1)])

    return aug


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mc", default=str(HERE / "results" / "variance.json"),
                    help="Monte-Carlo variances to compare with (benchmarks/variance.py output)")
    a = ap.parse_args(argv)

    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np

    import jaxdrift
    from _common import machine_info, write_results
    from _setup import force_rhs_u, paper_study

    mc = json.loads(Path(a.mc).read_text())["tables"]
    rows_b, rows_z = mc["half-car: beta"], mc["half-car: z3"]
    ts = np.array([r["t"] for r in rows_b])
    T = float(ts.max())
    st = paper_study(T=T)
    p, dt, n = st.params, st.dt, 10
    rhs = force_rhs_u(p)
    inp = jaxdrift.SampledSignal(0.0, dt, jnp.asarray(st.f0))
    x0 = jnp.asarray(st.x0)

    t0 = time.perf_counter()
    lin = jaxdrift.propagate_covariance(rhs, x0, 0.0, T, saveat=ts, inputs=inp, noise_sigma=st.sigma,
                                        noise_dt=dt, dt=dt)
    t_lin = time.perf_counter() - t0
    Q = jnp.eye(2) * jaxdrift.brownian_intensity(st.sigma, dt)
    t0 = time.perf_counter()
    sol = jaxdrift.solve_ode(cubature_moments(rhs, inp, Q, n), jnp.concatenate([x0, jnp.zeros(n * n)]), 0.0, T,
                             saveat=ts, dt=dt)
    t_cub = time.perf_counter() - t0
    P_cub = np.asarray(sol.ys[:, n:]).reshape(-1, n, n)
    P_lin = np.asarray(lin.cov)

    out_rows = []
    for k, t in enumerate(ts):
        row = {"t": float(t)}
        for name, col, mrow in (("beta", 3, rows_b[k]), ("z3", 2, rows_z[k])):
            lo, hi = mrow["ci"]
            row[name] = {
                "mc_var": mrow["mc_var"], "ci": [lo, hi],
                "linearised": float(P_lin[k, col, col]), "cubature": float(P_cub[k, col, col]),
                "linearised_std_ratio": float(np.sqrt(P_lin[k, col, col] / mrow["mc_var"])),
                "cubature_std_ratio": float(np.sqrt(P_cub[k, col, col] / mrow["mc_var"])),
                "linearised_inside": bool(lo <= P_lin[k, col, col] <= hi),
                "cubature_inside": bool(lo <= P_cub[k, col, col] <= hi),
            }
        out_rows.append(row)
    report = {"machine": machine_info(), "mc_source": str(Path(a.mc).name), "sigma_N": st.sigma,
              "seconds": {"linearised": t_lin, "cubature": t_cub}, "rows": out_rows}
    lines = [
        "Half-car on the study road (class D, sigma = 0.002 f_max), variance against the Monte-Carlo of "
        f"`{report['mc_source']}` ({rows_b[0]['n_paths']} paths): standard-deviation ratios over Monte-Carlo, "
        "`yes` inside its 95 % interval.",
        "",
        "| t [s] | beta: MC var | linearised | in | cubature closure | in | z3: linearised | in | cubature | in |",
        "|---:|---:|---:|---|---:|---|---:|---|---:|---|",
    ]
    for r in out_rows:
        b, z = r["beta"], r["z3"]
        yn = {True: "yes", False: "no"}
        lines.append(
            f"| {r['t']:g} | {b['mc_var']:.4g} | {b['linearised_std_ratio']:.3f} | {yn[b['linearised_inside']]} | "
            f"{b['cubature_std_ratio']:.3f} | {yn[b['cubature_inside']]} | {z['linearised_std_ratio']:.3f} | "
            f"{yn[z['linearised_inside']]} | {z['cubature_std_ratio']:.3f} | {yn[z['cubature_inside']]} |"
        )
    lines += ["", f"Linearised: {t_lin:.1f} s, cubature closure: {t_cub:.1f} s (including compilation).", "",
              "Reproduce: `python benchmarks/experiments/moment_closure.py`", ""]
    md = "\n".join(lines)
    jp, mp = write_results("moment-closure", report, md)
    print(md)
    print(f"wrote {jp} and {mp}")


if __name__ == "__main__":
    main()
