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


def assemble_report(d):
    """The report dict (docs/measured-data.md, kind "attitude") from the records of one sensor's run
    (:class:`._records.Diagnosis`). The findings are copies: the report's own."""
    comp, said, run = d.comparison, d.said, d.run
    t, dt = run["t"], run["dt"]
    n = len(t)
    T = t[-1] - t[0]
    allan = d.allan
    ranked = [dict(f) for f, _ in sorted(comp.findings, key=lambda fz: -fz[1])]
    if d.noise.finding is not None:
        ranked.append(dict(d.noise.finding))
    if d.vibration is not None:
        ranked.append(dict(d.vibration.finding))
    ranked.extend(dict(f) for f in comp.noise_findings)
    ranked = joint_intervals(ranked)
    if not ranked:
        ranked = [{"cause": "none", "estimate": None, "unit": None, "interval": None,
                   "evidence": "no systematic effect and no white noise above the file's rounding"}]
    report = {
        "schema": SCHEMA,
        "kind": "attitude",
        "simulation_error": comp.sim_err,
        "findings": ranked,
        "extended_model": {"corrections": corrections_json(comp.model.corrections)},
        "gain": comp.gain if comp.gain is not None else {"metric": None, "before": None, "after": None},
        "observability": {"used": list(said.observed), "not_observed": list(said.not_observed),
                          "notes": list(said.notes)},
        "not_determined": list(said.not_determined),
        "allan": None if allan is None else {
            "series": allan["series"], "N": allan["fit"]["N"], "B": allan["fit"]["B"], "K": allan["fit"]["K"],
            "units": {"N": "rad/sqrt(s)", "B": "rad/s", "K": "rad/s/sqrt(s)"},
        },
        "run": {"rows": int(n), "dt": float(dt), "duration_s": float(T), "reference_rows": d.n_ref,
                "sensors": 0 if d.positions is None else int(d.positions.shape[0]),
                "time_base": run_block(run.get("time_base")),
                "reference_alignment": d.alignment},
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
