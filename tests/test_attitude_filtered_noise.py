"""A gyro whose samples are filtered inside the sensor (PX4's ``sensor_combined`` averages a faster
gyro over each interval, after a low-pass): its noise near the sampling rate is far below its
white level, which is what an angle integrates. High-order differences see the former; the block
means of a still span see the latter (:func:`jaxdrift.diagnosis.attitude._noise.block_white_noise`).
Checked against the known level of generated noise and against the Allan deviation (allantools),
an independent implementation."""

import numpy as np
import pytest
from scipy import signal

from jaxdrift.diagnosis.attitude._noise import block_white_noise, estimate_white_noise

DT = 1 / 250


def _filtered(n, sigma, seed, cutoff_hz=30.0):
    """White noise of per-sample std ``sigma`` at 1 kHz, averaged over 4 samples (250 Hz), then a
    2nd-order Butterworth low-pass: the white level below the cutoff is ``sigma / 2`` per 250 Hz
    sample."""
    rng = np.random.default_rng(seed)
    raw = sigma * rng.standard_normal((4 * n, 3))
    avg = raw.reshape(n, 4, 3).mean(axis=1)
    b, a = signal.butter(2, cutoff_hz / (0.5 / DT), "low")
    return signal.lfilter(b, a, avg, axis=0)[200:]


def test_white_noise_is_the_same_either_way():
    x = 1e-3 * np.random.default_rng(3).standard_normal((15000, 3))
    bw = block_white_noise(x, DT)
    assert bw["plateau"]
    # every block size sees the same level (the largest, 32 samples, about 7 % standard error)
    assert all(abs(np.sqrt(v) - 1e-3) < 0.1e-3 for _, v, _ in bw["ladder"]), bw["ladder"]
    assert np.sqrt(np.mean(bw["var"])) == pytest.approx(1e-3, rel=0.1)


def test_a_filtered_gyro_keeps_its_white_level_in_the_block_means():
    """True level 1e-3 rad/s per 250 Hz sample (N = 6.3e-5 rad/sqrt(s)): the differences report
    about 2 % of it (the filter leaves little near 125 Hz); the block means' plateau is within
    6 % (the standard error of 60 s of 250 Hz samples in blocks of 16 is about 3 %), and so is
    the Allan deviation at 64 ms from allantools."""
    allantools = pytest.importorskip("allantools")
    x = _filtered(15200, 2e-3, seed=11)
    diff = np.sqrt(np.mean(estimate_white_noise(x, DT)["var"]))
    bw = block_white_noise(x, DT)
    blk = np.sqrt(np.mean(bw["var"]))
    assert diff < 0.05e-3  # the defect the block means mend
    assert bw["plateau"] and bw["m"] >= 8
    assert blk == pytest.approx(1e-3, rel=0.06)
    taus, adev, _, _ = allantools.oadev(x[:, 0], rate=1 / DT, data_type="freq", taus=np.array([16 * DT]))[:4]
    n_allan = adev[0] * np.sqrt(taus[0])  # white noise: sigma_A(tau) sqrt(tau) = N
    assert n_allan == pytest.approx(1e-3 * np.sqrt(DT), rel=0.06)


def test_the_diagnosis_reports_the_level_below_the_filter(tmp_path):
    """A generated drive at 250 Hz that stands still for its first 40 s, the reference every 5th
    row, its gyro biased and filtered as above: the report's gyro_noise is the white level below
    the filter (within 10 %), says why, and the biases are still found."""
    import json

    from jaxdrift.cli import main
    from jaxdrift.studies import make_attitude_run, write_attitude_csv

    bias = np.array([2e-3, -1e-3, 5e-4])
    truth = make_attitude_run(tmp_path, 7, duration=90.0, rate_hz=250.0, static_s=40.0, bias=tuple(bias),
                              reference=5, name="clean")
    t = truth["t"]
    x = _filtered(len(t) + 200, 2e-3, seed=12)
    w = truth["w_true"] + bias + x
    q = np.where((np.arange(len(t)) % 5 == 0)[:, None], truth["q"], np.nan)
    path = tmp_path / "filtered.csv"
    write_attitude_csv(path, t, w, q)
    out = tmp_path / "r.json"
    assert main(["-q", "diagnose", str(path), "--json", str(out)]) == 0
    rep = json.loads(out.read_text())
    f = next(f for f in rep["findings"] if f["cause"] == "gyro_noise")
    N_true = 1e-3 * np.sqrt(DT)
    assert f["estimate_kind"] == "estimate" and f["estimate"] == pytest.approx(N_true, rel=0.10), f
    assert "filtered" in f["evidence"]
    named = {f["channel"]: f["estimate"] for f in rep["findings"] if f["cause"] == "gyro_bias"}
    for ch, b in zip(("wx", "wy", "wz"), bias):
        assert named[ch] == pytest.approx(b, abs=2e-4), named
