"""Rates logged as means over their own windows (PX4 ``sensor_combined.gyro_rad`` with
``gyro_integral_dt``): integrated as such, not interpolated as points (#45 item 5).

Checked against analytic integrals (a vibration near the Nyquist frequency that point
interpolation cannot integrate), against the windows a logger dropped, and end to end on a
ULog written by pyulog: a vibrating gyro with a known bias, its attitude stamped at window ends
as PX4 stamps it, 5 % of the messages lost.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from jaxdrift.io import read_attitude_run
from jaxdrift.io._timebase import resample, resample_windows, window_integral

SMALL = Path(__file__).parent / "data" / "ulog" / "sample_log_small.ulg"
F_VIB = 90.0  # Hz, near the Nyquist frequency of a 250 Hz log
A_VIB = 0.5  # rad/s


def _theta(t):
    """Analytic integral of the rate: a slow swing plus a 90 Hz vibration."""
    k = 2 * np.pi * F_VIB
    return 0.2 * np.sin(2 * np.pi * 0.2 * t) + A_VIB * (1 - np.cos(k * t)) / k


def _rate(t):
    return 0.2 * 2 * np.pi * 0.2 * np.cos(2 * np.pi * 0.2 * t) + A_VIB * np.sin(2 * np.pi * F_VIB * t)


def _windows(n, dt, rng, jitter=0.05):
    t = 3.0 + np.cumsum(dt * (1 + jitter * rng.uniform(-1, 1, n)))
    d = np.r_[dt, np.diff(t)]
    return t, d, (_theta(t) - _theta(t - d)) / d


def test_window_integral_is_exact_at_window_ends_and_the_grid_telescopes():
    rng = np.random.default_rng(4501)
    dt = 0.004
    t, d, v = _windows(2500, dt, rng)
    grid = t[0] + dt * np.arange(int((t[-1] - t[0]) / dt))
    theta = window_integral(t, v, d, t, dt)
    np.testing.assert_allclose(theta - theta[0], _theta(t) - _theta(t[0]), atol=1e-12)
    out, frac, _, filtered, spans = resample_windows(t, v, d, grid, dt)
    assert not filtered and len(spans) == 0 and np.isfinite(out).all()
    assert np.all((frac >= 0) & (frac <= 1))
    # the rows' sum between two grid times is the windows' integral between them
    cum = np.r_[0.0, np.cumsum(out * dt)]
    at = window_integral(t, v, d, np.r_[grid, grid[-1] + dt], dt)
    np.testing.assert_allclose(cum, at - at[0], atol=1e-12)
    # and within half a window's vibration of the truth anywhere (linear within each window):
    # max |theta''| d^2 / 8
    bound = A_VIB * 2 * np.pi * F_VIB * (1.05 * dt) ** 2 / 8 * 2 + 1e-12
    truth = _theta(np.r_[grid, grid[-1] + dt]) - _theta(grid[0])
    err_win = np.abs(cum - truth)
    assert err_win.max() <= bound
    # the same samples taken as points and interpolated: 3.7e-3 rad off (measured), 5.4 times the
    # windows' 5.5e-4, which is the within-window error at a grid time that no window ends at
    pts, _, _, _ = resample(t, v, grid)
    err_pts = np.abs(np.r_[0.0, np.cumsum(pts * dt)] - truth)
    assert err_pts.max() > 4 * err_win.max()


def test_missing_windows_are_unmeasured_and_gaps_are_nan():
    rng = np.random.default_rng(4502)
    dt = 0.004
    t, d, v = _windows(1500, dt, rng)
    drop = np.array([100, 400, 401])
    gap = np.arange(900, 960)  # 60 windows: a gap, not a bridge
    keep = np.setdiff1d(np.arange(len(t)), np.r_[drop, gap])
    t, d, v = t[keep], d[keep], v[keep]
    grid = t[0] + dt * np.arange(int((t[-1] - t[0]) / dt))
    out, _, st, _, spans = resample_windows(t, v, d, grid, dt)
    assert len(st["gap_steps"]) == 1
    # one span per hole, from the end of the window before to the start of the one after
    i = [int(np.searchsorted(t, t_) ) for t_ in spans[:, 1]]
    np.testing.assert_allclose(spans[:, 1], t[i] - d[i], atol=1e-12)
    np.testing.assert_allclose(spans[:, 0], t[np.array(i) - 1], atol=1e-12)
    assert len(spans) == 2  # drop 100, drop 400-401 (one hole); the gap is no span
    g0, g1 = t[int(st["gap_steps"][0])], t[int(st["gap_steps"][0]) + 1]
    inside = (grid > g0) & (grid + dt < g1 - d[int(st["gap_steps"][0]) + 1])
    assert inside.sum() > 50 and np.isnan(out[inside]).all()
    assert np.isfinite(out[~inside & (grid + dt <= t[-1])]).mean() > 0.99


def _ulog(path, *, windowed, bias=0.0, n=5000, lost=0.0, seed=4503):
    """A ULog (the pyulog fixture's topics rewritten) of a body swinging about x with a 90 Hz
    vibration on every axis, rates as PX4 logs them (window means, ``gyro_integral_dt``) or as
    points (``gyro_integral_dt`` 0), a bias on wx, the attitude at 50 Hz stamped at window ends
    (PX4's ``timestamp_sample``) and ``lost`` of the rate messages dropped by the logger."""
    pyulog = pytest.importorskip("pyulog")
    u = pyulog.ULog(str(SMALL), ["sensor_combined", "vehicle_attitude"])
    rng = np.random.default_rng(seed)
    sc, va = u.get_dataset("sensor_combined"), u.get_dataset("vehicle_attitude")
    dt = 0.004
    t = np.round((3.0 + np.cumsum(dt * (1 + 0.03 * rng.uniform(-1, 1, n)))) * 1e6) * 1e-6
    d = np.r_[dt, np.diff(t)]
    mean = (_theta(t) - _theta(t - d)) / d
    vib = lambda s: A_VIB * (1 - np.cos(2 * np.pi * F_VIB * s + 1.0)) / (2 * np.pi * F_VIB)  # noqa: E731
    # x: swing + vibration (the reference turns with it); y, z: vibration about a still attitude
    # would turn the reference too, so y and z vibrate with zero mean integral over each window
    w = np.column_stack([mean if windowed else _rate(t), np.zeros(n), np.zeros(n)])
    w[:, 1] = ((vib(t) - vib(t - d)) / d) if windowed else np.gradient(vib(t), t)
    w[:, 0] += bias
    w += rng.normal(0, 2e-4, w.shape)
    data = {"timestamp": np.round(t * 1e6).astype(np.uint64),
            "gyro_integral_dt": np.round(d * 1e6).astype(np.uint32) if windowed else np.zeros(n, np.uint32)}
    for j in range(3):
        data[f"gyro_rad[{j}]"] = w[:, j].astype(np.float32)
    keep = np.sort(rng.choice(n, int(round(n * (1 - lost))), replace=False)) if lost else np.arange(n)
    keep = np.union1d(keep, np.arange(0, n, 5))  # the attitude's own IMU samples are logged
    for k in list(sc.data):
        src = data.get(k)
        if src is None:
            src = np.resize(sc.data[k], n)
        sc.data[k] = np.asarray(src)[keep]
    # the attitude (about x by the swing and vibration; y's vibration turns it too) every 5th window end
    ta = t[::5]
    ax, ay = _theta(ta), vib(ta)
    from scipy.spatial.transform import Rotation

    q = Rotation.from_rotvec(np.column_stack([ax, 0 * ta, 0 * ta])) * Rotation.from_rotvec(np.column_stack([0 * ta, ay, 0 * ta]))
    qw = q.as_quat()[:, [3, 0, 1, 2]]
    m = len(ta)
    for k in list(va.data):
        va.data[k] = np.resize(va.data[k], m)
    va.data["timestamp"] = np.round(ta * 1e6).astype(np.uint64)
    va.data["timestamp_sample"] = va.data["timestamp"].copy()
    for j in range(4):
        va.data[f"q[{j}]"] = qw[:, j].astype(np.float32)
    u.write_ulog(str(path))
    return t, keep


def test_ulog_windows_carry_the_reference_exactly(tmp_path):
    from jaxdrift.models._quaternion import quat_conjugate_np, quat_multiply_np, quat_exp_np

    def closure(run):
        """Angle between the reference's increment and the rows' integral over each pair of
        consecutive reference rows (y's vibration does not commute with x's swing: small steps)."""
        rows = np.nonzero(np.isfinite(run["q_ref"][:, 0]))[0]
        errs = []
        for a, b in zip(rows[:-1], rows[1:]):
            q = run["q_ref"][a]
            for k in range(a, b):
                q = quat_multiply_np(q, quat_exp_np(run["w"][k] * run["dt"]))
            e = quat_multiply_np(quat_conjugate_np(run["q_ref"][b]), q)
            errs.append(2 * np.arcsin(min(1.0, float(np.linalg.norm(e[1:])))))
        return np.array(errs)

    win = tmp_path / "win.ulg"
    _ulog(win, windowed=True, n=1500)
    run = read_attitude_run(str(win))
    assert run["time_base"]["method"] == "window integral"
    assert run["w_unmeasured"] is not None and len(run["w_unmeasured"]) == 0
    assert any("carried to their nearest grid rows" in n for n in run["info"]["notes"])
    e_win = closure(run)
    pts = tmp_path / "pts.ulg"
    _ulog(pts, windowed=False, n=1500)
    run_p = read_attitude_run(str(pts))
    assert run_p["w_unmeasured"] is None and "windows" not in run_p["time_base"]
    e_pts = closure(run_p)
    # float32 rates and quaternions, white noise 2e-4 rad/s over 5 steps, coning of y under x
    assert np.median(e_win) < 2e-5, np.median(e_win)
    assert np.median(e_pts) > 10 * np.median(e_win)


def test_lost_windows_are_left_out_and_the_vibrating_bias_is_found(tmp_path):
    """End to end: 30 s of a gyro vibrating 0.5 rad/s at 90 Hz with a 2 mrad/s bias on x, 5 % of
    its messages lost. Read as windows, the bias is named and its interval holds the truth; the
    intervals with a lost window are not compared."""
    from jaxdrift.diagnosis.attitude import analysed_part, diagnose_attitude

    path = tmp_path / "vib.ulg"
    _, keep = _ulog(path, windowed=True, bias=2e-3, n=7500, lost=0.05)
    run, _ = analysed_part(read_attitude_run(str(path)))
    assert len(run["w_unmeasured"]) > 200
    report, _ = diagnose_attitude(run)
    bias = [f for f in report["findings"] if f["cause"] == "gyro_bias" and f["channel"] == "wx"]
    assert bias, [f["cause"] for f in report["findings"]]
    lo, hi = bias[0]["interval"]
    assert lo <= 2e-3 <= hi and hi - lo < 0.5e-3
    # the intervals holding a lost window are not compared (about 1 in 4 here: 5 % of windows lost,
    # 5 windows an interval, none of the attitude's own)
    used, n_int = (int(x) for x in report["observability"]["used"][0].split("(")[1].split(" intervals")[0].split(" of "))
    p = (1 - len(keep) / 7500) * 5 / 4  # the share lost of the 4 windows an interval may lose
    assert n_int == 1499 and abs(1 - used / n_int - (1 - (1 - p) ** 4)) < 0.04
