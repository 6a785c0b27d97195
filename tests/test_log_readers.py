"""Real logs as they are recorded: jittered time, gaps, a slower reference, ULog and ROS bags.

The time-base policy (jaxdrift/io/_timebase.py, docs/measured-data.md "Time base") is checked
against analytic signals (linear interpolation error bound), against the samples as written
(references, gaps), and against scipy's filter; the readers against the libraries that wrote the
files (pyulog, rosbags) and against a small real PX4 log from the pyulog project
(tests/data/ulog/sample_log_small.ulg, BSD licence: tests/data/ulog/LICENSE-pyulog).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import json

import numpy as np
import pytest

from jaxdrift import cli
from jaxdrift.errors import InputError, UsageError
from jaxdrift.io import load_run, read_attitude_run
from jaxdrift.io._attitude_files import attitude_segments
from jaxdrift.io._timebase import GAP_FACTOR

DATA = Path(__file__).parent / "data" / "ulog"
SMALL = DATA / "sample_log_small.ulg"
F = 1.3  # Hz, the analytic rate signal


def _jittered_t(n, dt, rng, jitter=0.02, gaps=()):
    steps = dt * (1 + jitter * rng.uniform(-1, 1, n - 1))
    for i, k in gaps:  # at step i, k samples missing
        steps[i] += k * dt
    return np.round(np.concatenate([[0.0], np.cumsum(steps)]) + 3.0, 9)  # as written with 9 decimals


def _w(t):
    return np.column_stack([0.3 * np.sin(2 * np.pi * F * t), 0.2 * np.cos(2 * np.pi * F * t), 0.01 + 0 * t])


def _write_csv(path, t, w, q=None, qrows=None):
    with open(path, "w") as fh:
        fh.write("t,wx,wy,wz" + (",qw,qx,qy,qz" if q is not None else "") + "\n")
        for i in range(len(t)):
            row = f"{t[i]:.9f}," + ",".join(f"{v:.12g}" for v in w[i])
            if q is not None:
                row += "," + (",".join(f"{v:.12g}" for v in q[qrows[i]]) if qrows[i] >= 0 else ",,,")
            fh.write(row + "\n")


def _quat(t):
    a = 0.2 * np.sin(2 * np.pi * 0.2 * t)
    return np.column_stack([np.cos(a / 2), np.sin(a / 2), 0 * t, 0 * t])


def test_jittered_csv_refused_strict_and_resampled_otherwise(tmp_path):
    rng = np.random.default_rng(4021)
    dt = 0.005
    t = _jittered_t(2000, dt, rng)
    path = tmp_path / "jit.csv"
    _write_csv(path, t, _w(t))
    with pytest.raises(UsageError, match=r"column t: non-uniform sampling"):
        read_attitude_run(str(path), strict_time=True)
    run = read_attitude_run(str(path))
    tb = run["time_base"]
    d = np.diff(t)
    assert tb["resampled"] and tb["method"] == "linear" and tb["gaps"] == []
    assert tb["nominal_dt"] == pytest.approx(np.median(d), rel=1e-12)
    assert tb["jitter_max_rel"] == pytest.approx(np.max(np.abs(d / np.median(d) - 1)), rel=1e-9)
    assert tb["jitter_std_rel"] == pytest.approx(np.std(d / np.median(d) - 1), rel=1e-9)
    g = run["t"]
    np.testing.assert_allclose(np.diff(g), tb["nominal_dt"], rtol=1e-9)
    assert g[0] == pytest.approx(t[0]) and g[-1] <= t[-1]
    # linear interpolation error <= h^2/8 max|w''| (h the longest step), plus the 12 digits written
    bound = (d.max() ** 2 / 8) * 0.3 * (2 * np.pi * F) ** 2 + 1e-9
    err = np.abs(run["w"] - _w(g))
    assert np.all(np.isfinite(err)) and err.max() <= bound
    assert err.max() > bound / 100  # the bound is not vacuous: the grid is not the samples
    np.testing.assert_allclose(run["w_recorded_t"], t, atol=0)
    np.testing.assert_allclose(run["w_recorded"], _w(t), atol=1e-11)


def test_gap_is_never_interpolated_across(tmp_path):
    """9 and 3 missing samples are gaps (segments, NaN rows); one or two dropped samples are
    bridged by the interpolation and reported (a logger that drops a sample now and then is not
    cut into a segment per drop)."""
    rng = np.random.default_rng(4022)
    dt = 0.004
    t = _jittered_t(1500, dt, rng, gaps=[(300, 2), (600, 9), (900, 1), (1300, 3)])
    w = _w(t)
    path = tmp_path / "gap.csv"
    _write_csv(path, t, w)
    run = read_attitude_run(str(path))
    tb = run["time_base"]
    assert [(g["t_start"], g["t_end"]) for g in tb["gaps"]] == [(pytest.approx(t[600]), pytest.approx(t[601])),
                                                                 (pytest.approx(t[1300]), pytest.approx(t[1301]))]
    assert all(g["duration_s"] > GAP_FACTOR * dt for g in tb["gaps"])
    br = tb["bridged"]["wx"]
    assert br["steps"] == 2 and br["missing_samples"] == 3
    assert [b["t_start"] for b in br["first"]] == [pytest.approx(t[300]), pytest.approx(t[900])]
    assert any("bridged" in n for n in run["info"]["notes"])
    segs = tb["segments"]
    assert len(segs) == 3
    g = run["t"]
    for (a, b), (i0, i1) in zip([(t[0], t[600]), (t[601], t[1300]), (t[1301], t[-1])], segs):
        assert a <= g[i0] and g[i1 - 1] <= b  # every row of a segment between its own samples
        assert np.all(np.isfinite(run["w"][i0:i1]))
    gap_rows = (g > t[600]) & (g < t[601])
    assert gap_rows.sum() >= 9 and np.all(np.isnan(run["w"][gap_rows]))
    # across a bridged drop the rows are the linear interpolation of the samples either side
    rows = (g > t[900]) & (g < t[901])
    assert rows.sum() >= 1
    np.testing.assert_allclose(run["w"][rows, 0], np.interp(g[rows], t[900:902], w[900:902, 0]), rtol=1e-9)
    parts = attitude_segments(run)
    assert [p["rows"] for p in parts] == [tuple(s) for s in segs]
    assert all(np.all(np.isfinite(p["w"])) for p in parts)
    assert sum(len(p["t"]) for p in parts) == int(np.isfinite(run["w"][:, 0]).sum())


def test_reference_stays_on_its_own_times(tmp_path):
    rng = np.random.default_rng(4023)
    t = _jittered_t(1200, 0.005, rng, jitter=0.03)
    q = _quat(t)
    qrows = np.where(np.arange(len(t)) % 4 == 1, np.arange(len(t)), -1)  # a 50 Hz reference
    path = tmp_path / "ref.csv"
    _write_csv(path, t, _w(t), q, qrows)
    run = read_attitude_run(str(path))
    have = qrows >= 0
    np.testing.assert_allclose(run["q_ref_t"], t[have], rtol=0, atol=1e-12)
    np.testing.assert_allclose(run["q_ref_q"], q[have], atol=1e-11)  # as written, not interpolated
    placed = np.flatnonzero(np.isfinite(run["q_ref"][:, 0]))
    assert len(placed) == have.sum()
    # each on the grid row nearest its own time, with its own value
    k = np.rint((t[have] - run["t"][0]) / run["dt"]).astype(int)
    np.testing.assert_array_equal(placed, k)
    np.testing.assert_allclose(run["q_ref"][k], q[have], atol=1e-11)
    assert run["time_base"]["reference"]["samples"] == have.sum()


def test_uniform_runs_are_unchanged(tmp_path):
    t = np.arange(800) * 0.005
    path = tmp_path / "uni.csv"
    _write_csv(path, t, _w(t))
    run = read_attitude_run(str(path))
    assert run["time_base"]["resampled"] is False and run["time_base"]["segments"] == [[0, 800]]
    np.testing.assert_allclose(run["w"], _w(t), atol=1e-11)


def test_noise_variance_factor_matches_resampled_white_noise(tmp_path):
    """Linear interpolation leaves (1-a)^2 + a^2 of a white noise's variance: the factor the time
    base reports is what the resampled noise shows (statistical bound: 5 standard errors)."""
    from jaxdrift.io._timebase import build_time_base

    rng = np.random.default_rng(4024)
    n = 40000
    t = _jittered_t(n, 0.004, rng, jitter=0.3)
    x = rng.normal(0, 1, n)
    _, on_grid, _, tb = build_time_base({"wx": (t, x)}, "wx")
    v = np.nanvar(on_grid["wx"])
    se = np.sqrt(2.0 / n)
    assert tb["noise_variance_factor"] < 0.95
    assert abs(v - tb["noise_variance_factor"]) < 5 * se


def test_vehicle_run_is_analysed_on_its_longest_segment(tmp_path):
    rng = np.random.default_rng(4025)
    dt = 0.002
    t = _jittered_t(3000, dt, rng, jitter=0.01, gaps=[(700, 20)])
    f1 = 3825 + 50 * np.sin(2 * np.pi * 0.7 * t)
    path = tmp_path / "veh.csv"
    with open(path, "w") as fh:
        fh.write("t,f1,f2\n")
        for i in range(len(t)):
            fh.write(f"{t[i]:.9f},{f1[i]:.9f},{f1[i]:.9f}\n")
    with pytest.raises(InputError, match="non-uniform"):
        load_run(path, strict_time=True)
    run = load_run(path)
    tb = run.time_base
    assert len(tb["segments"]) == 2 and tb["analysed_segment"] == tb["segments"][1]
    assert run.t[0] >= t[701] and run.t[-1] <= t[-1]
    assert np.all(np.isfinite(run["f1"]))
    np.testing.assert_allclose(run["f1"], 3825 + 50 * np.sin(2 * np.pi * 0.7 * run.t), atol=1e-3)
    assert any("longest segment" in n for n in run.info["notes"])


# ----------------------------------------------------------------------------------- ULog

def _w_integral(t):
    """The running integral of :func:`_w` (analytic)."""
    k = 2 * np.pi * F
    return np.column_stack([0.3 * (1 - np.cos(k * t)) / k, 0.2 * np.sin(k * t) / k, 0.01 * t])


def _synthetic_ulog(path, gaps=((400, 12),), seed=4026, windowed=False, drop=()):
    """The real fixture's sensor_combined and vehicle_attitude, with analytic rates at jittered
    times (one gap) and an analytic reference at 50 Hz, written back by pyulog. ``windowed``: the
    rates are the exact means over their windows (``gyro_integral_dt`` the step before each, as
    PX4 writes them; ``drop`` the samples the logger lost, their windows with them), else point
    values at the stamps with ``gyro_integral_dt`` 0 (no windows)."""
    pyulog = pytest.importorskip("pyulog")
    u = pyulog.ULog(str(SMALL), ["sensor_combined", "vehicle_attitude"])
    rng = np.random.default_rng(seed)
    sc, va = u.get_dataset("sensor_combined"), u.get_dataset("vehicle_attitude")
    n = len(sc.data["timestamp"])
    t = _jittered_t(n, 0.004, rng, jitter=0.03, gaps=gaps) + 20.0
    sc.data["timestamp"] = np.round(t * 1e6).astype(np.uint64)
    t = sc.data["timestamp"] * 1e-6
    if windowed:
        d = np.r_[0.004, np.diff(t)]
        d[1:][np.diff(t) > 0.006] = 0.004  # a window after a gap is one step long
        sc.data["gyro_integral_dt"] = np.round(d * 1e6).astype(sc.data["gyro_integral_dt"].dtype)
        d = sc.data["gyro_integral_dt"] * 1e-6
        w = (_w_integral(t) - _w_integral(t - d)) / d[:, None]
    else:
        sc.data["gyro_integral_dt"] = np.zeros_like(sc.data["gyro_integral_dt"])
        w = _w(t)
    for j in range(3):
        sc.data[f"gyro_rad[{j}]"] = w[:, j].astype(np.float32)
    if drop:
        keep = np.setdiff1d(np.arange(n), drop)
        for k_ in list(sc.data):
            sc.data[k_] = sc.data[k_][keep]
        t, w = t[keep], w[keep]
    m = len(va.data["timestamp"])
    tq = t[0] + 0.02 * np.arange(m) + 0.001
    va.data["timestamp"] = np.round(tq * 1e6).astype(np.uint64)
    if "timestamp_sample" in va.data:
        va.data["timestamp_sample"] = va.data["timestamp"].copy()
    tq = va.data["timestamp"] * 1e-6
    q = _quat(tq)
    for j in range(4):
        va.data[f"q[{j}]"] = q[:, j].astype(np.float32)
    u.write_ulog(str(path))
    return t, w, tq, q


def test_ulog_defaults_time_base_and_reference(tmp_path):
    path = tmp_path / "syn.ulg"
    t, w, tq, q = _synthetic_ulog(path)
    run = read_attitude_run(str(path))
    assert run["info"]["format"] == "ulog"
    assert run["info"]["columns"]["wx"] == "sensor_combined:0.gyro_rad[0]"
    tb = run["time_base"]
    assert len(tb["gaps"]) == 1 and tb["gaps"][0]["t_start"] == pytest.approx(t[400])
    assert len(tb["segments"]) == 2
    ok = np.isfinite(run["w"][:, 0])
    bound = (np.diff(t).max() ** 2 / 8) * 0.3 * (2 * np.pi * F) ** 2 + 1e-7  # + float32 storage
    assert np.max(np.abs(run["w"][ok] - _w(run["t"][ok]))) <= bound
    inside = (tq >= run["t"][0]) & (tq <= run["t"][-1])
    np.testing.assert_allclose(run["q_ref_t"], tq, atol=1e-9)
    np.testing.assert_allclose(run["q_ref_q"], q, atol=1e-6)  # float32 in the log
    assert np.isfinite(run["q_ref"][:, 0]).sum() == pytest.approx(inside.sum(), abs=len(tq) * 0.02)
    with pytest.raises(UsageError, match="different times"):
        read_attitude_run(str(path), strict_time=True)


def test_ulog_map_picks_fields_and_instances(tmp_path):
    path = tmp_path / "syn.ulg"
    t, w, _, _ = _synthetic_ulog(path, gaps=())
    run = read_attitude_run(str(path), map="wx=sensor_combined.gyro_rad[1],wy=sensor_combined:0.gyro_rad[0]")
    np.testing.assert_allclose(run["w"][:, 0], _w(run["t"])[:, 1], atol=2e-4)
    with pytest.raises(UsageError, match=r"topic 'sensor_combined' has no instance 3 \(instances: 0"):
        read_attitude_run(str(path), map="wx=sensor_combined:3.gyro_rad[0]")
    with pytest.raises(UsageError, match=r"no field 'gyro_rad\[5\]'; did you mean"):
        read_attitude_run(str(path), map="wx=sensor_combined.gyro_rad[5]")
    with pytest.raises(UsageError, match=r"no topic 'sensor_gyr' logged; did you mean 'sensor_gyro'"):
        read_attitude_run(str(path), map="wx=sensor_gyr:1.x")


def test_real_ulog_and_its_csv_export_read_the_same(tmp_path, capsys, monkeypatch):
    pytest.importorskip("pyulog")
    from jaxdrift.io import _logs

    # the log's rates are window means (gyro_integral_dt), read as such; a CSV has no windows: the
    # export is compared with the log read as points
    assert read_attitude_run(str(SMALL))["time_base"]["windows"]["channels"] == ["wx", "wy", "wz"]
    monkeypatch.setattr(_logs, "ULOG_WINDOWS", {})
    run = read_attitude_run(str(SMALL))
    tb = run["time_base"]
    assert "windows" not in tb
    assert run["info"]["log"]["ver_hw"] == "CUBEPILOT_CUBEORANGE"  # real hardware, not SITL
    assert tb["fs"] == pytest.approx(204.58, rel=1e-3) and len(tb["gaps"]) == 1
    assert tb["gaps"][0]["duration_s"] == pytest.approx(0.1613, abs=2e-4)
    out = tmp_path / "small.csv"
    assert cli.main(["topics", str(SMALL), "--export-csv", str(out)]) == 0
    head = out.read_text().splitlines()
    assert head[0] == "t,wx,wy,wz,qw,qx,qy,qz"
    assert head[1].startswith("0,") and sum(1 for ln in head if not ln.endswith(",,,")) > 1000
    again = read_attitude_run(str(out))
    assert again["time_base"]["segments"] == tb["segments"]
    np.testing.assert_allclose(again["t"] - again["t"][0], run["t"] - run["t"][0], atol=1e-9)
    np.testing.assert_allclose(again["w"], run["w"], atol=1e-6, equal_nan=True)
    assert len(again["q_ref_t"]) == len(run["q_ref_t"])
    np.testing.assert_allclose(again["q_ref_q"], run["q_ref_q"], atol=1e-7)


def test_topics_lists_the_log(tmp_path, capsys):
    pytest.importorskip("pyulog")
    assert cli.main(["topics", str(SMALL)]) == 0
    out = capsys.readouterr().out
    line = next(ln for ln in out.splitlines() if ln.startswith("sensor_combined "))
    assert "gyro_rad[0]" in line and "204.6" in line
    assert sum(ln.startswith("sensor_gyro ") for ln in out.splitlines()) == 3  # instances 0, 1, 2
    rc = cli.main(["diagnose", str(SMALL), "--json", str(tmp_path / "r.json"), "--strict-time"])
    assert rc == 2 and "non-uniform sampling" in capsys.readouterr().err


@pytest.mark.parametrize("module,fname,extra", [("pyulog", "x.ulg", "ulog"), ("rosbags", "x.bag", "ros")])
def test_missing_extra_says_how_to_install(tmp_path, monkeypatch, module, fname, extra):
    path = tmp_path / fname
    path.write_bytes(b"not read")
    for m in [k for k in sys.modules if k == module or k.startswith(module + ".")]:
        monkeypatch.delitem(sys.modules, m)
    monkeypatch.setitem(sys.modules, module, None)  # import -> ImportError
    with pytest.raises(UsageError, match=rf"pip install 'jaxdrift\[{extra}\]'"):
        read_attitude_run(str(path))


# ----------------------------------------------------------------------------------- ROS bags

def _imu_msgs(store, t, w, q=None, kind="ROS2"):
    T = store.types
    out = []
    for i in range(len(t)):
        sec = int(t[i])
        stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t[i] - sec) * 1e9)))
        o = q[i] if q is not None else (0.0, 0.0, 0.0, 0.0)
        cov = np.zeros(9)
        if q is None:
            cov[0] = -1.0
        out.append(T["sensor_msgs/msg/Imu"](
            header=(T["std_msgs/msg/Header"](seq=i, stamp=stamp, frame_id="imu") if "ROS1" in kind
                    else T["std_msgs/msg/Header"](stamp=stamp, frame_id="imu")),
            orientation=T["geometry_msgs/msg/Quaternion"](w=o[0], x=o[1], y=o[2], z=o[3]),
            orientation_covariance=cov,
            angular_velocity=T["geometry_msgs/msg/Vector3"](x=w[i, 0], y=w[i, 1], z=w[i, 2]),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=9.81),
            linear_acceleration_covariance=np.zeros(9)))
    return out


@pytest.mark.parametrize("ros", [1, 2])
@pytest.mark.parametrize("with_q", [True, False])
def test_ros_bag_imu(tmp_path, monkeypatch, ros, with_q):
    pytest.importorskip("rosbags")
    from rosbags.typesys import Stores, get_typestore

    rng = np.random.default_rng(4027 + ros)
    t = _jittered_t(600, 0.005, rng, jitter=0.05, gaps=[(300, 6)]) + 1000.0
    w = _w(t)
    q = _quat(t) if with_q else None
    msgs = _imu_msgs(get_typestore(Stores.ROS2_HUMBLE), t, w, q)
    if ros == 2:
        from rosbags.rosbag2 import Writer

        path = tmp_path / "bag2"
        store = get_typestore(Stores.ROS2_HUMBLE)
        with Writer(path, version=9) as wr:
            c = wr.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=store)
            for ti, m in zip(t, msgs):
                wr.write(c, int(ti * 1e9) + 1234, store.serialize_cdr(m, "sensor_msgs/msg/Imu"))
    else:
        from rosbags.rosbag1 import Writer

        path = tmp_path / "run.bag"
        store = get_typestore(Stores.ROS1_NOETIC)
        msgs = _imu_msgs(store, t, w, q, "ROS1")
        with Writer(path) as wr:
            c = wr.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=store)
            for ti, m in zip(t, msgs):
                wr.write(c, int(ti * 1e9) + 1234, store.serialize_ros1(m, "sensor_msgs/msg/Imu"))
    run = read_attitude_run(str(path))
    assert run["info"]["format"] == "bag"
    assert run["info"]["columns"]["wx"] == "/imu/data.angular_velocity.x"
    tb = run["time_base"]
    assert len(tb["gaps"]) == 1 and tb["gaps"][0]["t_start"] == pytest.approx(t[300], abs=1e-8)
    ok = np.isfinite(run["w"][:, 0])
    bound = (np.diff(t).max() ** 2 / 8) * 0.3 * (2 * np.pi * F) ** 2 + 1e-9
    assert np.max(np.abs(run["w"][ok] - _w(run["t"][ok]))) <= bound
    if with_q:
        np.testing.assert_allclose(run["q_ref_t"], t, atol=1e-8)  # header stamps, not record times
        np.testing.assert_allclose(run["q_ref_q"], q, atol=1e-12)
    else:
        assert run["q_ref"] is None and run["q_ref_t"] is None
    rows = cli.main(["topics", str(path)])
    assert rows == 0
    if ros == 2 and with_q:
        # a ROS 2 bag is a folder: the report's provenance hashes every file in it
        assert cli.main(["-q", "diagnose", str(path), "--json", str(tmp_path / "r.json"), "--force"]) == 0  # wz constant
        (inp,) = json.loads((tmp_path / "r.json").read_text())["provenance"]["inputs"]
        assert inp["bytes"] == sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
        assert len(inp["sha256"]) == 64
    # the numpy path over the raw messages is taken, and reads what rosbags deserialises
    from jaxdrift.io import _bag_fast, _logs

    reader = _logs._bag_reader(path)
    try:
        conns = [c for c in reader.connections if c.topic == "/imu/data"]
        assert _bag_fast.imu_series(reader, conns, ["angular_velocity.x"], _logs._stamp, _logs._getter) is not None
    finally:
        reader.close()
    monkeypatch.setattr(_bag_fast, "imu_series", lambda *args: None)
    slow = read_attitude_run(str(path))
    np.testing.assert_array_equal(slow["w"], run["w"])
    np.testing.assert_array_equal(slow["t"], run["t"])
    if with_q:
        np.testing.assert_array_equal(slow["q_ref_q"], run["q_ref_q"])


def test_parquet_with_jittered_time_reads_as_the_csv(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    rng = np.random.default_rng(4029)
    t = _jittered_t(900, 0.005, rng, gaps=[(500, 3)])
    w = _w(t)
    _write_csv(tmp_path / "j.csv", t, w)
    pq.write_table(pa.table({"t": t, "wx": w[:, 0], "wy": w[:, 1], "wz": w[:, 2]}), tmp_path / "j.parquet")
    a, b = read_attitude_run(str(tmp_path / "j.csv")), read_attitude_run(str(tmp_path / "j.parquet"))
    assert a["time_base"]["segments"] == b["time_base"]["segments"] and len(b["time_base"]["gaps"]) == 1
    np.testing.assert_allclose(b["w"], a["w"], atol=1e-11, equal_nan=True)


def test_mf4_attitude_reference_on_its_own_times(tmp_path):
    pytest.importorskip("asammdf")
    from asammdf import MDF, Signal

    rng = np.random.default_rng(4030)
    t = _jittered_t(1500, 0.004, rng, jitter=0.02, gaps=[(800, 5)])
    w = _w(t)
    tq = np.round(np.arange(t[0] + 0.001, t[-1], 0.02), 9)  # a 50 Hz reference
    q = _quat(tq)
    mdf = MDF(version="4.10")
    mdf.append([Signal(w[:, j], t, name=f"gyro_{a}", unit="rad/s") for j, a in enumerate("xyz")])
    mdf.append([Signal(q[:, j], tq, name=f"att_{a}") for j, a in enumerate("wxyz")])
    mdf.save(tmp_path / "att.mf4", overwrite=True)
    mdf.close()
    m = "wx=gyro_x,wy=gyro_y,wz=gyro_z,qw=att_w,qx=att_x,qy=att_y,qz=att_z"
    run = read_attitude_run(str(tmp_path / "att.mf4"), map=m)
    assert len(run["time_base"]["segments"]) == 2
    np.testing.assert_allclose(run["q_ref_t"], tq, atol=1e-12)
    np.testing.assert_allclose(run["q_ref_q"], q, atol=1e-12)  # never interpolated
    ok = np.isfinite(run["w"][:, 0])
    bound = (np.diff(t).max() ** 2 / 8) * 0.3 * (2 * np.pi * F) ** 2 + 1e-12
    assert np.max(np.abs(run["w"][ok] - _w(run["t"][ok]))) <= bound


def test_ulog_fast_path_reads_what_pyulog_reads(tmp_path, monkeypatch):
    """The fast path (headers walked, payloads read by numpy) gives pyulog's arrays bit for bit,
    every topic of every log at hand (appended data included); a log it does not take (a corrupt
    or unknown message) goes to pyulog with the same result."""
    pyulog = pytest.importorskip("pyulog")
    from jaxdrift.io import _ulog_fast

    topics = ["sensor_combined", "vehicle_attitude", "sensor_gyro"]
    fast = _ulog_fast.read_topics(SMALL, topics, pyulog.ULog)
    assert fast is not None
    ref = {(d.name, d.multi_id): d.data for d in pyulog.ULog(str(SMALL), topics).data_list}
    got = {(d.name, d.multi_id): d.data for d in fast[0]}
    assert set(got) == set(ref) and len(got) == 5  # sensor_gyro has 3 instances
    for key, data in ref.items():
        assert set(got[key]) == set(data)
        for f, v in data.items():
            np.testing.assert_array_equal(got[key][f], v)
    for log in (SMALL, DATA / "sample_appended_multiple.ulg", DATA / "sample.ulg"):  # every topic
        if not log.exists():
            continue  # the larger pyulog logs come with the real-data validation
        fast = _ulog_fast.read_topics(log, None, pyulog.ULog)
        u = pyulog.ULog(str(log))
        ref = {(d.name, d.multi_id): d.data for d in u.data_list}
        got = {(d.name, d.multi_id): d.data for d in fast[0]}
        assert set(got) == set(ref) and fast[2] == [d.duration for d in u.dropouts]
        assert all(np.array_equal(got[k][f], v, equal_nan=True) for k in ref for f, v in ref[k].items())
    a = read_attitude_run(str(SMALL))
    monkeypatch.setattr(_ulog_fast, "read_topics", lambda *args: None)
    b = read_attitude_run(str(SMALL))
    np.testing.assert_array_equal(a["w"], b["w"])
    np.testing.assert_array_equal(a["q_ref_q"], b["q_ref_q"])
    assert a["info"]["log"] == b["info"]["log"]


def test_ulog_fs_makes_a_coarser_grid_with_the_filter_first(tmp_path):
    from scipy.signal import butter, sosfiltfilt

    path = tmp_path / "syn.ulg"
    t, w, _, _ = _synthetic_ulog(path, gaps=())
    run = read_attitude_run(str(path), fs=100.0)
    tb = run["time_base"]
    assert tb["fs"] == 100.0 and tb["filtered"] == ["wx", "wy", "wz"] and tb["primary_fs"] > 240
    fs_c = 1.0 / np.median(np.diff(t))
    sos = butter(4, 0.8 * 50.0, fs=fs_c, output="sos")
    ref = np.interp(run["t"], t, sosfiltfilt(sos, w[:, 0].astype(np.float32).astype(float)))
    np.testing.assert_allclose(run["w"][:, 0], ref, atol=1e-9)


def test_attitude_report_run_block_shows_the_time_base(tmp_path):
    rng = np.random.default_rng(4031)
    t = _jittered_t(3000, 0.005, rng, jitter=0.02)
    w = _w(t) + rng.normal(0, 1e-3, (len(t), 3))
    q = _quat(t)
    path = tmp_path / "jit.csv"
    _write_csv(path, t, w, q, np.where(np.arange(len(t)) % 5 == 0, np.arange(len(t)), -1))
    out = tmp_path / "r.json"
    assert cli.main(["-q", "diagnose", str(path), "--json", str(out)]) == 0
    import json

    rep = json.loads(out.read_text())
    tb = rep["run"]["time_base"]
    assert tb["resampled"] is True and tb["method"] == "linear" and tb["gaps"] == []
    assert tb["jitter_max_rel"] == pytest.approx(np.max(np.abs(np.diff(t) / np.median(np.diff(t)) - 1)), rel=1e-6)
    assert rep["provenance"]["reading"]["time_base"]["reference"]["samples"] == 600


def test_resample_equals_interpolation_segment_by_segment():
    """One interpolation with the gap rows cut == np.interp inside each segment separately
    (many gaps, some isolated samples), NaN outside every segment."""
    from jaxdrift.io._timebase import resample, sample_segments, step_stats

    rng = np.random.default_rng(4032)
    gaps = [(int(i), int(k)) for i, k in zip(rng.choice(np.arange(5, 4990), 120, replace=False),
                                              rng.integers(1, 6, 120))]
    t = _jittered_t(5000, 0.01, rng, jitter=0.2, gaps=gaps)
    v = rng.normal(size=len(t))
    grid = t[0] + np.arange(int((t[-1] - t[0]) / 0.01) + 1) * 0.01
    out, frac, st, _ = resample(t, v, grid)
    ref = np.full(len(grid), np.nan)
    for a, b in sample_segments(len(t), st["gap_steps"]):
        m = (grid >= t[a]) & (grid <= t[b - 1])
        ref[m] = np.interp(grid[m], t[a:b], v[a:b])
    np.testing.assert_array_equal(np.isnan(out), np.isnan(ref))
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12, equal_nan=True)
    assert len(frac) == np.isfinite(out).sum() and np.all((frac >= 0) & (frac <= 1))


def test_ulog_reference_samples_that_are_no_rotation_are_left_out(tmp_path):
    """A flight controller logs zeros before its estimator has an attitude: those samples are
    left out of the reference with a note (a CSV with such a row is refused, as before)."""
    pyulog = pytest.importorskip("pyulog")
    path = tmp_path / "syn.ulg"
    _, _, tq, q = _synthetic_ulog(path, gaps=())
    u = pyulog.ULog(str(path))
    va = u.get_dataset("vehicle_attitude")
    for j in range(4):
        va.data[f"q[{j}]"][:5] = 0.0
    u.write_ulog(str(tmp_path / "zeros.ulg"))
    run = read_attitude_run(str(tmp_path / "zeros.ulg"))
    np.testing.assert_allclose(run["q_ref_t"], tq[5:], atol=1e-9)
    assert any("5 of" in n and "no unit quaternion" in n for n in run["info"]["notes"])


def test_gapped_attitude_run_is_diagnosed_not_crashed(tmp_path, capsys):
    """A run split by a gap is diagnosed whole (the attitude diagnosis analyses its segments
    jointly, SEGMENTS_JOINT); were it not, `diagnose` would give it the longest segment, say so, and
    the report's run block would name it."""
    import json

    from jaxdrift.diagnosis.attitude import _pipeline

    rng = np.random.default_rng(4033)
    t = _jittered_t(2500, 0.005, rng, jitter=0.02, gaps=[(700, 8)])
    w = _w(t) + rng.normal(0, 1e-3, (len(t), 3))
    path = tmp_path / "gap.csv"
    _write_csv(path, t, w, _quat(t), np.where(np.arange(len(t)) % 5 == 0, np.arange(len(t)), -1))
    out = tmp_path / "r.json"
    # the page too: its gyro spectrum is taken on the longest stretch of finite rows (NaN rows in
    # the gap made the report non-finite and the command fail)
    assert cli.main(["diagnose", str(path), "--json", str(out), "--html", str(tmp_path / "r.html")]) == 0
    assert (tmp_path / "r.html").stat().st_size > 0
    rep = json.loads(out.read_text())
    tb = rep["run"]["time_base"]
    joint = getattr(_pipeline, "SEGMENTS_JOINT", False)
    if not joint:
        assert tb["analysed_segment"] == tb["segments"][1] and rep["run"]["rows"] == np.diff(tb["segments"][1])[0]
        assert "analyses the longest" in capsys.readouterr().err
    assert len(tb["gaps"]) == 1
    if joint:
        assert "analysed_segment" not in tb
        assert "analyses the longest" not in capsys.readouterr().err
        assert rep["run"]["rows"] == tb["segments"][-1][1] - tb["segments"][0][0]


def test_ros_bag_with_varying_frame_names_reads_message_by_message(tmp_path):
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    from jaxdrift.io import _bag_fast, _logs

    store = get_typestore(Stores.ROS2_HUMBLE)
    t = _jittered_t(200, 0.005, np.random.default_rng(4034)) + 50.0
    msgs = _imu_msgs(store, t, _w(t), _quat(t))
    for i, m in enumerate(msgs):
        m.header.frame_id = "imu" if i % 2 else "imu_link"  # two lengths: no fixed layout
    path = tmp_path / "bag2"
    with Writer(path, version=9) as wr:
        c = wr.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=store)
        for ti, m in zip(t, msgs):
            wr.write(c, int(ti * 1e9), store.serialize_cdr(m, "sensor_msgs/msg/Imu"))
    reader = _logs._bag_reader(path)
    try:
        assert _bag_fast.imu_series(reader, list(reader.connections), ["angular_velocity.x"],
                                    _logs._stamp, _logs._getter) is None
    finally:
        reader.close()
    run = read_attitude_run(str(path))
    np.testing.assert_allclose(run["q_ref_q"], _quat(t), atol=1e-12)
    np.testing.assert_allclose(run["w_recorded"], _w(t), atol=1e-12)


def test_log_times_zero_repeated_and_out_of_order_are_noted():
    from jaxdrift.io._logs import _clean_times

    t = np.array([0.0, 1.0, 2.0, 2.0, 4.0, 3.0, 5.0])
    v = np.arange(7.0)
    tc, (vc,), notes = _clean_times("x.ulg", "topic:0", t, [v])
    np.testing.assert_array_equal(tc, [1.0, 2.0, 3.0, 4.0, 5.0])
    np.testing.assert_array_equal(vc, [1.0, 2.0, 5.0, 4.0, 6.0])
    assert len(notes) == 3 and "zero time stamp" in notes[0] and "sorted" in notes[1] and "repeating" in notes[2]


def test_fs_on_a_jittered_csv_sets_the_grid_and_is_checked(tmp_path):
    rng = np.random.default_rng(4035)
    t = _jittered_t(1000, 0.005, rng, jitter=0.02)
    path = tmp_path / "jit.csv"
    _write_csv(path, t, _w(t))
    run = read_attitude_run(str(path), fs=200.0)
    assert run["time_base"]["fs"] == 200.0 and run["dt"] == pytest.approx(0.005, rel=1e-12)
    with pytest.raises(UsageError, match=r"median\), but --fs 250 gives 0.004 s"):
        read_attitude_run(str(path), fs=250.0)


def test_legitimate_logs_need_no_force(tmp_path):
    """A log format fixes its time unit: a gyro logged at 9.6 Hz is a coarse log, not t in
    milliseconds; a hand-spun IMU at 30 rad/s is within a MEMS gyro's range. The same coarse
    step in a CSV's own t column is still asked about, and deg/s read as rad/s still refused."""
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    t = 1000.0 + np.arange(200) / 9.6
    w = _w(t) * [100.0, 1.0, 1.0]  # wx up to 30 rad/s
    w[:, 2] += 0.05 * np.sin(t)  # (a constant wz would be a dead channel)
    store = get_typestore(Stores.ROS2_HUMBLE)
    path = tmp_path / "spin"
    with Writer(path, version=9) as wr:
        c = wr.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=store)
        for ti, m in zip(t, _imu_msgs(store, t, w, _quat(t))):
            wr.write(c, int(ti * 1e9), store.serialize_cdr(m, "sensor_msgs/msg/Imu"))
    run = read_attitude_run(str(path), checks=True)
    assert run["info"]["rate_hz"] == pytest.approx(9.6, rel=1e-6) and not run["info"]["forced"]
    _write_csv(tmp_path / "coarse.csv", t - 1000.0, w / [100.0, 1.0, 1.0])
    with pytest.raises(UsageError, match="milliseconds"):
        read_attitude_run(str(tmp_path / "coarse.csv"), checks=True)
    t2 = 3.0 + np.arange(400) * 0.005
    _write_csv(tmp_path / "degs.csv", t2, np.degrees(_w(t2) * [5.0, 1.0, 1.0] + np.outer(np.sin(t2), [0, 0, 0.05])))
    with pytest.raises(UsageError, match="deg/s"):
        read_attitude_run(str(tmp_path / "degs.csv"), checks=True)
