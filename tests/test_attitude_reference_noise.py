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

from _attitude_synth import diagnose_synthetic

FS, EVERY, T = 400.0, 8, 90.0


def _diagnose(seed, bias=(0.0, 0.0, 0.0), sigma_ref=1.5e-3, offset_s=0.0, converge_deg=0.0, tau_s=10.0):
    return diagnose_synthetic(seed, FS, EVERY, T, bias=bias, sigma_ref=sigma_ref, offset_s=offset_s,
                              converge_deg=converge_deg, tau_s=tau_s)


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


def test_an_estimator_converging_names_no_bias():
    """Weighed with its decay fitted beside the gyro's effects (the weighted and unweighted fits agree
    with it): the decay's time constant is a parameter of the fit, and its error taken out exactly,
    else a 2 % error of the profile's grid read as a wz bias of 8.9e-6 [5.1e-6, 1.3e-5] rad/s."""
    rep = _diagnose(5103, sigma_ref=5e-4, converge_deg=5.0)
    assert not _by(rep, "gyro_bias") and not _by(rep, "gyro_scale") and not _by(rep, "gyro_bias_drift"), rep["findings"]
    note = next(n for n in rep["observability"]["notes"] if "converges like an estimator" in n)
    assert "time constant of 10" in note or "time constant of 9.9" in note, note


def test_a_slowly_converging_estimator_is_fitted_beside_the_bias(monkeypatch):
    """An estimator 4 deg off whose error decays with a 30 s time constant over a 90 s run: no
    stretch can be left out (a third of the run in, its rate still exceeds the bias), so the decay is
    fitted beside the gyro's effects (``_decay.decay_profile``): the wy bias is found inside its
    interval and nothing else is named. Without the decay the bias is lost under the fading error."""
    from jaxdrift.diagnosis.attitude import _decay

    kw = dict(bias=(0.0, -5e-4, 0.0), sigma_ref=3e-4, converge_deg=4.0, tau_s=30.0)
    rep = _diagnose(5104, **kw)
    b = _by(rep, "gyro_bias")
    assert set(b) == {"wy"} and b["wy"]["interval"][0] <= -5e-4 <= b["wy"]["interval"][1], rep["findings"]
    assert not _by(rep, "gyro_scale") and not _by(rep, "gyro_bias_drift"), rep["findings"]
    note = next(n for n in rep["observability"]["notes"] if "converges like an estimator" in n)
    assert " deg off " in note
    monkeypatch.setattr(_decay, "DECAY_CHI2", math.inf)
    rep = _diagnose(5104, **kw)
    assert "wy" not in _by(rep, "gyro_bias"), rep["findings"]  # measured: the bias is lost under the decay
