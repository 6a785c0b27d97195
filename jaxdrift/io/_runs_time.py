"""The time-base policy applied to a run being read (:func:`jaxdrift.io.load_run`).

A run whose time column is uniform (within the tolerance of the strict check) is used as it is;
otherwise, and for channels written on their own times (MDF4, ULog, bags), the policy of
:mod:`._timebase` makes the grid: jitter and gaps measured, channels resampled inside segments,
the reference quaternion kept on its own times. A vehicle run is analysed on its longest segment
(the others are reported in ``time_base``); an attitude run keeps every segment on one grid with
NaN rows in the gaps.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ._table import Columns, file_label
from ._timebase import METHOD, build_time_base, nearest_rows, place_nearest, window_integral

__all__ = ["apply_policy", "REFERENCE_COLUMNS"]

REFERENCE_COLUMNS = ("qw", "qx", "qy", "qz")
#: windowed rates (means over their own windows) are integrated as such where their windows cover
#: at least this share of the time; below it they are snapshots, resampled as points
WINDOW_COVER = 0.8
#: a logged reference sample whose norm is further than this from 1 is no attitude (left out)
LOG_QUAT_NORM_TOL = 1e-3


def _reference(cols: Columns, data: dict, times, names, notes=None) -> tuple[np.ndarray, np.ndarray]:
    """The reference quaternion's samples at their own times (rows with all four cells)."""
    tq = times(names[0])
    for c in names[1:]:
        if len(times(c)) != len(tq) or not np.array_equal(times(c), tq):
            raise InputError(f"{file_label(cols.path)}: the reference columns {', '.join(names)} are not "
                             f"sampled at the same times ({names[0]} and {c} differ)")
    q = np.column_stack([data[c] for c in names])
    fin = np.isfinite(q)
    partial = fin.any(1) & ~fin.all(1)
    if partial.any():
        i = int(np.argmax(partial))
        j = int(np.argmax(~fin[i]))
        raise InputError(f"{cols.where(i, names[j])}: empty or NaN while other quaternion cells are set")
    have = fin.all(1)
    if cols.fmt in ("ulog", "bag"):
        # a flight controller logs its attitude before the estimator has one (zeros) or after a
        # reset: samples that are no rotation are left out of the reference, with a note
        norms = np.linalg.norm(np.where(fin, q, 0.0), axis=1)
        bad = have & (np.abs(norms - 1.0) > LOG_QUAT_NORM_TOL)
        if bad.any():
            (notes if notes is not None else []).append(f"{file_label(cols.path)}: {int(bad.sum())} of {int(have.sum())} reference samples "
                              f"are no unit quaternion (norm {float(norms[bad][0]):.3g} at t = {float(tq[bad][0]):.6f} s) "
                              f"and are left out")
            have &= ~bad
    return tq[have], q[have]


def apply_policy(cols: Columns, data: dict, t_raw: np.ndarray | None, kind: str, fs: float | None,
                 min_rows: int) -> tuple[np.ndarray, dict, dict, dict, list[str]]:
    """(grid t, channels on the grid, exact references {"q": (t, q)}, time_base, notes)."""
    fname = file_label(cols.path)
    times_of = (lambda c: cols.times[c]) if cols.times else (lambda c: t_raw)
    ref_names = [c for c in REFERENCE_COLUMNS if c in data] if kind == "attitude" else []
    ref_notes: list[str] = []
    notes_w: list[str] = []
    refs = {"q": _reference(cols, data, times_of, ref_names, ref_notes)} if ref_names else {}
    streams = {c: (times_of(c), v) for c, v in data.items() if c not in ref_names}
    primary = "wx" if kind == "attitude" else "f1"
    for c, (t, _) in streams.items():
        if len(t) < 2:
            raise InputError(f"{fname}, column {c}: {len(t)} sample(s); a run needs at least {min_rows}")
    if fs is not None and not cols.times:
        step = float(np.median(np.diff(t_raw)))
        if abs(step * fs - 1.0) > 0.01:
            raise InputError(f"{fname}, column t: steps of {step:.9g} s (median), but --fs {fs:g} "
                             f"gives {1.0 / fs:.9g} s")
    windows = {c: d for c, d in (cols.windows or {}).items() if c in streams}
    for c in list(windows):
        t = streams[c][0]
        cover = float(np.sum(np.minimum(windows[c][1:], np.diff(t))) / (t[-1] - t[0])) if len(t) > 1 else 0.0
        if cover < WINDOW_COVER:
            # windows that leave most of the time unmeasured (a log that keeps one message in 25):
            # snapshots, resampled as points
            notes_w.append(f"{fname}: {c}'s logged windows cover {100 * cover:.3g} % of the time; resampled as points")
            del windows[c]
    grid, on_grid, placed, tb = build_time_base(streams, primary, fs=fs, references=refs, windows=windows)
    if not tb["segments"]:
        raise InputError(f"{fname}: the channels have no stretch of samples in common "
                         f"({', '.join(streams)}); nothing to analyse")
    spans = tb.pop("unmeasured_spans", None)
    if spans is not None:
        refs["unmeasured"] = (spans[:, 0], spans[:, 1])  # where windowed rates measured nothing
    notes = [_describe(fname, tb)] + ref_notes + notes_w[:1]
    rates = [streams[c] for c in ("wx", "wy", "wz") if c in streams]
    if kind == "attitude" and len(rates) == 3 and all(np.array_equal(r[0], rates[0][0]) for r in rates):
        refs["w"] = (rates[0][0], np.column_stack([r[1] for r in rates]))  # the rates as recorded
    if "q" in placed and all(c in windows for c in ("wx", "wy", "wz")):
        placed["q"], refs["q"], carried = _carry_reference(grid, on_grid, streams, windows, refs["q"], tb["nominal_dt"])
        notes.append(f"{fname}: the reference's samples carried to their nearest grid rows by the rates' recorded windows "
                     f"(by at most half a step; {carried} sample(s)), so that it meets the rates' integral where that is exact")
    if "q" in placed:
        for j, c in enumerate(ref_names):
            on_grid[c] = placed["q"][:, j]
        tq = refs["q"][0]
        tb["reference"] = {"samples": int(len(tq)), "on_grid_rows": int(np.isfinite(placed["q"][:, 0]).sum()),
                           "fs": float(1.0 / np.median(np.diff(tq))) if len(tq) > 1 else 0.0}
    if kind != "attitude":
        # a measured motion channel slower than the grid (a pitch from another logger): on the
        # grid by linear interpolation (the vehicle diagnosis reads it per row), and its samples
        # at their own times in the references
        for c, (t, v) in streams.items():
            if c != primary and tb["channels"][c]["fs"] * 1.05 < tb["fs"]:
                refs[c] = (t, v)
        lengths = [b - a for a, b in tb["segments"]]
        k = int(np.argmax(lengths))
        i0, i1 = tb["segments"][k]
        tb["analysed_segment"] = [i0, i1]
        if len(lengths) > 1:
            notes.append(f"{fname}: the run is analysed on its longest segment, {grid[i0]:.6g} .. "
                         f"{grid[i1 - 1]:.6g} s ({i1 - i0} rows); the other {len(lengths) - 1} segment(s) "
                         f"are listed in the report's time base")
        grid = grid[i0:i1]
        on_grid = {c: v[i0:i1] for c, v in on_grid.items()}
        for c, (t, v) in list(refs.items()):
            m = (t >= grid[0]) & (t <= grid[-1])
            refs[c] = (t[m], v[m])
    return grid, on_grid, refs, tb, notes


def _carry_reference(grid, on_grid, streams, windows, ref, dt):
    """The reference moved onto the grid exactly: each sample (stamped where a window of the rates
    ends, as PX4 stamps its attitude with the IMU sample it used) turned by the rates' integral from
    its stamp to its nearest grid row, read from the windows (exact at the stamp; within a window at
    the row, which is where the grid's own rows put it too: the rows' sum between two grid times is
    that integral). Interpolating a vibrating rate over the sub-step would err by up to half a step
    of vibration, per sample. Returns (reference on the grid, the reference at the rows' times,
    how many samples were carried)."""
    from scipy.spatial.transform import Rotation

    tq, q = ref
    valid = np.ones(len(grid), bool)
    for v in on_grid.values():
        valid &= np.isfinite(v)
    i, k = nearest_rows(grid, valid, tq, dt)
    tq, q = tq[i], q[i]
    # the integral at the stamps and at their rows, from one build of each channel's knots
    both = np.column_stack([window_integral(streams[c][0], streams[c][1], windows[c], np.r_[tq, grid[k]], dt)
                            for c in ("wx", "wy", "wz")])
    dtheta = both[:len(tq)] - both[len(tq):]
    # q(row) = q(stamp) (x) exp(-dtheta): the body turned by dtheta from the row to the stamp
    q2 = (Rotation.from_quat(q[:, [1, 2, 3, 0]]) * Rotation.from_rotvec(-dtheta)).as_quat()[:, [3, 0, 1, 2]]
    q2 *= np.where(np.sum(q2 * q, 1) < 0, -1.0, 1.0)[:, None]  # the recorded sign
    t2 = grid[k]
    return place_nearest(grid, valid, t2, q2, dt), (t2, q2), int(np.sum(np.any(dtheta != 0, 1)))


def _describe(fname: str, tb: dict) -> str:
    gaps = tb["gaps"]
    gap_txt = (f"; {len(gaps)} gap(s) longer than {tb['gap_factor']:g} steps (longest "
               f"{max(g['duration_s'] for g in gaps):.4g} s) split it into {len(tb['segments'])} segment(s), "
               f"never interpolated across") if gaps else ""
    filt = f"; low-pass filtered first: {', '.join(tb['filtered'])}" if tb["filtered"] else ""
    br = tb.get("bridged") or {}
    br_txt = ("; dropped samples bridged by the interpolation (at most "
              f"{tb['bridge_samples']} in a row): " + ", ".join(f"{c} {b['missing_samples']} at {b['steps']} place(s)"
                                                             for c, b in br.items())) if br else ""
    win = tb.get("windows")
    how = f"by {tb['method']} interpolation" if not win else (
        f"by their integral over the windows they were logged as ({', '.join(win['channels'])}: means over "
        f"each sample's own window; {win['unmeasured_spans']} missing window(s), {win['unmeasured_s']:.3g} s, "
        "bridged but never compared across)" + ("" if tb["method"] == "window integral" else f", the rest by {METHOD} interpolation"))
    return (f"{fname}: time base {tb['fs']:.6g} Hz from the median step; jitter {100 * tb['jitter_std_rel']:.3g} % "
            f"(std), {100 * tb['jitter_max_rel']:.3g} % (max){gap_txt}{br_txt}; channels resampled onto the uniform "
            f"grid {how}{filt}")
