"""The time-base policy: one rule for every kind of run and every format (numpy and scipy; no JAX).

Real loggers jitter (0.1-5 % per step), drop samples and write channels at different rates. The
policy (docs/measured-data.md, "Time base"):

1. **Nominal rate** of a channel: from the median of its time steps (one odd step cannot move it).
   The run's grid step is the nominal step of its primary channel (``f1`` for vehicle runs, ``wx``
   for attitude runs), or ``1 / fs`` when ``--fs`` is given.
2. **Jitter**: the relative step deviation ``(step - nominal) / nominal`` over the steps that are
   not gaps; its standard deviation and largest magnitude are reported.
3. **Dropped samples and gaps**: a step longer than :data:`GAP_FACTOR` x nominal (1.5: at least
   one sample is missing; the jitter of the real logs seen is below 0.25) is a missing stretch.
   At most :data:`BRIDGE_SAMPLES` missing samples (a step shorter than ``BRIDGE_SAMPLES + 1.5``
   nominal steps: a logger that drops a sample now and then) are **bridged**: interpolated like
   any other step, and counted in ``bridged``. A longer one is a **gap**: it splits the channel
   into segments; nothing is interpolated across it, grid rows inside a gap are NaN.
4. **Resampling**: each channel is interpolated linearly (:data:`METHOD`) at the grid times inside
   its own segments. A channel whose nominal rate is more than :data:`FILTER_RATIO` times the
   grid's is first low-pass filtered: a Butterworth filter of order :data:`FILTER_ORDER`, run
   forward and backward (zero phase), cut off at :data:`FILTER_CUTOFF` times the grid's Nyquist
   frequency, per segment, on the channel's own samples taken as uniform at its nominal rate.
5. **Segments of the run**: the grid rows where every channel has a value, in runs of consecutive
   rows; a run shorter than 2 rows is dropped (and reported). The grid starts at the first row of
   the first segment and ends with the last row of the last one.
5a. **Windowed channels** (a rate that is the mean over its own integration window, PX4's
   ``sensor_combined.gyro_rad`` with ``gyro_integral_dt``: a delta angle divided by its window)
   are carried onto the grid by their integral, not by their points: the running integral of the
   windows (exact at each window's end) is read at the grid's times and each row holds the mean
   rate over the step after it (:func:`resample_windows`). Under vibration, where the rate
   changes sign from one sample to the next, interpolating points loses the integral a sample at a
   time; this keeps it to within one window at any time. Where windows are missing (the logger
   dropped messages) the rate is bridged as above, and the spans are returned as **unmeasured**: a
   comparison of integrals must not cross them.
6. **References** (an attitude run's quaternion) are not resampled: their samples are returned at
   their own times; for callers that read them per grid row they are also placed on the grid row
   nearest each sample (within half a step, inside a segment), NaN elsewhere.

Linear interpolation of white noise at a fraction ``a`` between two samples leaves
``(1 - a)^2 + a^2`` of its variance; the mean of that over the grid is returned as
``noise_variance_factor`` (1 when the grid falls on the samples), so a noise level estimated on
the grid can be referred back to the samples as recorded.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GAP_FACTOR", "BRIDGE_SAMPLES", "METHOD", "FILTER_RATIO", "FILTER_ORDER", "FILTER_CUTOFF", "step_stats",
           "sample_segments", "resample", "resample_windows", "window_integral", "nearest_rows", "place_nearest", "row_segments", "true_runs", "longest_run", "build_time_base",
           "uniform_time_base", "segment_arrays", "run_block"]

#: a step longer than GAP_FACTOR x the nominal step is a gap (a sample or more is missing)
GAP_FACTOR = 1.5
#: at most this many missing samples in a row are bridged by the interpolation, not a gap
BRIDGE_SAMPLES = 2
#: how samples are carried onto the grid
METHOD = "linear"
#: a channel faster than FILTER_RATIO x the grid rate is low-pass filtered before resampling
FILTER_RATIO = 1.05
FILTER_ORDER = 4
#: cut-off of the anti-alias filter, as a fraction of the grid's Nyquist frequency
FILTER_CUTOFF = 0.8
#: a windowed channel's sample whose window starts more than this share of the nominal window
#: after the previous one ended leaves the time between them unmeasured
HOLE_TOL = 0.05


def step_stats(t: np.ndarray) -> dict:
    """Nominal step (median), jitter, the indices of gap steps and of bridged steps (a sample or
    two dropped) of increasing times ``t``."""
    d = np.diff(t)
    nominal = float(np.median(d))
    missing = d > GAP_FACTOR * nominal
    gap = d >= (BRIDGE_SAMPLES + GAP_FACTOR) * nominal
    dev = (d[~missing] - nominal) / nominal
    return {"nominal_dt": nominal, "fs": 1.0 / nominal,
            "jitter_std_rel": float(np.std(dev)) if dev.size else 0.0,
            "jitter_max_rel": float(np.max(np.abs(dev))) if dev.size else 0.0,
            "gap_steps": np.flatnonzero(gap), "bridged_steps": np.flatnonzero(missing & ~gap)}


def sample_segments(n: int, gap_steps: np.ndarray) -> list[tuple[int, int]]:
    """Sample index ranges ``[a, b)`` between gaps (a gap step i lies between samples i and i+1)."""
    edges = [0] + [int(i) + 1 for i in gap_steps] + [n]
    return [(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def _lowpass(v: np.ndarray, fs_channel: float, fs_grid: float) -> np.ndarray:
    from scipy.signal import butter, sosfiltfilt

    sos = butter(FILTER_ORDER, FILTER_CUTOFF * 0.5 * fs_grid, fs=fs_channel, output="sos")
    pad = min(3 * (2 * len(sos) + 1), len(v) - 1)
    if pad < 1:
        return v
    return sosfiltfilt(sos, v, axis=0, padlen=pad)


def resample(t: np.ndarray, v: np.ndarray, grid: np.ndarray, *, fs_grid: float | None = None):
    """``v`` (n,) sampled at ``t`` onto ``grid``: linear inside each segment of ``t``, NaN outside;
    low-pass filtered first when ``t`` is more than FILTER_RATIO times faster than ``fs_grid``.

    Returns (values on the grid, fractions ``a`` of the interpolated rows, stats of ``t``, filtered)."""
    st = step_stats(t)
    filtered = bool(fs_grid and st["fs"] > FILTER_RATIO * fs_grid)
    if filtered:
        v = np.array(v, dtype=np.float64)
        for a, b in sample_segments(len(t), st["gap_steps"]):
            if b - a > 1:
                v[a:b] = _lowpass(v[a:b], st["fs"], fs_grid)
    # one interpolation over all samples; rows inside a gap step (or outside the samples) are then
    # cut: inside a segment, the two samples around a row are that segment's own
    out = np.interp(grid, t, v)
    j = np.clip(np.searchsorted(t, grid, side="right"), 1, len(t) - 1)
    gap = np.zeros(len(t) - 1, bool)
    gap[st["gap_steps"]] = True
    on_sample = grid == t[j - 1]
    bad = (grid < t[0]) | (grid > t[-1]) | (gap[j - 1] & ~on_sample)
    out[bad] = np.nan
    frac = (grid[~bad] - t[j - 1][~bad]) / (t[j] - t[j - 1])[~bad]
    return out, np.clip(frac, 0.0, 1.0), st, filtered


def true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Runs of consecutive True entries of ``mask`` as ``[i0, i1)``, in order."""
    d = np.diff(np.concatenate([[False], mask, [False]]).astype(np.int8))
    return [(int(a), int(b)) for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1))]


def longest_run(mask: np.ndarray) -> tuple[int, int]:
    """The longest run of True in ``mask`` as ``[i0, i1)`` (the first of equals; (0, 0) if none)."""
    runs = true_runs(mask)
    return max(runs, key=lambda r: r[1] - r[0]) if runs else (0, 0)


def row_segments(valid: np.ndarray) -> tuple[list[tuple[int, int]], list[tuple[int, int]]]:
    """Runs of consecutive True rows as ``[i0, i1)``: (kept: 2 rows or more, dropped: shorter)."""
    runs = true_runs(valid)
    return [r for r in runs if r[1] - r[0] >= 2], [r for r in runs if r[1] - r[0] < 2]


def nearest_rows(grid: np.ndarray, valid: np.ndarray, t_ref: np.ndarray, dt: float) -> np.ndarray:
    """Indices into ``t_ref`` of the samples that own a grid row, and the rows: each sample goes to
    the row nearest it (within half a step, on a valid row); where two samples share a row the
    nearer one keeps it. Returns (sample indices, rows)."""
    k = np.rint((t_ref - grid[0]) / dt).astype(np.int64) if len(t_ref) else np.zeros(0, np.int64)
    idx = np.nonzero((k >= 0) & (k < len(grid)))[0]
    k = k[idx]
    dist = np.abs(grid[k] - t_ref[idx])
    ok = (dist <= 0.5 * dt * (1 + 1e-9)) & valid[k]
    idx, k, dist = idx[ok], k[ok], dist[ok]
    order = np.lexsort((dist, k))  # per row, the nearest sample first
    idx, k = idx[order], k[order]
    first = np.concatenate([[True], k[1:] != k[:-1]])
    return idx[first], k[first]


def place_nearest(grid: np.ndarray, valid: np.ndarray, t_ref: np.ndarray, v_ref: np.ndarray,
                  dt: float) -> np.ndarray:
    """Reference samples on the grid row nearest each (:func:`nearest_rows`), NaN elsewhere.
    ``v_ref`` is (m, k)."""
    out = np.full((len(grid), v_ref.shape[1]), np.nan)
    idx, k = nearest_rows(grid, valid, t_ref, dt)
    out[k] = v_ref[idx]
    return out


def _gaps(streams: dict, stats: dict) -> list[dict]:
    gaps = {}
    for name, (t, _) in streams.items():
        for i in stats[name]["gap_steps"]:
            key = (float(t[i]), float(t[i + 1]))
            gaps.setdefault(key, []).append(name)
    return [{"t_start": a, "t_end": b, "duration_s": b - a, "channels": ch}
            for (a, b), ch in sorted(gaps.items())]


def value_step(v: np.ndarray) -> float:
    """The step a channel's recorded values are written in (a CAN signal's resolution, an ADC's
    LSB): the smallest difference between its distinct values where at least 99 % of the values
    are whole multiples of it (to 1e-3 of a step), else 0 (no common step: float data)."""
    v = np.asarray(v, np.float64)
    v = v[np.isfinite(v)]
    u = np.unique(v)
    if len(u) < 3:
        return 0.0
    q = float(np.min(np.diff(u)))
    if not q > 0 or q < 1e-9 * float(np.max(np.abs(u))):
        return 0.0
    r = v / q
    return q if np.mean(np.abs(r - np.rint(r)) < 1e-3) >= 0.99 else 0.0


def _window_starts(t: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Each window's start: ``t - d``, never before the previous window's end (a window longer than
    its step overlaps the one before: the overlap is counted once)."""
    starts = t - d
    starts[1:] = np.maximum(starts[1:], t[:-1])
    return starts


def _window_knots(t, v, d, dt):
    """The running integral of a windowed channel as a piecewise-linear function: (knot times,
    values, window starts, holes before each window, gap flags). Exact at every window's end;
    linear across a missing window (the mean of its neighbours' rates) and flat across a gap."""
    st = step_stats(t)
    starts = _window_starts(t, d)
    hole = np.r_[0.0, starts[1:] - t[:-1]]
    gap = np.zeros(len(t), bool)
    gap[st["gap_steps"] + 1] = True  # window i starts after a gap
    bridge = np.r_[0.0, 0.5 * (v[1:] + v[:-1]) * hole[1:]]
    bridge[gap] = 0.0
    theta_end = np.cumsum(bridge + v * (t - starts))
    theta_start = theta_end - v * (t - starts)
    own = hole > 0
    own[0] = True
    kt = np.concatenate([starts[own], t])
    kv = np.concatenate([theta_start[own], theta_end])
    order = np.argsort(kt, kind="stable")
    # past the last window by at most a step, its own rate holds
    kt = np.r_[kt[order], t[-1] + dt]
    kv = np.r_[kv[order], theta_end[-1] + v[-1] * dt]
    return kt, kv, starts, hole, gap, st


def window_integral(t, v, d, x, dt):
    """The running integral of a windowed channel (``v[i]`` the mean over ``[t[i] - d[i], t[i]]``)
    at times ``x``, from its first window's start: exact at window ends (see :func:`resample_windows`)."""
    kt, kv = _window_knots(np.asarray(t, np.float64), np.asarray(v, np.float64), np.asarray(d, np.float64), dt)[:2]
    return np.interp(x, kt, kv)


def resample_windows(t: np.ndarray, v: np.ndarray, d: np.ndarray, grid: np.ndarray, dt: float):
    """A windowed channel onto ``grid``: ``v[i]`` the mean over ``[t[i] - d[i], t[i]]`` (``d`` the
    window durations). Each grid row gets the mean over ``[grid, grid + dt]`` of the channel's
    running integral (piecewise linear: exact at every window end; bridged linearly across missing
    windows and NaN across gaps, as :func:`resample`), so that the rows' sum between two grid times
    is the integral between them.

    Returns (values on the grid, fractions ``a``: the share of each row's step after the window its
    start falls in, stats of ``t``, filtered (always False: the step mean is the filter), unmeasured
    spans ``(k, 2)`` [s] where windows are missing)."""
    t = np.asarray(t, np.float64)
    v = np.asarray(v, np.float64)
    d = np.asarray(d, np.float64)
    kt, kv, starts, hole, gap, st = _window_knots(t, v, d, dt)
    out = (np.interp(grid + dt, kt, kv) - np.interp(grid, kt, kv)) / dt
    # rows whose step is not inside one segment's windows are NaN (the last segment's last row
    # reaches past its last window by less than a step)
    cover0 = np.r_[starts[0], starts[gap]]
    cover1 = np.r_[t[:-1][gap[1:]], t[-1] + dt]
    s0 = np.clip(np.searchsorted(cover0, grid, side="right") - 1, 0, len(cover0) - 1)
    bad = (grid < cover0[s0]) | (grid + dt > cover1[s0] + 1e-9 * dt)
    out[bad] = np.nan
    j = np.clip(np.searchsorted(t, grid, side="left"), 0, len(t) - 1)  # the window a row starts in
    frac = np.clip((grid + dt - t[j]) / dt, 0.0, 1.0)[~bad]
    unmeasured = (hole > HOLE_TOL * float(np.median(d))) & ~gap
    spans = np.column_stack([t[:-1][unmeasured[1:]], starts[unmeasured]]) if unmeasured.any() else np.zeros((0, 2))
    return out, frac, st, False, spans


def _bridged(streams: dict, stats: dict) -> dict:
    """What was bridged, per channel: the count of steps, the samples they miss, the longest, and
    the first few (a log that drops a sample now and then drops hundreds)."""
    out = {}
    for name, (t, _) in streams.items():
        i = stats[name]["bridged_steps"]
        if len(i):
            d = t[i + 1] - t[i]
            miss = np.rint(d / stats[name]["nominal_dt"]).astype(int) - 1
            out[name] = {"steps": int(len(i)), "missing_samples": int(np.maximum(miss, 1).sum()),
                         "longest_s": float(d.max()),
                         "first": [{"t_start": float(t[k]), "t_end": float(t[k + 1])} for k in i[:10]]}
    return out


def build_time_base(streams: dict, primary: str, *, fs: float | None = None,
                    references: dict | None = None, windows: dict | None = None) -> tuple[np.ndarray, dict, dict, dict]:
    """The policy for channels on their own times: ``streams`` {name: (t, v)} (v (n,)),
    ``primary`` the channel whose nominal step makes the grid (unless ``fs``), ``references``
    {name: (t, v (m, k))} kept on their own times, ``windows`` {name: durations (n,)} of the
    channels that are means over their own windows (:func:`resample_windows`).

    Returns (grid t, {name: values on the grid, NaN in gaps}, {name: reference on the grid's
    nearest rows}, time_base dict). The time base's ``windows`` block (where any) names those
    channels and counts their unmeasured spans; ``unmeasured_spans`` ((k, 2) array, not in the
    report) holds them."""
    t_p = streams[primary][0]
    st_p = step_stats(t_p)
    dt = 1.0 / fs if fs else st_p["nominal_dt"]
    t0 = max(float(t[0]) for t, _ in streams.values())
    t1 = min(float(t[-1]) for t, _ in streams.values())
    n = int(np.floor((t1 - t0) / dt * (1 + 1e-12) + 1e-9)) + 1 if t1 >= t0 else 0
    grid = t0 + np.arange(n) * dt
    grid = grid[grid <= t1]
    n = len(grid)
    data, stats, fracs, filtered, holes = {}, {}, [], [], {}
    windows = windows or {}
    for name, (t, v) in streams.items():
        if name in windows:
            data[name], frac, stats[name], f, holes[name] = resample_windows(t, v, windows[name], grid, dt)
        else:
            data[name], frac, stats[name], f = resample(t, v, grid, fs_grid=1.0 / dt)
        if name == primary:
            fracs = frac
        if f:
            filtered.append(name)
    valid = np.ones(n, bool)
    for v in data.values():
        valid &= np.isfinite(v)
    kept, dropped = row_segments(valid)
    for a, b in dropped:
        valid[a:b] = False
    # the grid spans the kept segments: rows before the first and after the last are cut
    lo, hi = (kept[0][0], kept[-1][1]) if kept else (0, 0)
    grid, valid = grid[lo:hi], valid[lo:hi]
    data = {name: v[lo:hi] for name, v in data.items()}
    kept = [(a - lo, b - lo) for a, b in kept]
    dropped = [(a - lo, b - lo) for a, b in dropped if lo <= a and b <= hi]
    refs = {name: place_nearest(grid, valid, tr, vr, dt) for name, (tr, vr) in (references or {}).items()}
    fa = np.asarray(fracs)
    tb = {"nominal_dt": dt, "fs": 1.0 / dt, "jitter_std_rel": st_p["jitter_std_rel"],
          "jitter_max_rel": st_p["jitter_max_rel"], "gap_factor": GAP_FACTOR, "gaps": _gaps(streams, stats),
          "bridge_samples": BRIDGE_SAMPLES, "bridged": _bridged(streams, stats),
          "segments": [list(s) for s in kept], "dropped_segments": [list(s) for s in dropped],
          "resampled": True, "method": METHOD, "filtered": filtered,
          "noise_variance_factor": float(np.mean((1 - fa) ** 2 + fa ** 2)) if fa.size else 1.0,
          "channels": {name: {"fs": s["fs"], "samples": int(len(streams[name][0])),
                              "jitter_std_rel": s["jitter_std_rel"], "jitter_max_rel": s["jitter_max_rel"],
                              "gaps": int(len(s["gap_steps"])), "bridged": int(len(s["bridged_steps"])),
                              "value_step": value_step(streams[name][1])}
                       for name, s in stats.items()}}
    if fs:
        tb["primary_fs"] = st_p["fs"]
    if holes:
        spans = np.unique(np.concatenate(list(holes.values())), axis=0)
        spans = spans[(spans[:, 1] > grid[0]) & (spans[:, 0] < grid[-1])] if len(grid) else spans[:0]
        tb["method"] = "window integral" if set(holes) == set(streams) else METHOD + " (window integral where windowed)"
        tb["windows"] = {"channels": sorted(holes), "unmeasured_spans": int(len(spans)),
                         "unmeasured_s": float(np.sum(spans[:, 1] - spans[:, 0])) if len(spans) else 0.0,
                         "first": [{"t_start": float(a), "t_end": float(b)} for a, b in spans[:10]]}
        tb["unmeasured_spans"] = spans
    return grid, data, refs, tb


def uniform_time_base(t: np.ndarray) -> dict:
    """The record of a run already on a uniform grid (nothing resampled): one segment."""
    dt = float((t[-1] - t[0]) / (len(t) - 1)) if len(t) > 1 else 0.0
    dev = (np.diff(t) - dt) / dt if dt else np.zeros(0)
    return {"nominal_dt": dt, "fs": 1.0 / dt if dt else 0.0, "jitter_std_rel": float(np.std(dev)) if dev.size else 0.0,
            "jitter_max_rel": float(np.max(np.abs(dev))) if dev.size else 0.0, "gap_factor": GAP_FACTOR, "gaps": [],
            "segments": [[0, int(len(t))]], "dropped_segments": [], "resampled": False, "method": None,
            "filtered": [], "noise_variance_factor": 1.0}


def segment_arrays(run: dict, names=("t", "w", "q_ref", "acc")):
    """Per segment of an attitude run (the dict of :func:`read_attitude_run`), a dict of its
    arrays restricted to the segment (every value finite except the reference's NaN rows):
    ``[{"t": ..., "w": ..., "q_ref": ..., "acc": ..., "rows": (i0, i1)}, ...]``."""
    segs = run.get("time_base", {}).get("segments") or [[0, len(run["t"])]]
    out = []
    for i0, i1 in segs:
        d = {k: (None if run.get(k) is None else run[k][i0:i1]) for k in names}
        d["rows"] = (int(i0), int(i1))
        d["dt"] = run["dt"]
        out.append(d)
    return out


def run_block(tb: dict | None) -> dict | None:
    """The time base as a report's ``run`` block shows it (JSON-ready; None without a record)."""
    if not tb:
        return None
    keys = ("fs", "nominal_dt", "jitter_std_rel", "jitter_max_rel", "gap_factor", "gaps", "bridge_samples",
            "bridged", "logger_faults", "sound_part_s", "segments",
            "analysed_segment", "resampled", "method", "filtered", "noise_variance_factor", "windows")
    return {k: tb[k] for k in keys if k in tb}
