"""The bias drift test of the reference fit (:func:`drift_tests`): restricted maximum likelihood
of a bias random walk on the segment biases of each channel (:func:`._gyro.reml_drift`, the walk's
covariance :func:`._gyro.rw_cov`), against a constant bias and against a scatter that does not
wander."""

from __future__ import annotations

import math

import numpy as np

from ._common import CHANNELS, DRIFT_FLOOR, DRIFT_LR, DRIFT_LR_GIVEN_BIAS, Z_SIGNIFICANT, fmt
from ._gyro import reml_drift, rw_cov
from ._realworld import degenerate

__all__ = ["drift_tests"]


def drift_tests(dt, fit0, anchors, int_seg, M):
    """REML test of a bias random walk on the M segment biases of each channel: ``({channel:
    result}, notes)``.

    A random walk is named only where it explains the segment biases better than a scatter of
    equal size that does not wander (each segment off by its own amount, the same REML with the
    identity for the walk's covariance). Both have one parameter more than a constant bias, so
    their likelihoods compare directly. Segment biases that jump and come back are the reference's
    trouble in those segments (an onboard estimator's corrections, a reset the consistency check
    did not cut out), not a gyro's bias wandering: on a PX4 flight log with 20 Hz attitude the
    walk read 0.116 rad/s/sqrt(s), from segments at -325 and -463 mrad/s between ones near 0."""
    infl = max(1.0, fit0["chi2"] / fit0["dof"])
    drift, notes = {}, []
    bounds_rows = np.concatenate([anchors[:-1][np.searchsorted(int_seg, np.arange(M))], [anchors[-1]]])
    bounds = (bounds_rows - 0) * dt  # time since the first row
    S_rw = rw_cov(bounds)
    bad = degenerate(fit0)
    for c in range(3):
        # the segments the reference determines (one inside a span left out tells nothing): the walk's
        # covariance over them is its own rows and columns
        ok = np.array([i not in bad for i in range(fit0["offs"][c], fit0["offs"][c + 1])])
        if ok.sum() < 4:
            continue
        sel = fit0["offs"][c] + np.nonzero(ok)[0]
        b = fit0["theta"][sel]
        V = fit0["cov"][np.ix_(sel, sel)] * infl
        d = reml_drift(b, V, S_rw[np.ix_(ok, ok)])
        d["segments"] = ok
        # a constant bias that is significant may be the mean of a wandering one: then the
        # choice is between two models of the same size and a lower threshold applies
        Vi = np.linalg.pinv(V)
        one = np.ones(len(b))
        z_const = abs(one @ Vi @ b) / math.sqrt(max(one @ Vi @ one, 1e-300))
        thr = DRIFT_LR_GIVEN_BIAS if z_const > Z_SIGNIFICANT else DRIFT_LR
        d["z_const"] = float(z_const)
        if d["lr"] > thr and d["K"] > DRIFT_FLOOR:
            scatter = reml_drift(b, V, np.eye(len(b)) * float(np.mean(np.diff(bounds))))
            if scatter["lr"] >= d["lr"]:
                notes.append(f"the {CHANNELS[c]} bias differs from segment to segment beyond its errors (REML "
                             f"likelihood ratio {fmt(scatter['lr'])} against a constant bias) without wandering like "
                             f"a random walk ({fmt(d['lr'])}): the reference is off in some segments; no bias drift "
                             f"named")
                continue
            drift[c] = d
    return drift, notes
