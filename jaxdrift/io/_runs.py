"""One reader for every kind of run (vehicle, attitude, durability): :func:`load_run`.

The same rules and messages for every kind and format (CSV, Parquet, MDF4): the columns are
checked by name (required, optional, a name close to a known one is an error with a hint), the
cells for empty, NaN and infinite values, the time column for order and uniform sampling (within
the resolution it is printed with), then the run for plausibility (units, dead channels, glitches;
:mod:`._plausible`). Every refusal is an :class:`InputError` naming the file, the line (or row) and
the column; nothing is computed before. ``--map``, ``--units`` and ``--fs`` are the options
``map``, ``units`` and ``fs``; ``force=True`` turns plausibility errors into warnings.
"""

from __future__ import annotations

import dataclasses
import difflib
import re

import numpy as np

from ..errors import InputError
from ._model import DEFAULT_MODEL, DEFAULT_MODEL_LABEL
from ._options import parse_map, parse_units, quantity_of, UNITS
from ._faults import SOUND_MIN_SHARE, find_faults, sound_part
from ._plausible import plausibility_problems
from ._logs import LOG_FORMATS
from ._runs_time import REFERENCE_COLUMNS, _reference, apply_policy
from ._table import Columns, _open_check, detect_format, file_label, read_columns, read_header_any
from ._timebase import true_runs, uniform_time_base

__all__ = ["VehicleRun", "AttitudeRun", "KINDS", "load_run", "VEHICLE_REQUIRED", "VEHICLE_OPTIONAL",
           "ATTITUDE_REQUIRED", "ATTITUDE_OPTIONAL", "EULER_COLUMNS", "MIN_SAMPLES", "MIN_DURATION_S", "JITTER_TOL"]

VEHICLE_REQUIRED: tuple[str, ...] = ("t", "f1", "f2")
VEHICLE_OPTIONAL: tuple[str, ...] = ("beta", "beta_rate", "z3", "s1", "s2", "zeta1", "zeta2")
ATTITUDE_REQUIRED: tuple[str, ...] = ("t", "wx", "wy", "wz")
ATTITUDE_OPTIONAL: tuple[str, ...] = ("qw", "qx", "qy", "qz")  # plus a1x, a1y, a1z, ...
#: a reference as z-y-x Euler angles (yaw about the world's vertical, then pitch, then roll; body to
#: world); yaw alone is a heading-only reference (a car's GNSS course or a compass)
EULER_COLUMNS: tuple[str, ...] = ("roll", "pitch", "yaw")
KINDS = {"vehicle": (VEHICLE_REQUIRED, VEHICLE_OPTIONAL), "durability": (VEHICLE_REQUIRED, VEHICLE_OPTIONAL),
         "attitude": (ATTITUDE_REQUIRED, ATTITUDE_OPTIONAL + EULER_COLUMNS)}

#: A vehicle run needs at least this many samples and this duration to say anything about drift:
#: the chassis modes of the seed's vehicle have time constants of about 0.1-1 s.
MIN_SAMPLES = 100
MIN_DURATION_S = 1.0
#: an attitude run needs this many rows (the noise estimate uses up to 8th differences)
MIN_ATTITUDE_ROWS = 16
#: Relative jitter allowed on the sample spacing (the spec: below 1e-6), on top of the
#: resolution the time column is printed with.
JITTER_TOL = 1e-6
_ACC = re.compile(r"^a(\d+)([xyz])$")


@dataclasses.dataclass(frozen=True)
class VehicleRun:
    """A validated run: uniform time grid and the channels present (float64 arrays, SI units).

    ``info`` says how it was read: format, file columns used, units converted, rate, notes."""

    path: str
    t: np.ndarray
    channels: dict[str, np.ndarray]
    warnings: tuple[str, ...] = ()
    info: dict = dataclasses.field(default_factory=dict, compare=False)
    #: how the time base was made (docs/measured-data.md, "Time base"): nominal_dt, fs, jitter,
    #: gaps, segments (grid row ranges), resampled, method, ...; also in ``info["time_base"]``
    time_base: dict = dataclasses.field(default_factory=dict, compare=False)
    #: channels kept on their own times: ``{"q": (t (m,), q (m, 4))}`` for an attitude reference
    references: dict = dataclasses.field(default_factory=dict, compare=False)

    @property
    def dt(self) -> float:
        return float((self.t[-1] - self.t[0]) / (len(self.t) - 1))

    @property
    def n(self) -> int:
        return len(self.t)

    def has(self, name: str) -> bool:
        return name in self.channels

    def __getitem__(self, name: str) -> np.ndarray:
        return self.channels[name]

    def with_channels(self, changed: dict) -> "VehicleRun":
        """A copy with the channels of ``changed`` replaced (the run itself never changes)."""
        return dataclasses.replace(self, channels={**self.channels, **changed})


class AttitudeRun(VehicleRun):
    """A validated attitude run (same fields; channels ``wx, wy, wz``, ``qw..qz``, ``a1x..``).

    Empty reference-quaternion cells are NaN (rows without a reference)."""


def _known(kind: str, name: str) -> bool:
    req, opt = KINDS[kind]
    return name in req or name in opt or (kind == "attitude" and bool(_ACC.match(name)))


#: more unused columns than this are summarised in one warning
MAX_UNUSED_LISTED = 5


def _check_names(fname, header, kind) -> tuple[list[str], list[str]]:
    """Check the (mapped) header. Returns (warnings, close-name problems)."""
    req, opt = KINDS[kind]
    for i, h in enumerate(header):
        if h == "":
            raise InputError(f"{fname}, line 1, column {i + 1}: empty column name in the header")
    seen: dict[str, int] = {}
    for i, h in enumerate(header):
        if h in seen:
            raise InputError(f"{fname}, line 1: column {h!r} appears twice (columns {seen[h] + 1} and {i + 1})")
        seen[h] = i
    extras = [h for h in header if not _known(kind, h)]
    for r in req:
        if r not in seen:
            hint = difflib.get_close_matches(r, extras, n=1, cutoff=0.5)
            hint = hint or [h for h in extras if h.lower() == r.lower()]
            did = f"; did you mean {hint[0]!r}? (names are case-sensitive; or --map {r}={hint[0]})" if hint else ""
            raise InputError(f"{fname}, line 1: missing required column {r!r}{did} "
                             f"(found: {', '.join(header)}; required: {', '.join(req)})")
    warnings, close, unused = [], [], []
    # Euler angles are a reference only by name or --map: a logger's 'Roll' or 'Pitch' channel is
    # no misspelt column (and a heading-only run maps yaw alone)
    known = [k for k in list(req) + list(opt) if k not in EULER_COLUMNS]
    for h in extras:
        hint = difflib.get_close_matches(h, known, n=1, cutoff=0.75)
        hint = hint or [k for k in known if k.lower() == h.lower()]
        if hint and hint[0] not in seen:
            close.append(f"{fname}, line 1: unknown column {h!r}: did you mean `{hint[0]}`? "
                         f"(rename it, or --map {hint[0]}={h})")
        elif hint:
            warnings.append(f"{fname}: column {h!r} is not used and was ignored (did you mean {hint[0]!r}?)")
        else:
            unused.append(h)
    if len(unused) > MAX_UNUSED_LISTED:  # a logger's file holds dozens of channels: one line for them
        warnings.append(f"{fname}: {len(unused)} columns are not used and were ignored: "
                        f"{', '.join(repr(h) for h in unused[:MAX_UNUSED_LISTED])}, ...")
    else:
        warnings += [f"{fname}: column {h!r} is not used and was ignored" for h in unused]
    return warnings, close


def _check_order(cols: Columns, t: np.ndarray, kind: str) -> None:
    fname = file_label(cols.path)
    n = len(t)
    min_n = MIN_ATTITUDE_ROWS if kind == "attitude" else MIN_SAMPLES
    if n < 2:
        raise InputError(f"{fname}: only {n} data row(s); a run needs at least {min_n}")
    d = np.diff(t)
    bad = np.flatnonzero(~(d > 0))
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(f"{cols.where(i, 't')}: time not strictly increasing "
                         f"(t = {float(t[i])!r} after {float(t[i - 1])!r})")


#: the largest share of rows that may repeat the time stamp of the row before (a time column
#: printed coarser than the sampling, a logger writing two samples in one tick); more is refused
MAX_REPEATED_SHARE = 0.01


def _spread_repeated(cols: Columns, t: np.ndarray, notes: list) -> np.ndarray:
    """A few rows that repeat the time stamp of the row before (a motion-capture export whose
    90.9 Hz samples are stamped to 0.01 s, a logger writing two samples in one tick) are spread
    evenly between that stamp and the next different one, and said in a note naming the first
    such line; the rows and their data are kept, and the run is resampled like any other uneven
    time base. Stamps that go backwards, repeats in more than ``MAX_REPEATED_SHARE`` of the rows,
    and any repeat under ``--strict-time`` are refused (the order check)."""
    t = np.asarray(t, float)
    d = np.diff(t)
    rep = np.flatnonzero(d == 0) + 1
    if not rep.size or np.any(d < 0) or rep.size > MAX_REPEATED_SHARE * len(t):
        return t
    t = t.copy()
    step = float(np.median(d[d > 0])) if np.any(d > 0) else 0.0
    n = len(t)
    for a, b in true_runs(d == 0):
        b += 1  # rows a..b-1 share one stamp
        nxt = t[b] if b < n else t[a] + (b - a) * step
        t[a:b] = t[a] + (nxt - t[a]) * np.arange(b - a) / (b - a)
    notes.append(f"{file_label(cols.path)}: {rep.size} row(s) repeat the time stamp of the row before (first at "
                 f"{cols.where(int(rep[0]), 't')}); each was placed evenly between that stamp and the next")
    return t


def _step_tolerance(t: np.ndarray, quantum: float, fs: float | None) -> tuple[float, float]:
    """(nominal step, allowed deviation per step) of the strict check."""
    step = 1.0 / fs if fs else float(np.median(np.diff(t)))  # one odd step must not move it
    return step, JITTER_TOL * step + quantum + 4 * np.finfo(float).eps * float(np.max(np.abs(t[[0, -1]])))


def _is_uniform(t: np.ndarray, quantum: float, fs: float | None) -> bool:
    step, tol = _step_tolerance(t, quantum, fs)
    return bool(np.all(np.abs(np.diff(t) - step) <= tol))


def _check_time(cols: Columns, t: np.ndarray, quantum: float, fs: float | None, kind: str):
    """Order, uniform step within JITTER_TOL and the printed resolution (the strict check and
    the check of runs already uniform); returns (t, note)."""
    fname = file_label(cols.path)
    _check_order(cols, t, kind)
    n = len(t)
    d = np.diff(t)
    step, tol = _step_tolerance(t, quantum, fs)
    dev = np.abs(d - step)
    bad = np.flatnonzero(dev > tol)
    note = None
    if bad.size:
        i = int(bad[0]) + 1
        res = f" and the printed resolution {quantum:.3g} s" if quantum > 0 else ""
        if fs and np.mean(dev > tol) > 0.5:
            raise InputError(f"{fname}, column t: steps of {float(np.median(d)):.9g} s, but --fs {fs:g} "
                             f"gives {step:.9g} s")
        raise InputError(
            f"{cols.where(i, 't')}: non-uniform sampling (step {float(d[i - 1]):.9g} s where the others "
            f"are {step:.9g} s; relative deviation {float(dev[i - 1] / step):.2g} > {JITTER_TOL:g}{res}; "
            f"--strict-time refuses it: without that option the run is resampled, see "
            f"docs/measured-data.md, 'Time base')")
    if np.max(dev) > JITTER_TOL * step:
        # uniform within the printed resolution only: the exact grid is the run's time base
        # least-squares line through (k, t_k): the rounding errors average out
        k = np.arange(n, dtype=np.float64)
        kc = k - 0.5 * (n - 1)
        tbar = float(np.mean(t))
        dt = step if fs else float(np.dot(kc, t - tbar) / np.dot(kc, kc))
        t = tbar + kc * dt
        note = (f"{fname}: column t is printed with a resolution of {quantum:.3g} s; the run uses "
                f"the uniform grid t0 + k dt with dt = {dt:.12g} s")
    _check_size(fname, t, kind)
    return t, note


def _check_size(fname: str, t: np.ndarray, kind: str, what: str = "run") -> None:
    n = len(t)
    duration = t[-1] - t[0] if n else 0.0
    if kind != "attitude" and (n < MIN_SAMPLES or duration < MIN_DURATION_S):
        raise InputError(f"{fname}: {what} too short to say anything ({n} samples over {duration:.6g} s; "
                         f"need at least {MIN_SAMPLES} samples and {MIN_DURATION_S:g} s)")
    if kind == "attitude" and n < MIN_ATTITUDE_ROWS:
        raise InputError(f"{fname}: only {n} data rows; an attitude run needs at least {MIN_ATTITUDE_ROWS}")


def _check_cells(cols: Columns, name: str, col: str, v: np.ndarray, allow_empty: bool) -> None:
    e = cols.empty.get(col, -1)
    if e >= 0 and not allow_empty:
        extra = "" if name in ("t",) or name in KINDS["vehicle"][0] or name in KINDS["attitude"][0] \
            else " (an optional column must be complete or left out)"
        raise InputError(f"{cols.where(e, name)}: empty cell{extra}")
    nan = np.isnan(v)
    if nan.any() and not allow_empty:
        i = int(np.argmax(nan))
        raise InputError(f"{cols.where(i, name)}: NaN")
    inf = np.isinf(v)
    if inf.any():
        i = int(np.argmax(inf))
        raise InputError(f"{cols.where(i, name)}: infinite value {float(v[i])!r}")


def _attitude_columns(fname, header) -> list[str]:
    """Accelerometer triads a1x.. in order, contiguous; quaternion all four or none."""
    present = [c for c in ATTITUDE_OPTIONAL if c in header]
    if present and len(present) != 4:
        missing = [c for c in ATTITUDE_OPTIONAL if c not in header]
        raise InputError(f"{fname}, line 1: reference attitude needs qw, qx, qy, qz; missing {', '.join(missing)}")
    acc, k = [], 1
    while any(f"a{k}{a}" in header for a in "xyz"):
        trip = [f"a{k}{a}" for a in "xyz"]
        for c in trip:
            if c not in header:
                raise InputError(f"{fname}, line 1: accelerometer {k} needs {', '.join(trip)}; column {c} missing")
        acc += trip
        k += 1
    stray = [c for c in header if _ACC.match(c) and c not in acc]
    if stray:
        raise InputError(f"{fname}, line 1: accelerometer column(s) {', '.join(stray)} out of sequence "
                         f"(a1x.. must be contiguous)")
    euler = [c for c in EULER_COLUMNS if c in header]
    if euler and present:
        raise InputError(f"{fname}, line 1: the reference is given twice (qw..qz and {', '.join(euler)}); "
                         f"give one of them")
    if euler and "yaw" not in euler:
        raise InputError(f"{fname}, line 1: a reference in Euler angles needs yaw (the heading); "
                         f"{', '.join(euler)} alone do not make one")
    return present + euler + acc


def _euler_reference(fname: str, used: list, data: dict, cols: Columns, file_of: dict, notes: list) -> list:
    """Euler-angle reference columns (z-y-x, radians after ``--units``) turned into qw..qz where
    they stand, on the yaw's own times where channels keep their times (roll and pitch interpolated
    onto them); a missing roll or pitch is 0 (a heading-only reference, said in a note). Returns
    the used columns with qw..qz in place of the angles, and whether the reference is a heading
    only."""
    from scipy.spatial.transform import Rotation

    eul = [c for c in EULER_COLUMNS if c in used and c in data]
    if "yaw" not in eul:
        return used, False
    yaw = np.asarray(data["yaw"], float)
    t_yaw = cols.times.get("yaw") if cols.times else None

    def on_yaw(c):
        if c not in eul:
            return np.zeros_like(yaw)
        v = np.asarray(data[c], float)
        if t_yaw is None:
            return v
        tc = cols.times[c]
        ok = np.isfinite(v)
        return np.interp(t_yaw, tc[ok], v[ok], left=np.nan, right=np.nan)

    roll, pitch = on_yaw("roll"), on_yaw("pitch")
    fin = np.isfinite(yaw) & np.isfinite(roll) & np.isfinite(pitch)
    q = np.full((len(yaw), 4), np.nan)
    if fin.any():
        xyzw = Rotation.from_euler("ZYX", np.column_stack([yaw[fin], pitch[fin], roll[fin]])).as_quat()
        q[fin] = xyzw[:, [3, 0, 1, 2]]
    for i, c in enumerate(("qw", "qx", "qy", "qz")):
        data[c] = q[:, i]
        file_of[c] = f"{file_of['yaw']} (as {c})"
        cols.empty[c] = cols.empty.get("yaw", -1)
        if cols.times:
            cols.times[c] = t_yaw
    for c in eul:
        data.pop(c, None)
        if cols.times:
            cols.times.pop(c, None)
    heading = eul == ["yaw"]
    notes.append(f"{fname}: the reference is given as Euler angles ({', '.join(file_of[c] for c in eul)}; z-y-x, body "
                 "to world)" + ("; yaw alone: a heading-only reference, which tells rotation about the vertical "
                                "only" if heading else ""))
    return [c for c in used if c not in EULER_COLUMNS] + ["qw", "qx", "qy", "qz"], heading


def load_run(path, kind: str = "vehicle", *, map=None, units=None, fs: float | None = None,  # noqa: A002
             force: bool = False, model: dict | None = None, checks: bool = True,
             strict_time: bool = False) -> VehicleRun:
    """Read, validate and (``checks``) plausibility-check a run file of any supported format.

    ``kind``: ``vehicle``, ``durability`` (the vehicle columns) or ``attitude``. ``map``:
    ``"f1=Fz_FL,..."`` or a dict, contract name -> file column (a log's channel
    ``TOPIC:INSTANCE.FIELD``). ``units``: ``"f1=kN,t=ms"`` or a dict. ``fs``: the sample rate
    [Hz] (checked against ``t``; with no ``t`` column it makes the time base; for channels on
    their own times the grid rate). ``force``: plausibility problems become warnings. ``model``:
    the vehicle model for the static-load check (default: the seed's table). ``strict_time``:
    refuse a time column that is not uniform (else the time-base policy resamples it,
    docs/measured-data.md "Time base"; ``run.time_base`` says how).
    Returns a :class:`VehicleRun` (:class:`AttitudeRun` for attitude runs); raises InputError.
    """
    if kind not in KINDS:
        raise InputError(f"unknown kind of run {kind!r} (one of {', '.join(KINDS)})")
    if fs is not None and not (np.isfinite(fs) and fs > 0):
        raise InputError(f"--fs must be a positive rate in Hz, got {fs!r}")
    req, opt = KINDS[kind]
    fname = file_label(path)
    fmt = detect_format(path)
    known_names = tuple(req) + tuple(opt)
    notes, optional = [], ()
    if fmt in LOG_FORMATS:
        _open_check(path)
        map, header, notes, optional = _log_mapping(path, kind, map, known_names)  # noqa: A001
    else:
        header = read_header_any(path)
    mapping = parse_map(map, known_names)
    factors = parse_units(units)
    for col, file_col in mapping.items():
        if file_col not in header:
            hint = difflib.get_close_matches(file_col, header, n=1, cutoff=0.5)
            did = f"; did you mean `{hint[0]}`?" if hint else ""
            raise InputError(f"--map {col}={file_col}: {fname} has no column {file_col!r}{did}")
    to_contract = {v: k for k, v in mapping.items()}
    shadowed = [h for h in header if h in mapping and h not in to_contract]
    canon = [to_contract.get(h, h) for h in header if h not in shadowed]
    own_times = fmt in LOG_FORMATS or (fmt == "mf4" and not strict_time)
    synth_t = "t" not in canon and (fs is not None or fmt in ("mf4",) + LOG_FORMATS)
    if synth_t:
        canon = ["t"] + canon
    warnings, close = _check_names(fname, canon, kind)
    warnings += [f"{fname}: column {h!r} is not used (--map reads {to_contract.get(h, mapping[h])!r} from "
                 f"{mapping[h]!r})" for h in shadowed]
    used = [c for c in canon if c in req or c in opt]
    if kind == "attitude":
        used = list(req) + _attitude_columns(fname, canon)
    for c in factors:
        if c not in used:
            raise InputError(f"--units {c}=...: the run has no column {c!r}")
    file_of = {c: mapping.get(c, c) for c in used}
    want = [file_of[c] for c in used if not (c == "t" and synth_t)]
    cols = read_columns(path, want, fs=fs, time_col=("t" if synth_t and fmt == "mf4" else None),
                        resample=not own_times, optional=optional)
    if optional:  # a default reference the log does not have: no reference
        used = [c for c in used if c == "t" or file_of[c] in cols.data]
    data = {c: cols.data[file_of[c]] for c in used if file_of[c] in cols.data}
    if cols.times:
        cols.times = {c: cols.times[file_of[c]] for c in used if file_of[c] in cols.times}
        cols.windows = {c: cols.windows[file_of[c]] for c in used if file_of[c] in cols.windows}
    elif synth_t and "t" not in data:
        data["t"] = np.arange(cols.n) / fs
    cols.empty = {c: cols.empty.get(file_of[c], -1) for c in used}
    notes += list(cols.notes)
    converted, cols = _convert_units(fname, used, factors, cols, file_of, data, notes)
    heading_only = False
    if kind == "attitude":
        used, heading_only = _euler_reference(fname, used, data, cols, file_of, notes)
    q_t = cols.quantum.get(file_of["t"], 0.0) * converted.get("t", 1.0)
    for c in used:
        if c in data:
            _check_cells(cols, c, c, data[c], allow_empty=(kind == "attitude" and c in ATTITUDE_OPTIONAL))
    t, data, tb, refs, where = _time_base(cols, data, q_t, fs, kind, strict_time, notes)
    if kind != "attitude" and ("s1" in data) != ("s2" in data):
        warnings.append(f"{fname}: only one of s1, s2 given; it is used alone")
    problems = list(close)
    if checks:
        valid = np.ones(len(t), bool)
        for c, v in data.items():
            if c not in ATTITUDE_OPTIONAL:
                valid &= np.isfinite(v)
        rows = np.flatnonzero(valid) if not valid.all() else None  # (no copy of a complete run)
        t_ok, data_ok = (t, data) if rows is None else (t[rows], {c: v[rows] for c, v in data.items()})
        model_label = DEFAULT_MODEL_LABEL if model is None else "the given model"
        problems += plausibility_problems(
            kind, t_ok, data_ok,
            where=where if rows is None else (lambda i, c=None: where(int(rows[i]), c)),
            name_of=lambda c: file_of.get(c, c),
            model=dict(DEFAULT_MODEL if model is None else model), model_label=model_label,
            quantity_of=quantity_of,
            time_unit_known=own_times or synth_t or "t" in factors)
    if problems and not force:
        more = "\n  ".join(problems)
        raise InputError(f"{more}\n  (nothing computed; if the file is right, --force goes on anyway)")
    warnings += [f"{p} (--force: going on)" for p in problems]
    if kind != "attitude" and checks:
        t, data, refs, tb = _logger_faults(fname, t, data, refs, tb, notes)
    info = {"format": cols.fmt, "kind": kind, "columns": {c: file_of[c] for c in used},
            "units_converted": converted, "rate_hz": 1.0 / float((t[-1] - t[0]) / (len(t) - 1)),
            "notes": notes, "forced": bool(problems), "heading_only": bool(heading_only),
            "quantum": {c: cols.quantum.get(file_of[c], 0.0) * converted.get(c, 1.0) for c in used},
            "printed_steps": {c: (cols.steps[file_of[c]][0] * converted.get(c, 1.0) ** 2, cols.steps[file_of[c]][1])
                              for c in used if file_of[c] in cols.steps},
            "time_base": tb}
    if cols.meta:
        info["log"] = cols.meta
    cls = AttitudeRun if kind == "attitude" else VehicleRun
    return cls(path=str(path), t=t, channels=data, warnings=tuple(warnings), info=info, time_base=tb,
               references=refs)


def _logger_faults(fname, t, data, refs, tb, notes):
    """A force channel that goes dead or sticks for part of the run (:mod:`._faults`): the
    run is cut to its longest sound stretch, the faults named in ``time_base["logger_faults"]``;
    refused where the sound stretch is too short to analyse."""
    n = len(t)
    # a channel constant over the whole run is the plausibility check's (which --force overrides)
    faults = [f for f in find_faults(t, data, [c for c in ("f1", "f2") if c in data]) if f["rows"] != [0, n]]
    if not faults:
        return t, data, refs, tb
    i0, i1 = sound_part(n, faults)
    said = "; ".join(f["evidence"] for f in faults)
    if i1 - i0 < max(MIN_SAMPLES, SOUND_MIN_SHARE * n):
        raise InputError(f"{fname}: {said}; no stretch free of logger faults is long enough to analyse "
                         f"({i1 - i0} of {n} samples)")
    tb = dict(tb)
    tb["logger_faults"] = [{k: v for k, v in f.items() if k != "rows"} for f in faults]
    tb["sound_part_s"] = [float(t[i0]), float(t[i1 - 1])]
    notes.append(f"{fname}: logger fault(s) found before any cause was fitted: {said}; the run is analysed on "
                 f"t = {t[i0]:.6g} .. {t[i1 - 1]:.6g} s ({i1 - i0} of {n} samples), free of them")
    t_cut = t[i0:i1]
    refs = {c: (tr[(tr >= t_cut[0]) & (tr <= t_cut[-1])], v[(tr >= t_cut[0]) & (tr <= t_cut[-1])])
            for c, (tr, v) in refs.items()}
    return t_cut, {c: v[i0:i1] for c, v in data.items()}, refs, tb


def _convert_units(fname, used, factors, cols, file_of, data, notes) -> dict:
    """--units and the units an MDF4 file stores, converted to SI in place; returns the factors."""
    converted = {}
    for c in used:
        f = factors.get(c)
        stored = cols.units.get(file_of[c], "")
        if f is None and stored and quantity_of(c):
            table = UNITS[quantity_of(c)]
            if stored in table and table[stored] != 1.0:
                f = table[stored]
                notes.append(f"{fname}: {c} stored in {stored}, converted to SI")
        if f is not None and f != 1.0:
            if c in data:
                data[c] = data[c] * f
            converted[c] = f
    if "t" in converted and cols.times:
        cols = dataclasses.replace(cols, times={c: v * converted["t"] for c, v in cols.times.items()},
                                   windows={c: v * converted["t"] for c, v in cols.windows.items()})
    return converted, cols


def _time_base(cols: Columns, data: dict, q_t: float, fs, kind: str, strict: bool, notes: list):
    """The run's time base: (t, channels, time_base, references, where(row, col))."""
    fname = file_label(cols.path)
    t_raw = data.pop("t", None)
    if cols.times and strict:
        first = next(iter(cols.times.values()))
        if any(len(v) != len(first) or not np.array_equal(v, first) for v in cols.times.values()):
            raise InputError(f"{fname}: the channels are written at different times "
                             f"({', '.join(f'{c}: {len(v)} samples' for c, v in cols.times.items())}); "
                             f"--strict-time needs one time column (without it the run is resampled)")
        t_raw, cols = first, dataclasses.replace(cols, times={})
    if not cols.times:
        if not strict:
            t_raw = _spread_repeated(cols, t_raw, notes)
        _check_order(cols, t_raw, kind)
        if strict or _is_uniform(t_raw, q_t, fs):
            t, tnote = _check_time(cols, t_raw, q_t, fs, kind)
            if tnote:
                notes.append(tnote)
            refs = {}
            if kind == "attitude" and "qw" in data:
                refs = {"q": _reference(cols, data, lambda c: t, [c for c in REFERENCE_COLUMNS])}
            return t, data, uniform_time_base(t), refs, cols.where
    min_rows = MIN_ATTITUDE_ROWS if kind == "attitude" else MIN_SAMPLES
    t, data, refs, tb, more = apply_policy(cols, data, t_raw, kind, fs, min_rows)
    notes += more
    valid = np.ones(len(t), bool)
    for c, v in data.items():
        if c not in ATTITUDE_OPTIONAL:
            valid &= np.isfinite(v)
    _check_size(fname, t[valid], kind, "the analysed segment" if kind != "attitude" else "run")

    def where(i, col=None):
        return f"{fname}, near t = {float(t[i]):.6f} s" + (f", column {col}" if col else "")

    return t, data, tb, refs, where


def _log_mapping(path, kind, user_map, known) -> tuple[dict, list[str], list[str], tuple]:
    """A logger file's contract columns: the defaults (ULog: sensor_combined.gyro_rad,
    vehicle_attitude.q; a bag: its Imu topic) overridden by ``--map``; (map, header, notes,
    the default reference channels, read only where the log has them)."""
    from ._logs import canonical, default_map

    fmt = detect_format(path)
    user = parse_map(user_map, known)
    user = {k: canonical(v, fmt) for k, v in user.items()}
    need_default = fmt == "ulog" or any(c not in user for c in ATTITUDE_REQUIRED[1:])
    defaults, notes = default_map(path, kind) if need_default else ({}, [])
    if kind != "attitude":
        default_map(path, kind)  # the refusal: a logger file is an attitude run
    if any(c in user for c in ATTITUDE_OPTIONAL):
        defaults = {k: v for k, v in defaults.items() if k not in ATTITUDE_OPTIONAL}
    merged = {**defaults, **user}
    optional = tuple(v for k, v in defaults.items() if k in ATTITUDE_OPTIONAL and k not in user)
    return merged, list(merged.values()), notes, optional
