"""Reading a table of numeric channels from CSV, Parquet or MDF4 (numpy and pyarrow, no JAX).

One entry point, :func:`read_columns`, for every kind of run. It returns the requested columns as
float64 arrays plus what the checks downstream need: where each row sits in the file (the line
number for CSV), the printed resolution of each CSV column (a time column printed with 9 decimals
has a resolution of 1e-9 s, which the time-step check must allow), and notes to show the user.

CSV goes through ``pyarrow.csv`` (vectorised, multithreaded); the per-cell Python parsing of the
first reader took 67 s and 2.2 GB for 5 million rows. The slow paths here run only to find the
line of an error. MDF4 (``.mf4``) needs the optional extra ``asammdf``.
"""

from __future__ import annotations

import csv
import dataclasses
import os
import re

import numpy as np

from ..errors import InputError

__all__ = ["Columns", "file_label", "read_header_any", "read_columns", "FORMATS"]

FORMATS = ("csv", "parquet", "mf4", "ulog", "bag")
#: a number as pyarrow accepts it for a float64 column (plus surrounding blanks)
_NUMBER = r"^\s*[-+]?((\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|nan|NaN|NAN|inf|Inf|INF|infinity|Infinity)\s*$"
_QUANTUM_BYTES = 1 << 18  # text read from each end of a CSV to find the printed resolution


def file_label(path) -> str:
    return os.path.basename(str(path)) or str(path)


@dataclasses.dataclass
class Columns:
    """Columns read from a file: ``data[name]`` float64 (NaN where a cell was empty or NaN),
    ``empty[name]`` first row index of an empty cell (or -1), ``first_line`` the file line of
    row 0 (CSV; 0 for binary formats, where messages give the row), ``quantum[name]`` the printed
    resolution (0 when not known), ``notes`` things the user should be told."""

    path: str
    fmt: str
    header: list[str]
    data: dict[str, np.ndarray]
    empty: dict[str, int]
    first_line: int
    quantum: dict[str, float]
    notes: list[str]
    rate_hz: float | None = None  # MDF4: the common rate the channels were resampled to
    units: dict[str, str] = dataclasses.field(default_factory=dict)  # MDF4: units stored per channel
    steps: dict[str, tuple] = dataclasses.field(default_factory=dict)  # CSV: (sum of step^2, cells) sampled
    #: multi-rate sources (MDF4, ULog, bags): each channel's own sample times [s]; ``data[name]``
    #: then holds that channel's samples as recorded (the time-base policy makes the grid)
    times: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)
    meta: dict = dataclasses.field(default_factory=dict)  # what a logger file says about itself
    #: channels that are means over their own integration windows (PX4 ``sensor_combined`` rates):
    #: each sample's window [s], ending at its time
    windows: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(next(iter(self.data.values()))) if self.data else 0

    def where(self, row: int, col: str | None = None) -> str:
        """``file, line L, column c`` (CSV) or ``file, row R, column c`` (binary formats)."""
        loc = f"line {self.first_line + row}" if self.fmt == "csv" else f"row {row + 1}"
        out = f"{file_label(self.path)}, {loc}"
        return out + (f", column {col}" if col else "")


def detect_format(path) -> str:
    from ._logs import log_format

    log = log_format(path)
    if log:
        return log
    ext = os.path.splitext(str(path))[1].lower()
    if ext in (".parquet", ".pq"):
        return "parquet"
    if ext in (".mf4", ".mdf"):
        return "mf4"
    return "csv"


def _open_check(path):
    if not os.path.exists(path):
        raise InputError(f"{path}: file not found")
    if os.path.isdir(path) and detect_format(path) != "bag":
        raise InputError(f"{path}: is a directory, expected a run file (CSV, Parquet, MF4, ULog, ROS bag) or a ROS 2 bag folder (with metadata.yaml)")
    if not os.access(path, os.R_OK):
        raise InputError(f"{path}: cannot read (permission denied)")


# ----------------------------------------------------------------------------------- CSV

def _csv_header(path) -> tuple[list[str], str, str]:
    """(names, delimiter, decimal point) from the first line(s) of a CSV file."""
    fname = file_label(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 16)
    except OSError as e:
        raise InputError(f"{path}: cannot read ({e.strerror})") from None
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        if e.start < len(head) - 4:  # not just a multibyte character cut at the block end
            raise InputError(f"{fname}: not a text CSV file ({e.reason} at byte {e.start})") from None
        text = head[: e.start].decode("utf-8-sig")
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise InputError(f"{fname}, line 1: empty file, expected a header row with column names")
    first = lines[0]
    delim = ","
    if "," not in first:
        for d in (";", "\t"):
            if d in first:
                delim = d
                break
    names = [h.strip() for h in next(csv.reader([first], delimiter=delim))]
    decimal = "."
    if delim != "," and len(lines) > 1 and re.search(r"\d,\d", lines[1]):
        decimal = ","  # 1,5;2,0 as European spreadsheets write it
    return names, delim, decimal


def _first_bad_cell(path, names, delim, decimal, col) -> tuple[int, str]:
    """Row index and text of the first cell of ``col`` that is not a number (error path)."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.csv as pcsv

    tab = pcsv.read_csv(
        path, read_options=pcsv.ReadOptions(skip_rows=1, column_names=names),
        parse_options=pcsv.ParseOptions(delimiter=delim, ignore_empty_lines=False),
        convert_options=pcsv.ConvertOptions(include_columns=[col], column_types={col: pa.string()},
                                            strings_can_be_null=True, null_values=[""]))
    s = tab.column(col)
    if decimal == ",":
        s = pc.replace_substring(s, ",", ".")
    ok = pc.fill_null(pc.match_substring_regex(s, _NUMBER), True)
    idx = pc.index(ok, False).as_py()
    return idx, tab.column(col)[idx].as_py()


def _first_ragged_line(path, delim, ncol) -> tuple[int, int]:
    """(line, cells) of the first line whose cell count differs from the header (error path)."""
    with open(path, newline="", encoding="utf-8-sig", errors="replace") as fh:
        for lineno, row in enumerate(csv.reader(fh, delimiter=delim), start=1):
            if len(row) != ncol and not (len(row) == 0):
                return lineno, len(row)
    return -1, -1


def _printed_digits(cell: str, decimal: str) -> tuple[int, int]:
    """(significant digits, decimal exponent of the last digit) of a printed number:
    ``0.000976562`` -> (6, -9), ``1.5e-3`` -> (2, -4), ``3`` -> (1, 0), ``0.00`` -> (0, -2);
    (-1, 0) for text that is no plain number."""
    s = cell.strip().lower().replace(decimal, ".").lstrip("+-")
    mant, _, exp = s.partition("e")
    try:
        e = int(exp) if exp else 0
    except ValueError:
        return -1, 0
    whole, _, frac = mant.partition(".")
    if not (whole + frac).isdigit():
        return -1, 0
    sig = len((whole + frac).lstrip("0"))
    return sig, e - len(frac)


def _text_quanta(path, names, delim, decimal, cols) -> dict[str, tuple[int, int, float, int]]:
    """Per column, the most significant digits and the finest last digit printed, from the text
    at both ends of the file (cells that are exact with fewer digits do not count against it),
    and the sum of squares and count of the cells' last-digit steps (their RMS rounding error is
    ``sqrt(sum / count / 12)``)."""
    size = os.path.getsize(path)
    with open(path, "rb") as fh:
        blocks = [fh.read(_QUANTUM_BYTES)]
        if size > 2 * _QUANTUM_BYTES:
            fh.seek(size - _QUANTUM_BYTES)
            blocks.append(fh.read())
    idx = {c: names.index(c) for c in cols}
    out = {c: (0, 0, 0.0, 0) for c in cols}
    for bi, b in enumerate(blocks):
        lines = b.decode("utf-8-sig", errors="replace").splitlines()
        lines = lines[1:-1] if (bi > 0 or size > _QUANTUM_BYTES) else lines[1:]
        for row in csv.reader(lines, delimiter=delim):
            if len(row) != len(names):
                continue
            for c, j in idx.items():
                sig, last = _printed_digits(row[j], decimal)
                s0, l0, sq, k = out[c]
                if sig >= 0:  # a number (0.0000 too: its last digit is a rounding step)
                    out[c] = (max(s0, sig), min(l0, last), sq + 10.0 ** min(2 * last, 300), k + 1)
    return out


def _quantum(v: np.ndarray, digits: tuple[int, int]) -> float:
    """Printed resolution of a column: the larger of the finest decimal printed and one unit in
    the last significant digit at the largest magnitude (for numbers printed to S digits)."""
    sig, last = digits[:2]
    if sig <= 0:
        return 0.0
    fin = v[np.isfinite(v)]
    vmax = float(np.max(np.abs(fin))) if fin.size else 0.0
    q_sig = 10.0 ** (np.floor(np.log10(vmax)) - sig + 1) if vmax > 0 else 0.0
    return float(max(10.0 ** last, q_sig))


def _read_csv(path, want: list[str]) -> Columns:
    import pyarrow as pa
    import pyarrow.csv as pcsv

    fname = file_label(path)
    names, delim, decimal = _csv_header(path)
    missing = [c for c in want if c not in names]
    if missing:
        raise InputError(f"{fname}, line 1: column {missing[0]!r} not found")
    try:
        tab = pcsv.read_csv(
            path,
            read_options=pcsv.ReadOptions(skip_rows=1, column_names=names, block_size=1 << 24),
            parse_options=pcsv.ParseOptions(delimiter=delim, ignore_empty_lines=False),
            convert_options=pcsv.ConvertOptions(
                include_columns=want, column_types={c: pa.float64() for c in want},
                null_values=[""], decimal_point=decimal))
    except pa.ArrowInvalid as e:
        msg = str(e)
        m = re.search(r"column #(\d+)", msg)
        if "conversion error" in msg:
            cols = [want[int(m.group(1))]] if m and int(m.group(1)) < len(want) else want
            for col in cols:
                row, text = _first_bad_cell(path, names, delim, decimal, col)
                if row is not None and row >= 0:
                    raise InputError(f"{fname}, line {row + 2}, column {col}: not a number: {text!r}") from None
        if "Expected" in msg:
            line, cells = _first_ragged_line(path, delim, len(names))
            if line > 0:
                raise InputError(f"{fname}, line {line}: {cells} cells but the header has {len(names)}") from None
        raise InputError(f"{fname}: cannot parse as CSV ({msg.splitlines()[0]})") from None
    except UnicodeDecodeError as e:
        raise InputError(f"{fname}: not a text CSV file ({e.reason})") from None
    except OSError as e:
        raise InputError(f"{path}: cannot read ({e})") from None
    n = tab.num_rows
    data, empty = {}, {}
    blank = None
    for c in want:
        col = tab.column(c)
        v = col.to_numpy()
        if v.dtype != np.float64:
            v = np.asarray(v, dtype=np.float64)
        data[c] = v
        empty[c] = -1
        if col.null_count:
            import pyarrow.compute as pc

            isnull = pc.is_null(col).to_numpy(zero_copy_only=False)
            blank = isnull if blank is None else blank & isnull
            empty[c] = int(np.argmax(isnull))
        else:
            blank = np.zeros(n, bool)
    if blank is not None and blank.any() and len(names) > 1:
        # a row with every cell empty is a blank line: allowed at the end only
        last = n
        while last > 0 and blank[last - 1]:
            last -= 1
        inside = np.flatnonzero(blank[:last])
        if inside.size:
            raise InputError(f"{fname}, line {int(inside[0]) + 2}: blank line inside the data")
        if last < n:
            data = {c: v[:last] for c, v in data.items()}
            empty = {c: (e if e < last else -1) for c, e in empty.items()}
    if not data or len(next(iter(data.values()))) == 0:
        raise InputError(f"{fname}: no data rows after the header")
    digits = _text_quanta(path, names, delim, decimal, want)
    quanta = {c: _quantum(data[c], digits[c]) for c in want}
    steps = {c: digits[c][2:] for c in want}
    notes = []
    if delim != ",":
        notes.append(f"{fname}: columns separated by {delim!r}" + (", decimal comma" if decimal == "," else ""))
    return Columns(str(path), "csv", names, data, empty, 2, quanta, notes, steps=steps)


# ----------------------------------------------------------------------------------- Parquet

def _parquet_header(path) -> list[str]:
    import pyarrow.parquet as pq

    try:
        return list(pq.read_schema(path).names)
    except Exception as e:  # noqa: BLE001 - pyarrow raises several types for a bad file
        raise InputError(f"{file_label(path)}: not a readable Parquet file ({e})") from None


def _read_parquet(path, want: list[str]) -> Columns:
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    fname = file_label(path)
    names = _parquet_header(path)
    tab = pq.read_table(path, columns=want)
    data, empty, quanta = {}, {}, {}
    for c in want:
        col = tab.column(c)
        if not (pa.types.is_floating(col.type) or pa.types.is_integer(col.type)):
            raise InputError(f"{fname}, column {c}: type {col.type}, expected numbers")
        empty[c] = int(np.argmax(pc.is_null(col).to_numpy(zero_copy_only=False))) if col.null_count else -1
        v = np.asarray(col.to_numpy(zero_copy_only=False), dtype=np.float64)
        data[c] = v
        # binary floats: the resolution is the storage precision
        eps = np.finfo(np.float32).eps if col.type == pa.float32() else np.finfo(np.float64).eps
        quanta[c] = float(eps * np.nanmax(np.abs(v))) if v.size and np.isfinite(v).any() else 0.0
    if tab.num_rows == 0:
        raise InputError(f"{fname}: no data rows")
    return Columns(str(path), "parquet", names, data, empty, 0, quanta, [])


# ----------------------------------------------------------------------------------- MDF4

MDF_MISSING = ("reading MDF4 files (.mf4) needs the optional extra 'mdf': "
               "pip install 'jaxdrift[mdf]' (installs asammdf)")


def _asammdf():
    try:
        import asammdf
    except ImportError:
        raise InputError(MDF_MISSING) from None
    return asammdf


def _mdf_open(path):
    asammdf = _asammdf()
    try:
        return asammdf.MDF(str(path))
    except Exception as e:  # noqa: BLE001 - asammdf raises many types for a bad file
        raise InputError(f"{file_label(path)}: not a readable MDF4 file ({e})") from None


def _mdf_names(mdf) -> list[str]:
    return sorted(n for n in mdf.channels_db if not n.startswith("$"))


def _read_mf4(path, want: list[str], fs: float | None, time_col: str | None, resample: bool = True) -> Columns:
    """Channels ``want`` (``time_col`` is the master time, not a channel): with ``resample``
    (``--strict-time``) interpolated linearly to one uniform time base (``fs`` if given, else the
    highest rate among the channels); without, each on its own times (:attr:`Columns.times`)."""
    fname = file_label(path)
    mdf = _mdf_open(path)
    try:
        sigs = {}
        for c in want:
            if c == time_col:
                continue
            try:
                s = mdf.get(c)
            except Exception as e:  # noqa: BLE001
                raise InputError(f"{fname}: channel {c!r}: {e}") from None
            ts = np.asarray(s.timestamps, dtype=np.float64)
            v = np.asarray(s.samples, dtype=np.float64)
            if ts.size < 2:
                raise InputError(f"{fname}, channel {c}: {ts.size} sample(s)")
            if np.any(np.diff(ts) <= 0):
                i = int(np.argmax(np.diff(ts) <= 0)) + 1
                raise InputError(f"{fname}, channel {c}, sample {i + 1}: time stamps not strictly increasing")
            sigs[c] = (ts, v, (s.unit or "").strip())
    finally:
        mdf.close()
    if not sigs:
        raise InputError(f"{fname}: no channels selected")
    rates = {c: (len(ts) - 1) / (ts[-1] - ts[0]) for c, (ts, _, _) in sigs.items()}
    if not resample:
        src = ", ".join(f"{c} {rates[c]:.6g} Hz" for c in sigs)
        return Columns(str(path), "mf4", list(sigs), {c: v for c, (_, v, _) in sigs.items()},
                       {c: -1 for c in sigs}, 0, {c: 0.0 for c in sigs},
                       [f"{fname}: channels read on their own times ({src})"],
                       units={c: u for c, (_, _, u) in sigs.items()},
                       times={c: ts for c, (ts, _, _) in sigs.items()})
    t0 = max(ts[0] for ts, _, _ in sigs.values())
    t1 = min(ts[-1] for ts, _, _ in sigs.values())
    if not t1 > t0:
        raise InputError(f"{fname}: the selected channels do not overlap in time")
    rate = float(fs) if fs else max(rates.values())
    n = int(np.floor((t1 - t0) * rate * (1 + 1e-12))) + 1
    t = t0 + np.arange(n) / rate
    data = {c: np.interp(t, ts, v) for c, (ts, v, _) in sigs.items()}
    uniform = all(abs(r - rate) <= 1e-6 * rate for r in rates.values())
    src = ", ".join(f"{c} {rates[c]:.6g} Hz" for c in sigs)
    notes = [f"{fname}: channels resampled (linear) to a common time base of {rate:.6g} Hz "
             f"over {t0:.6g} .. {t[-1]:.6g} s ({src})" + ("" if not uniform else "; rates already equal")]
    faster = [c for c in sigs if rates[c] > rate * (1 + 1e-6)]
    if faster:
        notes.append(f"{fname}: {', '.join(faster)} decimated from a higher rate by linear interpolation, "
                     f"without an anti-alias filter: content above {rate / 2:.6g} Hz folds back")
    units = {c: u for c, (_, _, u) in sigs.items()}
    if time_col:
        data[time_col] = t
    return Columns(str(path), "mf4", list(sigs), data, {c: -1 for c in data}, 0,
                   {c: 0.0 for c in data}, notes, rate_hz=rate, units=units)


# ----------------------------------------------------------------------------------- entry points

def read_header_any(path, fmt: str | None = None) -> list[str]:
    """The column (channel) names of a run file of any supported format."""
    _open_check(path)
    fmt = fmt or detect_format(path)
    if fmt == "parquet":
        return _parquet_header(path)
    if fmt in ("ulog", "bag"):
        from ._logs import default_map

        return sorted(set(default_map(path)[0].values()))
    if fmt == "mf4":
        mdf = _mdf_open(path)
        try:
            return _mdf_names(mdf)
        finally:
            mdf.close()
    return _csv_header(path)[0]


def read_columns(path, want: list[str], *, fmt: str | None = None, fs: float | None = None,
                 time_col: str | None = None, resample: bool = True, optional=()) -> Columns:
    """Read ``want`` (names as in the file) from a CSV, Parquet, MF4 run file or a logger file
    (ULog, ROS bag: channels on their own times). ``resample``: MF4 channels onto one time base
    at once (the ``--strict-time`` behaviour) rather than on their own times. ``optional``: log
    channels left out (with a note) where the log does not have them."""
    _open_check(path)
    fmt = fmt or detect_format(path)
    if fmt == "parquet":
        return _read_parquet(path, want)
    if fmt in ("ulog", "bag"):
        from ._logs import read_log

        series, notes, meta = read_log(path, [w for w in want if w != time_col], optional=optional)
        windows = meta.pop("windows", {})
        return Columns(str(path), fmt, list(series), {c: v for c, (_, v) in series.items()},
                       {c: -1 for c in series}, 0, {c: 0.0 for c in series}, notes,
                       times={c: t for c, (t, _) in series.items()}, meta=meta, windows=windows)
    if fmt == "mf4":
        return _read_mf4(path, want, fs, time_col, resample)
    return _read_csv(path, want)

