"""Noise detectors on the measured signals: white force noise from high-order differences, white
sensor noise on the measured motion from the residual's top band, and the noise that printing a
value with a limited number of digits adds."""

from __future__ import annotations

import math

import numpy as np
import scipy.optimize
import scipy.signal

from ._causes import FORCE_CHANNELS

#: below this force-noise level [N] no noise is reported (about 1e-4 of the seed's static load;
#: the low-band estimate of a noise-free run stays below about 0.2 N)
NOISE_MIN_N = 0.5


def _diff_sigma(x: np.ndarray, k: int) -> float:
    """Robust white-noise level from the k-th difference (var = C(2k, k) sigma^2 for white noise)."""
    d = np.diff(x, k)
    mad = np.median(np.abs(d - np.median(d))) * 1.4826
    return float(mad / math.sqrt(math.comb(2 * k, k)))


def _hf_noise_sigma(f: np.ndarray) -> float:
    """Robust white-noise level from the 4th difference; an upper bound when the signal itself
    has content near the Nyquist frequency."""
    return _diff_sigma(f, 4)


def _force_hf_noise(run) -> tuple[float, float, float]:
    """Force-noise level from both forces' 4th differences, with its 95 % interval (an upper
    bound: the forces' own content near the Nyquist frequency counts as noise)."""
    sigma = float(np.sqrt(np.mean([_hf_noise_sigma(run[ch]) ** 2 for ch in FORCE_CHANNELS])))
    half = 1.96 * 1.6 / math.sqrt(2 * (run.n - 4))
    return sigma, sigma * (1 - half), sigma * (1 + half)


#: residual channel -> the measured motion it differentiates
MOTION_COLUMN = {"moment": "beta", "heave": "z3", "spring1": "s1", "spring2": "s2"}


#: band of the residual where the sensor noise on the measured motion is measured [share of fs]
TOP_BAND = (0.25, 0.45)


def _welch(x: np.ndarray, fs: float, nperseg: int):
    """One-sided PSD (Welch, Hann, half overlap, linear detrend) of x without its first and last
    5 % (the record's ends)."""
    k = len(x) // 20
    return scipy.signal.welch(x[k:len(x) - k], fs=fs, nperseg=nperseg, detrend="linear")


def welch_segment(n: int) -> int:
    """Welch segment length for a record of n samples: at least 16 segments, 64 to 512 samples."""
    return int(min(512, max(64, 1 << int(math.floor(math.log2(max(n, 2) / 16))))))


def motion_noise_from_residual(r: np.ndarray, r_motion: np.ndarray, r_force: np.ndarray,
                               fs: float, known=None) -> tuple[float, float]:
    """White sensor noise on a measured motion [per sample] and white force noise [N] that
    together explain the top band of a residual channel.

    ``r``: the residual channel of the model; ``r_motion``, ``r_force``: the same channel's
    response to unit white noise on the motion it differentiates and on both forces (computed by
    the pipeline itself, so the shapes include its interpolation and differentiation). In the top
    band (``TOP_BAND`` of fs) white sensor noise grows like (2 pi f)^4 in the enforced moment and
    heave (like (2 pi f)^2 in the spring channels) while the road-driven motion the model predicts
    and the force noise passed by the model fall off: the residual's PSD there is fitted as
    ``s_m^2 P_motion + s_f^2 P_force`` by non-negative least squares in relative terms.
    ``known``: PSD (same Welch grid) already attributed to other noise, taken out first.

    This replaces a test on the motion alone (its 4th against its 8th differences), which read
    rough-road motion whose 4th difference is white (a road spectrum reaching the Nyquist
    frequency) as sensor noise: 3e-5 m on spring travel written with 9 digits."""
    nper = welch_segment(len(r))
    f, P = _welch(r, fs, nper)
    _, G = _welch(r_motion, fs, nper)
    _, F = _welch(r_force, fs, nper)
    band = (f >= TOP_BAND[0] * fs) & (f <= TOP_BAND[1] * fs)
    if np.count_nonzero(band) < 4:
        return 0.0, 0.0
    w = 1.0 / np.maximum(P[band], 1e-300)
    A = np.column_stack([G[band] * w, F[band] * w])
    y = np.ones(np.count_nonzero(band))
    if known is not None:
        y = np.maximum(1.0 - known[band] * w, 0.0)
    coef, _ = scipy.optimize.nnls(A, y)
    return math.sqrt(coef[0]), math.sqrt(coef[1])


def written_noise_sigma(x: np.ndarray) -> float:
    """Standard deviation of the rounding noise of values printed with as few significant digits
    as reproduce them (uniform over one unit of the last digit: q^2 / 12), 0 for full precision.
    The digits are found as the smallest count (up to 15) at which rounding leaves the values
    unchanged to 1e-12 relative."""
    x = np.asarray(x, dtype=float)
    nz = x[x != 0]
    if nz.size == 0:
        return 0.0
    sample = nz[:: max(1, nz.size // 2000)]
    mag = np.floor(np.log10(np.abs(sample)))
    for d in range(3, 16):
        q = 10.0 ** (mag - d + 1)
        if np.all(np.abs(np.round(sample / q) * q - sample) <= 1e-12 * np.abs(sample)):
            qa = 10.0 ** (np.floor(np.log10(np.abs(nz))) - d + 1)
            return float(np.sqrt(np.mean(qa * qa) / 12.0))
    return 0.0


def lowband_cutoff(fs: float) -> float:
    """Upper edge [Hz] of the band where the force noise is measured (see lowband_noise)."""
    return min(fs / 6.0, 40.0)

