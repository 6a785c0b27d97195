"""The series behind a page's figures (a report's ``series_preview``, :mod:`._preview`) as
``time_figure`` panels: traces grouped, coloured by what they are (measured, model as given,
extended), the time origin."""

from __future__ import annotations

from . import _figures as F

__all__ = ["group_panel", "series_traces", "series_t0", "NO_SERIES"]


def series_traces(report: dict) -> dict:
    return ((report.get("series_preview") or {}).get("traces")) or {}


def series_t0(report: dict) -> float:
    ts = [tr["t"][0] for tr in series_traces(report).values() if tr.get("t")]
    return min(ts) if ts else 0.0


_COLOURS = {"measured": F.MEAS_C, "model": F.MODEL_C, "extended": F.EXT_C, "corrected": F.EXT_C,
            "gyro": F.MEAS_C, "reference": F.REF_C, "before": F.MODEL_C, "after": F.EXT_C}


def _colour(name: str, k: int):
    name = name.removesuffix("_zoom")  # a zoom's traces keep their colours
    for suffix, c in _COLOURS.items():
        if name.endswith(suffix):
            return c
    return f"C{k % 10}"


def group_panel(report: dict, group: str, ylabel: str | None = None):
    tr = {k: v for k, v in series_traces(report).items() if v.get("group") == group}
    if not tr:
        return None
    unit = next(iter(tr.values())).get("unit", "")
    lw = {"measured": 1.1, "gyro": 0.8}
    return (ylabel or f"{group} [{unit}]",
            [(v, _colour(k, j), next((w for s, w in lw.items() if k.endswith(s)), 0.8)) for j, (k, v) in enumerate(tr.items())])


NO_SERIES = ("<p class=muted>This report has no <span class=mono>series_preview</span> block, so no time series "
             "can be drawn (reports written with <span class=mono>--html</span> carry one).</p>")
