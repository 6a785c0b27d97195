"""Readers of attitude runs (docs/measured-data.md): the run CSV and the accelerometer positions JSON.

numpy only. Bad input raises :class:`jaxdrift.errors.UsageError` with a message that names the file,
the row and the column; nothing is analysed here beyond what validation needs (the quantisation
step of the rate columns, read from the text, so that the diagnosis can tell noise from rounding).
"""

from __future__ import annotations

import json
import math
import os

import numpy as np

from ..errors import UsageError

__all__ = ["read_attitude_run", "read_sensors", "RATE_COLUMNS", "QUATERNION_COLUMNS"]

CHANNELS = ("wx", "wy", "wz")
Q_COLS = ("qw", "qx", "qy", "qz")
RATE_COLUMNS = CHANNELS
QUATERNION_COLUMNS = Q_COLS
QUAT_NORM_TOL = 1e-3


def _usage_error(msg):
    return UsageError(msg)


def _float_cells(path, lines, first_line, names, ncol):
    """Parse a block of CSV lines into floats (NaN for empty cells); errors name the row and column."""
    rows = [ln.split(",") for ln in lines]
    for i, r in enumerate(rows):
        if len(r) != ncol:
            raise _usage_error(f"{path}, row {first_line + i}: {len(r)} cells, expected {ncol} as in the header")
    arr = np.char.strip(np.array(rows, dtype=str)) if rows else np.zeros((0, ncol), str)
    empty = arr == ""
    arr = np.where(empty, "nan", arr)
    try:
        return arr.astype(float)
    except ValueError:
        for i, r in enumerate(arr):
            for j, c in enumerate(r):
                try:
                    float(c)
                except ValueError:
                    raise _usage_error(f"{path}, row {first_line + i}, column {names[j]}: not a number: {c!r}") from None
        raise


def _decimal_step(s):
    s = s.strip().lower()
    mant, _, exp = s.partition("e")
    e = int(exp) if exp else 0
    dec = len(mant.partition(".")[2])
    return 10.0 ** (e - dec)


def _rounding_rms(lines, columns):
    """RMS rounding error of the cells of ``columns`` in ``lines``, from their written decimals."""
    steps = []
    for ln in lines:
        cells = ln.split(",")
        for j in columns:
            try:
                steps.append(_decimal_step(cells[j]))
            except (ValueError, IndexError):
                pass
    return float(np.sqrt(np.mean(np.square(steps)) / 12.0)) if steps else 0.0


def _significant_digits(s):
    """Significant digits written in a number's text ("0.00552004" -> 6, "-1.2e+03" -> 2)."""
    mant = s.strip().lower().partition("e")[0].lstrip("+-").replace(".", "")
    return len(mant.lstrip("0"))


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
        dec = np.array([_decimal_step(c) for c, _ in cells])
        p = max(_significant_digits(c) for c, _ in cells)
        mag = np.floor(np.log10(np.abs([v for _, v in cells])))
        steps.append(np.maximum(np.minimum(dec, 10.0 ** (mag - p + 1)), dec.min()))
    if not steps:
        return 0.0
    return float(np.sqrt(np.mean(np.square(np.concatenate(steps))) / 12.0))


def read_attitude_run(path):
    """Read and validate an attitude run CSV. Raises UsageError on bad input.

    Returns a dict: ``path``, ``t`` (n,), ``dt``, ``w`` (n, 3), ``q_ref`` (n, 4, NaN rows where no
    reference; None without), ``acc`` (n, N, 3) or None, ``extra_columns``, ``quantisation`` and
    ``acc_quantisation`` (RMS rounding error of the rate and accelerometer cells as written).
    """
    if not os.path.isfile(path):
        raise _usage_error(f"{path}: no such file")
    with open(path) as fh:
        text = fh.read()
    lines = text.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        raise _usage_error(f"{path}: empty file")
    names = [c.strip() for c in lines[0].split(",")]
    if len(set(names)) != len(names):
        dup = sorted({c for c in names if names.count(c) > 1})
        raise _usage_error(f"{path}, row 1: duplicate column(s) {', '.join(dup)}")
    for c in ("t",) + CHANNELS:
        if c not in names:
            raise _usage_error(f"{path}, row 1: required column {c} missing (attitude runs need t, wx, wy, wz)")
    body = lines[1:]
    if len(body) < 16:
        raise _usage_error(f"{path}: only {len(body)} data rows; an attitude run needs at least 16")
    ncol = len(names)
    blocks = []
    for s in range(0, len(body), 50_000):
        blocks.append(_float_cells(path, body[s : s + 50_000], s + 2, names, ncol))
    data = np.concatenate(blocks, 0)
    col = {c: i for i, c in enumerate(names)}
    # required columns: finite everywhere
    for c in ("t",) + CHANNELS:
        bad = ~np.isfinite(data[:, col[c]])
        if bad.any():
            i = int(np.argmax(bad))
            raise _usage_error(f"{path}, row {i + 2}, column {c}: empty, NaN or inf (required column)")
    t = data[:, col["t"]]
    dts = np.diff(t)
    if np.any(dts <= 0):
        i = int(np.argmax(dts <= 0))
        raise _usage_error(f"{path}, row {i + 3}, column t: time not strictly increasing ({t[i]!r} then {t[i + 1]!r})")
    dt = (t[-1] - t[0]) / (len(t) - 1)
    jitter = np.abs(dts - dt) / dt
    if np.any(jitter > 1e-6):
        i = int(np.argmax(jitter > 1e-6))
        raise _usage_error(
            f"{path}, row {i + 3}, column t: non-uniform sampling (step {dts[i]:.9g} s, mean step {dt:.9g} s; "
            "relative jitter must stay below 1e-6)"
        )
    w = data[:, [col[c] for c in CHANNELS]]
    # reference attitude: all four columns or none; per row all four cells or none
    present = [c for c in Q_COLS if c in col]
    q_ref = None
    if present:
        if len(present) != 4:
            missing = [c for c in Q_COLS if c not in col]
            raise _usage_error(f"{path}, row 1: reference attitude needs qw, qx, qy, qz; missing {', '.join(missing)}")
        q_ref = data[:, [col[c] for c in Q_COLS]]
        fin = np.isfinite(q_ref)
        partial = fin.any(1) & ~fin.all(1)
        if partial.any():
            i = int(np.argmax(partial))
            j = int(np.argmax(~fin[i]))
            raise _usage_error(f"{path}, row {i + 2}, column {Q_COLS[j]}: empty or NaN while other quaternion cells are set")
        inf = np.isinf(q_ref).any(1)
        if inf.any():
            i = int(np.argmax(inf))
            raise _usage_error(f"{path}, row {i + 2}: infinite quaternion component")
        have = fin.all(1)
        norms = np.linalg.norm(np.where(have[:, None], q_ref, 1.0), axis=1)
        bad = have & (np.abs(norms - 1.0) > QUAT_NORM_TOL)
        if bad.any():
            i = int(np.argmax(bad))
            raise _usage_error(
                f"{path}, row {i + 2}, columns qw..qz: quaternion norm {norms[i]:.6g} is far from 1 "
                f"(tolerance {QUAT_NORM_TOL:g})"
            )
        if not have.any():
            q_ref = None
        else:
            q_ref = np.where(have[:, None], q_ref / norms[:, None], np.nan)
    # accelerometer columns a1x, a1y, a1z, ...
    acc_names = []
    k = 1
    while f"a{k}x" in col or f"a{k}y" in col or f"a{k}z" in col:
        trip = [f"a{k}{a}" for a in "xyz"]
        for c in trip:
            if c not in col:
                raise _usage_error(f"{path}, row 1: accelerometer {k} needs {', '.join(trip)}; column {c} missing")
        acc_names.append(trip)
        k += 1
    acc = None
    if acc_names:
        idx = [[col[c] for c in trip] for trip in acc_names]
        acc = data[:, idx]  # (n, N, 3)
        bad = ~np.isfinite(acc)
        if bad.any():
            i, s_, a_ = (int(v[0]) for v in np.nonzero(bad))
            raise _usage_error(f"{path}, row {i + 2}, column a{s_ + 1}{'xyz'[a_]}: empty, NaN or inf")
    known = {"t", *CHANNELS, *Q_COLS, *(c for trip in acc_names for c in trip)}
    extra = [c for c in names if c not in known]
    stray_acc = [c for c in extra if len(c) >= 3 and c[0] == "a" and c[1:-1].isdigit() and c[-1] in "xyz"]
    if stray_acc:
        raise _usage_error(f"{path}, row 1: accelerometer column(s) {', '.join(stray_acc)} out of sequence (a1x.. must be contiguous)")
    # quantisation of the rate columns (and of the accelerometer columns), from the text: the RMS
    # rounding error sqrt(mean(step^2) / 12) of the written digits (to tell noise from rounding).
    # The rates keep the plain last-decimal step (the gyro noise floor was set with it; it
    # overstates the rounding of %g text by up to a few times); the accelerometers use the robust one.
    sample = body[:: max(1, len(body) // 5000)]
    quant = _rounding_rms(sample, [col[c] for c in CHANNELS])
    acc_quant = _written_rounding_rms(sample, [col[c] for trip in acc_names for c in trip]) if acc_names else 0.0
    return {"path": path, "t": t, "dt": dt, "w": w, "q_ref": q_ref, "acc": acc, "extra_columns": extra, "quantisation": quant,
            "acc_quantisation": acc_quant}


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
