"""What a log says besides the rates: the flight controller's own bias estimate, and sensor switches.

- :func:`onboard_block`: where the log carries the flight controller's gyro-bias estimate (PX4
  ``estimator_sensor_bias``, read by :func:`jaxdrift.io._logs.ulog_context`), the report's
  ``onboard_bias`` sets it beside jaxdrift's estimate on every axis, named or not, and says where
  the two agree; each ``gyro_bias`` finding carries it as ``onboard``. The onboard value is the
  median of the estimator's samples over the last half of the span (an estimator converges from
  zero after boot), its spread the range of those samples.
- :func:`sensor_parts`: a log whose primary gyro changes (``gyro_switch`` events) holds two or more
  sensors, each with its own bias: the run is cut at every switch (switches closer than
  :data:`SWITCH_CLUSTER_S` count as one, and the rows between them are left out) into parts of at
  least :data:`MIN_PART_S`, each diagnosed on its own; :func:`merge_parts` writes one report
  whose findings name their part.
"""

from __future__ import annotations

import math

import numpy as np

from ...io._timebase import run_block
from ._common import CHANNELS, fmt

__all__ = ["onboard_block", "sensor_parts", "slice_run", "merge_parts", "SWITCH_CLUSTER_S", "MIN_PART_S",
           "AGREE_REL"]

#: switches closer than this [s] are one switch (PX4 may toggle between gyros for a few ms)
SWITCH_CLUSTER_S = 0.5
#: a part between switches shorter than this [s] is left out (named in the report)
MIN_PART_S = 1.0
#: the onboard estimate agrees when it lies in jaxdrift's interval or within this share of it
AGREE_REL = 0.25


def onboard_block(report, run, bias_fit, span):
    """The report with the flight controller's bias estimate set beside jaxdrift's (see the module
    docstring): a new dict, the report given where the log has no estimate."""
    ob = run.get("onboard_bias")
    if ob is None:
        return report
    t, b = ob["t"], ob["b"]
    inside = (t >= span[0]) & (t <= span[1])
    late = inside & (t >= 0.5 * (span[0] + span[1]))
    use = late if late.sum() >= 2 else inside
    if not use.any():
        return {**report, "onboard_bias": {"topic": ob["topic"], "axes": [],
                                           "note": "no onboard estimate inside the analysed span"}}
    axes = []
    for c, ch in enumerate(CHANNELS):
        v = b[use, c]
        on = float(np.median(v))
        entry = {"channel": ch, "onboard": on, "onboard_range": [float(v.min()), float(v.max())],
                 "jaxdrift": None, "interval": None, "agree": None}
        if ch in bias_fit:
            est, half = bias_fit[ch]
            entry["jaxdrift"], entry["interval"] = est, [est - half, est + half]
            tol = max(half, AGREE_REL * abs(est), float(v.max() - v.min()) / 2.0)
            entry["agree"] = bool(abs(on - est) <= tol)
        axes.append(entry)
    agree = [a["channel"] for a in axes if a["agree"]]
    differ = [a["channel"] for a in axes if a["agree"] is False]
    block = {
        "topic": ob["topic"], "samples": int(use.sum()), "device_ids": ob.get("device_ids", []),
        "span_s": [float(t[use][0]), float(t[use][-1])], "axes": axes,
        "summary": (f"the flight controller's own estimate agrees on {', '.join(agree) or 'no axis'}"
                    + (f" and differs on {', '.join(differ)}" if differ else "")),
    }
    by_ch = {a["channel"]: a for a in axes}
    findings = [{**f, "onboard": {"estimate": by_ch[f["channel"]]["onboard"], "range": by_ch[f["channel"]]["onboard_range"],
                                  "agree": by_ch[f["channel"]]["agree"]}}
                if f.get("cause") == "gyro_bias" and f.get("channel") in by_ch else f for f in report["findings"]]
    return {**report, "findings": findings, "onboard_bias": block}


def sensor_parts(run):
    """``(parts, dropped)``: parts ``[(i0, i1, label)]`` between the primary gyro's switches, or
    ``(None, [])`` where the log names no switch inside the run."""
    t = run["t"]
    sw = sorted(e["t"] for e in (run.get("events") or []) if e["kind"] == "gyro_switch" and t[0] < e["t"] < t[-1])
    if not sw:
        return None, []
    clusters = [[sw[0], sw[0]]]
    for x in sw[1:]:
        if x - clusters[-1][1] <= SWITCH_CLUSTER_S:
            clusters[-1][1] = x
        else:
            clusters.append([x, x])
    details = {e["t"]: e["detail"] for e in run["events"] if e["kind"] == "gyro_switch"}
    edges = [(float(t[0]), "the gyro in use at the start")]
    for a, b in clusters:
        edges.append((a, None))
        edges.append((b, f"after the switch at {fmt(b)} s ({details.get(b, '')})"))
    edges.append((float(t[-1]) + run["dt"], None))
    parts, dropped = [], []
    for (ta, label), (tb, _) in zip(edges[0::2], edges[1::2]):
        i0, i1 = int(np.searchsorted(t, ta, side="left")), int(np.searchsorted(t, tb, side="left"))
        if ta > t[0]:
            i0 = int(np.searchsorted(t, ta, side="right"))
        if (i1 - i0) * run["dt"] >= MIN_PART_S:
            parts.append((i0, i1, label))
        elif i1 > i0:
            dropped.append([float(t[i0]), float(t[i1 - 1])])
    return parts, dropped


def slice_run(run, i0, i1):
    """The rows ``[i0, i1)`` of an attitude run dict as a run of its own (time base re-based)."""
    out = dict(run)
    for k in ("t", "w", "q_ref", "acc"):
        if run.get(k) is not None:
            out[k] = run[k][i0:i1]
    t0, t1 = float(run["t"][i0]) - 0.5 * run["dt"], float(run["t"][i1 - 1]) + 0.5 * run["dt"]
    for kt, kv in (("q_ref_t", "q_ref_q"), ("w_recorded_t", "w_recorded")):
        if run.get(kt) is not None:
            m = (run[kt] >= t0) & (run[kt] <= t1)
            out[kt], out[kv] = run[kt][m], run[kv][m]
    tb = dict(run.get("time_base") or {})
    segs = [[max(a, i0) - i0, min(b, i1) - i0] for a, b in tb.get("segments") or [[0, len(run["t"])]]
            if min(b, i1) - max(a, i0) >= 2]
    tb["segments"] = segs or [[0, i1 - i0]]
    tb["gaps"] = [g for g in tb.get("gaps", []) if t0 <= g["t_start"] <= t1]
    out["time_base"] = tb
    return out


def merge_parts(done, run, dropped):
    """One report from the reports of a log's parts (one per gyro): every finding names its part
    (``part``: index, span, which gyro); ``parts`` lists each part's gain; the overall gain is the
    row-weighted RMS of the parts'. The first part's figures."""
    base = done[0][0]
    findings, not_det, obs = [], [], {"used": [], "not_observed": [], "notes": []}
    parts = []
    for k, (rep, _, label, span) in enumerate(done):
        tag = {"index": k, "span_s": list(span), "sensor": label}
        for f in rep["findings"]:
            findings.append({**f, "part": tag})
        not_det += [{**d, "part": tag} for d in rep["not_determined"]]
        for key in obs:
            obs[key] += [f"part {k} ({fmt(span[0])}..{fmt(span[1])} s): {x}" for x in rep["observability"][key]]
        parts.append({**tag, "gain": rep["gain"], "rows": rep["run"]["rows"],
                      "onboard_bias": rep.get("onboard_bias"), "extended_model": rep["extended_model"]})
    switches = [e for e in run.get("events") or [] if e["kind"] == "gyro_switch"]
    obs["notes"].insert(0, f"the primary gyro switches {len(switches)} time(s) "
                           f"({', '.join(fmt(e['t']) + ' s' for e in switches[:6])}): the log is diagnosed as "
                           f"{len(done)} part(s), each its own sensor"
                        + (f"; left out (shorter than {fmt(MIN_PART_S)} s): "
                           + ", ".join(f"{fmt(a)}..{fmt(b)} s" for a, b in dropped) if dropped else ""))
    gains = [p["gain"] for p in parts]
    gain = {"metric": None, "before": None, "after": None}
    if all(g.get("metric") == gains[0].get("metric") and g.get("before") is not None for g in gains):
        rows = np.array([p["rows"] for p in parts], float)
        rms = lambda key: float(math.sqrt(np.sum(rows * np.square([g[key] for g in gains])) / rows.sum()))  # noqa: E731
        gain = {**gains[0], "before": rms("before"), "after": rms("after")}
    report = dict(base)
    report.update({
        "findings": findings, "not_determined": not_det, "observability": obs, "gain": gain,
        "parts": parts,
        "extended_model": parts[max(range(len(parts)), key=lambda i: parts[i]["rows"])]["extended_model"],
    })
    report.pop("onboard_bias", None)
    report["run"] = {**base["run"], "rows": int(len(run["t"])), "duration_s": float(run["t"][-1] - run["t"][0]),
                     "reference_rows": int(sum(rep["run"]["reference_rows"] for rep, *_ in done)),
                     "time_base": run_block(run.get("time_base")),
                     "events": run.get("events") or []}
    return report, done[0][1]
