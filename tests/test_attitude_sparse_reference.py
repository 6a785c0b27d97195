"""Attitude runs whose reference is sparse, late or still converging, as the independent attitude
generator draws them (``benchmarks/validation/gen_attitude.py``, the ``wide`` design), each reduced
to the one habit that broke the diagnosis (``jaxdrift/diagnosis/attitude``):

- a body standing still for the first seconds: that block of the clock-offset search tells no offset
  (its best lies on the search's edge), and it widened the offset's interval twentyfold, so a 30 ms
  offset found to 0.2 ms was not applied (``_alignment.alignment_step``);
- a 1 Hz reference with 0.6 mrad of noise per row: over 80 intervals the robust spreads could not show
  the noise (2.3 standard errors), so it was not weighed, every interval was widened 7x and a bias
  random walk went unseen; neighbouring residuals opposite beyond three standard errors of a
  correlation now show it (``_gyro.reference_noise_var``);
- an estimator converging from 8.6 deg with an 11.5 s time constant (the generator's own run): the
  consistency check leaves out its first half minute, and the tail that decays after it was read as
  a gyro bias drift on a clean gyro; the tail is now fitted with the time constant the check found
  (``_decay.decay_tail``).
"""

import math

from _attitude_synth import diagnose_synthetic as _diagnose


def _by(rep, cause):
    return {f.get("channel"): f for f in rep["findings"] if f["cause"] == cause}


def test_a_block_of_a_body_standing_still_does_not_keep_an_offset_from_being_applied():
    """30 ms late at 50 Hz, the first 8 s of 60 standing still: the other nine blocks agree on the
    offset within a fraction of a millisecond, so it is applied with a narrow interval."""
    rep = _diagnose(7301, 400.0, 8, 60.0, sigma_ref=2e-4, offset_s=0.030, still_s=8.0)
    al = rep["run"]["reference_alignment"]
    lo, hi = al["clock_offset_interval_s"]
    # within half a gyro step (the sampling convention is the reference fit's own parameter)
    assert al["applied"]["clock_offset"] and abs(al["clock_offset_s"] - 0.030) <= 0.5 / 400.0 and hi - lo < 0.004, al
    assert not _by(rep, "gyro_scale") and not _by(rep, "gyro_bias") and not _by(rep, "gyro_bias_drift"), rep["findings"]


def test_a_bias_random_walk_under_a_sparse_noisy_reference_is_found():
    """A 1 Hz reference with 0.6 mrad per row over 80 s and a wx bias walking at 1e-4 rad/s/sqrt(s):
    the walk is named on wx, its interval holds the intensity, and no other axis drifts."""
    K = 1e-4
    rep = _diagnose(7302, 100.0, 100, 80.0, noise=1.2e-4, sigma_ref=6e-4, walk=K)
    assert any("weighs the fit (GLS)" in n for n in rep["observability"]["notes"]), rep["observability"]["notes"]
    d = _by(rep, "gyro_bias_drift")
    assert set(d) == {"wx"} and d["wx"]["interval"][0] <= K <= d["wx"]["interval"][1], rep["findings"]


def test_the_tail_of_a_converging_estimator_is_no_gyro_drift(tmp_path, monkeypatch):
    """The independent generator's run (``attitude-wide2/indep`` case 2 of the scorecard): a clean
    gyro at 1 kHz, a 5 Hz reference 60 ms late converging from 8.6 deg with an 11.5 s time constant.
    No gyro effect is named; without the tail's fit a wz bias drift of about 1e-4 rad/s/sqrt(s) was."""
    import jaxdrift
    from benchmarks import scorecard as sc
    from benchmarks.validation import gen_attitude as ga
    from benchmarks.validation.sweep import SIZING
    from jaxdrift.diagnosis.attitude import _pipeline

    case = ga.make_case(sc.cases(sc.BY_NAME["attitude-wide2/indep"])[2], **SIZING["attitude"])
    assert case["reference"]["quality"] == "converging" and not [e for e in case["effects"] if e["cause"] != "gyro_noise"]
    csv = ga.make_run(case, str(tmp_path))["csv"]
    gyro = ("gyro_bias", "gyro_scale", "gyro_bias_drift")
    rep = jaxdrift.run_attitude_diagnosis(csv, None)
    assert not [f for f in rep["findings"] if f["cause"] in gyro], rep["findings"]
    monkeypatch.setattr(_pipeline, "decay_tail", lambda *a, **k: (None, None))
    rep = jaxdrift.run_attitude_diagnosis(csv, None)
    assert [f["channel"] for f in rep["findings"] if f["cause"] == "gyro_bias_drift"] == ["wz"], rep["findings"]


def test_a_sparse_reference_on_an_unsettled_clock_is_weighed_where_its_intervals_are_long(monkeypatch):
    """A 30 ms offset left unapplied (``Z_APPLY`` raised past any offset) under a 1 Hz reference with
    1.5 mrad of noise: the offset is 3 % of the 1 s intervals, so the reference's noise is weighed and
    nothing is named (``_alignment.clock_settled``); at 4 Hz (12 %) it is not weighed."""
    from jaxdrift.diagnosis.attitude import _alignment

    monkeypatch.setattr(_alignment, "Z_APPLY", math.inf)
    rep = _diagnose(5106, 400.0, 400, 90.0, sigma_ref=1.5e-3, offset_s=0.030)
    assert not rep["run"]["reference_alignment"]["applied"]["clock_offset"]
    assert any("weighs the fit (GLS)" in n for n in rep["observability"]["notes"]), rep["observability"]["notes"]
    assert not [f for f in rep["findings"] if f["cause"].startswith("gyro_") and f["cause"] != "gyro_noise"], rep["findings"]
    rep = _diagnose(5107, 400.0, 100, 90.0, sigma_ref=1.5e-3, offset_s=0.030)
    assert not any("weighs the fit (GLS)" in n for n in rep["observability"]["notes"]), rep["observability"]["notes"]


def test_a_turned_frame_under_a_converging_estimator_is_fitted_beside_its_decay():
    """A 20 Hz reference converging from 4.5 deg (12 s time constant) in a frame turned by a constant
    1.1 deg, with 0.9 mrad of noise per row: the decay alone or the turn alone leaves a fading
    residual that read as a bias drift beside a false bias; fitted together (``_decay.decay_profile``)
    the gyro's 0.3 mrad/s wy bias is found, and nothing else."""
    b = 3e-4
    rep = _diagnose(4410, 400.0, 20, 90.0, noise=5e-5, bias=(0.0, b, 0.0), sigma_ref=9e-4, converge_deg=4.5,
                    tau_s=12.0, turn=(-0.006, 0.0033, 0.0176))
    notes = rep["observability"]["notes"]
    assert any("converges like an estimator" in n and "turned by a constant" in n for n in notes), notes
    gyro = [(f["cause"], f.get("channel")) for f in rep["findings"] if f["cause"].startswith("gyro_") and f["cause"] != "gyro_noise"]
    assert gyro == [("gyro_bias", "wy")], rep["findings"]
    lo, hi = _by(rep, "gyro_bias")["wy"]["interval"]
    assert lo <= b <= hi, (lo, hi)
