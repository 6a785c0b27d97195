"""A synthetic attitude run for the diagnosis tests: a body rocking at 0.9-2.1 Hz (standing still
for its first ``still_s``), a gyro with white noise, a constant bias and a bias random walk on wx,
and a reference attitude every ``every`` rows, late by ``offset_s``, with white noise per row and
an estimator's error decaying from ``converge_deg``, its frame turned by the rotation vector ``turn``.
Returns the report."""

import math

import numpy as np
from scipy.spatial.transform import Rotation

from jaxdrift.diagnosis.attitude import diagnose_attitude
from jaxdrift.models._quaternion import integrate_rates_np


def rates(t, still_s=0.0):
    w = np.column_stack([0.3 * np.sin(2 * np.pi * 0.9 * t + 0.3), 0.25 * np.sin(2 * np.pi * 1.3 * t),
                         0.2 * np.sin(2 * np.pi * 0.04 * t) + 0.05 * np.sin(2 * np.pi * 2.1 * t + 1.0)])
    return np.where((t >= still_s)[:, None], w, 0.0)


def diagnose_synthetic(seed, fs, every, T, noise=1e-5, bias=(0.0, 0.0, 0.0), sigma_ref=0.0, offset_s=0.0,
                       still_s=0.0, walk=None, converge_deg=0.0, tau_s=10.0, turn=(0.0, 0.0, 0.0)):
    rng = np.random.default_rng(seed)
    dt = 1.0 / fs
    t = np.arange(0.0, T, dt)
    k = 8  # the true attitude on a fine grid, so that a late reference is read between samples
    tf = np.arange(0.0, T + 0.2, dt / k)
    qf = integrate_rates_np(np.array([1.0, 0.0, 0.0, 0.0]), rates(tf, still_s), dt / k)
    w_meas = rates(t, still_s) + np.asarray(bias) + rng.normal(0.0, noise / math.sqrt(dt), (len(t), 3))
    if walk:
        w_meas[:, 0] += np.concatenate([[0.0], np.cumsum(walk * math.sqrt(dt) * rng.standard_normal(len(t) - 1))])
    rows = np.arange(0, len(t), every)
    src = np.clip(np.round((t[rows] - offset_s) / (dt / k)).astype(int), 0, len(tf) - 1)
    err = sigma_ref * rng.standard_normal((len(rows), 3))
    if converge_deg:
        d = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
        err += np.outer(np.exp(-t[rows] / tau_s), d) * math.radians(converge_deg)
    x = (Rotation.from_quat(qf[src][:, [1, 2, 3, 0]]) * Rotation.from_rotvec(turn) * Rotation.from_rotvec(err)).as_quat()
    q_ref = np.full((len(t), 4), np.nan)
    q_ref[rows] = x[:, [3, 0, 1, 2]]
    run = {"path": "synthetic", "t": t, "dt": dt, "w": w_meas, "q_ref": q_ref, "acc": None, "extra_columns": [],
           "quantisation": 0.0, "acc_quantisation": 0.0, "warnings": [], "info": {}}
    return diagnose_attitude(run)[0]
