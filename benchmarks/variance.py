"""Empirical against analytic variance of the drift, for every model of the seed paper.

For each model: Monte-Carlo variance (``jaxdrift.monte_carlo``, fixed 1 ms DOPRI5 on inputs sampled
at 1 kHz, float64) with its 95 % chi-square interval, the closed form where one exists, and the
covariance propagated along the noise-free reference (``jaxdrift.propagate_covariance``), at several
times up to 30 s:

* point mass (2.1), ``eta = 0`` and ``eta = 0.5``: (2.8) and (2.11) with sigma^2 = sigma_M^2 dt (2.5);
* the force-driven half-car on the seed's road (``benchmarks/_setup.py``: ISO 8608 class D,
  +-2 m hills, 20 m/s, sigma = 0.002 f_max), pitch ``beta`` and heave ``z3``; the closed form is the
  free-mode law (double-integrated noise through the generalised inertia, ``docs/variance.md``),
  the reference is the trajectory under the undisturbed forces;
* the quaternion reconstruction of section 3.2 (rates with sigma_M = 0.1 rad/s on all three axes,
  a slowly rotating body): the three components of the attitude-error angle against (3.16)
  ``sigma^2 t``, and the Ito norm growth (3.14) of the explicit Euler scheme.

"ratio" columns are standard-deviation ratios (closed form or propagated over Monte-Carlo).
Writes ``benchmarks/results/variance.json``, ``variance.md`` and ``variance.png``.

Reproduce (about 10 minutes on 2 cores; ``--quick``: smaller sizes, 10 s)::

    python benchmarks/variance.py
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE / "results"
sys.path.insert(0, str(HERE))

LEVEL = 0.95


def _row(t, mc_var, n, closed=None, prop=None):
    import numpy as np

    from jaxdrift.analysis._variance import variance_interval

    lo, hi = variance_interval(mc_var, n, LEVEL)
    row = {"t": float(t), "mc_var": float(mc_var), "ci": [float(lo), float(hi)], "n_paths": int(n)}
    for name, v in (("closed", closed), ("propagated", prop)):
        if v is not None:
            row[name] = float(v)
            row[f"{name}_inside"] = bool(lo <= v <= hi)
            row[f"{name}_std_ratio"] = float(np.sqrt(v / mc_var)) if mc_var > 0 else None
    return row


def _mc(path_fn, n_paths, ts, chunk):
    import jax

    import jaxdrift

    res = jaxdrift.monte_carlo(path_fn, n_paths, key=jax.random.key(7), save_ts=ts, chunk_size=chunk, progress=False)
    if res.count != n_paths:
        raise RuntimeError(f"{n_paths - res.count} paths failed")
    return res


def point_mass(n_paths, T, chunk):
    import jax
    import jax.numpy as jnp
    import numpy as np

    import jaxdrift

    m, sigma_m, dt = 750.0, 32.0, 1e-3
    n = int(round(T / dt)) + 1
    ts = np.array([t for t in (1.0, 2.0, 5.0, 10.0, 20.0, 30.0) if t <= T])
    out = {}
    for eta in (0.0, 0.5):

        def rhs(t, y, sig):
            return jnp.stack([y[1], sig(t)[0] / m - eta * y[1]])

        def path_fn(key, i, model):
            sig = jaxdrift.SampledSignal(0.0, dt, sigma_m * jaxdrift.path_normals(key, i, n, 1))
            sol = jaxdrift.solve_ode(rhs, jnp.zeros(2), 0.0, T, saveat=ts, args=sig, dt=dt)
            return sol.ys, sol.result

        res = _mc(path_fn, n_paths, ts, chunk)
        closed = jaxdrift.point_mass_covariance(ts, sigma_m=sigma_m, dt=dt, m=m, eta=eta)
        prop = jaxdrift.propagate_covariance(
            lambda t, y, u, a: jnp.stack([y[1], u[0] / m - eta * y[1]]), jnp.zeros(2), 0.0, T, saveat=ts,
            inputs=lambda t: jnp.zeros(1), noise_sigma=sigma_m, noise_dt=dt, dt=dt,
        )
        pv = np.asarray(prop.var)
        for j, q in enumerate(("x", "v")):
            out[f"point mass eta={eta:g}: {q}"] = [
                _row(t, res.var[k, j], res.count, closed[k, j, j], pv[k, j]) for k, t in enumerate(ts)
            ]
    return out


def halfcar(n_paths, T, chunk):
    import jax.numpy as jnp
    import numpy as np

    import jaxdrift
    from _setup import force_rhs, force_rhs_u, paper_study

    study = paper_study(T=T)
    p = study.params
    rhs = force_rhs(p)
    dt, n = study.dt, study.n_samples
    ts = np.array([t for t in (1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0) if t <= T])
    f0 = jnp.asarray(study.f0)
    x0 = jnp.asarray(study.x0)

    def path_fn(key, i, model):
        sig = jaxdrift.SampledSignal(0.0, dt, f0 + study.sigma * jaxdrift.path_normals(key, i, n, 2))
        sol = jaxdrift.solve_ode(rhs, x0, 0.0, T, saveat=ts, args=sig, dt=dt)
        return sol.ys[:, jnp.array([2, 3])], sol.result

    t0 = time.perf_counter()
    res = _mc(path_fn, n_paths, ts, chunk)
    t_mc = time.perf_counter() - t0
    t0 = time.perf_counter()
    prop = jaxdrift.propagate_covariance(
        force_rhs_u(p), x0, 0.0, T, saveat=ts, inputs=jaxdrift.SampledSignal(0.0, dt, f0),
        noise_sigma=study.sigma, noise_dt=dt, dt=dt,
    )
    t_prop = time.perf_counter() - t0
    pv = np.asarray(prop.var)
    free = jaxdrift.halfcar_free_mode_covariance(ts, p, sigma_m=study.sigma, dt=dt)
    ref = np.asarray(prop.mean)
    out = {}
    for j, (q, col, fm) in enumerate((("z3", 2, 0), ("beta", 3, 1))):
        out[f"half-car: {q}"] = [
            _row(t, res.var[k, j], res.count, free[k, fm, fm], pv[k, col]) | {"reference": float(ref[k, col])}
            for k, t in enumerate(ts)
        ]
    from _setup import ROAD_CLASS, ROAD_SEED, SPEED

    meta = {"road": f"ISO 8608 class {ROAD_CLASS}, seed {ROAD_SEED}, +-2 m hills of 250 m, {SPEED:g} m/s",
            "sigma_N": study.sigma, "mc_seconds": t_mc, "propagation_seconds": t_prop,
            "max_abs_reference_beta_deg": float(np.degrees(np.max(np.abs(study.xbar_ref[:, 3]))))}
    return out, meta


def _quat_mul(p, q):
    import jax.numpy as jnp

    p0, pv = p[0], p[1:]
    q0, qv = q[0], q[1:]
    return jnp.concatenate([jnp.array([p0 * q0 - pv @ qv]), p0 * qv + q0 * pv + jnp.cross(pv, qv)])


def quaternion(n_paths, T, chunk):
    import jax
    import jax.numpy as jnp
    import numpy as np

    import jaxdrift
    from jaxdrift.models._quaternion import omega_matrix

    sigma_m, dt = 0.1, 1e-3  # the seed's section 3.2 example
    n = int(round(T / dt)) + 1
    ts = np.array([t for t in (1.0, 2.0, 5.0, 10.0, 20.0, 30.0) if t <= T])
    tt = np.arange(n) * dt
    w_true = np.stack([0.3 * np.sin(0.5 * tt), 0.2 * np.cos(0.3 * tt), 0.1 + 0.0 * tt], -1)
    w_true = jnp.asarray(w_true)
    q0 = jnp.array([1.0, 0.0, 0.0, 0.0])

    def rhs(t, q, sig):
        return 0.5 * omega_matrix(sig(t)) @ q

    q_ref = jaxdrift.solve_ode(rhs, q0, 0.0, T, saveat=ts, args=jaxdrift.SampledSignal(0.0, dt, w_true), dt=dt).ys

    def err_angles(qr, q):
        q = q / jnp.linalg.norm(q)
        d = _quat_mul(qr * jnp.array([1.0, -1.0, -1.0, -1.0]), q)  # conj(q_ref) (x) q: body-frame error
        return 2.0 * d[1:] * jnp.sign(d[0])

    def path_fn(key, i, model):
        sig = jaxdrift.SampledSignal(0.0, dt, w_true + sigma_m * jaxdrift.path_normals(key, i, n, 3))
        sol = jaxdrift.solve_ode(rhs, q0, 0.0, T, saveat=ts, args=sig, dt=dt)
        return jax.vmap(err_angles)(q_ref, sol.ys), sol.result

    res = _mc(path_fn, n_paths, ts, chunk)
    prop = jaxdrift.propagate_covariance(
        lambda t, q, u, a: 0.5 * omega_matrix(u) @ q, q0, 0.0, T, saveat=ts,
        inputs=jaxdrift.SampledSignal(0.0, dt, w_true), noise_sigma=sigma_m, noise_dt=dt, dt=dt,
    )
    J = jax.vmap(lambda qr: jax.jacfwd(lambda q: err_angles(qr, q))(qr))(prop.mean)
    cov_err = np.asarray(jnp.einsum("tij,tjk,tlk->til", J, prop.cov, J))
    closed = jaxdrift.quaternion_angle_variance(ts, sigma_m=sigma_m, dt=dt)
    out = {}
    for j, ax in enumerate("xyz"):
        out[f"quaternion: angle error {ax}"] = [
            _row(t, res.var[k, j], res.count, closed[k], cov_err[k, j, j]) for k, t in enumerate(ts)
        ]

    # (3.14): the explicit Euler scheme on noisy samples grows |q| like exp(3 sigma^2 t / 8).
    def euler_norm(i):
        w = w_true + sigma_m * jaxdrift.path_normals(jax.random.key(8), i, n, 3)

        def step(q, wk):
            q = q + 0.5 * dt * omega_matrix(wk) @ q
            return q, None

        k_end = int(round(T / dt))
        q, _ = jax.lax.scan(step, q0, w[:k_end])
        return jnp.sum(q * q)

    nsq = np.asarray(jax.jit(jax.vmap(euler_norm))(jnp.arange(min(n_paths, 500))))
    omega_sq_mean = float(np.mean(np.sum(np.asarray(w_true[: int(round(T / dt))]) ** 2, -1)))
    norm = {
        "t": T,
        "mc_mean_norm_sq": float(nsq.mean()),
        "mc_sem": float(nsq.std(ddof=1) / np.sqrt(nsq.size)),
        "euler_exact_mean_norm_sq": float(
            np.prod(1.0 + (np.sum(np.asarray(w_true[: int(round(T / dt))]) ** 2, -1) + 3 * sigma_m**2) * dt**2 / 4.0)
        ),
        "ito_limit_noise_only": float(jaxdrift.quaternion_norm_growth(T, sigma_m=sigma_m, dt=dt, n_axes=3) ** 2),
        "mean_true_rate_sq": omega_sq_mean,
    }
    return out, norm


def _flag(r, name):
    """'yes' inside the 95 % interval; otherwise say whether it is inside the 99.9 % one."""
    from jaxdrift.analysis._variance import variance_interval

    if r[f"{name}_inside"]:
        return "yes"
    lo, hi = variance_interval(r["mc_var"], r["n_paths"], 0.999)
    return "no (in 99.9 %)" if lo <= r[name] <= hi else "**no**"


def _markdown(report):
    n_rows = sum(len(rows) for rows in report["tables"].values())
    lines = [
        f"Monte-Carlo variance ({report['config']['paths']} paths, 1 ms DOPRI5 on inputs sampled at 1 kHz, float64) "
        f"with its {LEVEL:.0%} chi-square interval, the closed form and the propagated (linearised) covariance. "
        "Ratios are standard-deviation ratios over Monte-Carlo. `yes`: inside the 95 % interval; "
        "`no (in 99.9 %)`: outside the 95 % but inside the 99.9 % interval. "
        f"Of {n_rows} rows about 5 % fall outside a 95 % interval by chance alone (rows of one quantity share their "
        "paths, so such misses come in runs); `**no**` marks a miss beyond 99.9 %.",
        "",
        "| quantity | t [s] | MC var | 95 % interval | closed form | ratio | in | propagated | ratio | in |",
        "|---|---:|---:|---|---:|---:|---|---:|---:|---|",
    ]
    for name, rows in report["tables"].items():
        for r in rows:
            c = r.get("closed")
            lines.append(
                f"| {name} | {r['t']:g} | {r['mc_var']:.4g} | [{r['ci'][0]:.4g}, {r['ci'][1]:.4g}] | "
                + (f"{c:.4g} | {r['closed_std_ratio']:.3f} | {_flag(r, 'closed')} | " if c is not None else "- | | | ")
                + f"{r['propagated']:.4g} | {r['propagated_std_ratio']:.3f} | {_flag(r, 'propagated')} |"
            )
    hc = report.get("halfcar")
    if hc:
        lines += [
            "",
            f"Half-car on {hc.get('road', 'the seed road')}: sigma = {hc['sigma_N']:.1f} N per force channel (0.002 f_max of this road), largest reference "
            f"pitch {hc['max_abs_reference_beta_deg']:.2f} deg; Monte-Carlo {hc['mc_seconds']:.0f} s, propagation "
            f"{hc['propagation_seconds']:.0f} s on this machine.",
        ]
    qn = report.get("quaternion_norm")
    if qn:
        lines += [
            "",
            f"Quaternion norm under the explicit Euler scheme (3.14), t = {qn['t']:g} s, 3 noisy axes: "
            f"MC mean |q|^2 = {qn['mc_mean_norm_sq']:.8f} +- {qn['mc_sem']:.1e} (s.e.); exact Euler mean "
            f"{qn['euler_exact_mean_norm_sq']:.8f}; Ito growth of the noise alone exp(3 sigma^2 t/4) = "
            f"{qn['ito_limit_noise_only']:.8f} (the rest is the true rotation's own Euler growth).",
        ]
    fails = report.get("closed_form_failures")
    if fails:
        lines += ["", "Where the closed form leaves the interval:", ""]
        for f in fails:
            lines.append(f"- {f}")
    lines += ["", f"Reproduce: `{report['command']}`"]
    return "\n".join(lines) + "\n"


def _plot(report, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    names = [k for k in ("point mass eta=0: x", "point mass eta=0.5: x", "half-car: beta", "half-car: z3",
                         "quaternion: angle error x") if k in report["tables"]]
    fig, axes = plt.subplots(1, len(names), figsize=(4 * len(names), 3.6))
    for ax, name in zip(np.atleast_1d(axes), names):
        rows = report["tables"][name]
        t = np.array([r["t"] for r in rows])
        lo = np.sqrt([r["ci"][0] for r in rows])
        hi = np.sqrt([r["ci"][1] for r in rows])
        ax.fill_between(t, lo, hi, alpha=0.3, label="MC 95 % interval")
        ax.plot(t, np.sqrt([r["mc_var"] for r in rows]), "k.", label="Monte-Carlo")
        if "closed" in rows[0]:
            ax.plot(t, np.sqrt([r["closed"] for r in rows]), "r--", label="closed form")
        ax.plot(t, np.sqrt([r["propagated"] for r in rows]), "b-", label="propagated")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(name, fontsize=9)
        ax.set_xlabel("t [s]")
    np.atleast_1d(axes)[0].set_ylabel("standard deviation")
    np.atleast_1d(axes)[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--paths", type=int, default=None)
    ap.add_argument("--T", type=float, default=None)
    ap.add_argument("--chunk", type=int, default=250)
    ap.add_argument("--out", default=None)
    ap.add_argument("--road-class", default=None, help="ISO 8608 class of the half-car road (default: _setup's, D)")
    ap.add_argument("--render-only", action="store_true", help="rewrite the markdown and plot from the JSON")
    a = ap.parse_args(argv)
    if a.render_only:
        stem = Path(a.out) if a.out else RESULTS / ("variance-quick" if a.quick else "variance")
        report = json.loads(stem.with_suffix(".json").read_text())
        stem.with_suffix(".md").write_text(_markdown(report))
        _plot(report, stem.with_suffix(".png"))
        return 0
    import jax

    jax.config.update("jax_enable_x64", True)
    if a.road_class:
        import _setup

        _setup.ROAD_CLASS = a.road_class
    T = a.T or (10.0 if a.quick else 30.0)
    n_paths = a.paths or (250 if a.quick else 1000)
    report = {
        "command": "python benchmarks/variance.py" + (" " + " ".join(sys.argv[1:]) if argv is None and sys.argv[1:] else ""),
        "config": {"T": T, "paths": n_paths, "level": LEVEL, "dt": 1e-3},
        "tables": {},
    }
    print("point mass ...", flush=True)
    report["tables"].update(point_mass(n_paths, T, a.chunk))
    print("half-car ...", flush=True)
    tabs, meta = halfcar(n_paths, T, a.chunk)
    report["tables"].update(tabs)
    report["halfcar"] = meta
    print("quaternion ...", flush=True)
    tabs, norm = quaternion(n_paths, T, a.chunk)
    report["tables"].update(tabs)
    report["quaternion_norm"] = norm
    fails = []
    for name, rows in report["tables"].items():
        for r in rows:
            if "closed" in r and not r["closed_inside"]:
                fails.append(f"{name} at t = {r['t']:g} s: closed-form std / MC std = {r['closed_std_ratio']:.3f}")
    report["closed_form_failures"] = fails
    report["propagated_outside"] = [
        f"{name} at t = {r['t']:g} s" for name, rows in report["tables"].items() for r in rows if not r["propagated_inside"]
    ]
    stem = Path(a.out) if a.out else RESULTS / ("variance-quick" if a.quick else "variance")
    stem.parent.mkdir(parents=True, exist_ok=True)
    stem.with_suffix(".json").write_text(json.dumps(report, indent=2) + "\n")
    stem.with_suffix(".md").write_text(_markdown(report))
    _plot(report, stem.with_suffix(".png"))
    print(_markdown(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
