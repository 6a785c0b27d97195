"""Derivatives of a measured, noisy signal (the pitch angle) for the prescribed-pitch simulation.

Prescribing the measured pitch (seed (4.4)/(A.5)) needs ``beta'`` (the dampers ``d3, d4``
multiply it, so it enters the section forces directly) and ``beta''`` (the enforced moment).
A plain finite difference of an angle with white noise of standard deviation ``sigma`` at step
``dt`` has a rate noise of about ``sigma / dt``: 0.01 deg at 500 Hz is 0.087 rad/s, which through
``d3 b`` is 870 N of white noise on ``f3``. So the signal is low-pass filtered first, with a
cutoff read from the data:

1. **noise level** ``sigma``: from the 4th differences of the signal, which remove a smooth signal
   and leave ``70 sigma^2`` of white noise variance; robust scale (1.4826 x median absolute
   deviation) so that a few steps in the signal do not count as noise;
2. **cutoff** ``f_c``: the Welch PSD of the signal (segments of ``WELCH_SEGMENT_S``), averaged over
   bands of ``BAND_HZ``, against the white-noise floor ``N0 = 2 sigma^2 dt`` (one-sided): the
   highest frequency where the band-averaged PSD less the floor exceeds ``SNR_CROSSING x N0``
   (where the signal sinks into the noise); the filter cutoff is ``CUTOFF_FACTOR x`` that frequency, clamped to
   ``[MIN_CUTOFF_HZ, MAX_CUTOFF_FRACTION x fs]``. The factor is above 1 because the section forces
   need the pitch up to where it is buried: a cutoff at a lower frequency loses more damage (the
   simulated spring travel no longer matches the prescribed pitch) than the noise let through adds
   (measured in ``docs/durability.md``);
3. **filter**: Butterworth of order ``ORDER``, applied forwards and backwards (zero phase, so the
   prescribed pitch is not delayed against the forces), odd-reflection padding at the ends;
4. **derivatives**: central differences of the filtered signal (``numpy.gradient``, 2nd order).

When the noise estimate is below ``NOISE_FLOOR_RAD`` (a clean, simulated signal), nothing is
filtered (``kind = "none"``): central differences of the signal itself. When the run has a
measured rate (``beta_rate``), ``beta'`` is that rate, filtered by the same rule applied to the
rate, and ``beta''`` its central difference; the angle is filtered by its own rule.

The rule and its numbers are returned (``derivative_filter`` of the durability report).
"""

from __future__ import annotations

import numpy as np
from scipy import signal

__all__ = ["noise_from_differences", "choose_cutoff", "lowpass", "filtered_derivatives",
           "SNR_CROSSING", "CUTOFF_FACTOR", "BAND_HZ", "ORDER", "NOISE_FLOOR_RAD"]

ORDER = 4
SNR_CROSSING = 1.0
CUTOFF_FACTOR = 1.5
BAND_HZ = 2.0
MIN_CUTOFF_HZ = 0.5
MAX_CUTOFF_FRACTION = 0.4
WELCH_SEGMENT_S = 4.0
#: below this 4th-difference noise level (rad) a signal counts as clean
NOISE_FLOOR_RAD = 1e-7


def noise_from_differences(x) -> float:
    """White-noise standard deviation of ``x`` from its 4th differences (robust scale)."""
    x = np.asarray(x, dtype=float)
    if x.size < 8:
        return 0.0
    d4 = np.diff(x, 4)
    mad = np.median(np.abs(d4 - np.median(d4)))
    return float(1.4826 * mad / np.sqrt(70.0))


def choose_cutoff(x, fs: float, sigma: float, *, snr: float = SNR_CROSSING,
                  factor: float = CUTOFF_FACTOR) -> tuple[float, float]:
    """``(cutoff_hz, crossing_hz)`` of the rule in the module docstring."""
    x = np.asarray(x, dtype=float)
    nper = int(min(x.size, max(64, round(WELCH_SEGMENT_S * fs))))
    f, p = signal.welch(x - np.mean(x), fs=fs, nperseg=nper, detrend="linear")
    floor = 2.0 * sigma**2 / fs
    # band average over BAND_HZ (at least 4 bins): the noise-only bins then scatter by a few %,
    # and narrow notches of the signal (the wheelbase filter) do not end the signal band early
    w = max(4, int(round(BAND_HZ / (f[1] - f[0]))))
    avg = np.convolve(p, np.ones(w) / w, mode="same")
    above = np.nonzero(avg > (1.0 + snr) * floor)[0]  # signal part = avg - floor
    crossing = float(f[above[-1]]) if above.size else float(f[1])
    hi = MAX_CUTOFF_FRACTION * fs
    cutoff = float(np.clip(factor * crossing, min(MIN_CUTOFF_HZ, hi), hi))
    return cutoff, crossing


def lowpass(x, fs: float, cutoff_hz: float, order: int = ORDER) -> np.ndarray:
    """Zero-phase Butterworth low-pass (forwards-backwards, odd padding)."""
    sos = signal.butter(order, cutoff_hz, btype="low", fs=fs, output="sos")
    x = np.asarray(x, dtype=float)
    padlen = int(min(x.size - 1, max(3 * (2 * len(sos) + 1), round(3.0 * fs / cutoff_hz))))
    return signal.sosfiltfilt(sos, x, padtype="odd", padlen=padlen)


def _smooth(x, fs, name):
    sigma = noise_from_differences(x)
    if sigma < NOISE_FLOOR_RAD:
        return np.asarray(x, float), {"signal": name, "kind": "none", "noise_estimate": sigma,
                                      "cutoff_hz": None, "crossing_hz": None}
    cutoff, crossing = choose_cutoff(x, fs, sigma)
    return lowpass(x, fs, cutoff), {"signal": name, "kind": f"butterworth{ORDER}_zero_phase",
                                    "noise_estimate": sigma, "cutoff_hz": cutoff,
                                    "crossing_hz": crossing}


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
        db = np.gradient(b, dt)
        rate_source = "central difference of the filtered beta"
        main = info_b
    ddb = np.gradient(db, dt)
    info = {
        "kind": main["kind"],
        "cutoff_hz": main["cutoff_hz"],
        "rate_source": rate_source,
        "signals": [info_b] + ([info_r] if beta_rate is not None else []),
        "rule": (f"noise sigma from 4th differences (robust); cutoff = {CUTOFF_FACTOR:g} x the highest "
                 f"frequency where the Welch PSD ({BAND_HZ:g} Hz band average) less the noise floor N0 = "
                 f"2 sigma^2 dt exceeds {SNR_CROSSING:g} x N0, clamped to [{MIN_CUTOFF_HZ:g} Hz, {MAX_CUTOFF_FRACTION:g} fs]; "
                 f"Butterworth order {ORDER}, zero phase; no filter below {NOISE_FLOOR_RAD:g} of noise"),
    }
    return b, db, ddb, info
