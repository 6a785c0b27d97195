"""Derivatives of a measured, noisy signal (the pitch angle) for the prescribed-pitch simulation.

Prescribing the measured pitch (seed (4.4)/(A.5)) needs ``beta'`` (the dampers ``d3, d4``
multiply it, so it enters the section forces directly) and ``beta''`` (the enforced moment).
A plain finite difference of an angle with white noise of standard deviation ``sigma`` at step
``dt`` has a rate noise of about ``sigma / dt``: 0.01 deg at 500 Hz is 0.087 rad/s, which through
``d3 b`` is 870 N of white noise on ``f3``. So the signal is low-pass filtered first, with a
cutoff read from the data:

1. **noise level** ``sigma``: the smaller of two estimates (:func:`noise_level`): the 4th
   differences of the signal, which remove a smooth signal and leave ``70 sigma^2`` of white noise
   variance (robust scale, 1.4826 x median absolute deviation, so that a few steps in the signal do
   not count as noise), and the mean Welch PSD above ``SPECTRUM_BAND x fs`` (``sigma^2 = PSD fs / 2``);
2. **cutoff**: the Welch PSD ``P`` of the signal (segments of ``WELCH_SEGMENT_S``) and the white
   noise floor ``N0 = 2 sigma^2 dt`` (one-sided) give the frequency ``f*`` that minimises the
   mean-square error of the derivative behind an ideal low-pass: the signal power of ``x'`` lost
   above ``f*``, ``sum (2 pi f)^2 (P - N0) df``, plus the noise power of ``x'`` let through below it,
   ``sum (2 pi f)^2 N0 df`` (sums, not a threshold on single bins, so the scatter of the PSD
   estimate and the notches of the signal's spectrum, such as the wheelbase filter, do not move it
   much). The Butterworth cutoff is ``CUTOFF_FACTOR x f*`` (its roll-off starts below the cutoff),
   clamped to ``[MIN_CUTOFF_HZ, MAX_CUTOFF_FRACTION x fs]``. The factor is above 1 because the
   section forces need the pitch up to where it is buried: a lower cutoff loses more damage (the
   simulated spring travel no longer matches the prescribed pitch) than the noise let through adds
   (measured in ``docs/durability.md``);
3. **filter**: Butterworth of order ``ORDER``, applied forwards and backwards (zero phase, so the
   prescribed pitch is not delayed against the forces), odd-reflection padding at the ends;
4. **derivatives**: 4th-order central differences of the filtered signal (:func:`derivative`,
   five points; 2nd order at the two ends). A 2nd-order difference passes a sine of ``theta``
   radians per sample with the gain ``sin(theta) / theta``: 0.92 for the wheel hop (22 Hz) at
   200 Hz, which took 7 % off the damage of ``f3`` from measured spring travel; the five-point
   stencil's gain there is 0.994.

When the noise estimate is below ``NOISE_FLOOR_RAD`` (a clean, simulated signal), nothing is
filtered (``kind = "none"``): central differences of the signal itself. When the run has a
measured rate (``beta_rate``), ``beta'`` is that rate, filtered by the same rule applied to the
rate, and ``beta''`` its central difference; the angle is filtered by its own rule.

The rule and its numbers are returned (``derivative_filter`` of the durability report).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

from ..diagnosis import robust_diff_sigma as _diff_sigma

__all__ = ["derivative", "noise_from_differences", "noise_from_spectrum", "noise_level", "choose_cutoff", "lowpass", "filtered_derivatives",
           "CUTOFF_FACTOR", "ORDER", "NOISE_FLOOR_RAD"]

ORDER = 4
CUTOFF_FACTOR = 1.5
MIN_CUTOFF_HZ = 0.5
MAX_CUTOFF_FRACTION = 0.4
WELCH_SEGMENT_S = 4.0
SPECTRUM_BAND = 0.3
#: below this 4th-difference noise level (rad) a signal counts as clean
NOISE_FLOOR_RAD = 1e-7


def noise_from_differences(x) -> float:
    """White-noise standard deviation of ``x`` from its 4th differences (robust scale): the
    diagnosis's k-th difference estimator with k = 4."""
    x = np.asarray(x, dtype=float)
    if x.size < 8:
        return 0.0
    return _diff_sigma(x, 4)


def noise_from_spectrum(x, fs: float) -> float:
    """White-noise standard deviation of ``x`` from the mean Welch PSD above ``SPECTRUM_BAND x fs``
    (``sigma^2 = mean PSD x fs / 2``): the band where a vehicle signal has sunk into the noise."""
    x = np.asarray(x, dtype=float)
    nper = int(min(x.size, max(64, round(WELCH_SEGMENT_S * fs))))
    f, p = signal.welch(x - np.mean(x), fs=fs, nperseg=nper, detrend="linear")
    band = (f >= SPECTRUM_BAND * fs) & (f < 0.5 * fs)  # the Nyquist bin has half the weight
    return float(np.sqrt(np.mean(p[band]) * fs / 2.0)) if band.any() else math.inf


def noise_level(x, fs: float) -> float:
    """The smaller of :func:`noise_from_differences` and :func:`noise_from_spectrum`: either one
    overestimates when the signal itself reaches into what it measures (the 4th differences of a
    200 Hz spring travel with the 22 Hz wheel hop in it), neither underestimates white noise."""
    return min(noise_from_differences(x), noise_from_spectrum(x, fs))


def choose_cutoff(x, fs: float, sigma: float, *, factor: float = CUTOFF_FACTOR) -> tuple[float, float]:
    """``(cutoff_hz, mse_optimal_hz)`` of the rule in the module docstring."""
    x = np.asarray(x, dtype=float)
    nper = int(min(x.size, max(64, round(WELCH_SEGMENT_S * fs))))
    f, p = signal.welch(x - np.mean(x), fs=fs, nperseg=nper, detrend="linear")
    floor = 2.0 * sigma**2 / fs
    w = (2.0 * np.pi * f) ** 2 * (f[1] - f[0])  # derivative weight times bin width
    # J(k) = signal power of x' above bin k (PSD less the floor, not clipped: over the noise-only
    # bins it sums to about zero, so single bins that scatter high do not move the minimum)
    #        + noise power of x' up to bin k
    sig_above = np.concatenate([np.cumsum((w * (p - floor))[::-1])[::-1][1:], [0.0]])
    noise_below = np.cumsum(w * floor)
    k = int(np.argmin(sig_above + noise_below))
    f_opt = float(f[max(k, 1)])
    hi = MAX_CUTOFF_FRACTION * fs
    cutoff = float(np.clip(factor * f_opt, min(MIN_CUTOFF_HZ, hi), hi))
    return cutoff, f_opt


def lowpass(x, fs: float, cutoff_hz: float, order: int = ORDER) -> np.ndarray:
    """Zero-phase Butterworth low-pass (forwards-backwards, odd padding)."""
    sos = signal.butter(order, cutoff_hz, btype="low", fs=fs, output="sos")
    x = np.asarray(x, dtype=float)
    padlen = int(min(x.size - 1, max(3 * (2 * len(sos) + 1), round(3.0 * fs / cutoff_hz))))
    return signal.sosfiltfilt(sos, x, padtype="odd", padlen=padlen)


def derivative(x, dt: float) -> np.ndarray:
    """``x'`` by the five-point central difference ``(x[k-2] - 8 x[k-1] + 8 x[k+1] - x[k+2]) / 12 dt``
    (4th order), ``numpy.gradient``'s 2nd-order differences at the two samples of each end."""
    x = np.asarray(x, dtype=float)
    out = np.gradient(x, dt, edge_order=2) if x.size > 2 else np.gradient(x, dt)
    if x.size >= 5:
        out[2:-2] = (x[:-4] - 8.0 * x[1:-3] + 8.0 * x[3:-1] - x[4:]) / (12.0 * dt)
    return out


def _smooth(x, fs, name):
    sigma = noise_level(x, fs)
    if sigma < NOISE_FLOOR_RAD:
        return np.asarray(x, float), {"signal": name, "kind": "none", "noise_estimate": sigma,
                                      "cutoff_hz": None, "mse_optimal_hz": None}
    cutoff, f_opt = choose_cutoff(x, fs, sigma)
    return lowpass(x, fs, cutoff), {"signal": name, "kind": f"butterworth{ORDER}_zero_phase",
                                    "noise_estimate": sigma, "cutoff_hz": cutoff,
                                    "mse_optimal_hz": f_opt}


def filtered_derivatives(beta, dt: float, beta_rate=None) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """``(beta, beta', beta'', info)`` from a measured angle (and rate, if measured).

    ``info`` is the report's ``derivative_filter``: ``kind``, ``cutoff_hz`` (of the signal that is
    differentiated), the noise estimates and the rule.
    """
    fs = 1.0 / float(dt)
    b, info_b = _smooth(beta, fs, "beta")
    if beta_rate is not None:
        db, info_r = _smooth(beta_rate, fs, "beta_rate")
        rate_source = "measured beta_rate"
        main = info_r
    else:
        db = derivative(b, dt)
        rate_source = "4th-order central difference of the filtered beta"
        main = info_b
    ddb = derivative(db, dt)
    info = {
        "kind": main["kind"],
        "cutoff_hz": main["cutoff_hz"],
        "rate_source": rate_source,
        "signals": [info_b] + ([info_r] if beta_rate is not None else []),
        "rule": (f"noise sigma: the smaller of the 4th-difference estimate (robust) and the mean PSD above "
                 f"{SPECTRUM_BAND:g} fs; f* minimises the derivative's mean-square "
                 f"error (signal power lost above f* + noise power below f*, from the Welch PSD and the "
                 f"floor 2 sigma^2 dt); cutoff = {CUTOFF_FACTOR:g} f*, clamped to [{MIN_CUTOFF_HZ:g} Hz, "
                 f"{MAX_CUTOFF_FRACTION:g} fs]; Butterworth order {ORDER}, zero phase; no filter below "
                 f"{NOISE_FLOOR_RAD:g} of noise"),
    }
    return b, db, ddb, info
