"""The restoration of a force channel's pinned bursts (``unclip``, ``ForceCorrection.clip``),
checked against the truth the clipping took away on signals clipped here (two-tone forces and
road-like noise, a fresh draw: the method was chosen on other signals)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

from jaxdrift.io._corrections import Corrections, ForceCorrection, unclip

FS = 250.0


def _signals():
    """Two-tone forces and road-like noise (4th-order low-pass at 10 Hz), 20 s at 250 Hz."""
    rng = np.random.default_rng(32001)
    t = np.arange(0.0, 20.0, 1.0 / FS)
    out = {f"two-tone {f0} Hz": 4000 + 1500 * np.sin(2 * np.pi * f0 * t) + 600 * np.sin(2 * np.pi * 1.7 * f0 * t + 1)
           + 2.0 * rng.standard_normal(t.size) for f0 in (2.0, 5.0, 10.0)}
    b, a = scipy.signal.butter(4, 10.0 / (FS / 2))
    w = scipy.signal.lfilter(b, a, rng.standard_normal(t.size + 500))[500:]
    out["road 10 Hz"] = 4000 + 800 * w / w.std() + 2.0 * rng.standard_normal(t.size)
    return t, out


#: the largest share of the RMS the clipping took that may be left (measured 0.12, 0.06, 0.49 and
#: 0.09 at the 99 % quantile, 0.06, 0.03, 0.27 and 0.22 at the 95 %: the 2 Hz force's bursts
#: last 7-17 samples, and the flanks' 2 N of noise goes into so long a fill)
LEFT = {"two-tone 5.0 Hz": 0.2, "two-tone 10.0 Hz": 0.2, "two-tone 2.0 Hz": 0.6, "road 10 Hz": 0.35}


@pytest.mark.parametrize("q", [0.99, 0.95])
def test_unclip_restores_what_the_clipping_took(q):
    """What the restoration leaves of the RMS the clipping took from the pinned samples (bursts at
    the record's ends, which have one flank and are left pinned, not counted); never more than the
    clipping, never below the range, and the unpinned samples untouched."""
    t, sigs = _signals()
    for name, x in sigs.items():
        hi = float(np.quantile(x[10:-10], q))
        m = np.minimum(x, hi)
        r = unclip(t, m, None, hi)
        pinned = m == hi
        inner = pinned.copy()
        inner[:10] = inner[-10:] = False
        lost = np.sqrt(np.mean((x - m)[inner] ** 2))
        left = np.sqrt(np.mean((x - r)[inner] ** 2))
        assert left <= LEFT[name] * lost, (name, left, lost)
        assert np.all(r >= m) and np.array_equal(r[~pinned], m[~pinned])
        # the low end alike (a force pinned at the bottom of its range)
        lo = float(np.quantile(x[10:-10], 1 - q))
        np.testing.assert_allclose(-unclip(t, np.maximum(x, lo), lo, None), unclip(t, -np.maximum(x, lo), None, -lo))


def test_the_record_carries_the_clip_and_applies_it_first():
    """``clip`` survives the report's JSON; ``apply`` restores before the delay and the offset."""
    c = ForceCorrection(offset=12.0, clip=(None, 5100.0))
    assert ForceCorrection.from_json(c.to_json()) == c
    assert c.to_json()["clip"] == [None, 5100.0]
    assert "clip" not in ForceCorrection(offset=12.0).to_json()
    t, sigs = _signals()
    x = sigs["two-tone 5.0 Hz"] + 12.0
    hi = float(np.quantile(x, 0.97))
    corr = Corrections(f1=ForceCorrection(offset=12.0, clip=(None, hi)))
    out = corr.apply(t, {"f1": np.minimum(x, hi), "f2": x})
    err = (out["f1"] - (x - 12.0))[20:-20]
    lost = (x - np.minimum(x, hi))[20:-20]
    assert np.sqrt(np.mean(err ** 2)) < LEFT["two-tone 5.0 Hz"] * np.sqrt(np.mean(lost ** 2))
    np.testing.assert_array_equal(out["f2"], x - 0.0)
    with pytest.raises(ValueError, match="clip"):
        ForceCorrection.from_json({"clip": [1.0]})
