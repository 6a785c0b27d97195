"""Outputs of the durability analysis: ``durability.json``, ``section_forces.csv`` and figures,
written atomically into a folder.

Everything is computed and rendered in memory before the first byte is written, so bad input or a
failed analysis leaves the folder untouched. The files then go through the I/O layer's
:func:`jaxdrift.io._outputs.atomic_dir` (the writer every command uses): written into a temporary
folder beside the target, renamed in one by one, with a manifest of SHA-256 sums written last.
"""

from __future__ import annotations

import io
import json
import os

import numpy as np

from ..io._outputs import atomic_dir, finite_json

__all__ = ["write_outputs", "csv_columns", "OUTPUT_FILES"]

OUTPUT_FILES = ("durability.json", "section_forces.csv", "section_forces.png", "rainflow_histogram.png",
                "damage_ratio.png")
COLORS = {"force_driven": "tab:red", "pitch_spring": "tab:orange", "stabilised": "tab:blue",
          "extended": "tab:green", "measured": "black"}


def csv_columns(res) -> dict:
    """{name: (n,) array} of ``section_forces.csv``: ``t``, ``<variant>_f3``, ``<variant>_f4``, the
    pitch spring's reaction torque and the enforced moments."""
    cols = {"t": res.t}
    for v, F in res.forces.items():
        cols[f"{v}_f3"], cols[f"{v}_f4"] = F[:, 0], F[:, 1]
    cols["pitch_spring_torque"] = res.pitch_spring_torque
    for v, m in res.enforced_moment.items():
        cols[f"{v}_enforced_moment"] = m
    return cols


def _csv_bytes(cols: dict) -> bytes:
    buf = io.StringIO()
    data = np.column_stack([np.asarray(c, float) for c in cols.values()])
    np.savetxt(buf, data, delimiter=",", header=",".join(cols), comments="", fmt="%.10g")
    return buf.getvalue().encode()


def _window(res, window):
    t = res.t
    if window is not None:
        return float(window[0]), float(window[1])
    ref = res.forces.get("stabilised", next(iter(res.forces.values())))[:, 0]
    i = int(np.nanargmax(np.abs(ref - np.nanmean(ref))))
    half = min(1.0, 0.5 * (t[-1] - t[0]))
    lo = max(t[0], t[i] - half)
    return lo, min(t[-1], lo + 2 * half)


def _fig_forces(plt, res, window):
    lo, hi = _window(res, window)
    fig, axes = plt.subplots(2, 2, figsize=(13, 7), gridspec_kw={"width_ratios": [2, 1]}, sharey="row")
    sel = (res.t >= lo) & (res.t <= hi)
    for j, f in enumerate(("f3", "f4")):
        for v, F in res.forces.items():
            if not np.all(np.isfinite(F[:, j])):
                continue
            for ax, m in ((axes[j, 0], slice(None)), (axes[j, 1], sel)):
                ax.plot(res.t[m], F[m, j] / 1e3, lw=0.7 if ax is axes[j, 0] else 1.0, color=COLORS[v], label=v)
        axes[j, 0].axvspan(lo, hi, color="0.85", zorder=0)
        axes[j, 0].set_ylabel(f"{f} [kN]")
        axes[j, 1].set_xlim(lo, hi)
    axes[0, 0].set_title("section forces, whole run (grey: the window on the right)")
    axes[0, 1].set_title(f"window {lo:.2f}-{hi:.2f} s")
    axes[0, 0].legend(fontsize=8, ncol=3)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    fig.tight_layout()
    return fig


def _fig_hist(plt, res):
    edges = res.histogram_edges
    centers = 0.5 * (edges[1:] + edges[:-1])
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    hist = res.summary["range_histogram"]["cycles"]
    for j, f in enumerate(("f3", "f4")):
        ax = axes[j]
        for v, h in hist.items():
            if f in h:
                y = np.asarray(h[f], float)
                ax.step(centers / 1e3, np.where(y > 0, y, np.nan), where="mid", color=COLORS[v], label=v,
                        lw=1.0)  # empty bins left blank on the log axis
        ax.set_yscale("log")
        ax.set_xlabel(f"rainflow range of {f} [kN]")
        ax.set_title(f"{f}: cycles per range bin (ASTM E1049-85 rainflow)")
    axes[0].set_ylabel("cycles")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    return fig


def _fig_ratio(plt, res):
    s = res.summary
    fig, ax = plt.subplots(figsize=(8, 4.5))
    by_force = s.get("damage_ratio_to_stabilised_by_force", {})
    mc = res.mc_damage
    names = list(by_force)
    for i, v in enumerate(names):
        for j, f in enumerate(("f3", "f4")):
            x = i + (j - 0.5) * 0.25
            r = by_force[v][f]
            if r is None:
                continue
            ax.plot(x, r, "o", color=COLORS[v], mfc="white" if j else COLORS[v], ms=8,
                    label=f"{f} nominal" if i == 0 else None)
            if mc is not None and v in mc and "stabilised" in mc:
                q = np.nanquantile(mc[v][:, j] / mc["stabilised"][:, j], [0.05, 0.5, 0.95])
                ax.errorbar(x, q[1], yerr=[[q[1] - q[0]], [q[2] - q[1]]], fmt="_", color=COLORS[v], capsize=5,
                            label="noise band 5-95 % (median)" if i == 0 and j == 0 else None)
    ax.axhline(1.0, color="0.5", lw=0.8)
    ax.set_xticks(range(len(names)), names)
    ax.set_ylabel("pseudo-damage / stabilised")
    k = s["basquin_k"]
    mcs = s["monte_carlo"]
    ax.set_title(f"damage ratio to the stabilised simulation (K = {k:g}); band: {mcs['paths']} draws of "
                 f"{mcs['noise_N']:.3g} N force noise", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def _png(plt, fig, dpi) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    return buf.getvalue()


def write_outputs(res, out_dir, *, window=None, dpi: int = 100, figures: bool = True,
                  option: str = "--out") -> list[str]:
    """Write the outputs of a :class:`DurabilityResult` into ``out_dir`` (created if missing).

    All files are rendered in memory first; only then are they written, each atomically. Returns
    the paths written.
    """
    blobs = {"durability.json": (json.dumps(finite_json(res.summary), indent=1, allow_nan=False) + "\n").encode(),
             "section_forces.csv": _csv_bytes(csv_columns(res))}
    if figures:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        blobs["section_forces.png"] = _png(plt, _fig_forces(plt, res, window), dpi)
        blobs["rainflow_histogram.png"] = _png(plt, _fig_hist(plt, res), dpi)
        if res.summary.get("damage_ratio_to_stabilised_by_force"):
            blobs["damage_ratio.png"] = _png(plt, _fig_ratio(plt, res), dpi)
    with atomic_dir(out_dir, option) as tmp:
        for name, data in blobs.items():
            with open(os.path.join(tmp, name), "wb") as fh:
                fh.write(data)
    written = [os.path.join(out_dir, name) for name in blobs]
    return written
