"""Figures of the report pages: matplotlib drawn to inline SVG (text as text, no external
references), from the report's JSON only.

Every axis carries its unit, every figure with more than one trace a legend, an interval is a band.
Labels that come from input files are passed as plain text (math parsing off), and the SVG writer
escapes them as XML text.
"""

from __future__ import annotations

import io
import itertools
import re

import numpy as np

__all__ = ["svg", "time_figure", "interval_figure", "forest_figure", "bar_figure", "spectrum_figure"]

_COUNTER = itertools.count()
MODEL_C, EXT_C, MEAS_C, REF_C = "#c0392b", "#1f77b4", "#111111", "#2ca02c"


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _rc():
    return {"svg.fonttype": "none", "text.parse_math": False, "font.size": 9, "axes.grid": True,
            "grid.alpha": 0.3, "svg.hashsalt": f"jaxdrift-fig-{next(_COUNTER)}"}


def figure(nrows=1, ncols=1, height=2.6, width=8.5, **kw):
    plt = _plt()
    with plt.rc_context(_rc()):
        fig, axes = plt.subplots(nrows, ncols, figsize=(width, height * nrows), squeeze=False, **kw)
    return fig, axes


def svg(fig, alt: str = "") -> str:
    """The figure as an inline ``<svg>`` element (XML prolog and DOCTYPE removed)."""
    plt = _plt()
    buf = io.StringIO()
    with plt.rc_context(_rc()):
        fig.tight_layout()
        fig.savefig(buf, format="svg")
    plt.close(fig)
    text = buf.getvalue()
    text = text[text.index("<svg"):]
    text = re.sub(r"<metadata>.*?</metadata>", "", text, flags=re.S)
    # scale with the page: the viewBox stays, width/height become relative
    text = re.sub(r'<svg([^>]*?) width="[^"]*" height="[^"]*"', r'<svg\1 width="100%"', text, count=1)
    return text.replace("<svg", f'<svg role="img" aria-label="{_attr(alt)}"', 1)


def _attr(s: str) -> str:
    import html

    return html.escape(str(s), quote=True)


def _plain_log(ax, axis: str = "y") -> None:
    """Log-axis tick labels as plain text (the default ones are mathtext, which is off here)."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    a = ax.yaxis if axis == "y" else ax.xaxis
    a.set_major_formatter(FuncFormatter(lambda v, _: f"{v:.3g}"))
    a.set_minor_formatter(NullFormatter())


def report_markers(report: dict) -> list:
    """Gaps and segment starts; gyro and estimator switches, attitude resets (the first 50 events)."""
    ev = [e for e in ((report.get("run") or {}).get("events") or [])[:50]
          if isinstance(e, dict) and isinstance(e.get("t"), (int, float))]
    return list(((report.get("series_preview") or {}).get("markers")) or []) + [
        {"t": float(e["t"]), "label": str(e.get("kind", "event")).replace("_", " "), "kind": e.get("kind")} for e in ev]


#: line colours of the events a log names (others: purple)
_EVENT_C = {"gyro_switch": "#c0392b", "estimator_switch": "#e67e22", "attitude_reset": "#2c3e50"}


def _markers(ax, markers, t0=0.0):
    spans = False
    labelled = set()
    for m in markers or []:
        if "t_end" in m and m["t_end"] > m["t"]:
            ax.axvspan(m["t"] - t0, m["t_end"] - t0, color="#f39c12", alpha=0.25, lw=0,
                       label=None if spans else "gap (no data)")
            spans = True
        else:
            label = str(m.get("label", "marker"))
            ax.axvline(m["t"] - t0, color=_EVENT_C.get(m.get("kind"), "#8e44ad"), lw=0.8, ls="--",
                       label=None if label in labelled else label)
            labelled.add(label)


def time_figure(panels, markers=(), title: str = "", clip_to: str | None = None, t0: float = 0.0,
                height: float = 2.4) -> str:
    """``panels``: list of (ylabel with unit, [(trace dict, colour, width), ...]). ``clip_to``: a
    trace label whose range (x3) bounds the y axis (a diverging simulation would hide it)."""
    fig, axes = figure(len(panels), 1, height=height, sharex=True)
    for ax, (ylabel, traces) in zip(axes[:, 0], panels):
        lim = None
        for tr, colour, lw in traces:
            t = np.asarray(tr["t"], float) - t0
            ax.plot(t, tr["y"], color=colour, lw=lw, label=tr.get("label"))
            if clip_to and tr.get("label", "").endswith(clip_to) and len(tr["y"]):
                y = np.asarray(tr["y"], float)
                mid, half = 0.5 * (y.max() + y.min()), 0.5 * (y.max() - y.min())
                half = max(half, 1e-9, 0.05 * abs(mid))
                lim = (mid - 3 * half, mid + 3 * half)
        if lim is not None:
            ax.set_ylim(*lim)
        _markers(ax, markers, t0)
        ax.set_ylabel(ylabel)
        if len(ax.get_legend_handles_labels()[0]) > 0:
            ax.legend(loc="upper left", fontsize=7, framealpha=0.85)
    axes[-1, 0].set_xlabel("t [s]")
    if title:
        axes[0, 0].set_title(title, fontsize=9)
    return svg(fig, title)


def interval_figure(estimate, interval, unit: str, reference: float | None, label: str,
                    extra: list[tuple[str, float]] = ()) -> str:
    """One estimate as a point, its interval as a band, the model's value (reference) as a line and
    other values (e.g. an onboard estimator's) as marks."""
    fig, axes = figure(1, 1, height=1.15, width=7.0)
    ax = axes[0, 0]
    lo, hi = interval
    ax.axvspan(lo, hi, color=EXT_C, alpha=0.25, label="interval")
    ax.plot([estimate], [0], "o", color=EXT_C, label="estimate")
    xs = [lo, hi, estimate]
    if reference is not None:
        ax.axvline(reference, color="0.3", lw=1, ls="--", label=f"no error ({reference:g})")
        xs.append(reference)
    for (name, v), m in zip(extra, "sD^v"):
        ax.plot([v], [0], m, color=MODEL_C, label=name)
        xs.append(v)
    span = max(xs) - min(xs) or abs(estimate) or 1.0
    ax.set_xlim(min(xs) - 0.15 * span, max(xs) + 0.15 * span)
    ax.set_yticks([])
    ax.set_xlabel(f"{label} [{unit}]")
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=7)
    ax.grid(True, axis="x", alpha=0.3)
    return svg(fig, label)


def forest_figure(parameter: str, rows, joint=None, unit: str = "ratio", reference: float | None = 1.0) -> str:
    """``rows``: [(run name, estimate, (lo, hi))]; ``joint``: (estimate, (lo, hi)) as a band."""
    fig, axes = figure(1, 1, height=0.6 + 0.32 * max(len(rows), 1), width=7.5)
    ax = axes[0, 0]
    if joint is not None:
        est, (lo, hi) = joint
        ax.axvspan(lo, hi, color=EXT_C, alpha=0.25, label="joint interval")
        ax.axvline(est, color=EXT_C, lw=1.2, label=f"joint estimate {est:.6g}")
    if reference is not None:
        ax.axvline(reference, color="0.3", lw=1, ls="--", label="model as given")
    for i, (name, est, iv) in enumerate(rows):
        y = len(rows) - 1 - i
        if iv is not None:
            ax.plot(iv, [y, y], color=MEAS_C, lw=2)
        ax.plot([est], [y], "s", color=MEAS_C, ms=4, label="run's own estimate, interval" if i == 0 else None)
    ax.set_yticks(range(len(rows)), [r[0] for r in rows][::-1])
    ax.set_xlabel(f"{parameter} [{unit}]")
    ax.set_ylim(-0.8, len(rows) - 0.2)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    return svg(fig, f"forest plot of {parameter}")


def bar_figure(categories, series, ylabel: str, title: str = "", log: bool = False) -> str:
    """Grouped bars; ``series``: [(label, values, (lower, upper) error arrays or None)]."""
    fig, axes = figure(1, 1, height=2.8, width=8.0)
    ax = axes[0, 0]
    n = max(len(series), 1)
    x = np.arange(len(categories))
    w = 0.8 / n
    for k, (label, vals, err) in enumerate(series):
        vals = np.asarray(vals, float)
        yerr = None
        if err is not None:
            lo, hi = (np.asarray(e, float) for e in err)
            yerr = np.vstack([np.clip(vals - lo, 0, None), np.clip(hi - vals, 0, None)])
        ax.bar(x + (k - (n - 1) / 2) * w, vals, w, yerr=yerr, capsize=2, label=label)
    ax.set_xticks(x, categories, rotation=20 if len(categories) > 4 else 0, ha="right" if len(categories) > 4 else "center")
    ax.set_ylabel(ylabel)
    if log:
        ax.set_yscale("log")
        _plain_log(ax)
    if title:
        ax.set_title(title, fontsize=9)
    if len(series) > 1 or any(s[2] is not None for s in series):
        ax.legend(fontsize=7)
    return svg(fig, title or ylabel)


def spectrum_figure(spectra: dict, title: str = "") -> str:
    fig, axes = figure(1, 1, height=3.0)
    ax = axes[0, 0]
    unit = ""
    for name, s in spectra.items():
        ax.loglog(s["f"], np.maximum(np.asarray(s["y"], float), 1e-300), lw=0.9, label=s.get("label", name))
        unit = s.get("unit", unit)
    _plain_log(ax, "x")
    _plain_log(ax, "y")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"power spectral density [{unit}]")
    ax.legend(fontsize=7)
    if title:
        ax.set_title(title, fontsize=9)
    return svg(fig, title or "spectrum")
