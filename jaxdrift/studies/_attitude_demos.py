"""The seed's attitude demonstrations: the INS study (section 3.2, Figs. 1-2, bias instability
beside angle random walk), the quaternion SDE's drift ((3.11)-(3.16)) and the accelerometer array
(section 3.1). Each writes its figures into a folder and returns its summary; ``jaxdrift ins``,
``quaternion-drift`` and ``accel-array`` call them (docs/attitude.md).
"""

from __future__ import annotations

import json
import math
import os
import sys


def _finish(plt, fig, ax, out, name, xlabel, ylabel, title, legend_size, log_grid):
    """Label, legend and grid one axis; save the figure as ``out/name`` and close it."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title[0], fontsize=title[1])
    ax.legend(fontsize=legend_size)
    if log_grid:
        ax.grid(True, which="both", alpha=0.3)
    else:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(out, name), dpi=90)
    plt.close(fig)


def _bar(total, desc, unit, enabled):
    """A progress bar on stderr (off unless ``enabled``)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False, disable=not enabled,
                dynamic_ncols=True)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def ins_study(out, *, seed=0, duration=600.0, dt=1e-3, sigma_m=0.1, n_paths=16, method="expmap", progress=False):
    import numpy as np
    from scipy import stats

    from ..models._ins import gyro_errors, vehicle_motion
    from ..models._quaternion import integrate_rates_np, quat_conjugate_np, quat_log_np, quat_multiply_np, quat_to_euler_np

    plt = _plt()
    motion = vehicle_motion(seed, duration + 1.0)
    n = int(round(duration / dt)) + 1
    t = np.arange(n) * dt
    q_true = motion.quaternion(t)
    w_true = motion.body_rates(t + 0.5 * dt)  # rate held over each step reproduces q_true (to ~1e-7 rad)
    rng = np.random.default_rng(seed + 1)
    true_ang = quat_to_euler_np(q_true)

    def recon(w_meas, meth="expmap"):
        if meth == "expmap":
            return integrate_rates_np(q_true[0], w_meas, dt)
        import jax
        import jax.numpy as jnp

        from ..analysis._attitude_paths import integrate_rates

        with jax.enable_x64(True):
            qs = integrate_rates(jnp.asarray(q_true[0]), jnp.asarray(w_meas), dt, method=meth, rtol=1e-6, atol=1e-8)
            qs = np.asarray(qs)
        return qs / np.linalg.norm(qs, axis=1, keepdims=True)

    errs = []  # body-frame error angles (rotation vector of S_true^T S_rec)
    ang_err = []
    first = None

    bar = _bar(total=n_paths, desc="ins", unit="path", enabled=progress)
    for p in range(n_paths):
        w_meas = w_true + rng.normal(size=w_true.shape) * sigma_m
        q_rec = recon(w_meas, method if p == 0 else "expmap")
        if p == 0:
            first = q_rec
        e = quat_log_np(quat_multiply_np(quat_conjugate_np(q_true), q_rec))
        errs.append(e[:: max(1, n // 2000)])
        d = quat_to_euler_np(q_rec) - true_ang
        ang_err.append(np.angle(np.exp(1j * d))[:: max(1, n // 2000)])
        bar.update(1)
    bar.close()
    ts = t[:: max(1, n // 2000)]
    errs = np.array(errs)
    ang_err = np.array(ang_err)
    sig = sigma_m * math.sqrt(dt)  # rad/sqrt(s)
    env = np.degrees(sig * np.sqrt(ts))
    rec_ang = quat_to_euler_np(first)
    names = ("roll", "pitch", "yaw")
    # Fig. 1
    fig, axs = plt.subplots(3, 1, figsize=(7, 6), sharex=True)
    for k in range(3):
        axs[k].plot(t[::10], np.degrees(np.unwrap(true_ang[::10, k])), lw=0.6, label="true")
        axs[k].plot(t[::10], np.degrees(np.unwrap(rec_ang[::10, k])), lw=0.6, label=f"reconstructed ({method})")
        axs[k].set_ylabel(f"{names[k]} [deg]")
    axs[0].legend(fontsize=7)
    axs[-1].set_xlabel("t [s]")
    fig.suptitle(f"True and reconstructed angles, white rate noise {sigma_m} rad/s at {1 / dt:g} Hz", fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig1_angles.png"), dpi=90)
    plt.close(fig)
    # Fig. 2
    fig, axs = plt.subplots(3, 1, figsize=(7, 6), sharex=True)
    for k in range(3):
        for p in range(n_paths):
            axs[k].plot(ts, np.degrees(ang_err[p, :, k]), lw=0.4, color="0.6")
        axs[k].plot(ts, np.degrees(ang_err[0, :, k]), lw=0.7, color="C1")
        axs[k].plot(ts, env, "k--", lw=1, label=f"+-{np.degrees(sig):.3f} deg/sqrt(s) sqrt(t)")
        axs[k].plot(ts, -env, "k--", lw=1)
        axs[k].plot(ts, 2 * env, "k:", lw=1, label="+-2 sigma")
        axs[k].plot(ts, -2 * env, "k:", lw=1)
        axs[k].set_ylabel(f"{names[k]} error [deg]")
    axs[0].legend(fontsize=7, loc="upper left")
    axs[-1].set_xlabel("t [s]")
    fig.suptitle(f"Reconstruction errors of {n_paths} noise samples and the expected envelope", fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig2_angle_errors.png"), dpi=90)
    plt.close(fig)
    # envelope check: body-frame error components at the end, chi-square interval for the variance
    v_end = np.mean(errs[:, -1, :] ** 2, axis=0)
    k_tot = errs.shape[0] * 3
    ratio = float(np.sum(v_end) / 3 / (sig**2 * ts[-1]))
    lo, hi = stats.chi2.ppf([0.005, 0.995], k_tot) / k_tot
    # grades: angle random walk vs bias instability (Monte-Carlo on a still body, error ~ integral of error)
    grades = {
        "consumer MEMS": {"arw_deg_sqrt_h": 0.5, "bias_instability_deg_h": 10.0},
        "tactical": {"arw_deg_sqrt_h": 0.1, "bias_instability_deg_h": 1.0},
    }
    dtg = 0.01
    ng = int(round(duration / dtg)) + 1
    tg = np.arange(ng) * dtg
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    grade_out = {}
    for gi, (gname, g) in enumerate(grades.items()):
        N = math.radians(g["arw_deg_sqrt_h"]) / 60.0
        B = math.radians(g["bias_instability_deg_h"]) / 3600.0
        e_arw = np.array([np.cumsum(gyro_errors(rng, ng, dtg, arw=N)[:, 0]) * dtg for _ in range(64)])
        e_bi = np.array([np.cumsum(gyro_errors(rng, ng, dtg, bias_instability=B, tau_c=300.0)[:, 0]) * dtg for _ in range(64)])
        s_arw = np.degrees(np.sqrt(np.mean(e_arw**2, 0)))
        s_bi = np.degrees(np.sqrt(np.mean(e_bi**2, 0)))
        ax.loglog(tg[1:], s_arw[1:], color=f"C{gi}", label=f"{gname}: ARW N = {g['arw_deg_sqrt_h']} deg/sqrt(h)")
        ax.loglog(tg[1:], s_bi[1:], "--", color=f"C{gi}", label=f"{gname}: bias instability {g['bias_instability_deg_h']} deg/h")
        ax.loglog(tg[1:], np.degrees(N * np.sqrt(tg[1:])), ":", color=f"C{gi}", lw=0.8)
        ax.loglog(tg[1:], np.degrees(B * tg[1:]), "-.", color=f"C{gi}", lw=0.8)
        sl_arw = np.polyfit(np.log(tg[100:]), np.log(s_arw[100:]), 1)[0]
        early = max(ng // 10, 110)  # the first tenth of the run, at least 10 points past t = 1 s
        sl_bi = np.polyfit(np.log(tg[100:early]), np.log(s_bi[100:early]), 1)[0]
        grade_out[gname] = {**g, "slope_arw": float(sl_arw), "slope_bias_instability_early": float(sl_bi),
                            "error_deg_at_end_arw": float(s_arw[-1]), "error_deg_at_end_bias_instability": float(s_bi[-1])}
    _finish(plt, fig, ax, out, "fig_grades.png", "t [s]", "RMS angle error [deg]",
            ("Angle random walk (slope 1/2, dotted) vs bias instability (slope 1, dash-dot)", 9), legend_size=6, log_grid=True)
    summary = {
        "duration_s": duration, "dt": dt, "sigma_m_rad_s": sigma_m, "paths": n_paths, "method_shown": method,
        "envelope": {
            "expected_deg_per_sqrt_s": float(np.degrees(sig)),
            "expected_std_deg_at_end": float(np.degrees(sig * math.sqrt(ts[-1]))),
            "measured_std_deg_at_end_per_axis": [float(v) for v in np.degrees(np.sqrt(v_end))],
            "variance_ratio_pooled": ratio,
            "chi2_99_interval": [float(lo), float(hi)],
        },
        "grades": grade_out,
    }
    with open(os.path.join(out, "ins_summary.json"), "w") as fh:
        json.dump(summary, fh, indent=1)
    return summary


def quaternion_drift_study(out, *, sigma=0.5, t1=4.0, dt=0.004, n_paths=400, seed=0, progress=False):
    import jax
    import numpy as np
    from scipy import stats

    from ..analysis._attitude_paths import quaternion_sde_paths
    from ..models._quaternion import ito_norm_growth, quat_log_np

    plt = _plt()
    res = {}

    bar = _bar(total=6, desc="quaternion-drift", unit="case", enabled=progress)
    with jax.enable_x64(True):
        key = jax.random.key(seed)
        for scheme in ("euler_maruyama", "heun", "expmap"):
            for axes in ((0,), (0, 1, 2)):
                ts, qs, W = quaternion_sde_paths(key, n_paths, t1, dt, sigma, scheme=scheme, axes=axes, n_save=41)
                res[(scheme, len(axes))] = (np.asarray(ts), np.asarray(qs), np.asarray(W))
                bar.update(1)
    bar.close()
    ts = res[("expmap", 1)][0]
    fig, ax = plt.subplots(figsize=(6, 4))
    summary = {"sigma": sigma, "t1": t1, "dt": dt, "paths": n_paths, "norm_at_end": {}, "angle_error": {}}
    for (scheme, na), (_, qs, _) in res.items():
        nrm = np.linalg.norm(qs, axis=-1)
        ax.plot(ts, nrm.mean(0), ("-" if na == 1 else "--"), label=f"{scheme}, {na} noisy ax{'is' if na == 1 else 'es'}")
        summary["norm_at_end"][f"{scheme}/{na}"] = {"mean": float(nrm[:, -1].mean()), "se": float(nrm[:, -1].std(ddof=1) / math.sqrt(n_paths))}
    for na in (1, 3):
        ax.plot(ts, ito_norm_growth(sigma, ts, na), "k:", lw=1)
        summary["norm_at_end"][f"ito_closed_form/{na}"] = float(ito_norm_growth(sigma, t1, na))
    _finish(plt, fig, ax, out, "quaternion_norm.png", "t [s]", "mean |q|",
            (f"(3.14): |q| of the Ito SDE grows like exp(n sigma^2 t/8) (dotted), sigma={sigma}", 9), legend_size=7, log_grid=False)
    # angle error: single axis, normalised q: the angle is exactly sigma W(t) for expmap
    fig, ax = plt.subplots(figsize=(6, 4))
    lo, hi = stats.chi2.ppf([0.005, 0.995], n_paths) / n_paths
    for scheme in ("euler_maruyama", "heun", "expmap"):
        _, qs, W = res[(scheme, 1)]
        ang = quat_log_np(qs / np.linalg.norm(qs, axis=-1, keepdims=True))[:, :, 0]
        sd = np.sqrt(np.mean(ang**2, 0))
        ax.plot(ts, sd, label=f"{scheme} (normalised)")
        ratio = float(np.mean(ang[:, -1] ** 2) / (sigma**2 * t1))
        summary["angle_error"][scheme] = {"std_at_end": float(sd[-1]), "variance_ratio": ratio,
                                          "inside_99": bool(lo < ratio < hi)}
    ax.plot(ts, sigma * np.sqrt(ts), "k--", label="sigma sqrt(t)")
    ax.fill_between(ts, sigma * np.sqrt(ts * lo), sigma * np.sqrt(ts * hi), color="0.85", label="99 % chi-square band")
    _finish(plt, fig, ax, out, "quaternion_angle_error.png", "t [s]", "Std of the spurious rotation angle [rad]",
            ("(3.16): the error angle is sigma W(t)", 9), legend_size=7, log_grid=False)
    summary["chi2_99_interval"] = [float(lo), float(hi)]
    with open(os.path.join(out, "quaternion_summary.json"), "w") as fh:
        json.dump(summary, fh, indent=1)
    return summary


def accel_array_study(out, *, seed=0, duration=60.0, dt=0.005, noise=0.02, n_paths=100, progress=False):
    import numpy as np
    from scipy import stats

    from ..models._accel_array import angle_error_std_closed_form, reconstruct, simulate_array
    from ..studies._attgen import DEFAULT_POSITIONS
    from ..models._ins import vehicle_motion
    from ..models._quaternion import quat_log_np, rotation_angle_between_np

    plt = _plt()
    r = DEFAULT_POSITIONS
    m = vehicle_motion(seed, duration + 1.0, road_rms_deg=1.0, curve_rate=0.3)
    n = int(round(duration / dt)) + 1
    t = np.arange(n) * dt
    q = m.quaternion(t)
    S = m.rotation_matrices(t)
    w = m.body_rates(t)
    x, xdd = m.position_acceleration(t)
    acc = simulate_array(S, w, m.body_angular_acceleration(t), xdd, r)
    ang0, _ = m.angles(t[:1])
    sp = m._sines(m.speed_terms, t[:1])[0][0] + m.v0
    v0 = [sp * math.cos(ang0[0, 2]), sp * math.sin(ang0[0, 2]), m._sines(m.heave_terms, t[:1])[1][0]]
    clean = reconstruct(acc, r, dt, q0=q[0], omega0=w[0], x0=x[0], v0=v0)
    rng = np.random.default_rng(seed + 7)
    noisy = reconstruct(acc + rng.normal(size=acc.shape) * noise, r, dt, q0=q[0], omega0=w[0], x0=x[0], v0=v0)
    fig, axs = plt.subplots(3, 1, figsize=(7, 6), sharex=True)
    true_ang = m.angles(t)[0]
    for k, name in enumerate(("roll", "pitch")):
        axs[k].plot(t, np.degrees(true_ang[:, k]), lw=0.6, label="true")
        axs[k].plot(t, np.degrees(clean["angles"][:, k]), lw=0.6, ls="--", label="noise-free array")
        axs[k].plot(t, np.degrees(noisy["angles"][:, k]), lw=0.6, label=f"array, noise {noise} m/s^2")
        axs[k].set_ylabel(f"{name} [deg]")
    axs[2].semilogy(t[1:], rotation_angle_between_np(clean["q"], q)[1:], lw=0.6, label="attitude error, noise-free")
    axs[2].semilogy(t[1:], rotation_angle_between_np(noisy["q"], q)[1:], lw=0.6, label="attitude error, noisy")
    axs[2].set_ylabel("[rad]")
    axs[2].set_xlabel("t [s]")
    axs[0].legend(fontsize=7)
    axs[2].legend(fontsize=7)
    fig.suptitle("Section 3.1: attitude from 5 accelerometers (six-step reconstruction)", fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "accel_reconstruction.png"), dpi=90)
    plt.close(fig)
    # noise growth at rest vs closed form
    T2 = min(duration, 10.0)
    n2 = int(round(T2 / dt)) + 1
    checks = np.unique(np.geomspace(10, n2 - 1, 12).astype(int))
    errs = np.empty((n_paths, len(checks), 3))

    bar = _bar(total=n_paths, desc="accel-array", unit="path", enabled=progress)
    for p in range(n_paths):
        out_p = reconstruct(rng.normal(size=(n2, r.shape[0], 3)) * noise, r, dt)
        errs[p] = quat_log_np(out_p["q"][checks])
        bar.update(1)
    bar.close()
    tt = checks * dt
    sd_cf = angle_error_std_closed_form(noise, r, dt, tt)
    sd_mc = np.sqrt(np.mean(errs**2, 0))
    lo, hi = stats.chi2.ppf([0.005, 0.995], n_paths) / n_paths
    fig, ax = plt.subplots(figsize=(6, 4))
    for k, name in enumerate("xyz"):
        ax.loglog(tt, sd_mc[:, k], "o", ms=3, color=f"C{k}", label=f"Monte-Carlo, about {name}")
        ax.loglog(tt, sd_cf[:, k], "-", color=f"C{k}", lw=0.8)
        ax.fill_between(tt, sd_cf[:, k] * math.sqrt(lo), sd_cf[:, k] * math.sqrt(hi), color=f"C{k}", alpha=0.15)
    ax.loglog(tt, math.radians(0.18) * np.sqrt(tt) * noise / 0.1 * 0, alpha=0)  # keep axes
    _finish(plt, fig, ax, out, "accel_noise_growth.png", "t [s]", "Std of the angle error [rad]",
            ("Array at rest, white accelerometer noise: two integrations, Std ~ t^3/2 (lines: closed form)", 8), legend_size=7, log_grid=True)
    slope = float(np.polyfit(np.log(tt[tt > 0.5]), np.log(sd_mc[tt > 0.5].mean(1)), 1)[0])
    # high-pass cut-off dependence
    # cut-offs far below 1/duration only add edge transients of the zero-phase filter: start at 2/T
    cutoffs = [c for c in (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0) if c >= 2.0 / duration]
    acc_n = acc + np.random.default_rng(seed + 11).normal(size=acc.shape) * noise

    def rp(out_):
        d = np.angle(np.exp(1j * (out_["angles"][:, :2] - true_ang[:, :2])))
        return float(np.degrees(np.sqrt(np.mean(d**2))))

    e_none = rp(reconstruct(acc_n, r, dt, q0=q[0], omega0=w[0]))
    e_cut = [rp(reconstruct(acc_n, r, dt, q0=q[0], omega0=w[0], highpass_omega=fc, highpass_angles=fc)) for fc in cutoffs]
    e_cut_clean = [rp(reconstruct(acc, r, dt, q0=q[0], omega0=w[0], highpass_omega=fc, highpass_angles=fc)) for fc in cutoffs]
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.loglog(cutoffs, e_cut, "o-", label=f"noise {noise} m/s^2")
    ax.loglog(cutoffs, e_cut_clean, "s--", label="noise-free (filter distortion only)")
    ax.axhline(e_none, color="k", ls=":", label="no filter, noisy")
    _finish(plt, fig, ax, out, "accel_highpass.png", "high-pass cut-off on omega_l and on the angles [Hz]", "RMS roll/pitch error [deg]",
            ("Remark 2: the result depends on the cut-off", 9), legend_size=7, log_grid=True)
    summary = {
        "duration_s": duration, "dt": dt, "accel_noise": noise, "sensors": r.tolist(),
        "noise_free": {"max_rate_error": float(np.max(np.abs(clean["omega"] - w))),
                       "max_attitude_error_rad": float(np.max(rotation_angle_between_np(clean["q"], q))),
                       "max_position_error_m": float(np.max(np.linalg.norm(clean["xc"] - x, axis=1))),
                       "max_consistency_residual": float(np.max(np.abs(clean["consistency"])))},
        "noise_growth": {"slope": slope, "variance_ratio_at_end": [float(v) for v in (sd_mc[-1] / sd_cf[-1]) ** 2],
                         "chi2_99_interval": [float(lo), float(hi)]},
        "highpass": {"cutoffs_hz": cutoffs, "rms_roll_pitch_error_deg": e_cut, "noise_free_deg": e_cut_clean,
                     "no_filter_deg": e_none},
    }
    with open(os.path.join(out, "accel_summary.json"), "w") as fh:
        json.dump(summary, fh, indent=1)
    return summary
