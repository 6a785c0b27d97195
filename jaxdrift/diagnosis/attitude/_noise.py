"""Gyro white noise: from the variance of high-order differences, and the Allan deviation (N, B, K).

- :func:`estimate_white_noise`: the variance of the k-th differences of each column, divided by
  ``C(2k, k)``, is the white-noise variance once the (smooth) motion no longer contributes; the order
  is raised until two consecutive orders agree. Its standard error follows from the MA(k)
  autocorrelation of differenced white noise (``sum rho^2 = C(4k,2k)/C(2k,k)^2``).
- :func:`allan`: overlapping Allan deviation (allantools) of an error series and a fit of N, B, K.
"""

from __future__ import annotations

import numpy as np

from .._diffnoise import diff_variance, first_plateau

__all__ = ["estimate_white_noise", "allan"]


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

