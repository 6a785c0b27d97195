"""Detectors on the measured signals: the causes read off the forces before anything is fitted
(:func:`read_signals`), white force noise from high-order differences, white sensor noise on the
measured motion from the residual's top band, and the noise that printing a value with a limited
number of digits adds."""

from __future__ import annotations

import math

import numpy as np
import scipy.optimize
import scipy.signal
import scipy.stats

from .._diffnoise import robust_diff_sigma
from ...io._corrections import NO_CORRECTION, Corrections
from ._causes import FORCE_CHANNELS
from ._nonlinear import signal_detectors

#: below this force-noise level [N] no noise is reported (about 1e-4 of the seed's static load;
#: the low-band estimate of a noise-free run stays below about 0.2 N)
NOISE_MIN_N = 0.5


def _diff_sigma(x: np.ndarray, k: int) -> float:
    """Robust white-noise level from the k-th difference (:func:`.._diffnoise.robust_diff_sigma`)."""
    return robust_diff_sigma(x, k)


def _hf_noise_sigma(f: np.ndarray) -> float:
    """Robust white-noise level from the 4th difference; an upper bound when the signal itself
    has content near the Nyquist frequency."""
    return _diff_sigma(f, 4)


def read_signals(run) -> tuple[object, tuple]:
    """The causes read off the measured forces before anything is fitted (the registry
    ``_nonlinear.signal_detectors``, each detector on its channel of the run as given, with the
    forces' top-band noise level). Returns the run with every detection's inverse applied to the
    samples of its channel (the run itself where none changes anything) and the ``(detector,
    detection)`` pairs found, in the registry's order."""
    sigma = _force_hf_noise(run)[0]
    found = []
    for d in signal_detectors():
        det = d.detect(run[d.channel], sigma) if run.has(d.channel) else None
        if det is not None:
            found.append((d, det))
    found = tuple(found)
    corr = with_detections(NO_CORRECTION, found)
    if corr == NO_CORRECTION:
        return run, found
    return run.with_channels(corr.restore(run.t, {ch: run[ch] for ch in FORCE_CHANNELS})), found


def with_detections(corr: Corrections, found) -> Corrections:
    """``corr`` with the inverse of every detection of :func:`read_signals` added to its channel."""
    for d, det in found:
        corr = corr.with_record(d.channel, d.corrected(corr[d.channel], det))
    return corr


def _force_hf_noise(run) -> tuple[float, float, float]:
    """Force-noise level from both forces' 4th differences, with its 95 % interval (an upper
    bound: the forces' own content near the Nyquist frequency counts as noise)."""
    sigma = float(np.sqrt(np.mean([_hf_noise_sigma(run[ch]) ** 2 for ch in FORCE_CHANNELS])))
    half = 1.96 * 1.6 / math.sqrt(2 * (run.n - 4))
    return sigma, sigma * (1 - half), sigma * (1 + half)


#: difference orders whose white-noise levels must agree for the forces' top band to count as
#: noise alone, and the agreement asked beyond the estimates' own scatter (a MAD level from n
#: differences scatters by about 1.1/sqrt(n); white noise reads the same at every order, within
#: 3 % at 5000 samples, while a force with real content there reads less at each higher order:
#: 9.8, 3.8 and 2.5 N at orders 4, 6 and 8 on an independent 500 Hz run with 2 N of noise,
#: benchmarks/results/diagnosis-noise-checks.json)
WHITE_ORDERS = (4, 6, 8)
WHITE_TOL = 0.1


def force_top_band_white(run) -> bool:
    """True when both forces' k-th differences give the same white-noise level at every order of
    ``WHITE_ORDERS`` (within ``WHITE_TOL`` plus 5/sqrt(n)): the top of the band then holds noise
    alone and the 4th-difference level estimates it, unless the two forces share it
    (:func:`force_top_band_shared`, which the caller asks once); otherwise the forces carry real
    content there and that level is only an upper bound."""
    tol = 1.0 + WHITE_TOL + 5.0 / math.sqrt(max(run.n, 1))
    for ch in FORCE_CHANNELS:
        lv = [_diff_sigma(run[ch], k) for k in WHITE_ORDERS]
        if min(lv) <= 0.0 or max(lv) / min(lv) > tol:
            return False
    return True


#: how far apart the two wheels may meet the same road [s] (a 4 m wheelbase at 1.6 m/s)
SHARED_LAG_MAX_S = 2.5
#: family-wise false-alarm rate of the shared-content test over all the lags it searches
SHARED_ALPHA = 0.01
#: shared content counts where it holds at least this share of the 4th differences' power (the
#: correlation: content c in both forces over noise n gives rho = c / (c + n)); below it, it adds
#: less than 5 % to the level
SHARED_MIN_SHARE = 0.1


def force_top_band_shared(run) -> tuple[float, float, float] | None:
    """``(lag_s, correlation, threshold)`` where the two forces' top bands share content, else None.

    Noise on two transducers is independent; the road is not: the rear wheel meets the front
    wheel's road ``wheelbase / speed`` later, so road content at the top of the band (a road of
    straight lines between profile points puts a jump in the tyre force at every point, and
    sampling without an anti-aliasing filter folds what lies above the Nyquist frequency down to
    it) shows in both forces' 4th differences at one lag. Such content is as white as noise at the
    4th, 6th and 8th differences (an independent 600 Hz run at 31 m/s read 8.6 N at all three for
    3.4 N of noise), so only this test tells them apart. The normalised cross-correlation of the
    two 4th differences is searched over lags up to ``SHARED_LAG_MAX_S`` either way; under
    independent white noise each lag's value has variance 2.63 / n (the 4th difference's
    autocorrelation), and the threshold is Bonferroni's over the lags at ``SHARED_ALPHA``."""
    d1, d2 = (np.diff(np.asarray(run[ch], float), 4) for ch in FORCE_CHANNELS)
    n = len(d1)
    if n < 64:
        return None
    d1, d2 = d1 - np.mean(d1), d2 - np.mean(d2)
    s = float(np.sqrt(np.sum(d1 * d1) * np.sum(d2 * d2)))
    if s <= 0.0:
        return None
    m = int(min(n // 4, SHARED_LAG_MAX_S / run.dt))
    c = scipy.signal.correlate(d2, d1, mode="full", method="fft")[n - 1 - m:n + m] / s
    # the overlap shrinks with the lag: scale each lag's value to the full-length variance
    c = c * n / (n - np.abs(np.arange(-m, m + 1)))
    z = float(scipy.stats.norm.isf(SHARED_ALPHA / (2 * (2 * m + 1))))
    thr = z * math.sqrt(2.63 / (n - m))
    j = int(np.argmax(np.abs(c)))
    if abs(c[j]) <= max(thr, SHARED_MIN_SHARE):
        return None
    return (j - m) * run.dt, float(c[j]), thr


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


def transfer_psd(x_in: np.ndarray, y_out: np.ndarray, fs: float, nperseg: int) -> np.ndarray:
    """PSD the linear map ``x_in -> y_out`` gives unit white noise, |H|^2 * 2/fs, with H the Welch
    estimate Pxy/Pxx on the same segments as ``_welch`` (smooth: y_out is an exact response to
    x_in, so H carries no noise of its own, unlike the PSD of one noisy realisation)."""
    k = len(x_in) // 20
    x, y = x_in[k:len(x_in) - k], y_out[k:len(y_out) - k]
    _, Pxy = scipy.signal.csd(x, y, fs=fs, nperseg=nperseg, detrend="linear")
    _, Pxx = scipy.signal.welch(x, fs=fs, nperseg=nperseg, detrend="linear")
    return np.abs(Pxy / np.maximum(Pxx, 1e-300)) ** 2 * (2.0 / fs)


def noise_fit(P: np.ndarray, G: np.ndarray, F: np.ndarray, band: np.ndarray, n_seg: int,
              known=None) -> tuple[float, float, float]:
    """White sensor noise on a measured motion [per sample] and white force noise [N] that
    together explain the top band of a residual channel, and the z-score of the motion term.

    ``P``: Welch PSD of the residual channel of the model; ``G``, ``F``: the PSD the channel gets
    from unit white noise on the motion it differentiates and on both forces (the pipeline's own
    transfer functions, so they include its interpolation and differentiation); ``band``: the bins
    of the top band (``TOP_BAND`` of fs). There white sensor noise grows like (2 pi f)^4 in the
    enforced moment and heave (like (2 pi f)^2 in the spring channels) while the road-driven
    motion the model predicts and the force noise passed by the model fall off: P is fitted as
    ``s_m^2 G + s_f^2 F`` by non-negative least squares in relative terms. ``known``: PSD already
    attributed (other noise, the pipeline's floor), taken out first. The z-score uses the Welch
    bins' relative variance 2/dof, dof about 1.8 per segment (Hann, half overlap), doubled for the
    correlation of neighbouring bins.

    This replaces a test on the motion alone (its 4th against its 8th differences), which read
    rough-road motion whose 4th difference is white (a road spectrum reaching the Nyquist
    frequency) as sensor noise: 3e-5 m on spring travel written with 9 digits."""
    nb = int(np.count_nonzero(band))
    if nb < 4:
        return 0.0, 0.0, 0.0
    w = 1.0 / np.maximum(P[band], 1e-300)
    A = np.column_stack([G[band] * w, F[band] * w])
    y = np.ones(nb) if known is None else np.maximum(1.0 - known[band] * w, 0.0)
    coef, _ = scipy.optimize.nnls(A, y)
    cov = 2.0 * 2.0 / (1.8 * max(n_seg, 1)) * np.linalg.pinv(A.T @ A)
    z = coef[0] / math.sqrt(cov[0, 0]) if cov[0, 0] > 0 else 0.0
    return math.sqrt(coef[0]), math.sqrt(coef[1]), float(z)


def welch_segments(n: int, nperseg: int) -> int:
    """Number of half-overlapping segments ``_welch`` uses on n samples."""
    m = n - 2 * (n // 20)
    return max((m - nperseg) // (nperseg // 2) + 1, 1)


def written_digits(x: np.ndarray) -> int:
    """The fewest significant digits (3-15) that reproduce the values to 1e-12 relative, as
    ``written_noise_sigma`` finds them; 16 for full precision or an all-zero column."""
    x = np.asarray(x, dtype=float)
    nz = x[x != 0]
    if nz.size == 0:
        return 16
    sample = nz[:: max(1, nz.size // 2000)]
    mag = np.floor(np.log10(np.abs(sample)))
    for d in range(3, 16):
        q = 10.0 ** (mag - d + 1)
        if np.all(np.abs(np.round(sample / q) * q - sample) <= 1e-12 * np.abs(sample)):
            return d
    return 16


def written_noise_sigma(x: np.ndarray) -> float:
    """Standard deviation of the rounding noise of values printed with as few significant digits
    as reproduce them (uniform over one unit of the last digit: q^2 / 12), 0 for full precision.
    The digits are found as the smallest count (up to 15) at which rounding leaves the values
    unchanged to 1e-12 relative (``written_digits``)."""
    x = np.asarray(x, dtype=float)
    d = written_digits(x)
    if d > 15:
        return 0.0
    nz = x[x != 0]
    qa = 10.0 ** (np.floor(np.log10(np.abs(nz))) - d + 1)
    return float(np.sqrt(np.mean(qa * qa) / 12.0))


def lowband_cutoff(fs: float) -> float:
    """Upper edge [Hz] of the band where the force noise is measured (see lowband_noise)."""
    return min(fs / 6.0, 40.0)

