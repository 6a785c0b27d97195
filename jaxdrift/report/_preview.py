"""``series_preview``: the signals behind a report, decimated for display, stored in the report.

The HTML page (:mod:`jaxdrift.report._html`) is built from a report's JSON alone; a report that
should show time series carries them in a compact block under the top-level key
``series_preview`` (additive: no other key changes)::

    {"schema": "jaxdrift.series_preview/1", "method": "min/max per bin", "bins": 1000,
     "traces": {NAME: {"t": [...], "y": [...], "unit": "rad", "label": "...", "group": "..."}},
     "markers": [{"t": 12.3, "t_end": 12.4, "label": "gap"}, ...],
     "spectra": {NAME: {"f": [...], "y": [...], "unit": "(rad/s)^2/Hz", "label": "..."}}}

Each trace keeps, per bin of equal time, the sample with the smallest and the one with the largest
value, in time order (about 2 x ``bins`` points): a peak one sample wide is still drawn, which
plain subsampling would lose. Values are rounded to 6 significant digits.
"""

from __future__ import annotations

import math

import numpy as np

from ..io._timebase import longest_run

__all__ = ["minmax_decimate", "vehicle_preview", "attitude_preview", "durability_preview", "BINS"]

SCHEMA = "jaxdrift.series_preview/1"
#: bins per trace: about 2000 points, enough for a full-width figure
BINS = 1000


def minmax_decimate(t, y, bins: int = BINS) -> tuple[np.ndarray, np.ndarray]:
    """The min and the max sample of each of ``bins`` index bins, in time order (NaN dropped)."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    ok = np.isfinite(t) & np.isfinite(y)
    t, y = t[ok], y[ok]
    n = t.size
    if n <= 2 * bins:
        return t, y
    edges = np.linspace(0, n, bins + 1).astype(int)
    keep = []
    for a, b in zip(edges[:-1], edges[1:]):
        if b <= a:
            continue
        seg = y[a:b]
        i, j = a + int(np.argmin(seg)), a + int(np.argmax(seg))
        keep.extend(sorted({i, j}))
    idx = np.asarray(keep, int)
    return t[idx], y[idx]


def _r(x) -> list:
    return [float(f"{v:.6g}") for v in np.asarray(x, float)]


def _trace(t, y, unit: str, label: str, group: str, bins: int = BINS) -> dict:
    td, yd = minmax_decimate(t, y, bins)
    return {"t": _r(td), "y": _r(yd), "unit": unit, "label": label, "group": group}


def _block(traces: dict, markers=(), spectra=None, bins: int = BINS) -> dict:
    return {"schema": SCHEMA, "method": "min/max per bin", "bins": bins, "traces": traces,
            "markers": list(markers), "spectra": spectra or {}}


def _time_markers(tb: dict | None, t: np.ndarray) -> list[dict]:
    """Gaps (spans) and segment starts (lines) of a report's ``time_base`` block, on ``t``."""
    out = []
    if not tb:
        return out
    for g in tb.get("gaps") or []:
        if isinstance(g, dict) and "t_start" in g:
            out.append({"t": float(g["t_start"]), "t_end": float(g.get("t_end", g["t_start"])), "label": "gap"})
    segs = tb.get("segments") or []
    for s in segs[1:]:
        try:
            i = int(s[0])
        except (TypeError, ValueError, IndexError):
            continue
        if 0 <= i < t.size:
            out.append({"t": float(t[i]), "label": "segment start"})
    return out


# ----------------------------------------------------------------------------- vehicle


def vehicle_preview(run, model: dict, report: dict, bins: int = BINS) -> dict:
    """Measured against simulated pitch and heave (model as given and extended), the forces as
    measured and corrected, and each residual channel before/after the extension."""
    from ..diagnosis import vehicle_series
    from ..diagnosis.vehicle import ResidualPipeline
    from ..io._corrections import NO_CORRECTION, Corrections

    t = np.asarray(run.t, float)
    traces = {}
    cols = vehicle_series(run, model, report)
    for c, unit, scale in (("beta", "deg", 180 / np.pi), ("z3", "m", 1.0)):
        if run.has(c):
            traces[f"{c}_measured"] = _trace(t, cols[c] * scale, unit, f"{c} measured", c, bins)
            traces[f"{c}_model"] = _trace(t, cols[f"sim_{c}"] * scale, unit, f"{c} simulated, model as given", c, bins)
            traces[f"{c}_extended"] = _trace(t, cols[f"ext_{c}"] * scale, unit, f"{c} simulated, extended model", c, bins)
    for ch in ("f1", "f2"):
        traces[f"{ch}_measured"] = _trace(t, cols[ch], "N", f"{ch} measured", ch, bins)
        if not np.allclose(cols[f"{ch}_corrected"], cols[ch]):
            traces[f"{ch}_corrected"] = _trace(t, cols[f"{ch}_corrected"], "N", f"{ch} corrected", ch, bins)
    ext = report.get("extended_model") or {}
    corr = Corrections.from_json(ext.get("corrections"))
    # the forces as the diagnosis compared them (a clipped channel's bursts restored), each residual
    # channel in the band it was compared in (sensor noise on the motion: ``_problem.choose_bands``)
    pipe = ResidualPipeline(run.with_channels(corr.restore(run.t, {ch: run[ch] for ch in ("f1", "f2")})))
    bands = compared_bands(report, pipe.h)
    if bands:
        import scipy.signal

        pipe = pipe.with_band({nm: (fc, scipy.signal.butter(8, fc, fs=1.0 / pipe.h, output="sos"))
                               for nm, fc in bands.items()})
    r0 = pipe.residuals(model, NO_CORRECTION).channels
    r1 = pipe.residuals(ext.get("parameters", model), corr).channels
    units = {"moment": "N m", "heave": "N"}
    offset = {"moment": 1, "heave": 1}
    for nm, x0 in r0.items():
        if nm == "static" or nm not in r1:
            continue
        x0 = np.asarray(x0, float)
        x1 = np.asarray(r1[nm], float)
        # the rows the diagnosis kept: a band-limited channel's first 1.5 / fc s carry its filter's
        # start (``_problem._Problem``), and the last ``trim`` samples are room for delays
        off = offset.get(nm, 0)
        m = min(x0.size, x1.size, t.size - off, pipe.n - pipe.trim - off)
        skip = min(int(math.ceil(1.5 / (bands[nm] * pipe.h))), m // 4) if nm in bands else 0
        x0, x1, tt = x0[skip:m], x1[skip:m], t[off + skip:off + m]
        unit = units.get(nm, "N")
        band = [0.0, bands[nm]] if nm in bands else None
        where = f" below {band[1]:.3g} Hz" if nm in bands else ""
        traces.update(_residual_traces(nm, tt, x0, x1, unit, where, band if nm in bands else None, bins))
    tb = (report.get("run") or {}).get("time_base")
    return _block(traces, _time_markers(tb, t), None, bins)


def compared_bands(report: dict, h: float) -> dict:
    """``{residual channel: cutoff Hz}`` of the channels the diagnosis compared low-passed, read
    from the report (each finding's ``residual.band_hz``, the gain's ``band_hz``); a band reaching
    the Nyquist frequency of the step ``h`` is the full band, left out."""
    out = {}
    items = [(f.get("residual") or {}) for f in report.get("findings") or [] if isinstance(f, dict)]
    g = report.get("gain") or {}
    main = {"enforced_moment_rms": "moment", "vertical_enforced_force_rms": "heave"}.get(g.get("metric"))
    if main and g.get("band_hz"):
        items.append({"channel": main, "band_hz": g["band_hz"]})
    for r in items:
        b = r.get("band_hz")
        if r.get("channel") and isinstance(b, (list, tuple)) and len(b) == 2 and 0 < float(b[1]) < 0.5 / h * (1 - 1e-9):
            out[r["channel"]] = float(b[1])
    return out


#: the zoom on a residual's worst stretch: this long [s], or this share of the run where shorter
ZOOM_S, ZOOM_SHARE = 2.0, 0.1


def _residual_traces(nm, t, x0, x1, unit, where, band, bins) -> dict:
    """A residual channel before and after the extension: the whole run (its envelope, min/max per
    bin) and a zoom at full resolution on the stretch where it was largest before (``ZOOM_S``).
    Each trace records the band it was compared in (``band_hz``, None: the full band) and the RMS of
    what it plots (undecimated)."""
    rms = lambda x: float(np.sqrt(np.mean(np.square(x)))) if len(x) else 0.0  # noqa: E731
    out = {}
    for key, x, what in (("model", x0, "model as given"), ("extended", x1, "extended model")):
        tr = _trace(t, x, unit, f"{nm} residual{where}, {what}", f"residual_{nm}", bins)
        out[f"residual_{nm}_{key}"] = {**tr, "band_hz": band, "rms": rms(x)}
    n = len(t)
    if n > 10:
        dt = float((t[-1] - t[0]) / (n - 1))
        w = max(2, min(int(round(ZOOM_S / dt)), int(ZOOM_SHARE * n)))
        c = np.concatenate([[0.0], np.cumsum(np.square(x0))])
        i = int(np.argmax(c[w:] - c[:-w]))
        for key, x, what in (("model", x0, "model as given"), ("extended", x1, "extended model")):
            tr = _trace(t[i:i + w], x[i:i + w], unit, f"{nm} residual{where}, {what} (worst stretch)",
                        f"residual_{nm}_zoom", bins)
            out[f"residual_{nm}_{key}_zoom"] = {**tr, "band_hz": band, "rms": rms(x[i:i + w])}
    return out


# ----------------------------------------------------------------------------- attitude


def _reference_rates(tq, q) -> tuple[np.ndarray, np.ndarray]:
    """Body rates [rad/s] from a reference quaternion series (w, x, y, z; body to world,
    q' = 0.5 q (x) (0, omega)): 2 vec(conj(q_k) (x) q_k+1) / dt at the midpoints."""
    tq = np.asarray(tq, float)
    q = np.asarray(q, float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    a, b = q[:-1], q[1:]
    w0, v0 = a[:, 0], -a[:, 1:]
    w1, v1 = b[:, 0], b[:, 1:]
    dw = w0 * w1 - np.sum(v0 * v1, axis=1)
    dv = w0[:, None] * v1 + w1[:, None] * v0 + np.cross(v0, v1)
    dv = dv * np.sign(np.where(dw == 0, 1.0, dw))[:, None]
    dt = np.diff(tq)
    ok = dt > 0
    ang = 2 * np.arcsin(np.clip(np.linalg.norm(dv, axis=1), 0, 1))
    nrm = np.linalg.norm(dv, axis=1)
    axis = np.divide(dv, nrm[:, None], out=np.zeros_like(dv), where=nrm[:, None] > 0)
    rate = axis * (ang / np.where(ok, dt, 1.0))[:, None]
    tm = 0.5 * (tq[:-1] + tq[1:])
    return tm[ok], rate[ok]


def attitude_preview(run: dict, plots: dict, report: dict, bins: int = BINS) -> dict:
    """The gyro against the reference's rate per axis, the attitude error before/after the
    corrections, the gyro's spectrum per axis, and gaps and segments as markers."""
    t = np.asarray(run["t"], float)
    w = np.asarray(run["w"], float)
    traces = {}
    tq = run.get("q_ref_t")
    qq = run.get("q_ref_q")
    for i, ax in enumerate(("wx", "wy", "wz")):
        traces[f"{ax}_gyro"] = _trace(t, w[:, i], "rad/s", f"{ax} gyro", ax, bins)
    if tq is not None and qq is not None and len(tq) > 2:
        tm, rate = _reference_rates(tq, qq)
        for i, ax in enumerate(("wx", "wy", "wz")):
            traces[f"{ax}_reference"] = _trace(tm, rate[:, i], "rad/s", f"{ax} from the reference attitude", ax, bins)
    if "attitude" in plots:
        tt, eb, ea = plots["attitude"]
        traces["attitude_error_before"] = _trace(tt, np.degrees(eb), "deg", "gyro as measured", "attitude_error", bins)
        traces["attitude_error_after"] = _trace(tt, np.degrees(ea), "deg", "after the corrections", "attitude_error", bins)
    if "array" in plots:
        tt, rb, ra = plots["array"]
        traces["array_residual_before"] = _trace(tt, rb, "m/s^2", "given positions", "array_residual", bins)
        traces["array_residual_after"] = _trace(tt, ra, "m/s^2", "corrected positions", "array_residual", bins)
    spectra = {}
    dt = float(run.get("dt") or np.median(np.diff(t)))
    # on the longest stretch of finite rows (a gapped log has NaN rows between its segments)
    i0, i1 = longest_run(np.isfinite(w).all(1))
    ws = w[i0:i1]
    if ws.shape[0] >= 64 and dt > 0:
        from scipy.signal import welch

        nper = int(min(1024, 2 ** np.floor(np.log2(ws.shape[0] / 4))))
        for i, ax in enumerate(("wx", "wy", "wz")):
            f, p = welch(ws[:, i] - np.mean(ws[:, i]), fs=1.0 / dt, nperseg=max(nper, 16))
            spectra[ax] = {"f": _r(f[1:]), "y": _r(p[1:]), "unit": "(rad/s)^2/Hz", "label": f"{ax} gyro"}
    tb = (report.get("run") or {}).get("time_base") or run.get("time_base")
    return _block(traces, _time_markers(tb, t), spectra, bins)


# ----------------------------------------------------------------------------- durability


def durability_preview(res, bins: int = BINS) -> dict:
    """The section forces f3, f4 of every variant."""
    t = np.asarray(res.t, float)
    traces = {}
    for v, F in res.forces.items():
        F = np.asarray(F, float)
        for j, nm in enumerate(("f3", "f4")):
            traces[f"{v}_{nm}"] = _trace(t, F[:, j], "N", f"{nm} {v}", nm, bins)
    return _block(traces, (), None, bins)
