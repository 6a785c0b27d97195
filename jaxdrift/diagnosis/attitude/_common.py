"""Thresholds, the finding record and the number format shared by the steps of the attitude diagnosis."""

from __future__ import annotations

import math

SCHEMA = "jaxdrift.diagnosis/1"
CHANNELS = ("wx", "wy", "wz")
Z_SIGNIFICANT = 5.0  # |estimate - null| / SE for a systematic finding (false alarms ~ 1e-6 per test)
# ... for a bias whose standard error is the block (cluster-robust) one of residuals coloured by
# vibration: that error already carries the colour, and the t quantile of its 15 degrees of
# freedom (16 blocks) widens it further; 4 of those (a false alarm ~ 6e-4 per axis) is the "clear"
# bias of a real log (a Cube Orange in flight: +2.78 mrad/s at 4.8 of them, PX4's own estimate
# +2.0, an independent fit +2.91 +- 0.62, was left unnamed at 5)
Z_COLOURED = 4.0
DRIFT_LR = 16.0  # REML likelihood-ratio threshold for a bias random walk
DRIFT_LR_GIVEN_BIAS = 6.0  # ... when a constant bias is significant on the channel (p ~ 0.7 %)
POSITION_CHI2 = 40.0  # 3-dof chi-square threshold for a displaced sensor
# a displaced sensor's full-band and rigid-band (below RIGID_BAND_HZ) estimates must agree (Hausman
# chi-square, 3 dof, p = 0.001) or the rigid band alone must show it; vehicle bodies' structural
# modes lie well above 8 Hz
POSITION_AGREE_CHI2 = 16.3
RIGID_BAND_HZ = 4.0
NONRIGID_FLOOR = 2e-3  # m/s^2: below this, a rigidity residual is not reported
# practical floors below which a statistically significant effect is the discretisation of the file
# (noise-free runs at 100 and 50 Hz show apparent scales of 1e-5 and 1.5e-4), not a gyro property
SCALE_FLOOR = 5e-4  # 500 ppm
BIAS_FLOOR = 1e-6  # rad/s (0.2 deg/h)
DRIFT_FLOOR = 1e-7  # rad/s/sqrt(s)
# Runs without white gyro noise use the same floors: their tests' noise level is the reference fit's
# measured residual (chi-square inflation). A factor of 30 on these floors (and a drift floor of
# 1e-4) once stood here for noise-free runs; it hid noise-free biases of 2.6e-5 rad/s and drifts of
# 1e-5 rad/s/sqrt(s), and without it 15 effect-free noise-free independent runs (seeds 200-214) gave
# no systematic finding.
MIN_INTERVAL_ROWS = 20
DRIFT_OFF_DEG = 0.5


def finding(cause, estimate, unit, interval, evidence, z, **extra):
    """A report finding (keys in the spec's order) and its ranking statistic ``z``."""
    f = {"cause": cause}
    f.update(extra)
    f.update({"estimate": estimate, "unit": unit, "interval": interval, "evidence": evidence})
    return f, z


def fmt(x):
    """Three significant digits, the precision of every number quoted in an evidence sentence (a
    degenerate fit's infinite ratio reads "unbounded", never "inf": a report holds no inf or NaN)."""
    if not math.isfinite(x):
        return "undefined" if x != x else ("unbounded" if x > 0 else "-unbounded")
    return f"{x:.3g}"
