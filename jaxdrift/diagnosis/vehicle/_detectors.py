"""Noise detectors on the measured signals: white force noise and white sensor noise on the
measured motion, from high-order differences."""

from __future__ import annotations

import math

import numpy as np

from ._causes import FORCE_CHANNELS

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


def _motion_noise_sigma(x: np.ndarray) -> float:
    """White sensor noise on a measured motion channel, or 0 where none shows.

    White noise gives the same level from the 4th and the 8th differences; the motion's own
    content, at frequencies below the Nyquist frequency, is suppressed far more by the 8th
    (on true road-driven runs their ratio is 0.3-0.5 at 200 Hz and below 0.05 at 500 Hz and
    above). The 8th-difference level is taken as the noise where the ratio says white noise
    dominates the top band."""
    if len(x) < 64:
        return 0.0
    s4, s8 = _diff_sigma(x, 4), _diff_sigma(x, 8)
    return s8 if s4 > 0 and s8 >= 0.6 * s4 else 0.0


def lowband_cutoff(fs: float) -> float:
    """Upper edge [Hz] of the band where the force noise is measured (see lowband_noise)."""
    return min(fs / 6.0, 40.0)

