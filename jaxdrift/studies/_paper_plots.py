"""Outputs of the paper study: figures 4-8 and the pitch-spring figure, ``summary.json`` and the
solver comparison table ``solver_comparison.md`` (written atomically into the output folder).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["solver_table_markdown", "write_paper_outputs"]


def _fmt_t(v) -> str:
    if v is None or v == "inf" or (isinstance(v, float) and not math.isfinite(v)):
        return "> run"
    return f"{v:.2f}"


def solver_table_markdown(summary: dict) -> str:
    """The solver/tolerance comparison as a markdown table."""
    thr = summary["config"]["drift_threshold_deg"]
    lines = [
        f"Drift-off time [s] of beta (|beta - beta_measured| > {thr:g} deg); '> run' = never within the run.",
        "",
        "| solver | undisturbed | pitch error at end, undisturbed [deg] | paper-perturbed model | noisy: median | noisy: each sample |",
        "|---|---|---|---|---|---|",
    ]
    for row in summary["solver_comparison"]:
        noisy = [float("inf") if v == "inf" else v for v in row["noisy_drift_off_s"]]
        med = float(np.quantile(np.asarray(noisy, dtype=float), 0.5, method="inverted_cdf"))
        lines.append(
            f"| {row['solver']} | {_fmt_t(row['undisturbed_drift_off_s'])} | "
            f"{row['undisturbed_pitch_error_end_deg']:.3f} | {_fmt_t(row['perturbed_paper_drift_off_s'])} | "
            f"{_fmt_t(med)} | {', '.join(_fmt_t(v) for v in noisy)} |"
        )
    return "\n".join(lines) + "\n"


def write_paper_outputs(res: dict, out_dir, dpi: int = 90) -> list[str]:
    """Write figures 4-8 (+ pitch spring), ``summary.json`` and ``solver_comparison.md``.

    Files are written to a temporary folder inside ``out_dir`` first and moved into place at the
    end, so an interrupted run leaves no half-written set. Returns the written file names.
    """
    import os
    import shutil
    import tempfile

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(out_dir, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix=".paper-", dir=out_dir)
    try:
        files = _write_all(res, tmp, dpi, plt)
        for name in files:
            os.replace(os.path.join(tmp, name), os.path.join(out_dir, name))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return files


def _band(ax, ts, ys, ref, color, label, n_show=8, scale=1.0):
    q05, q50, q95 = np.quantile(ys * scale, [0.05, 0.5, 0.95], axis=0)
    ax.fill_between(ts, q05, q95, color=color, alpha=0.2, lw=0, label=f"{label}: 5-95 % band")
    for i in range(min(n_show, ys.shape[0])):
        ax.plot(ts, ys[i] * scale, color=color, lw=0.6, alpha=0.7, label=f"{label}: samples" if i == 0 else None)
    ax.plot(ts, ref * scale, color="k", lw=1.2, label="virtual measurement")


def _write_all(res, d, dpi, plt):
    import json
    import os

    cfg, vm, ts = res["cfg"], res["vm"], res["save_ts"]
    s = res["summary"]
    main, kinds = res["main"], res["kinds"]
    vts = np.asarray(vm.ts)
    beta_ref, z3_ref = res["beta_ref"], res["z3_ref"]
    deg = 180.0 / np.pi
    files = []

    def save(fig, name):
        fig.tight_layout()
        fig.savefig(os.path.join(d, name), dpi=dpi)
        plt.close(fig)
        files.append(name)

    def rows(kind):
        return np.flatnonzero(kinds == kind)

    # Fig. 4: road and wheel forces
    fig, ax = plt.subplots(3, 1, figsize=(8, 7), gridspec_kw=dict(height_ratios=[2, 1.2, 2]))
    zeta = np.asarray(vm.zeta)
    ax[0].plot(vts, zeta[:, 0], lw=0.8, label=r"$\zeta_1$ (front)")
    ax[0].plot(vts, zeta[:, 1], lw=0.8, label=r"$\zeta_2$ (rear)")
    ax[0].set_ylabel(r"road $\zeta$ [m] (z down)")
    ax[0].legend(loc="upper right")
    ax[0].set_title(f"ISO 8608 class {cfg.road_class} road with hills at {cfg.speed:g} m/s")
    t_lo = min(2.0, 0.5 * float(vts[-1]))
    m = (vts >= t_lo) & (vts <= t_lo + 1.0)
    ax[1].plot(vts[m], zeta[m, 0], lw=0.8)
    ax[1].plot(vts[m], zeta[m, 1], lw=0.8)
    ax[1].set_ylabel(r"$\zeta$ [m] (detail)")
    f = np.asarray(vm.forces)
    ax[2].plot(vts, f[:, 0] / 1e3, lw=0.5, label="$f_1$")
    ax[2].plot(vts, f[:, 1] / 1e3, lw=0.5, label="$f_2$", alpha=0.8)
    ax[2].set_ylabel("wheel force [kN]")
    ax[2].legend(loc="upper right")
    for a in ax:
        a.set_xlabel("t [s]")
    save(fig, "fig4_road_forces.png")

    # Fig. 5: z3 and beta for each step
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    series = [("virtual measurement", None, "k"), ("undisturbed forces", rows("undisturbed")[0], "C0"),
              ("noisy forces (one sample)", rows("noisy")[0], "C3"),
              ("perturbed model (paper's)", rows("perturbed_paper")[0], "C2")]
    for label, r, c in series:
        z = z3_ref if r is None else main.ys[r, :, 0]
        b = beta_ref if r is None else main.ys[r, :, 1]
        ax[0].plot(ts, z, color=c, lw=1.0, label=label)
        ax[1].plot(ts, b * deg, color=c, lw=1.0, label=label)
    ax[0].set_ylabel("$z_3$ [m] (down)")
    ax[1].set_ylabel(r"$\beta$ [deg]")
    lim = max(10.0, 2.0 * np.max(np.abs(beta_ref)) * deg)
    ax[1].set_ylim(-lim, lim)
    for a in ax:
        a.set_xlabel("t [s]")
    ax[1].legend(fontsize=7, loc="upper left")
    ax[0].set_title("vertical chassis motion")
    ax[1].set_title(f"pitch (drift-off: |error| > {cfg.drift_threshold_deg:g} deg)")
    save(fig, "fig5_z3_beta.png")

    # Fig. 6 / 7: bands over noise samples and perturbed models
    for name, kind, color, title in (("fig6_noise_samples.png", "noisy", "C3", "noise samples"),
                                     ("fig7_perturbed_models.png", "perturbed_random", "C2", "perturbed models")):
        r = rows(kind)
        fig, ax = plt.subplots(1, 2, figsize=(10, 4))
        _band(ax[0], ts, main.ys[r, :, 0], z3_ref, color, title)
        _band(ax[1], ts, main.ys[r, :, 1], beta_ref, color, title, scale=deg)
        ax[0].set_ylabel("$z_3$ [m] (down)")
        ax[1].set_ylabel(r"$\beta$ [deg]")
        ax[1].set_ylim(-lim, lim)
        for a in ax:
            a.set_xlabel("t [s]")
        ax[1].legend(fontsize=7, loc="upper left")
        ax[0].set_title(f"$z_3$ over {len(r)} {title}")
        ax[1].set_title(rf"$\beta$ over {len(r)} {title}")
        save(fig, name)

    # Fig. 8: inertia term and enforced moment
    stab, sk, mts = res["stab"], res["stab_kinds"], res["moment_ts"]
    i_pn = np.flatnonzero(sk == "perturbed_noisy")[0]
    i_uu = np.flatnonzero(sk == "unperturbed_undisturbed")[0]
    fig, ax = plt.subplots(1, 2, figsize=(10, 4), sharex=True)
    ax[0].plot(mts, stab.ys[i_pn, :, 2] / 1e3, lw=0.5, color="C0")
    ax[0].set_ylabel(r"inertia term $I\ddot\beta$ [kNm]")
    ax[0].set_title(r"inertia term $I\ddot\beta$")
    ax[1].plot(mts, stab.ys[i_pn, :, 1], lw=0.5, color="C3", label="perturbed model, noisy forces")
    ax[1].plot(mts, stab.ys[i_uu, :, 1], lw=0.5, color="k", label="original model, undisturbed forces")
    ax[1].set_ylabel(r"enforced moment $\lambda$ [Nm]")
    ax[1].set_title(r"enforced moment $\lambda = I\ddot\beta - \cos\beta\,(b f_3 - a f_4)$")
    ax[1].legend(fontsize=7, loc="upper left")
    for a in ax:
        a.set_xlabel("t [s]")
    save(fig, "fig8_enforced_moment.png")

    # pitch spring trade-off
    sp = [r for r in s["pitch_spring"] if r["stiffness"] > 0]
    free = [r for r in s["pitch_spring"] if r["stiffness"] == 0]
    if sp:
        k = np.array([r["stiffness"] for r in sp])
        fig, ax = plt.subplots(1, 1, figsize=(6, 4))
        ax.loglog(k, [r["pitch_error_rms_deg"] for r in sp], "o-", color="C0", label="pitch error RMS [deg]")
        ax.loglog(k, [r["pitch_error_max_deg"] for r in sp], "s--", color="C0", alpha=0.6,
                  label="pitch error max [deg]")
        if free:
            ax.axhline(free[0]["pitch_error_rms_deg"], color="C0", lw=0.8, ls=":",
                       label="pitch error RMS without spring [deg]")
        ax.set_xlabel("rotational spring stiffness [Nm/rad] (critically damped)")
        ax.set_ylabel("pitch error [deg]", color="C0")
        ax2 = ax.twinx()
        ax2.loglog(k, [r["reaction_torque_max"] for r in sp], "^-", color="C3", label="reaction torque max [Nm]")
        ax2.set_ylabel("reaction torque max [Nm]", color="C3")
        ax.set_title("section 3, approach 1: pitch spring to ground (noisy forces)")
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, fontsize=7, loc="upper center")
        save(fig, "fig_pitch_spring.png")

    with open(os.path.join(d, "summary.json"), "w") as fh:
        json.dump(s, fh, indent=2)
    files.append("summary.json")
    with open(os.path.join(d, "solver_comparison.md"), "w") as fh:
        fh.write(solver_table_markdown(s))
    files.append("solver_comparison.md")
    return files
