"""The attitude report: ranking of the findings, the report dict, and the figures.

Systematic findings are ranked by their statistic (z or its equivalent), largest first; white
noise (``gyro_noise``, then ``accel_noise``) is listed after them; a run without either reports
``none``.
"""

from __future__ import annotations

import os

import numpy as np

from ...io._corrections import corrections_json
from ...io._outputs import check_report_finite
from ...io._timebase import run_block
from .._intervals import joint_intervals
from ._common import CHANNELS, SCHEMA

__all__ = ["assemble_report", "write_plots"]


def assemble_report(s):
    """The report dict (docs/measured-data.md, kind "attitude") from the pipeline state ``s``."""
    findings = s.findings
    t, dt = s.t, s.dt
    n = s.n
    T = t[-1] - t[0]
    allan = s.allan
    findings.sort(key=lambda fz: -fz[1])
    ranked = [f for f, _ in findings]
    if s.noise_finding is not None:
        ranked.append(s.noise_finding)
    ranked.extend(s.noise_findings)
    joint_intervals(ranked)
    if not ranked:
        ranked = [{"cause": "none", "estimate": None, "unit": None, "interval": None,
                   "evidence": "no systematic effect and no white noise above the file's rounding"}]
    report = {
        "schema": SCHEMA,
        "kind": "attitude",
        "simulation_error": s.sim_err,
        "findings": ranked,
        "extended_model": {"corrections": corrections_json(s.corrections)},
        "gain": s.gain if s.gain is not None else {"metric": None, "before": None, "after": None},
        "observability": {"used": s.observed, "not_observed": s.not_observed, "notes": s.notes},
        "not_determined": s.not_determined,
        "allan": None if allan is None else {
            "series": allan["series"], "N": allan["fit"]["N"], "B": allan["fit"]["B"], "K": allan["fit"]["K"],
            "units": {"N": "rad/sqrt(s)", "B": "rad/s", "K": "rad/s/sqrt(s)"},
        },
        "run": {"rows": int(n), "dt": float(dt), "duration_s": float(T), "reference_rows": s.n_ref,
                "sensors": 0 if s.positions is None else int(s.positions.shape[0]),
                "time_base": run_block(s.run.get("time_base")),
                "reference_alignment": s.alignment},
    }
    check_report_finite(report)  # every attitude report, wherever it is made (CLI, API, tests, sweeps)
    return report


def write_plots(plots, out):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    written = []
    if "allan" in plots:
        a = plots["allan"]
        fig, ax = plt.subplots(figsize=(6, 4.5))
        for c, ad in enumerate(a["adev"]):
            ax.loglog(a["taus"], ad, "o-", ms=3, label=CHANNELS[c])
        f = a["fit"]
        tt = a["taus"]
        if f["N"] > 0:
            ax.loglog(tt, f["N"] / np.sqrt(tt), "k--", lw=1, label=f"N = {f['N']:.3g} rad/sqrt(s) (slope -1/2)")
        if f["B"] > 0:
            ax.loglog(tt, np.full_like(tt, 0.664 * f["B"]), "k:", lw=1, label=f"B = {f['B']:.3g} rad/s (flat)")
        if f["K"] > 0:
            ax.loglog(tt, f["K"] * np.sqrt(tt / 3.0), "k-.", lw=1, label=f"K = {f['K']:.3g} rad/s/sqrt(s) (slope +1/2)")
        ax.set_xlabel("tau [s]")
        ax.set_ylabel("Allan deviation [rad/s]")
        ax.set_title(f"Allan deviation: {a['series']}", fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
        p = os.path.join(out, "allan.png")
        fig.tight_layout()
        fig.savefig(p, dpi=110)
        plt.close(fig)
        written.append(p)
    def before_after(tt, before, after, labels, ylabel, name, lw=None):
        fig, ax = plt.subplots(figsize=(6, 3.5))
        ax.plot(tt - tt[0], before, lw=lw, label=labels[0])
        ax.plot(tt - tt[0], after, lw=lw, label=labels[1])
        ax.set_xlabel("t [s]")
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        p = os.path.join(out, name)
        fig.tight_layout()
        fig.savefig(p, dpi=110)
        plt.close(fig)
        written.append(p)

    if "attitude" in plots:
        tt, eb, ea = plots["attitude"]
        before_after(tt, np.degrees(eb), np.degrees(ea), ("gyro as measured", "after corrections"),
                     "attitude error [deg]", "attitude_error.png")
    if "array" in plots:
        tt, rb, ra = plots["array"]
        before_after(tt, rb, ra, ("given positions", "corrected positions"), "rigidity residual [m/s^2]",
                     "array_residual.png", lw=0.5)
    return written
