"""A reference with its own attitude noise, weighed by generalised least squares
(``jaxdrift/diagnosis/attitude/_gyro.py``: ``reference_fit(ref_var=...)``, ``reference_noise_var``,
``gls_agrees``, ``gyro_halves``; ``_alignment.clock_settled``).

A tracker's white attitude noise of 1.5 mrad per row at 50 Hz enters neighbouring intervals with
opposite signs: a constant bias compared interval by interval is read from the run's two ends
(standard error about sqrt(2) sigma / T = 2.4e-5 rad/s over 90 s), weighed by the noise's covariance
from every row (about sigma sqrt(12 / n) / T = 8.6e-7 rad/s over n = 4500 rows). A 1.5e-5 rad/s bias
is then found, inside its interval. Two ways the weights go wrong are guarded: a clock offset left
in the reference (30 ms, at 1 Hz rocking: a scale of several percent if weighed), and an estimator's
error decaying from 5 deg (no white noise at all): neither may name a cause that is not there."""

import math

import numpy as np
from scipy.spatial.transform import Rotation

from jaxdrift.diagnosis.attitude import diagnose_attitude
from jaxdrift.models._quaternion import integrate_rates_np

FS, EVERY, T = 400.0, 8, 90.0


def _rates(t):
    return np.column_stack([0.3 * np.sin(2 * np.pi * 0.9 * t + 0.3), 0.25 * np.sin(2 * np.pi * 1.3 * t),
                            0.2 * np.sin(2 * np.pi * 0.04 * t) + 0.05 * np.sin(2 * np.pi * 2.1 * t + 1.0)])


def _diagnose(seed, bias=(0.0, 0.0, 0.0), sigma_ref=1.5e-3, offset_s=0.0, converge_deg=0.0, tau_s=10.0):
    rng = np.random.default_rng(seed)
    dt = 1.0 / FS
    t = np.arange(0.0, T, dt)
    # the true attitude on a fine grid, so that a reference late by offset_s is read between samples
    k = 8
    tf = np.arange(0.0, T + 0.2, dt / k)
    qf = integrate_rates_np(np.array([1.0, 0.0, 0.0, 0.0]), _rates(tf), dt / k)
    w_meas = _rates(t) + np.asarray(bias) + rng.normal(0.0, 1e-5 / math.sqrt(dt), (len(t), 3))
    rows = np.arange(0, len(t), EVERY)
    src = np.clip(np.round((t[rows] - offset_s) / (dt / k)).astype(int), 0, len(tf) - 1)
    r = Rotation.from_quat(qf[src][:, [1, 2, 3, 0]])
    err = sigma_ref * rng.standard_normal((len(rows), 3))
    if converge_deg:
        d = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
        err += np.outer(np.exp(-t[rows] / tau_s), d) * math.radians(converge_deg)
    x = (r * Rotation.from_rotvec(err)).as_quat()
    q_ref = np.full((len(t), 4), np.nan)
    q_ref[rows] = x[:, [3, 0, 1, 2]]
    run = {"path": "synthetic", "t": t, "dt": dt, "w": w_meas, "q_ref": q_ref, "acc": None, "extra_columns": [],
           "quantisation": 0.0, "acc_quantisation": 0.0, "warnings": [], "info": {}}
    return diagnose_attitude(run)[0]


def _by(rep, cause):
    return {f.get("channel"): f for f in rep["findings"] if f["cause"] == cause}


def test_a_small_bias_under_a_noisy_reference_is_found_by_weighing_the_reference_noise():
    rep = _diagnose(5101, bias=(1.5e-5, 0.0, 0.0))
    b = _by(rep, "gyro_bias")
    assert "wx" in b and b["wx"]["interval"][0] <= 1.5e-5 <= b["wx"]["interval"][1], rep["findings"]
    assert not _by(rep, "gyro_scale") and not _by(rep, "gyro_bias_drift"), rep["findings"]
    assert any("weighs the fit (GLS)" in n for n in rep["observability"]["notes"]), rep["observability"]["notes"]


def test_a_clock_offset_under_a_noisy_reference_is_found_and_reads_as_no_scale():
    rep = _diagnose(5102, offset_s=0.030)
    al = rep["run"]["reference_alignment"]
    assert al["applied"]["clock_offset"], al
    # within half a gyro step: the gyro's sampling convention (a rate at its stamp, or held over the
    # step; here the reference is integrated with rates held over an eighth of a step) is the fit's
    # own parameter, not the offset's
    lo, hi = al["clock_offset_interval_s"]
    assert abs(al["clock_offset_s"] - 0.030) <= 0.5 / FS and hi - lo < 0.004, al
    assert not _by(rep, "gyro_scale") and not _by(rep, "gyro_bias"), rep["findings"]


def test_an_estimator_converging_is_not_weighed_and_names_no_bias():
    rep = _diagnose(5103, sigma_ref=5e-4, converge_deg=5.0)
    assert not _by(rep, "gyro_bias") and not _by(rep, "gyro_scale") and not _by(rep, "gyro_bias_drift"), rep["findings"]


def test_a_slowly_converging_estimator_is_fitted_beside_the_bias(monkeypatch):
    """An estimator 4 deg off whose error decays with a 30 s time constant over a 90 s run: no
    stretch can be left out (a third of the run in, its rate still exceeds the bias), so the decay is
    fitted beside the gyro's effects (``_gyro.decay_profile``): the wy bias is found inside its
    interval and nothing else is named. Without the decay the bias is lost under the fading error."""
    from jaxdrift.diagnosis.attitude import _gyro

    kw = dict(bias=(0.0, -5e-4, 0.0), sigma_ref=3e-4, converge_deg=4.0, tau_s=30.0)
    rep = _diagnose(5104, **kw)
    b = _by(rep, "gyro_bias")
    assert set(b) == {"wy"} and b["wy"]["interval"][0] <= -5e-4 <= b["wy"]["interval"][1], rep["findings"]
    assert not _by(rep, "gyro_scale") and not _by(rep, "gyro_bias_drift"), rep["findings"]
    note = next(n for n in rep["observability"]["notes"] if "converges like an estimator" in n)
    assert " deg off " in note
    monkeypatch.setattr(_gyro, "DECAY_CHI2", math.inf)
    rep = _diagnose(5104, **kw)
    assert "wy" not in _by(rep, "gyro_bias"), rep["findings"]  # measured: the bias is lost under the decay
