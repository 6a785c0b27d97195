"""Readers of attitude runs (docs/measured-data.md): the run file and the accelerometer positions JSON.

The run goes through the one reader of every kind of run (:func:`jaxdrift.io.load_run`). Bad input
raises :class:`jaxdrift.errors.UsageError` with a message that names the file, the line (row for
binary formats) and the column; nothing is analysed here beyond what validation needs (the printed
resolution of the rate columns, so that the diagnosis can tell noise from rounding).
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from ..errors import InputError, UsageError
from ._runs import load_run
from ._table import _printed_digits, read_header_any
from ._timebase import segment_arrays

__all__ = ["read_attitude_run", "attitude_segments", "read_sensors", "RATE_COLUMNS", "QUATERNION_COLUMNS"]

CHANNELS = ("wx", "wy", "wz")
Q_COLS = ("qw", "qx", "qy", "qz")
RATE_COLUMNS = CHANNELS
QUATERNION_COLUMNS = Q_COLS
QUAT_NORM_TOL = 1e-3


def _usage_error(msg):
    return UsageError(msg)


def read_attitude_run(path, *, map=None, units=None, fs=None, force=False, checks=False,  # noqa: A002
                      strict_time=False):
    """Read and validate an attitude run (CSV, Parquet, MF4, PX4 ULog or ROS bag) through the one
    reader (:func:`jaxdrift.io.load_run`, the same rules and messages as vehicle runs), plus what
    only attitude runs have: a reference quaternion (all four cells or none) of norm close to 1.
    Raises UsageError on bad input.

    Returns a dict: ``path``, ``t`` (n,), ``dt``, ``w`` (n, 3), ``q_ref`` (n, 4, NaN rows where no
    reference; None without), ``acc`` (n, N, 3) or None, ``extra_columns``, ``quantisation`` and
    ``acc_quantisation`` (RMS rounding error of the rate and accelerometer cells as written,
    sampled from both ends of a CSV file), ``warnings``, ``info`` (how the run was read), and the
    time base (docs/measured-data.md, "Time base"):

    - ``time_base``: ``nominal_dt``, ``fs``, ``jitter_std_rel``, ``jitter_max_rel``, ``gaps``
      (``[{"t_start", "t_end", "duration_s", "channels"}]``), ``segments`` (``[i0, i1)`` row
      ranges of the grid), ``resampled``, ``method``, ``noise_variance_factor``, ...;
    - ``t`` is one uniform grid over all segments; rows in a gap have NaN in ``w`` (and ``acc``):
      :func:`attitude_segments` yields each segment's arrays, all finite;
    - ``q_ref_t`` (m,) and ``q_ref_q`` (m, 4): the reference at its own times (None without);
      ``q_ref`` places each sample on the nearest grid row (NaN elsewhere).
    - ``w_recorded_t`` (k,) and ``w_recorded`` (k, 3): the rates as recorded, before resampling
      (where the three share their times; None for a run used as it is: then ``t``, ``w``);
    - ``heading_only``: the reference is a heading alone (a ``yaw`` column without roll and pitch:
      its quaternion is a rotation about the vertical; the diagnosis compares it about that axis only);
    - ``onboard_bias`` and ``events``: what a PX4 log says besides (:func:`jaxdrift.io._logs.ulog_context`:
      the flight controller's own gyro-bias estimate, gyro and estimator switches, attitude
      resets); None and [] for other formats;
    - ``w_unmeasured`` (k, 2): spans [s] where rates logged as means over their own windows (PX4's
      ``sensor_combined``) have no window (the logger dropped it): bridged on the grid, but an
      integral across them is not measured (None where the rates are points);
    - ``armed``: when the motors may run (``{"t", "armed"}``, from the same context), or None.
    """
    try:
        run = load_run(path, "attitude", map=map, units=units, fs=fs, force=force, checks=checks,
                       strict_time=strict_time)
    except InputError as e:
        raise _usage_error(str(e)) from None
    ch = run.channels
    where = _where(run)
    w = np.column_stack([ch[c] for c in CHANNELS])
    q_ref_t = q_ref_q = None
    if "q" in run.references and len(run.references["q"][0]) and run.time_base.get("resampled"):
        # a resampled run's rows are no file lines: its reference is checked sample by sample
        q_ref_t, q_ref_q = _exact_reference(run, where)
    q_ref = None
    if all(c in ch for c in Q_COLS):
        q_ref = np.column_stack([ch[c] for c in Q_COLS])
        fin = np.isfinite(q_ref)
        partial = fin.any(1) & ~fin.all(1)
        if partial.any():
            i = int(np.argmax(partial))
            j = int(np.argmax(~fin[i]))
            raise _usage_error(f"{where(i, Q_COLS[j])}: empty or NaN while other quaternion cells are set")
        have = fin.all(1)
        norms = np.linalg.norm(np.where(have[:, None], q_ref, 1.0), axis=1)
        bad = have & (np.abs(norms - 1.0) > QUAT_NORM_TOL)
        if bad.any():
            i = int(np.argmax(bad))
            raise _usage_error(f"{where(i, None)}, columns qw..qz: quaternion norm {norms[i]:.6g} is far from 1 "
                               f"(tolerance {QUAT_NORM_TOL:g})")
        q_ref = np.where(have[:, None], q_ref / norms[:, None], np.nan) if have.any() else None
    if q_ref_t is None and "q" in run.references and len(run.references["q"][0]):
        q_ref_t, q_ref_q = _exact_reference(run, where)  # (checked per line above)
    k, acc = 1, []
    while f"a{k}x" in ch:
        acc.append(np.column_stack([ch[f"a{k}{a}"] for a in "xyz"]))
        k += 1
    acc = np.stack(acc, axis=1) if acc else None  # (n, N, 3)
    used = set(run.info["columns"].values())
    header = [] if run.info["format"] in ("ulog", "bag") else read_header_any(path)
    extra = [c for c in header if c not in used]
    # the rounding of the rate (and accelerometer) columns as written, to tell noise from
    # rounding: the RMS rounding error sqrt(mean(step^2) / 12) of the cells' last digits
    acc_cols = [c for c in ch if c.startswith("a") and c[1:-1].isdigit()]
    context = {}
    if run.info["format"] == "ulog":
        from ._logs import ulog_context

        context = ulog_context(path, run.info["columns"].get("wx"))
    return {"path": path, "t": run.t, "dt": run.dt, "w": w, "q_ref": q_ref, "acc": acc, "extra_columns": extra,
            "onboard_bias": context.get("onboard_bias"), "events": context.get("events", []),
            "armed": context.get("armed"),
            "quantisation": _text_rounding(path, run.info, list(CHANNELS)),
            "acc_quantisation": _text_rounding(path, run.info, acc_cols),
            "warnings": run.warnings, "info": run.info, "time_base": run.time_base,
            "q_ref_t": q_ref_t, "q_ref_q": q_ref_q, "heading_only": bool(run.info.get("heading_only")),
            "w_unmeasured": np.column_stack(run.references["unmeasured"]) if "unmeasured" in run.references else None,
            "w_recorded_t": run.references["w"][0] if "w" in run.references else None,
            "w_recorded": run.references["w"][1] if "w" in run.references else None}


def _exact_reference(run, where):
    """The reference samples at their own times, normalised (norm checked as on the grid)."""
    tq, q = run.references["q"]
    norms = np.linalg.norm(q, axis=1)
    bad = np.abs(norms - 1.0) > QUAT_NORM_TOL
    if bad.any():
        i = int(np.argmax(bad))
        raise _usage_error(f"{os.path.basename(str(run.path))}, reference sample {i + 1} (t = {tq[i]:.6f} s), "
                           f"columns qw..qz: quaternion norm {norms[i]:.6g} is far from 1 (tolerance {QUAT_NORM_TOL:g})")
    return np.asarray(tq, float), q / norms[:, None]


def attitude_segments(run: dict) -> list[dict]:
    """Each segment of an attitude run (the dict of :func:`read_attitude_run`) as its own run:
    dicts with ``t``, ``dt``, ``w``, ``q_ref``, ``acc`` restricted to the segment (``w`` and
    ``acc`` finite), ``rows`` (``(i0, i1)`` on the grid), and ``q_ref_t``, ``q_ref_q``: the
    reference samples whose times fall inside the segment (within half a step)."""
    out = segment_arrays(run)
    for seg in out:
        if run.get("q_ref_t") is None:
            seg["q_ref_t"] = seg["q_ref_q"] = None
            continue
        t = seg["t"]
        m = (run["q_ref_t"] >= t[0] - 0.5 * run["dt"]) & (run["q_ref_t"] <= t[-1] + 0.5 * run["dt"])
        seg["q_ref_t"], seg["q_ref_q"] = run["q_ref_t"][m], run["q_ref_q"][m]
    return out


def _written_rounding_rms(lines, columns):
    """RMS rounding error of the cells of ``columns`` as written, robust to how they were printed.

    A cell's step is its last written decimal, except that ``%g`` drops trailing zeros ("1.2" for
    1.20000) and exact zeros carry no digits at all: per column, with ``p`` the most significant
    digits any cell shows and ``D`` the most decimals, a cell of magnitude ``10^e`` is rounded to
    ``max(min(decimal step, 10^(e - p + 1)), 10^-D)``: the significant-digit step for ``%g`` files,
    the fixed decimal step for ``%f`` files. Zero cells are skipped. Returns sqrt(mean(step^2) / 12).
    """
    steps = []
    for j in columns:
        cells = []
        for ln in lines:
            parts = ln.split(",")
            if j < len(parts):
                c = parts[j].strip()
                try:
                    v = float(c)
                except ValueError:
                    continue
                if v != 0.0 and math.isfinite(v):
                    cells.append((c, v))
        if not cells:
            continue
        digits = [_printed_digits(c, ".") for c, _ in cells]  # (significant digits, last exponent)
        dec = np.array([10.0 ** last for _, last in digits])
        p = max(sig for sig, _ in digits)
        mag = np.floor(np.log10(np.abs([v for _, v in cells])))
        steps.append(np.maximum(np.minimum(dec, 10.0 ** (mag - p + 1)), dec.min()))
    if not steps:
        return 0.0
    return float(np.sqrt(np.mean(np.square(np.concatenate(steps))) / 12.0))


def _text_rounding(path, info, cols) -> float:
    """The rounding of the cells of ``cols`` (rates or accelerometers), read from the text (the
    robust rule above): up to 5000 lines spread over the first 64 MiB of a CSV file. Binary formats
    are exact; a file whose columns were renamed by --map falls back to the reader's printed steps.
    (The reader's own steps count an exact "0" cell, as a noise-free static start writes, as a step
    of 1: on such a file they made the gyro's rounding floor 0.19 rad/s and hid a 7.9e-4 rad/s bias.)"""
    if not cols or info.get("format") != "csv":
        return _rounding_rms(info, cols) or _value_step_rms(info, cols)
    with open(path, errors="replace") as fh:
        head = fh.readline()
        body = fh.readlines(64 << 20)
    names = [c.strip() for c in head.split(",")]
    if not all(c in names for c in cols) or not body:
        return _rounding_rms(info, cols)
    sample = body[:: max(1, len(body) // 5000)]
    return _written_rounding_rms(sample, [names.index(c) for c in cols])


def _value_step_rms(info, columns) -> float:
    """RMS rounding error of channels recorded in steps (a CAN signal's resolution: its values,
    resampled or not, carry that rounding), from the time base's ``value_step`` per channel."""
    ch = (info.get("time_base") or {}).get("channels") or {}
    q = [ch.get(c, {}).get("value_step", 0.0) for c in columns]
    return float(math.sqrt(sum(x * x for x in q) / len(q) / 12.0)) if any(q) else 0.0


def _rounding_rms(info, columns) -> float:
    """RMS rounding error of the sampled cells of ``columns`` (0 for binary formats: exact)."""
    steps = [info.get("printed_steps", {}).get(c) for c in columns]
    sq = sum(s[0] for s in steps if s)
    n = sum(s[1] for s in steps if s)
    return float(math.sqrt(sq / n / 12.0)) if n else 0.0


def _where(run):
    fname = os.path.basename(str(run.path))
    binary = run.info["format"] != "csv"

    def where(i, col):
        loc = f"row {i + 1}" if binary else f"line {i + 2}"
        return f"{fname}, {loc}" + (f", column {col}" if col else "")

    return where


def read_sensors(path, n_expected=None, check_geometry=None):
    """Read and validate ``{"positions": [[x, y, z], ...]}``: N >= 4 numbers triples.

    ``check_geometry(r)`` (optional) returns ``None`` or the reason the positions cannot serve (the
    diagnosis passes :func:`jaxdrift.models.check_positions`, the rank condition of section 3.1,
    which lives with the model: this layer imports numpy only).
    """
    if not os.path.isfile(path):
        raise _usage_error(f"{path}: no such file")
    try:
        with open(path) as fh:
            obj = json.load(fh)
    except json.JSONDecodeError as e:
        raise _usage_error(f"{path}: not valid JSON ({e})") from None
    if not isinstance(obj, dict) or "positions" not in obj:
        raise _usage_error(f'{path}: expected an object {{"positions": [[x, y, z], ...]}}')
    pos = obj["positions"]
    if not isinstance(pos, list):
        raise _usage_error(f"{path}: positions must be a list of [x, y, z]")
    for i, p in enumerate(pos):
        if not (isinstance(p, list) and len(p) == 3 and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in p)):
            raise _usage_error(f"{path}: positions[{i}] (sensor {i + 1}) must be three numbers, got {p!r}")
        if not all(math.isfinite(v) for v in p):
            raise _usage_error(f"{path}: positions[{i}] (sensor {i + 1}) is not finite")
    r = np.asarray(pos, float).reshape(-1, 3)
    if r.shape[0] < 4:
        raise _usage_error(f"{path}: {r.shape[0]} sensor(s); the array needs at least 4 (m + 1 >= 4, section 3.1)")
    if n_expected is not None and r.shape[0] != n_expected:
        raise _usage_error(f"{path}: {r.shape[0]} positions but the run has {n_expected} accelerometers (a1x..a{n_expected}z)")
    if check_geometry is not None:
        msg = check_geometry(r)
        if msg:
            raise _usage_error(f"{path}: {msg}")
    return r
