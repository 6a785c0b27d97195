"""White-noise levels from k-th differences, one estimator for the vehicle and attitude diagnoses.

The k-th difference of white noise of variance s^2 has variance ``C(2k, k) s^2``, while a signal
that is smooth at the sampling rate is damped by ``(2 sin(pi f dt))^(2k)``: the level read from the
differences is the noise's, plus what is left of the signal (an upper bound), and raising the order
until two consecutive orders agree takes the signal out (:func:`first_plateau`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["white_factor", "mad_sigma", "robust_diff_sigma", "diff_variance", "first_plateau"]


def white_factor(k: int) -> int:
    """``C(2k, k)``: the variance of the k-th difference of unit white noise."""
    return math.comb(2 * k, k)


def mad_sigma(x: np.ndarray) -> float:
    """The standard deviation of normal data from their median absolute deviation (1.4826 x MAD:
    robust to a few outliers)."""
    return float(np.median(np.abs(x - np.median(x))) * 1.4826)


def robust_diff_sigma(x: np.ndarray, k: int) -> float:
    """The white-noise standard deviation of a 1-D series from the median absolute deviation of
    its k-th difference (robust to a few glitches)."""
    return mad_sigma(np.diff(x, k)) / math.sqrt(white_factor(k))


def diff_variance(x: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Per column of ``x`` (rows: samples): the white-noise variance from the mean square of the
    k-th difference, its standard error (the differences are correlated over ``2k + 1`` samples:
    ``var_se = v sqrt(2 C(4k, 2k) / C(2k, k)^2 / rows)``) and the number of difference rows."""
    d = np.diff(x, k, axis=0)
    ck = white_factor(k)
    v = np.mean(d * d, axis=0) / ck
    rho2 = math.comb(4 * k, 2 * k) / ck**2
    return v, v * np.sqrt(2.0 * rho2 / d.shape[0]), d.shape[0]


def first_plateau(ests: list, value=lambda e: e[1], se=lambda e: e[2], total=None):
    """The estimate at the first order whose level agrees with the order before within 3 standard
    errors (every column), and True; or, where no two consecutive orders agree, the smallest
    (``total``: how to compare multi-column levels, default their sum) and False (an upper bound).
    ``ests``: one entry per order, in order."""
    for e, nxt in zip(ests[:-1], ests[1:]):
        if np.all(np.abs(value(e) - value(nxt)) <= 3.0 * np.maximum(se(e), se(nxt)) + 1e-300):
            return nxt, True, e
    return min(ests, key=lambda e: float(np.sum(value(e))) if total is None else total(e)), False, None
