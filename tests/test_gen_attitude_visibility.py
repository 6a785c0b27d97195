"""The independent attitude generator's visibility oracle (``benchmarks/validation/gen_attitude.py``)
against a closed form: on a body standing still, read by a gyro of white noise N against a
reference on every row, a constant bias is estimated from the total angle over the run, so its
standard error is N / sqrt(T) and an effect b sits |b| sqrt(T) / N standard errors from zero; a
scale about an axis that never turns is not determined at all (visibility 0)."""

import math

import numpy as np

from benchmarks.validation import gen_attitude as ga


def _still_case(N, b, T=100.0, fs=100.0):
    n = int(T * fs) + 1
    tau = np.arange(n) / fs
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    w = np.zeros((n, 3))
    case = {"precision": 12, "effects": [{"cause": "gyro_noise", "value": N},
                                          {"cause": "gyro_bias", "channel": "wx", "value": b},
                                          {"cause": "gyro_scale", "channel": "wy", "value": 1.05}]}
    return case, tau, q, w


def test_bias_visibility_is_the_closed_form_and_an_unturned_scale_is_invisible():
    N, b, T = 2e-4, 1e-4, 100.0
    case, tau, q, w = _still_case(N, b, T)
    rows = np.arange(len(tau))
    z = ga.visibility(case, tau, q, w, np.zeros_like(w), rows, tau[rows])
    expected = abs(b) * math.sqrt(T) / N  # 5.0
    assert abs(z["gyro_bias:wx"] / expected - 1.0) < 1e-3, (z, expected)
    assert z["gyro_scale:wy"] < 0.01, z  # its standard error is set by the 1e-12 regulariser alone


def test_reference_noise_lowers_visibility_and_sparser_rows_keep_it_for_a_bias():
    """White attitude noise on the reference telescopes for a bias: with sigma_ref, the GLS standard
    error of a bias over rows 1 s apart is sqrt(N^2 / T + 12 sigma^2 / T^3 ...) -- here checked only
    for its direction: more reference noise, lower visibility; N alone, the same at every row spacing."""
    N, b, T = 2e-4, 1e-4, 100.0
    case, tau, q, w = _still_case(N, b, T)
    every = np.arange(0, len(tau), 100)
    z_dense = ga.visibility(case, tau, q, w, np.zeros_like(w), np.arange(len(tau)), tau)["gyro_bias:wx"]
    z_sparse = ga.visibility(case, tau, q, w, np.zeros_like(w), every, tau[every])["gyro_bias:wx"]
    assert abs(z_sparse / z_dense - 1.0) < 1e-3
    case["reference"] = {"noise_rad": 5e-3}
    z_noisy = ga.visibility(case, tau, q, w, np.zeros_like(w), every, tau[every])["gyro_bias:wx"]
    assert z_noisy < 0.9 * z_sparse


def test_the_truth_records_a_bias_walks_realised_level():
    """``generate`` writes the realised mean and spread of each axis's bias random walk (a constant
    bias fitted to the run can at most be right about that level); a walk of intensity K over T
    seconds has a spread of about K sqrt(T / 3) about its start, here checked within a factor 3."""
    case = ga.make_case({"index": 0, "stratum": "single", "what": ["gyro_bias_drift"], "seed": 11},
                        durations=(40.0, 40.0), rates=(100,))
    cols, extra = ga.generate(case)
    (ax, real), = extra["drift_realised"].items()
    K = next(e["value"] for e in case["effects"] if e["cause"] == "gyro_bias_drift")
    assert ax == next(e["channel"] for e in case["effects"] if e["cause"] == "gyro_bias_drift")
    scale = K * math.sqrt(case["duration"] / 3.0)
    assert np.isfinite(real["mean"]) and scale / 3.0 < real["std"] + abs(real["mean"]) < 3.0 * scale, (real, scale)
