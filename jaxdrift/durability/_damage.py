"""Rainflow counting (ASTM E1049-85) and Basquin pseudo-damage of a load history.

The counting itself is the ``rainflow`` package's (``rainflow.extract_cycles``: the four-point
rule of ASTM E1049-85 section 5.4.4, residue counted as half cycles). Before counting, the history
is reduced to its turning points with numpy: rainflow counting depends on the sequence of
reversals only, so the cycles are the same, and the Python loop of the package runs over the
reversals instead of every sample (a 60 s, 1 kHz section force has about a quarter as many
reversals as samples).

Pseudo-damage with Basquin slope ``K`` (the S-N line ``N = C S^-K``; the constant ``C`` cancels in
every ratio, so it is left out)::

    D = sum_i n_i S_i^K          (n_i = 1 or 0.5 cycles of range S_i in N)

The damage-equivalent range ``S_eq = (D / N_ref)^(1/K)`` is the constant range that would do the same
damage in ``N_ref`` cycles (default 1e6).
"""

from __future__ import annotations

import numpy as np
import rainflow

__all__ = ["turning_points", "rainflow_cycles", "pseudo_damage", "load_statistics",
           "range_histogram", "N_REF"]

#: cycles of the damage-equivalent range
N_REF = 1.0e6


def turning_points(x) -> np.ndarray:
    """The reversals of ``x``: first and last sample and every local extremum (plateaus merged).

    Rainflow counting of the result equals that of ``x`` (the counted cycles use reversals only).
    """
    x = np.asarray(x, dtype=float).ravel()
    if x.size < 2:
        return x.copy()
    keep = np.concatenate([[True], np.diff(x) != 0])  # merge plateaus
    y = x[keep]
    if y.size < 3:
        return y
    d = np.diff(y)
    s = np.sign(d)
    ext = s[1:] != s[:-1]
    idx = np.concatenate([[0], np.nonzero(ext)[0] + 1, [y.size - 1]])
    return y[idx]


def rainflow_cycles(x) -> tuple[np.ndarray, np.ndarray]:
    """``(ranges, counts)`` of the rainflow cycles of ``x`` (counts 1.0 or 0.5), by ``rainflow``."""
    tp = turning_points(x)
    if not np.all(np.isfinite(tp)):
        raise ValueError("rainflow_cycles: the load history is not finite")
    if tp.size < 2:
        return np.zeros(0), np.zeros(0)
    rc = [(rng, cnt) for rng, _mean, cnt, _i0, _i1 in rainflow.extract_cycles(tp)]
    if not rc:
        return np.zeros(0), np.zeros(0)
    a = np.asarray(rc, dtype=float)
    return a[:, 0], a[:, 1]


def pseudo_damage(ranges, counts, k: float = 5.0) -> float:
    """``sum n_i S_i^k`` (ranges in N)."""
    ranges, counts = np.asarray(ranges, float), np.asarray(counts, float)
    return float(np.sum(counts * ranges ** float(k)))


def load_statistics(x, k: float = 5.0, n_ref: float = N_REF) -> dict:
    """RMS, max |f|, mean, pseudo-damage and damage-equivalent range of one load history."""
    x = np.asarray(x, dtype=float)
    ranges, counts = rainflow_cycles(x)
    d = pseudo_damage(ranges, counts, k)
    return {
        "rms": float(np.sqrt(np.mean(x**2))),
        "max_abs": float(np.max(np.abs(x))),
        "mean": float(np.mean(x)),
        "damage": d,
        "equivalent_range_N": float((d / n_ref) ** (1.0 / k)) if d > 0 else 0.0,
        "cycles": float(np.sum(counts)),
        "max_range": float(ranges.max()) if ranges.size else 0.0,
    }


def range_histogram(ranges, counts, edges) -> np.ndarray:
    """Cycles per range bin (``len(edges) - 1`` bins; ranges above the last edge go to the last bin)."""
    ranges = np.minimum(np.asarray(ranges, float), edges[-1])
    h, _ = np.histogram(ranges, bins=edges, weights=np.asarray(counts, float))
    return h
