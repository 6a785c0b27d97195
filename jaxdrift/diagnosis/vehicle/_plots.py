"""The figures of a vehicle report."""

from __future__ import annotations

import numpy as np


def write_vehicle_plots(plots_dir, run, model, p_ext, pipe, prob, res0, res1, sims, sigma,
                        report) -> list[str]:
    """The pictures an engineer looks at; returns the paths written.

    * ``motion.png``: measured pitch (and heave) against the force-driven simulation before and
      after the extension;
    * ``enforced_moment.png``: the enforced moment before/after against the inertia term I beta''
      (or the vertical enforced force against m3 z3'');
    * ``residual_envelope.png``: the residual after the fit against the 95 % noise-only band, and
      the force-driven pitch error against the noise-only drift envelope;
    * ``tyre_forces.png`` (runs with the road height): the tyre-law residual of each wheel before
      and after, against the noise-only band;
    * ``unmodelled_mode.png`` (a mode named): the spectrum of the vertical enforced force before and
      after, with the mode's frequency and interval marked.
    """
    import os

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(plots_dir, exist_ok=True)
    t = run.t - run.t[0]
    paths = []

    def save(fig, name):
        fig.tight_layout()
        path = os.path.join(plots_dir, name)
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)

    if sims:
        rows = [c for c in ("beta", "z3") if run.has(c)]
        fig, axes = plt.subplots(len(rows), 1, figsize=(9, 3.2 * len(rows)), squeeze=False)
        for ax, c in zip(axes[:, 0], rows):
            idx = 3 if c == "beta" else 2
            scale = 180 / np.pi if c == "beta" else 1.0
            unit = "deg" if c == "beta" else "m"
            ax.plot(t, run[c] * scale, "k", lw=1.2, label="measured")
            ax.plot(t, sims["before"][:, idx] * scale, "C3", lw=0.9, label="force-driven, model")
            ax.plot(t, sims["after"][:, idx] * scale, "C0", lw=0.9, label="force-driven, extended")
            ax.set_ylabel(f"{c} [{unit}]")
            lim = np.max(np.abs(run[c] * scale))
            ax.set_ylim(-3 * lim - 1e-12 + np.mean(run[c] * scale), 3 * lim + 1e-12 + np.mean(run[c] * scale))
            ax.legend(loc="upper left", fontsize=8)
        axes[-1, 0].set_xlabel("t [s]")
        axes[0, 0].set_title("Measured motion against the force-driven simulation")
        save(fig, "motion.png")

    main = "moment" if "moment" in prob.names else ("heave" if "heave" in prob.names else None)
    if main is not None:
        tt = t[1:1 + prob.rows[main]]
        if main == "moment":
            inertia = model["I"] * pipe.d2beta[:prob.rows[main]]
            lab, unit = "inertia term I beta''", "N m"
        else:
            inertia = model["m3"] * pipe.d2z3[:prob.rows[main]]
            lab, unit = "inertia term m3 z3''", "N"
        fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
        axes[0].plot(tt, inertia, "0.4", lw=0.7)
        axes[0].set_ylabel(f"{lab} [{unit}]")
        axes[0].set_title("Enforced " + ("moment (A.5)" if main == "moment" else "vertical force")
                          + " against the inertia term")
        axes[1].plot(tt, res0.channels[main][:prob.rows[main]], "C3", lw=0.7, label="model")
        axes[1].plot(tt, res1.channels[main][:prob.rows[main]], "C0", lw=0.7, label="extended model")
        axes[1].set_ylabel(f"enforced [{unit}]")
        axes[1].set_xlabel("t [s]")
        axes[1].legend(loc="upper left", fontsize=8)
        save(fig, "enforced_moment.png")

    nplot = (main is not None) + bool(sims and run.has("beta"))
    if nplot:
        fig, axes = plt.subplots(nplot, 1, figsize=(9, 3.2 * nplot), squeeze=False)
        k = 0
        if main is not None:
            ax = axes[k, 0]
            k += 1
            tt = t[1:1 + prob.rows[main]]
            band = 1.96 * sigma * prob.noise_std[main]
            ax.plot(tt, res1.channels[main][:prob.rows[main]], "C0", lw=0.6, label="residual, extended model")
            ax.fill_between(tt, -band, band, color="0.8", alpha=0.7, label="95 % noise-only band")
            ax.set_ylabel(f"{main} residual")
            ax.legend(loc="upper left", fontsize=8)
            ax.set_title("Residual against the noise level")
        if sims and run.has("beta"):
            ax = axes[k, 0]
            env = 1.96 * sigma * sims["pitch_std_unit"] * 180 / np.pi
            ax.fill_between(t, -env, env, color="0.8", alpha=0.7, label="95 % noise-only drift envelope")
            ax.plot(t, (sims["before"][:, 3] - run["beta"]) * 180 / np.pi, "C3", lw=0.8, label="pitch error, model")
            ax.plot(t, (sims["after"][:, 3] - run["beta"]) * 180 / np.pi, "C0", lw=0.8, label="pitch error, extended")
            ax.set_ylabel("pitch error [deg]")
            ax.legend(loc="upper left", fontsize=8)
        axes[-1, 0].set_xlabel("t [s]")
        save(fig, "residual_envelope.png")

    mode = next((f for f in report.get("findings", []) if f.get("cause") == "unmodelled_mode"), None)
    if mode is not None and "heave" in prob.names:
        save(_mode_figure(plt, pipe, prob, res0, res1, mode), "unmodelled_mode.png")

    tyres = [nm for nm in prob.names if nm.startswith("tyre")]
    if tyres:
        fig, axes = plt.subplots(len(tyres), 1, figsize=(9, 3.2 * len(tyres)), squeeze=False, sharex=True)
        for ax, nm in zip(axes[:, 0], tyres):
            tt = t[:prob.rows[nm]]
            band = 1.96 * sigma * prob.noise_std[nm]
            ax.fill_between(tt, -band, band, color="0.8", alpha=0.7, label="95 % noise-only band")
            ax.plot(tt, res0.channels[nm][:prob.rows[nm]], "C3", lw=0.6, label="model")
            ax.plot(tt, res1.channels[nm][:prob.rows[nm]], "C0", lw=0.6, label="extended model")
            wheel = "front" if nm == "tyre1" else "rear"
            ax.set_ylabel(f"{wheel} tyre residual [N]")
            ax.legend(loc="upper left", fontsize=8)
        axes[0, 0].set_title("Measured wheel force minus the tyre law k (z - zeta) + d (z' - zeta')")
        axes[-1, 0].set_xlabel("t [s]")
        save(fig, "tyre_forces.png")
    return paths


def _mode_figure(plt, pipe, prob, res0, res1, mode: dict):
    """Amplitude spectra (Welch) of the vertical enforced force of the model and of the extended
    model, the mode's frequency and its interval marked."""
    import scipy.signal

    fs = 1.0 / pipe.h
    fig, ax = plt.subplots(figsize=(9, 4))
    rows = slice(prob.skip["heave"], prob.skip["heave"] + prob.rows["heave"])
    for res, col, lab in ((res0, "C3", "model"), (res1, "C0", "extended model")):
        x = np.asarray(res.channels["heave"])[rows]
        f, pxx = scipy.signal.welch(x - x.mean(), fs=fs, nperseg=min(len(x), int(8 * fs)))
        ax.loglog(f[1:], np.sqrt(pxx[1:]), col, lw=0.9, label=lab)
    lo, hi = mode["interval"]
    ax.axvspan(lo, hi, color="C1", alpha=0.25)
    ax.axvline(mode["estimate"], color="C1", lw=1.0,
               label=f"unmodelled mode {mode['estimate']:.3g} Hz, {mode['placement']['mass_kg']:.3g} kg")
    if "heave" in pipe.band:
        ax.axvline(pipe.band["heave"][0], color="0.5", ls="--", lw=0.8, label="compared below")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("vertical enforced force [N/sqrt(Hz)]")
    ax.set_title("A resonance the rigid model cannot make")
    ax.legend(loc="lower left", fontsize=8)
    return fig
