"""The attitude reference as an estimator still converging at the start of a run.

An estimator started off by ``e0`` adds the rate ``-(e0 / tau) exp(-t / tau)`` to the discrepancy
between reference and gyro; a gyro's bias adds a constant and its drift a random walk. The detector
(:func:`jaxdrift.diagnosis.attitude._consistency.converging`) must tell the two apart: the decay
found and cut where it is a degree or more, a wandering bias left alone.
"""

from __future__ import annotations

import math

import numpy as np

from jaxdrift.diagnosis.attitude._consistency import CONVERGE_TAIL, converging

DT = 0.2  # s between reference rows
N = 450  # 90 s


def _discrepancy(rng, e0_deg=0.0, tau=5.0, walk=0.0, noise=5e-3, bias=2e-3):
    """Per-interval discrepancy (3 axes, global frame) and the body frame's rotation (identity)."""
    t0 = np.arange(N) * DT
    tm = t0 + 0.5 * DT
    d = np.zeros((N, 3)) + bias + noise * rng.standard_normal((N, 3))
    if e0_deg:
        axis = rng.standard_normal(3)
        d += np.outer(-(math.radians(e0_deg) / tau) * np.exp(-tm / tau), axis / np.linalg.norm(axis))
    if walk:  # a bias random walk of intensity ``walk`` [rad/s/sqrt(s)]
        d += np.cumsum(walk * math.sqrt(DT) * rng.standard_normal((N, 3)), axis=0)
    return d, np.broadcast_to(np.eye(3), (N, 3, 3)), t0, t0 + DT


def test_a_converging_estimator_is_found_and_cut():
    """Decays of 4-8 deg with time constants of 2-6 s under 5 mrad/s of interval noise: found in at
    least 18 of 20 draws (20 of 20 here), each with the time constant within a factor 2 and the cut
    past 70 % of the point where the decaying rate falls below ``CONVERGE_TAIL``. Slower decays
    (10-15 s) at this noise gain a chi-square of 5-25 over a bias and a drift: they are not told
    from them, and not claimed (docs, attitude Limits)."""
    rng = np.random.default_rng(20261205)
    found = 0
    for _ in range(20):
        e0, tau = rng.uniform(4.0, 8.0), rng.uniform(2.0, 6.0)
        got = converging(*_discrepancy(rng, e0_deg=e0, tau=tau))
        if got is None:
            continue
        found += 1
        cut, span = got
        assert 0.5 * tau <= span["tau_s"] <= 2.0 * tau and span["kind"] == "converges"
        rate0 = math.radians(e0) / tau
        assert span["t1"] >= 0.7 * tau * math.log(rate0 / CONVERGE_TAIL)
        assert cut[0] and not cut[-1]
    assert found >= 18, found


def test_a_wandering_bias_is_not_an_estimator():
    """A bias random walk of 0.6 mrad/s/sqrt(s) (as large as the independent generator's drifts)
    over 90 s, and a constant bias alone: at most 1 of 40 draws is called converging (the test's
    chi-square limit over its 144 tries is passed by chance about once in a thousand; a walk can
    make a decay at the start, but as large ones elsewhere; 1 of 40 here)."""
    rng = np.random.default_rng(7)
    hits = sum(converging(*_discrepancy(rng, walk=6e-4)) is not None for _ in range(20))
    hits += sum(converging(*_discrepancy(rng)) is not None for _ in range(20))
    assert hits <= 1, hits
