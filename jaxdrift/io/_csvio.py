"""Reading and validating measured runs (CSV) and vehicle models (JSON).

The formats are the contract in ``docs/measured-data.md``. Everything here is plain Python and
numpy (no JAX), so bad input is refused fast and before any computation. Every refusal is an
:class:`InputError` whose message names the file, the line (1-based, as an editor shows it; the
header is line 1) or the column, and what is wrong; the CLI turns it into
``jaxdrift.cli.UsageError`` (exit code 2).
"""

from __future__ import annotations

import csv
import dataclasses
import difflib
import json
import math
import os
from typing import Mapping

import numpy as np

from ..errors import InputError

__all__ = [
    "InputError",
    "VehicleRun",
    "MODEL_KEYS",
    "DEFAULT_MODEL",
    "VEHICLE_REQUIRED",
    "VEHICLE_OPTIONAL",
    "MIN_SAMPLES",
    "MIN_DURATION_S",
    "read_header",
    "read_vehicle_run",
    "read_model",
    "write_vehicle_run",
]

#: The seed's parameter names, in the seed's order.
MODEL_KEYS: tuple[str, ...] = (
    "a", "b", "m1", "m2", "m3", "I", "k1", "k2", "k3", "k4", "d1", "d2", "d3", "d4", "g",
)
#: The seed's parameter table (the default model).
DEFAULT_MODEL: dict[str, float] = {
    "a": 1.0, "b": 1.0, "m1": 15.0, "m2": 15.0, "m3": 750.0, "I": 500.0,
    "k1": 2.0e5, "k2": 2.0e5, "k3": 1.0e5, "k4": 1.0e5,
    "d1": 2.0e2, "d2": 2.0e2, "d3": 1.0e4, "d4": 1.0e4, "g": 9.81,
}

VEHICLE_REQUIRED: tuple[str, ...] = ("t", "f1", "f2")
VEHICLE_OPTIONAL: tuple[str, ...] = ("beta", "beta_rate", "z3", "s1", "s2", "zeta1", "zeta2")

#: A run needs at least this many samples and this duration to say anything about drift:
#: the chassis modes of the seed's vehicle have time constants of about 0.1-1 s.
MIN_SAMPLES = 100
MIN_DURATION_S = 1.0
#: Relative jitter allowed on the sample spacing (the spec: below 1e-6).
JITTER_TOL = 1e-6


@dataclasses.dataclass(frozen=True)
class VehicleRun:
    """A validated vehicle run: uniform time grid and the channels present (float64 arrays)."""

    path: str
    t: np.ndarray
    channels: dict[str, np.ndarray]
    warnings: tuple[str, ...] = ()

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


def _name(path) -> str:
    return os.path.basename(str(path)) or str(path)


def read_header(path) -> list[str]:
    """The column names of a CSV file (stripped), or InputError if it cannot be read."""
    fname = _name(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header = next(reader, None)
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, expected a CSV file") from None
    except UnicodeDecodeError as e:
        raise InputError(f"{fname}: not a text CSV file ({e.reason} at byte {e.start})") from None
    except OSError as e:
        raise InputError(f"{path}: cannot read ({e.strerror})") from None
    if header is None or not any(h.strip() for h in header):
        raise InputError(f"{fname}, line 1: empty file, expected a header row with column names")
    return [h.strip() for h in header]


def _check_columns(fname: str, header: list[str], required, optional) -> list[str]:
    """Check names: duplicates, empty names, missing required ones. Returns warnings."""
    for i, h in enumerate(header):
        if h == "":
            raise InputError(f"{fname}, line 1, column {i + 1}: empty column name in the header")
    seen: dict[str, int] = {}
    for i, h in enumerate(header):
        if h in seen:
            raise InputError(
                f"{fname}, line 1: column {h!r} appears twice (columns {seen[h] + 1} and {i + 1})"
            )
        seen[h] = i
    known = set(required) | set(optional)
    for req in required:
        if req not in seen:
            extras = [h for h in header if h not in known]
            hint = difflib.get_close_matches(req, extras, n=1, cutoff=0.5)
            if not hint:
                hint = [h for h in extras if h.lower() == req.lower()]
            did = f"; did you mean {hint[0]!r}? (names are case-sensitive)" if hint else ""
            raise InputError(
                f"{fname}, line 1: missing required column {req!r}{did} "
                f"(found: {', '.join(header)}; required: {', '.join(required)})"
            )
    warnings = []
    for h in header:
        if h not in known:
            hint = difflib.get_close_matches(h, sorted(known), n=1, cutoff=0.6)
            did = f" (did you mean {hint[0]!r}?)" if hint else ""
            warnings.append(f"{fname}: column {h!r} is not used and was ignored{did}")
    return warnings


def _parse_float(fname: str, line: int, col: str, cell: str) -> float:
    s = cell.strip()
    if s == "":
        raise InputError(f"{fname}, line {line}, column {col}: empty cell")
    try:
        v = float(s)
    except ValueError:
        raise InputError(f"{fname}, line {line}, column {col}: not a number: {s!r}") from None
    if math.isnan(v):
        raise InputError(f"{fname}, line {line}, column {col}: NaN")
    if math.isinf(v):
        raise InputError(f"{fname}, line {line}, column {col}: infinite value {s!r}")
    return v


def _check_time(fname: str, t: np.ndarray, first_line: int) -> None:
    n = len(t)
    if n < 2:
        raise InputError(f"{fname}: only {n} data row(s); a run needs at least {MIN_SAMPLES}")
    d = np.diff(t)
    bad = np.flatnonzero(d <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(
            f"{fname}, line {first_line + i}, column t: time not strictly increasing "
            f"(t = {float(t[i])!r} after {float(t[i - 1])!r})"
        )
    dt = float(np.median(d))  # the nominal step; one odd step must not move it
    dev = np.abs(d - dt) / dt
    bad = np.flatnonzero(dev > JITTER_TOL)
    if bad.size:
        i = int(bad[0]) + 1
        raise InputError(
            f"{fname}, line {first_line + i}, column t: non-uniform sampling (step "
            f"{float(d[i - 1]):.9g} s where the others are {dt:.9g} s; relative deviation "
            f"{float(dev[i - 1]):.2g} > {JITTER_TOL:g})"
        )
    duration = t[-1] - t[0]
    if n < MIN_SAMPLES or duration < MIN_DURATION_S:
        raise InputError(
            f"{fname}: run too short to say anything ({n} samples over {duration:.6g} s; "
            f"need at least {MIN_SAMPLES} samples and {MIN_DURATION_S:g} s)"
        )


def read_table(path, required, optional) -> tuple[np.ndarray, list[str], list[str], int]:
    """Read a numeric CSV: returns (data (n, ncols) with NaN for empty optional cells,
    header, warnings, first data line). Required columns must be complete."""
    fname = _name(path)
    header = read_header(path)
    warnings = _check_columns(fname, header, required, optional)
    used = [i for i, h in enumerate(header) if h in set(required) | set(optional)]
    req_idx = {header.index(r) for r in required}
    rows = []
    with open(path, newline="", encoding="utf-8-sig") as fh:
        reader = csv.reader(fh)
        next(reader)
        for lineno, row in enumerate(reader, start=2):
            if not row or all(c.strip() == "" for c in row):
                if len(row) <= 1:  # a blank line (for example at the end)
                    continue
            if len(row) != len(header):
                raise InputError(
                    f"{fname}, line {lineno}: {len(row)} cells but the header has {len(header)}"
                )
            vals = []
            for i in used:
                cell = row[i]
                if i in req_idx:
                    vals.append(_parse_float(fname, lineno, header[i], cell))
                elif cell.strip() == "":
                    vals.append(math.nan)
                else:
                    vals.append(_parse_float(fname, lineno, header[i], cell))
            rows.append((lineno, vals))
    if not rows:
        raise InputError(f"{fname}: no data rows after the header")
    lines = [r[0] for r in rows]
    if lines != list(range(lines[0], lines[0] + len(lines))):
        # blank lines inside the data: refuse, the line numbers would lie
        for a, b in zip(lines, lines[1:]):
            if b != a + 1:
                raise InputError(f"{fname}, line {a + 1}: blank line inside the data")
    data = np.array([r[1] for r in rows], dtype=float).reshape(len(rows), len(used))
    return data, [header[i] for i in used], warnings, lines[0]


def read_vehicle_run(path) -> VehicleRun:
    """Read and validate a vehicle run CSV (``docs/measured-data.md``)."""
    fname = _name(path)
    data, cols, warnings, first = read_table(path, VEHICLE_REQUIRED, VEHICLE_OPTIONAL)
    t = data[:, cols.index("t")]
    _check_time(fname, t, first)
    channels = {}
    for j, c in enumerate(cols):
        if c == "t":
            continue
        v = data[:, j]
        bad = np.flatnonzero(~np.isfinite(v))
        if bad.size:
            raise InputError(
                f"{fname}, line {first + int(bad[0])}, column {c}: empty cell "
                f"(an optional column must be complete or left out)"
            )
        channels[c] = v
    if "s1" in channels and "s2" not in channels or "s2" in channels and "s1" not in channels:
        warnings.append(f"{fname}: only one of s1, s2 given; it is used alone")
    return VehicleRun(path=str(path), t=t, channels=channels, warnings=tuple(warnings))


def read_model(path) -> dict[str, float]:
    """Read and validate a vehicle model JSON: exactly the seed's keys, all positive numbers."""
    fname = _name(path)
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except (IsADirectoryError, UnicodeDecodeError, OSError) as e:
        raise InputError(f"{path}: cannot read ({e})") from None
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(f"{fname}, line {e.lineno}, column {e.colno}: invalid JSON ({e.msg})") from None
    return validate_model(obj, fname)


def validate_model(obj, fname: str = "model") -> dict[str, float]:
    if not isinstance(obj, Mapping):
        raise InputError(f"{fname}: expected a JSON object with keys {', '.join(MODEL_KEYS)}")
    unknown = [k for k in obj if k not in MODEL_KEYS]
    if unknown:
        missing = [k for k in MODEL_KEYS if k not in obj]
        hint = difflib.get_close_matches(unknown[0], missing or MODEL_KEYS, n=1, cutoff=0.5)
        did = f" (did you mean {hint[0]!r}?)" if hint else ""
        raise InputError(f"{fname}: unknown key {unknown[0]!r}{did}; keys are {', '.join(MODEL_KEYS)}")
    missing = [k for k in MODEL_KEYS if k not in obj]
    if missing:
        raise InputError(f"{fname}: missing key(s) {', '.join(missing)} (all of {', '.join(MODEL_KEYS)} are required)")
    out = {}
    for k in MODEL_KEYS:
        v = obj[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(f"{fname}: key {k!r} must be a number, got {v!r}")
        v = float(v)
        if not math.isfinite(v) or v <= 0:
            raise InputError(f"{fname}: key {k!r} must be a positive number, got {v!r}")
        out[k] = v
    return out


def write_vehicle_run(path, t, channels: Mapping[str, np.ndarray]) -> None:
    """Write a vehicle run CSV (full float precision), columns ``t`` then the channels."""
    names = ["t"] + list(channels)
    cols = [np.asarray(t, dtype=float)] + [np.asarray(channels[c], dtype=float) for c in channels]
    data = np.column_stack(cols)
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "w", newline="") as fh:
        fh.write(",".join(names) + "\n")
        np.savetxt(fh, data, delimiter=",", fmt="%.17g")
    os.replace(tmp, path)
