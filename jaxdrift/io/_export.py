"""A logger file (ULog, ROS bag) written as an attitude-run CSV as recorded (numpy and pyarrow).

Nothing is resampled: one row per sample of the rate topic, at its own (jittered) time, with the
gaps as they are; the reference quaternion only on the row nearest each of its samples (empty
cells elsewhere). The file is what a user would export by hand, and reads back through
:func:`jaxdrift.io.load_run` with the same time-base policy as the log itself.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ._logs import log_format, read_log
from ._outputs import atomic_path

__all__ = ["export_recorded_csv", "nearest_rows"]

RATES = ("wx", "wy", "wz")
QUAT = ("qw", "qx", "qy", "qz")


def nearest_rows(t_rows: np.ndarray, t_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For samples at ``t_ref``, the index of the nearest row of ``t_rows`` (increasing); samples
    outside the rows' span (by more than half the median step) are left out, and where two share
    a row the nearer one is kept. Returns (row indices, indices into t_ref)."""
    if len(t_rows) == 0 or len(t_ref) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    half = 0.5 * float(np.median(np.diff(t_rows))) if len(t_rows) > 1 else 0.0
    j = np.clip(np.searchsorted(t_rows, t_ref), 1, max(len(t_rows) - 1, 1))
    left = np.maximum(j - 1, 0)
    k = np.where(np.abs(t_ref - t_rows[left]) <= np.abs(t_rows[j] - t_ref), left, j)
    dist = np.abs(t_rows[k] - t_ref)
    src = np.flatnonzero((t_ref >= t_rows[0] - half) & (t_ref <= t_rows[-1] + half))
    k, dist = k[src], dist[src]
    order = np.lexsort((dist, k))
    k, src = k[order], src[order]
    first = np.concatenate([[True], k[1:] != k[:-1]])
    return k[first], src[first]


def _column(v: np.ndarray):
    import pyarrow as pa

    fin = v[np.isfinite(v)]
    exact32 = fin.size and np.array_equal(fin.astype(np.float32).astype(np.float64), fin)
    mask = ~np.isfinite(v)
    typ = pa.float32() if exact32 else pa.float64()
    return pa.array(v.astype(np.float32) if exact32 else v, type=typ, mask=mask)


def export_recorded_csv(path, out, map=None) -> dict:  # noqa: A002
    """Write the log's rates (and reference, where the log has one) to ``out`` as recorded:
    ``t`` in seconds from the first rate sample, ``wx, wy, wz`` (rad/s), ``qw..qz`` only on the
    row nearest each reference sample. ``map`` as for :func:`jaxdrift.io.load_run`. Returns what
    was written (rows, reference rows, channels)."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    from ._runs import ATTITUDE_OPTIONAL, ATTITUDE_REQUIRED, _log_mapping

    if log_format(path) is None:
        raise InputError(f"{path}: not a logger file (.ulg, .bag, a ROS 2 bag folder, .db3, .mcap)")
    mapping, _, notes, optional = _log_mapping(path, "attitude", map, ATTITUDE_REQUIRED + ATTITUDE_OPTIONAL)
    want = [mapping[c] for c in RATES] + [mapping[c] for c in QUAT if c in mapping]
    series, more, _ = read_log(path, want, optional=optional)
    notes += more
    tw = series[mapping["wx"]][0]
    for c in RATES[1:]:
        if not np.array_equal(series[mapping[c]][0], tw):
            raise InputError(f"{path}: wx and {c} ({mapping['wx']}, {mapping[c]}) are not sampled at the same "
                             f"times; the CSV export needs the rates from one topic")
    t = np.round(tw - tw[0], 9)
    cols = {"t": pa.array(t)}
    cols.update({c: _column(series[mapping[c]][1]) for c in RATES})
    ref_rows = 0
    if all(c in mapping and mapping[c] in series for c in QUAT):
        tq = series[mapping["qw"]][0]
        rows, src = nearest_rows(tw, tq)
        ref_rows = int(len(rows))
        if ref_rows < len(tq):
            notes.append(f"{path}: {len(tq) - ref_rows} of {len(tq)} reference samples have no rate row of "
                         f"their own (outside the rates' span, or sharing the nearest row with a nearer "
                         f"sample, as in a gap of the rates) and are not in the CSV")
        for c in QUAT:
            v = np.full(len(tw), np.nan)
            v[rows] = series[mapping[c]][1][src]
            cols[c] = _column(v)
    table = pa.table(cols)
    with atomic_path(out) as tmp:
        with open(tmp, "wb") as fh:
            fh.write((",".join(cols) + "\n").encode())
            pcsv.write_csv(table, fh, pcsv.WriteOptions(include_header=False, quoting_style="none"))
    return {"rows": int(len(tw)), "reference_rows": ref_rows, "t0_s": float(tw[0]),
            "columns": {c: mapping[c] for c in cols if c != "t"}, "notes": notes}
