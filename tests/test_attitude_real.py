"""The attitude diagnosis on what real runs hold: an estimator's reference that turns while the
gyro says still, a heading reset, true vibration that is not sensor noise, degenerate fits, and the
rule that no report holds inf or NaN. The truth is integrated here with scipy's Rotation.
"""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from jaxdrift.diagnosis.attitude import diagnose_attitude
from jaxdrift.io._outputs import check_report_finite, nonfinite_in_report, write_report

DATA = Path(__file__).parent / "data" / "ulog"


def _integrate(q0, w, dt):
    """Body-to-global attitudes (scalar first) with each rate held over its step."""
    steps = Rotation.from_rotvec(w[:-1] * dt)
    r = [q0]
    for k in range(len(steps)):
        r.append(r[-1] * steps[k])
    q = np.array([x.as_quat() for x in r])
    return q[:, [3, 0, 1, 2]]


def _run(t, w_meas, q_ref_rows):
    return {"path": "synthetic", "t": t, "dt": float(t[1] - t[0]), "w": w_meas, "q_ref": q_ref_rows, "acc": None,
            "extra_columns": [], "quantisation": 0.0, "acc_quantisation": 0.0, "warnings": [], "info": {}}


def _by(rep, cause):
    return [f for f in rep["findings"] if f["cause"] == cause]


def test_converging_heading_is_named_and_the_bias_still_found():
    rng = np.random.default_rng(4101)
    dt, T = 0.004, 12.0
    t = np.arange(0.0, T, dt)
    n = len(t)
    bias = np.array([0.004, 0.0, 0.0])
    N = 2e-4
    w_meas = bias + rng.normal(0.0, N / math.sqrt(dt), (n, 3))  # the body stands still
    tilt = Rotation.from_euler("xyz", [0.05, -0.03, 0.0])
    # the estimator's heading still converges: it turns about global z at a decaying rate
    yaw = -0.06 * 4.0 * (1.0 - np.exp(-t / 4.0))
    q = (Rotation.from_euler("z", yaw[:, None]) * tilt).as_quat()[:, [3, 0, 1, 2]]
    q_ref = np.full((n, 4), np.nan)
    q_ref[::5] = q[::5]  # 50 Hz reference
    rep, _ = diagnose_attitude(_run(t, w_meas, q_ref))
    check_report_finite(rep)
    inc = _by(rep, "reference_inconsistent")
    assert inc and {f["axis"] for f in inc} == {"z"}
    assert inc[0]["span_s"][1] - inc[0]["span_s"][0] > 0.5 * T
    b = {f["channel"]: f for f in _by(rep, "gyro_bias")}
    assert "wx" in b and b["wx"]["interval"][0] <= 0.004 <= b["wx"]["interval"][1]
    assert not _by(rep, "gyro_scale")
    assert all(abs(f["estimate"]) < 0.01 for f in b.values())
    nd = {(d["cause"], d["channel"]) for d in rep["not_determined"]}
    assert ("gyro_bias", "wz") in nd and all(d["reason"] for d in rep["not_determined"])
    # the body stands still by the reference on x and y but not on z: the noise is only a bound
    g = _by(rep, "gyro_noise")
    assert g and g[0]["estimate_kind"] in ("estimate", "upper_bound") and g[0]["interval"][1] >= N


def test_vibration_is_a_bound_and_does_not_hide_a_bias_and_a_reset_is_named():
    rng = np.random.default_rng(4102)
    dt, T = 0.004, 30.0
    t = np.arange(0.0, T, dt)
    n = len(t)
    smooth = np.column_stack([0.3 * np.sin(2 * np.pi * 0.4 * t), 0.25 * np.sin(2 * np.pi * 0.3 * t + 1.0),
                              0.4 * np.sin(2 * np.pi * 0.1 * t)])
    # true vibration: broadband 30-110 Hz, far above any MEMS gyro's noise
    spec = np.fft.rfft(rng.normal(size=(n, 3)), axis=0)
    f = np.fft.rfftfreq(n, dt)
    spec[(f < 30) | (f > 110)] = 0.0
    vib = np.fft.irfft(spec, n, axis=0)
    vib *= 0.08 / vib.std(0)
    w_true = smooth + vib
    bias = np.array([0.0, 0.003, -0.002])
    N = 1e-4
    w_meas = w_true + bias + rng.normal(0.0, N / math.sqrt(dt), (n, 3))
    q = _integrate(Rotation.identity(), w_true, dt)
    # a heading reset at t = 15 s: the estimator's yaw jumps by 0.08 rad
    jump = Rotation.from_euler("z", np.where(t >= 15.0, 0.08, 0.0)[:, None])
    q = (jump * Rotation.from_quat(q[:, [1, 2, 3, 0]])).as_quat()[:, [3, 0, 1, 2]]
    q_ref = np.full((n, 4), np.nan)
    q_ref[::8] = q[::8]  # 31 Hz
    rep, _ = diagnose_attitude(_run(t, w_meas, q_ref))
    check_report_finite(rep)
    inc = _by(rep, "reference_inconsistent")
    assert len(inc) == 1, inc  # one summary of the reference's problems
    assert any(s["axis"] == "z" and s["span_s"][0] - 0.5 <= 15.0 <= s["span_s"][1] + 0.5 for s in inc[0]["spans"]), inc
    b = {f["channel"]: f for f in _by(rep, "gyro_bias")}
    for c, ch in ((1, "wy"), (2, "wz")):
        assert ch in b, rep["findings"]
        assert b[ch]["interval"][0] <= bias[c] <= b[ch]["interval"][1] or abs(b[ch]["estimate"] - bias[c]) < 0.25 * abs(bias[c])
    assert all(abs(f["estimate"] - 1) < 0.1 for f in _by(rep, "gyro_scale"))
    g = _by(rep, "gyro_noise")
    assert g and g[0]["estimate_kind"] == "upper_bound" and g[0]["interval"][0] == 0.0
    assert g[0]["interval"][1] >= N and g[0]["estimate"] <= g[0]["interval"][1]
    assert rep["gain"]["after"] < rep["gain"]["before"]


def test_outliers_of_an_optical_reference_that_come_back_are_not_resets():
    """A motion-capture reference at the gyro's rate whose marker fit jitters now and then (the
    attitude off by 0.02-0.04 rad for 2-10 samples, then back): the outliers are left out of the fit
    and said in a note, but they are no reset and raise no ``reference_inconsistent``; a true step
    of the same size that stays is one."""
    rng = np.random.default_rng(4111)
    dt, T = 1 / 285.7, 40.0
    t = np.arange(0.0, T, dt)
    n = len(t)
    w_true = np.column_stack([0.8 * np.sin(2 * np.pi * 0.3 * t), 0.5 * np.sin(2 * np.pi * 0.23 * t + 1.0),
                              0.6 * np.sin(2 * np.pi * 0.17 * t + 2.0)])
    bias = np.array([0.004, -0.0025, 0.003])
    N = 1e-4
    w_meas = w_true + bias + rng.normal(0.0, N / math.sqrt(dt), (n, 3))
    q = Rotation.from_quat(_integrate(Rotation.identity(), w_true, dt)[:, [1, 2, 3, 0]])
    err = np.zeros((n, 3))
    for k, t0 in enumerate(np.arange(3.0, T - 2.0, 4.0)):
        i = int(t0 / dt)
        err[i : i + 2 + 2 * (k % 5), k % 3] = 0.02 + 0.005 * (k % 5)
    noisy = Rotation.from_rotvec(err + rng.normal(0.0, 3e-4, (n, 3))) * q
    q_ref = noisy.as_quat()[:, [3, 0, 1, 2]]
    rep, _ = diagnose_attitude(_run(t, w_meas, q_ref))
    check_report_finite(rep)
    assert not _by(rep, "reference_inconsistent"), _by(rep, "reference_inconsistent")
    notes = rep["observability"]["notes"]
    assert any("outlier" in nt for nt in notes), notes
    b = {f["channel"]: f for f in _by(rep, "gyro_bias")}
    for c, ch in enumerate(("wx", "wy", "wz")):
        assert ch in b and b[ch]["interval"][0] <= bias[c] <= b[ch]["interval"][1], rep["findings"]
    # the same size of step that stays is a reset
    step = Rotation.from_rotvec(np.where(t[:, None] >= 21.0, [0.03, 0.0, 0.0], 0.0))
    q_ref2 = (step * noisy).as_quat()[:, [3, 0, 1, 2]]
    rep2, _ = diagnose_attitude(_run(t, w_meas, q_ref2))
    inc = _by(rep2, "reference_inconsistent")
    assert any(s["axis"] == "x" and s["span_s"][0] - 0.5 <= 21.0 <= s["span_s"][1] + 0.5 for f in inc for s in f["spans"]), inc


def test_a_reference_whose_x_and_y_point_the_other_way_is_turned_by_an_axis_convention():
    """A pendulum turned about z (x and y rates ten times smaller) against a motion-capture body
    frame whose x and y point the other way: the full rotation is not determined from one axis,
    but the axis convention (180 degrees about z) is, is applied and reported, and the biases of
    all three axes are found inside their intervals."""
    rng = np.random.default_rng(4112)
    dt, T = 0.01, 120.0
    t = np.arange(0.0, T, dt)
    n = len(t)
    w_true = np.column_stack([0.06 * np.sin(2 * np.pi * 0.37 * t), 0.05 * np.sin(2 * np.pi * 0.29 * t + 1.0),
                              1.0 * np.sin(2 * np.pi * 0.5 * t)])
    bias = np.array([0.005, -0.006, -0.003])
    N = 2e-4
    w_meas = w_true + bias + rng.normal(0.0, N / math.sqrt(dt), (n, 3))
    q = Rotation.from_quat(_integrate(Rotation.identity(), w_true, dt)[:, [1, 2, 3, 0]])
    flip = Rotation.from_euler("z", np.pi)  # the markers' body frame: x and y reversed
    q_ref = (q * flip.inv()).as_quat()[:, [3, 0, 1, 2]]
    rep, _ = diagnose_attitude(_run(t, w_meas, q_ref))
    al = rep["run"]["reference_alignment"]
    assert al["applied"]["rotation"] and al["axis_convention"] == [[-1, 0, 0], [0, -1, 0], [0, 0, 1]], al
    b = {f["channel"]: f for f in _by(rep, "gyro_bias")}
    for c, ch in enumerate(("wx", "wy", "wz")):
        assert ch in b and b[ch]["interval"][0] <= bias[c] <= b[ch]["interval"][1], rep["findings"]
    assert not _by(rep, "reference_inconsistent")


def test_a_yawing_flight_against_its_own_estimator_is_not_turned():
    """A flight yawing at up to 3 rad/s (x and y rates a hundredth of that) against a 20 Hz attitude
    estimate in the gyro's own frame, with 3 mrad of attitude noise: the frame rotation found is
    a fraction of a degree and not applied. (The rotation nearest to the general least-squares map
    of the rates, which divides by their covariance, made 16 degrees of the x/y noise on a PX4
    FMU-V6C log, and 3 degrees here.)"""
    rng = np.random.default_rng(20261203)
    dt, T = 0.005, 60.0
    t = np.arange(0.0, T, dt)
    n = len(t)
    w_true = np.column_stack([0.03 * np.sin(2 * np.pi * 0.7 * t), 0.025 * np.sin(2 * np.pi * 0.9 * t + 1.0),
                              3.0 * np.sin(2 * np.pi * 0.2 * t)])
    w_meas = w_true + np.array([0.002, -0.001, 0.001]) + rng.normal(0.0, 2e-3, (n, 3))
    q = Rotation.from_quat(_integrate(Rotation.identity(), w_true, dt)[:, [1, 2, 3, 0]])
    noisy = q * Rotation.from_rotvec(rng.normal(0.0, 3e-3, (n, 3)))
    q_ref = np.full((n, 4), np.nan)
    q_ref[::10] = noisy.as_quat()[::10][:, [3, 0, 1, 2]]  # 20 Hz
    rep, _ = diagnose_attitude(_run(t, w_meas, q_ref))
    al = rep["run"]["reference_alignment"]
    assert al["rotation_deg"] < 1.0 and not al["applied"]["rotation"], al


def test_a_heading_only_reference_gives_the_vertical_bias_and_says_the_others_are_not_determined(tmp_path):
    """A car turning on a road that rolls and pitches it a little, its GNSS course as the only
    reference (a ``yaw`` column in degrees): the vertical gyro's bias is found inside its interval,
    the other two are not determined because the reference is a heading only, no span about x or y
    is called inconsistent, and the attitude error is the heading's."""
    from jaxdrift.io import read_attitude_run

    rng = np.random.default_rng(4113)
    dt, T = 0.01, 180.0
    t = np.arange(0.0, T, dt)
    n = len(t)
    w_true = np.column_stack([0.03 * np.sin(2 * np.pi * 0.9 * t), 0.02 * np.sin(2 * np.pi * 0.7 * t + 1.0),
                              0.25 * np.sin(2 * np.pi * 0.03 * t) + 0.1 * np.sin(2 * np.pi * 0.11 * t)])
    bias = np.array([0.004, -0.003, 0.002])
    N = 3e-4
    w_meas = w_true + bias + rng.normal(0.0, N / math.sqrt(dt), (n, 3))
    q = Rotation.from_quat(_integrate(Rotation.identity(), w_true, dt)[:, [1, 2, 3, 0]])
    yaw = np.degrees(q.as_euler("ZYX")[:, 0]) + rng.normal(0.0, 0.05, n)  # a GNSS course, 0.05 deg noise
    yaw_col = np.full(n, np.nan)
    yaw_col[::10] = yaw[::10]  # 10 Hz
    path = tmp_path / "car.csv"
    with open(path, "w") as fh:
        fh.write("t,wx,wy,wz,yaw\n")
        for k in range(n):
            y = "" if np.isnan(yaw_col[k]) else f"{yaw_col[k]:.6f}"
            fh.write(f"{t[k]:.4f},{w_meas[k, 0]:.7f},{w_meas[k, 1]:.7f},{w_meas[k, 2]:.7f},{y}\n")
    run = read_attitude_run(str(path), units={"yaw": "deg"})
    assert run["heading_only"] and any("heading-only" in nt for nt in run["info"]["notes"])
    rep, _ = diagnose_attitude(run)
    check_report_finite(rep)
    b = {f["channel"]: f for f in _by(rep, "gyro_bias")}
    assert "wz" in b and b["wz"]["interval"][0] <= bias[2] <= b["wz"]["interval"][1], rep["findings"]
    assert "wx" not in b and "wy" not in b
    nd = {(d["cause"], d["channel"]): d["reason"] for d in rep["not_determined"]}
    assert "heading only" in nd[("gyro_bias", "wx")] and "heading only" in nd[("gyro_bias", "wy")], nd
    assert all(f["axis"] == "z" for f in _by(rep, "reference_inconsistent"))
    assert rep["gain"]["after"] < rep["gain"]["before"]


def test_noise_is_an_estimate_where_the_reference_says_still():
    rng = np.random.default_rng(4103)
    dt, T = 0.005, 20.0
    t = np.arange(0.0, T, dt)
    n = len(t)
    on = np.clip((t - 6.0) / 2.0, 0.0, 1.0)
    w_true = on[:, None] * np.column_stack([0.2 * np.sin(2 * np.pi * 0.5 * t), 0.1 * np.cos(2 * np.pi * 0.7 * t),
                                            0.3 * np.sin(2 * np.pi * 0.2 * t)])
    N = 3e-4
    w_meas = w_true + rng.normal(0.0, N / math.sqrt(dt), (n, 3))
    q = _integrate(Rotation.identity(), w_true, dt)
    q_ref = np.full((n, 4), np.nan)
    q_ref[::4] = q[::4]
    rep, _ = diagnose_attitude(_run(t, w_meas, q_ref))
    g = _by(rep, "gyro_noise")[0]
    assert g["estimate_kind"] == "estimate"
    assert g["interval"][0] <= N <= g["interval"][1]
    assert "does not move" in g["evidence"]


def test_report_writer_refuses_non_finite(tmp_path):
    bad = {"findings": [{"cause": "gyro_scale", "estimate": 1.0, "interval": [0.9, 1.1],
                         "evidence": "rotation about wz is -20.4 times the gyro's (z = inf)"}], "x": [1.0, float("nan")]}
    where = nonfinite_in_report(bad)
    assert len(where) == 2 and "evidence" in where[0] and "x[1]" in where[1]
    with pytest.raises(ValueError, match="non-finite"):
        write_report(tmp_path / "r.json", bad)
    assert not (tmp_path / "r.json").exists()
    ok = {"evidence": "no information: an infinite z would follow (degenerate fit)", "v": [1.0, None, 2]}
    assert nonfinite_in_report(ok) == []
    write_report(tmp_path / "ok.json", ok)
    assert json.loads((tmp_path / "ok.json").read_text())["v"] == [1.0, None, 2]
    assert nonfinite_in_report({"a": np.array([1.0, np.inf])}) == ["report.a[1]: inf"]


def test_pyulog_fixtures_and_licence_are_there():
    for name in ("sample.ulg", "sample_log_small.ulg", "sample_appended_multiple.ulg"):
        assert (DATA / name).stat().st_size > 100_000
        assert (DATA / name).read_bytes()[:7] == b"ULog\x01\x12\x35"
    assert "Redistributions of source code must retain" in (DATA / "LICENSE-pyulog").read_text()


def test_a_gap_is_not_integrated_across():
    """Rows of a gap hold NaN rates (the readers' time base): the fit leaves out the reference
    intervals that hold them, the attitude error restarts on the reference after it, and the report
    stays finite with the bias right."""
    rng = np.random.default_rng(4104)
    dt, T = 0.004, 20.0
    t = np.arange(0.0, T, dt)
    n = len(t)
    w_true = np.column_stack([0.2 * np.sin(2 * np.pi * 0.5 * t), 0.15 * np.cos(2 * np.pi * 0.3 * t),
                              0.3 * np.sin(2 * np.pi * 0.2 * t)])
    bias = np.array([-0.002, 0.0015, 0.001])
    w_meas = w_true + bias + rng.normal(0.0, 1.5e-4 / math.sqrt(dt), (n, 3))
    q = _integrate(Rotation.identity(), w_true, dt)
    q_ref = np.full((n, 4), np.nan)
    q_ref[::6] = q[::6]
    g0, g1 = 2500, 2540  # a 160 ms gap
    w_meas[g0:g1] = np.nan
    run = _run(t, w_meas, q_ref)
    run["time_base"] = {"segments": [[0, g0], [g1, n]]}
    rep, _ = diagnose_attitude(run)
    check_report_finite(rep)
    assert not _by(rep, "reference_inconsistent")
    b = {f["channel"]: f for f in _by(rep, "gyro_bias")}
    for c, ch in enumerate(("wx", "wy", "wz")):
        assert b[ch]["interval"][0] <= bias[c] <= b[ch]["interval"][1], b[ch]
    assert rep["gain"]["after"] < 0.2 * rep["gain"]["before"]


def _ulog_reader():
    """jaxdrift's ULog reader and CSV export (the ``ulog`` extra), or None where not installed."""
    try:
        import pyulog  # noqa: F401

        from jaxdrift.io import export_recorded_csv
    except ImportError:
        return None
    return export_recorded_csv


HARDWARE = ("sample.ulg", "sample_log_small.ulg", "sample_appended_multiple.ulg")


@pytest.mark.skipif(_ulog_reader() is None, reason="needs jaxdrift's ULog reader: pip install -e '.[ulog]'")
@pytest.mark.parametrize("as_csv", [False, True], ids=["ulg", "csv-export"])
@pytest.mark.parametrize("name", HARDWARE)
def test_pyulog_hardware_logs_against_the_independent_estimate(tmp_path, name, as_csv):
    """Each hardware log, read as recorded (the .ulg, and its CSV export with jittered t, gaps and the
    reference only on its own rows): every axis whose independent bias (benchmarks/validation/real_logs.py,
    scipy's Rotation, in docs/validation/real_logs.json) is clear is named within 25 % or inside its
    interval; no absurd scale or bias; the attitude error falls where a bias was found."""
    from jaxdrift import run_attitude_diagnosis

    ref = Path(__file__).resolve().parents[1] / "docs" / "validation" / "real_logs.json"
    ind = {x["log"]: x for x in json.loads(ref.read_text())["logs"]}[name]["independent"]
    path = DATA / name
    if as_csv:
        path = tmp_path / (Path(name).stem + ".csv")
        _ulog_reader()(DATA / name, path)
    rep = run_attitude_diagnosis(str(path))
    check_report_finite(rep)
    biases = {f["channel"]: f for f in _by(rep, "gyro_bias")}
    for c, ch in enumerate(("wx", "wy", "wz")):
        if ind["clear"][c]:
            b, f = ind["bias"][c], biases.get(ch)
            assert f is not None, (ch, rep["findings"])
            assert abs(f["estimate"] - b) <= 0.25 * abs(b) or f["interval"][0] <= b <= f["interval"][1], (ch, f, b)
    assert all(abs(f["estimate"] - 1.0) <= 0.1 for f in _by(rep, "gyro_scale"))
    assert all(abs(f["estimate"]) <= 0.2 for f in biases.values())
    if biases:
        assert rep["gain"]["after"] < rep["gain"]["before"]


def _biased_gyro_against_reference(seed, dt, w_of_t, bias, N, every, T=120.0):
    """The diagnosis of a gyro (true rates ``w_of_t``, a constant ``bias``, white noise ``N``)
    against a perfect reference on every ``every``-th row."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, dt)
    w_true = w_of_t(t)
    w_meas = w_true + np.asarray(bias) + rng.normal(0.0, N / math.sqrt(dt), w_true.shape)
    q = _integrate(Rotation.identity(), w_true, dt)
    q_ref = np.full((len(t), 4), np.nan)
    q_ref[::every] = q[::every]
    return diagnose_attitude(_run(t, w_meas, q_ref))[0]


def test_a_bias_on_a_slow_turn_is_no_inconsistent_reference_and_the_reference_comes_after_the_causes():
    """A body yawing slowly (0.03 rad/s, below what the consistency check calls still) through 3.6
    rad and rocking in pitch (up to 0.012 rad/s) against a clean 10 Hz reference, with a 4 mrad/s
    bias on x: the bias turns with the body in the global frame, so the discrepancy about global y
    moves while the reference turns about y, as if the reference turned on its own. Judged
    against the gyro as the fit corrects it, the reference is consistent: no
    ``reference_inconsistent``, and the bias is found inside its interval. (Judged against the raw
    gyro, this run passes too: it guards the re-judging, it did not reproduce a false flag.)"""
    rep = _biased_gyro_against_reference(
        4120, 0.01, lambda t: np.column_stack([0 * t, 0.012 * np.sin(2 * np.pi * t / 20.0), 0 * t + 0.03]),
        bias=(0.004, 0.0, 0.0), N=2e-4, every=10)
    assert not _by(rep, "reference_inconsistent"), _by(rep, "reference_inconsistent")
    b = {f["channel"]: f for f in _by(rep, "gyro_bias")}
    assert "wx" in b and b["wx"]["interval"][0] <= 0.004 <= b["wx"]["interval"][1], rep["findings"]
    assert rep["findings"][0]["cause"] == "gyro_bias", rep["findings"]


def test_a_one_hertz_reference_consistent_as_given_is_neither_turned_nor_shifted():
    """A 120 s run whose reference has one row a second, in the gyro's own frame and clock, the body
    turning at 0.5-3 Hz: the reference's rotation over each second is compared with the gyro's
    integral over the same second, so no frame rotation or clock offset is applied (compared with
    the gyro at one instant, this run was turned by 37 deg), and a 2 mrad/s bias is found inside its
    interval."""
    rep = _biased_gyro_against_reference(
        4121, 0.005, lambda t: np.column_stack([0.3 * np.sin(2 * np.pi * 0.7 * t), 0.25 * np.sin(2 * np.pi * 1.3 * t + 1.0),
                                                0.2 * np.sin(2 * np.pi * 0.05 * t) + 0.1 * np.sin(2 * np.pi * 2.9 * t)]),
        bias=(0.0, 0.002, 0.0), N=1e-4, every=200)
    al = rep["run"]["reference_alignment"]
    assert al is not None and al["applied"] == {"clock_offset": False, "rotation": False}, al
    assert al["rotation_deg"] < 2.0, al
    b = {f["channel"]: f for f in _by(rep, "gyro_bias")}
    assert "wy" in b and b["wy"]["interval"][0] <= 0.002 <= b["wy"]["interval"][1], rep["findings"]
    assert rep["findings"][0]["cause"] == "gyro_bias" and rep["findings"][0]["channel"] == "wy", rep["findings"]
