"""Gyro white noise: from the variance of high-order differences, and the Allan deviation (N, B, K).

- :func:`estimate_white_noise`: the variance of the k-th differences of each column, divided by
  ``C(2k, k)``, is the white-noise variance once the (smooth) motion no longer contributes; the order
  is raised until two consecutive orders agree. Its standard error follows from the MA(k)
  autocorrelation of differenced white noise (``sum rho^2 = C(4k,2k)/C(2k,k)^2``).
- :func:`block_white_noise`: the same white level from the means of blocks of ``m`` samples of a
  still span (``m`` times the Allan variance at ``m dt``, which is the per-sample variance for
  white noise at every ``m``). A gyro whose samples are filtered or averaged inside the sensor (a
  PX4 log's ``sensor_combined``) has less noise near the sampling rate than below its cutoff: the
  differences see the former, the block means the latter, which is what an angle integrates.
- :func:`allan`: overlapping Allan deviation (allantools) of an error series and a fit of N, B, K.
- :func:`recorded_rates`: the rates as the logger recorded them over a span of the grid: every
  level above is measured on them, not on the grid, where the run was resampled.
"""

from __future__ import annotations

import numpy as np

from .._diffnoise import diff_variance, first_plateau

__all__ = ["estimate_white_noise", "allan", "block_white_noise", "recorded_rates", "white_noise_recorded", "to_grid"]

#: block sizes need this many blocks for the level of their means
BLOCK_MIN_BLOCKS = 128
#: the longest block [s]: a gyro's own filter settles far sooner (its cutoff is tens of Hz), while
#: longer blocks see the slow motion a "still" body still has
BLOCK_MAX_S = 0.15


def recorded_rates(run, i0: int, i1: int):
    """``(rates, step)``: the gyro's samples as recorded between grid rows ``i0`` and ``i1 - 1``
    and their median step, where the run was resampled onto its grid (a log's own times jitter, or
    its streams are merged); else the grid's rows and ``dt``. A linear interpolation between two
    samples averages them: at half a step it keeps half of white noise's variance and, of its k-th
    differences, less the higher k (on a ROS bag's 82 Hz IMU, 2.3 times less in std at order 4),
    so a level read on the grid is below the sensor's."""
    tr, wr = run.get("w_recorded_t"), run.get("w_recorded")
    tb = run.get("time_base") or {}
    if tr is None or wr is None or not tb.get("resampled") or i1 - i0 < 2:
        return run["w"][i0:i1], run["dt"]
    t = run["t"]
    tol = 1e-6 * run["dt"]
    a = int(np.searchsorted(tr, t[i0] - tol, side="left"))
    b = int(np.searchsorted(tr, t[i1 - 1] + tol, side="right"))
    x = np.asarray(wr[a:b], float)
    if b - a < max(2, (i1 - i0) // 2) or not np.all(np.isfinite(x)):
        return run["w"][i0:i1], run["dt"]
    return x, float(np.median(np.diff(tr[a:b])))


def white_noise_recorded(run, i0: int, i1: int, max_order: int = 8):
    """:func:`estimate_white_noise` on the rates as recorded over grid rows ``[i0, i1)``
    (:func:`recorded_rates`), its variances in per-grid-sample units (times the recorded step over
    ``dt``), so that ``var * dt`` is the density's square either way."""
    x, dtr = recorded_rates(run, i0, i1)
    wn = estimate_white_noise(x, dtr, max_order)
    return to_grid(wn, dtr, run["dt"])


def to_grid(wn, dtr, dt):
    """A level dict measured at step ``dtr`` in per-sample units of step ``dt``."""
    r = dtr / dt
    if r == 1.0:
        return wn
    out = dict(wn, dt=dt)
    for key in ("var", "var_se", "var_method"):
        if key in wn:
            out[key] = np.asarray(wn[key]) * r
    if "sigma" in wn:
        out["sigma"] = np.asarray(wn["sigma"]) * np.sqrt(r)
    return out


def estimate_white_noise(x, dt, max_order: int = 8):
    """White-noise standard deviation of each column of ``x`` from k-th differences.

    Returns a dict with ``sigma`` (per column, per sample), ``var_se``, ``order`` and ``plateau``
    (False when the motion still dominated the highest order: then ``sigma`` is an upper bound).
    """
    x = np.asarray(x, float)
    n = x.shape[0]
    ests = [(k, *diff_variance(x, k)[:2]) for k in range(1, max_order + 1) if n - k >= 8]
    chosen, plateau, before = first_plateau(ests)
    # the motion's share left at the chosen order: each order damps a motion at f by
    # (2 sin(pi f dt))^2 / (C(2k+2, k+1) / C(2k, k)) ~ sin^2(pi f dt), at most 1/2 below fs/4, so
    # the share left is at most the change from the order before (per column)
    leak = np.abs(before[1] - chosen[1]) if plateau else np.zeros_like(chosen[1])
    k, v, se = chosen
    return {"sigma": np.sqrt(v), "var": v, "var_se": se, "var_method": leak, "order": k, "plateau": plateau, "dt": dt}


def block_white_noise(x, dt, min_blocks: int = BLOCK_MIN_BLOCKS):
    """White-noise level of each column of a still span ``x`` from block means.

    For ``m = 1, 2, 4, ...`` (at least ``min_blocks`` blocks, at most :data:`BLOCK_MAX_S`):
    ``v_m = m / 2 * s^2`` per column, ``s`` the robust (MAD) spread of ``b_{k+1} - b_k`` (``b``:
    the means of consecutive blocks of ``m`` samples), the per-sample variance of white noise at
    every ``m``. Returns ``None`` when the span is too short, else a dict with ``m`` (the block
    size of the plateau: the last of the first chain of sizes whose ``v_m`` and ``v_2m`` agree
    within two standard errors, averaged over the columns), ``var`` (per column, per-sample
    units), ``var_se`` and the whole ``ladder`` [(m, mean v_m, se)]; ``plateau`` is False when
    ``v_m`` still changes at the largest block size.
    """
    x = np.asarray(x, float)
    n = x.shape[0]
    ladder = []
    m = 1
    while n // m >= min_blocks and m * dt <= BLOCK_MAX_S:
        nb = n // m
        b = x[: nb * m].reshape(nb, m, -1).mean(axis=1)
        d = np.diff(b, axis=0)
        # robust (MAD) spread: a "still" span's edge may hold some of the motion around it
        v = 0.5 * m * (1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0)) ** 2
        # adjacent differences share a block (about 1.5 x the variance of nb - 1 independent ones),
        # and the MAD's efficiency is 37 % of the variance's
        se = v * np.sqrt(1.5 * 2.0 / (nb - 1) / 0.37)
        ladder.append((m, v, se))
        m *= 2
    if len(ladder) < 2:
        return None

    def agree(a, b):
        se = float(np.sqrt(np.mean(a[2] ** 2 + b[2] ** 2) / a[1].size))
        return abs(float(np.mean(b[1])) - float(np.mean(a[1]))) <= 2.0 * se

    i = 0
    while i < len(ladder) - 1:
        if agree(ladder[i], ladder[i + 1]):
            # a filter's level is approached from below: the last block size that still agrees
            # with the one before (until slow motion lifts the level further)
            j = i + 1
            while j + 1 < len(ladder) and agree(ladder[j], ladder[j + 1]):
                j += 1
            if j + 1 < len(ladder) and float(np.mean(ladder[j + 1][1])) < float(np.mean(ladder[j][1])):
                # the level falls after it: no filtered white noise (which stays once reached) but a
                # vibration the blocks have begun to average out (sinusoids at 0.08-0.3 of the rate
                # read 2.88, 4.68, 4.69, 3.35 mrad/s per sample at 1, 2, 4, 8 samples)
                i = j + 1
                continue
            m0, v0, s0 = ladder[j]
            return {"m": m0, "var": v0, "var_se": s0, "plateau": True, "dt": dt,
                    "ladder": [(mm, float(np.mean(vv)), float(np.mean(ss))) for mm, vv, ss in ladder]}
        i += 1
    m0, v0, s0 = ladder[-1]
    return {"m": m0, "var": v0, "var_se": s0, "plateau": False, "dt": dt,
            "ladder": [(mm, float(np.mean(vv)), float(np.mean(ss))) for mm, vv, ss in ladder]}


def allan(series, dt):
    """Overlapping Allan deviation per axis (allantools) and a fit of N, B, K (IEEE 952)."""
    import allantools

    out = {"taus": None, "adev": [], "fit": None}
    n = series.shape[0]
    taus_all = None
    for c in range(series.shape[1]):
        taus, adev, _, _ = allantools.oadev(series[:, c], rate=1.0 / dt, data_type="freq", taus="octave")[:4]
        keep = taus <= n * dt / 9.0  # enough averages for a stable estimate
        taus_all = taus[keep]
        out["adev"].append(adev[keep])
    out["taus"] = taus_all
    av = np.mean(np.square(out["adev"]), axis=0)  # axis-averaged Allan variance
    # sigma^2(tau) = N^2 / tau + (0.664 B)^2 + K^2 tau / 3, fitted with relative weights (NNLS)
    from scipy.optimize import nnls

    X = np.stack([1.0 / taus_all, np.full_like(taus_all, 0.664**2), taus_all / 3.0], 1)
    wgt = 1.0 / np.maximum(av, 1e-300)
    coef, _ = nnls(X * wgt[:, None], av * wgt)
    N_, B_, K_ = np.sqrt(coef)
    out["fit"] = {"N": float(N_), "B": float(B_), "K": float(K_)}
    return out

