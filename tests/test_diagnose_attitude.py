"""Attitude-run diagnosis: hidden causes in generated runs, clean runs, bad input.

Seeds, magnitudes and motions here differ from those used while developing the methods
(seeds 5-11, arw 3e-4, bias 1-2e-3, scale 1.02, rrw 2e-4, 500 Hz, 60-120 s).
"""

import json
import os

import numpy as np
import pytest

from jaxdrift.studies._attgen import DEFAULT_POSITIONS, make_attitude_run, write_attitude_csv
from jaxdrift.diagnosis.attitude._diagnose import run_attitude_diagnosis
from jaxdrift.cli import UsageError

SYSTEMATIC = {"gyro_bias", "gyro_scale", "gyro_bias_drift", "sensor_position", "nonrigid"}


def _inside(f, true):
    lo, hi = np.asarray(f["interval"][0], float), np.asarray(f["interval"][1], float)
    return bool(np.all((lo <= np.asarray(true)) & (np.asarray(true) <= hi)))


def _diag(tmp_path, seed, **kw):
    tr = make_attitude_run(str(tmp_path), seed, name=f"run{seed}", **kw)
    rep = run_attitude_diagnosis(tr["paths"]["run"], tr["paths"]["sensors"], None)
    json.dumps(rep)  # serialisable
    return tr, rep


def _check_schema(rep):
    assert rep["schema"] == "jaxdrift.diagnosis/1"
    assert rep["kind"] == "attitude"
    for k in ("simulation_error", "findings", "extended_model", "gain"):
        assert k in rep
    assert set(rep["extended_model"]["corrections"]) >= {"wx", "wy", "wz"}
    for f in rep["findings"]:
        assert {"cause", "estimate", "unit", "interval", "evidence"} <= set(f)


GYRO = dict(duration=40.0, rate_hz=200.0)


def test_noise_only_run_reports_noise_first_with_true_value(tmp_path):
    arw = 7e-4
    tr, rep = _diag(tmp_path, 101, arw=arw, **GYRO)
    _check_schema(rep)
    causes = [f["cause"] for f in rep["findings"]]
    assert causes == ["gyro_noise"], causes
    assert _inside(rep["findings"][0], arw)
    # the run has a full reference: departure reported, and the corrections do not make it worse
    assert rep["simulation_error"]["attitude"]["rms"] > 0
    assert rep["gain"]["after"] <= rep["gain"]["before"] * 1.05


def test_clean_run_reports_none(tmp_path):
    tr, rep = _diag(tmp_path, 102, **GYRO)
    assert rep["findings"][0]["cause"] == "none"
    assert len(rep["findings"]) == 1


@pytest.mark.parametrize(
    "seed, kw, cause, channel, true",
    [
        (103, dict(bias=(0.0, 0.0, -1.5e-3)), "gyro_bias", "wz", -1.5e-3),
        (104, dict(bias=(7e-4, 0.0, 0.0)), "gyro_bias", "wx", 7e-4),
        (105, dict(scale=(1.0, 1.0, 0.97), curve_rate=0.25), "gyro_scale", "wz", 0.97),
        (106, dict(scale=(1.0, 1.04, 1.0), road_rms_deg=1.0), "gyro_scale", "wy", 1.04),
        (107, dict(rrw=(0.0, 6e-4, 0.0)), "gyro_bias_drift", "wy", 6e-4),
    ],
)
def test_hidden_gyro_cause_is_first_with_true_value_inside(tmp_path, seed, kw, cause, channel, true):
    arw = 5e-4
    tr, rep = _diag(tmp_path, seed, arw=arw, **GYRO, **kw)
    first = rep["findings"][0]
    assert (first["cause"], first.get("channel")) == (cause, channel), rep["findings"]
    assert _inside(first, true), first
    # the noise finding comes after the systematic one, with the true value inside
    noise = [f for f in rep["findings"] if f["cause"] == "gyro_noise"]
    assert len(noise) == 1 and _inside(noise[0], arw)
    assert rep["gain"]["after"] < rep["gain"]["before"]


def test_two_causes_at_once(tmp_path):
    tr, rep = _diag(tmp_path, 108, arw=4e-4, bias=(-8e-4, 0.0, 0.0), scale=(1.0, 1.0, 1.03), **GYRO)
    top = {(f["cause"], f.get("channel")): f for f in rep["findings"][:2]}
    assert set(top) == {("gyro_bias", "wx"), ("gyro_scale", "wz")}, rep["findings"]
    assert _inside(top[("gyro_bias", "wx")], -8e-4)
    assert _inside(top[("gyro_scale", "wz")], 1.03)
    assert rep["findings"][2]["cause"] == "gyro_noise"
    corr = rep["extended_model"]["corrections"]
    assert corr["wx"]["bias"] == top[("gyro_bias", "wx")]["estimate"]
    assert corr["wz"]["scale"] == top[("gyro_scale", "wz")]["estimate"]
    assert corr["wy"] == {"bias": 0.0, "scale": 1.0}


def test_sparse_reference_rows(tmp_path):
    tr, rep = _diag(tmp_path, 109, arw=5e-4, bias=(0.0, 9e-4, 0.0), reference=25, **GYRO)
    first = rep["findings"][0]
    assert (first["cause"], first["channel"]) == ("gyro_bias", "wy") and _inside(first, 9e-4)


def test_static_segment_gives_bias_without_reference(tmp_path):
    tr, rep = _diag(tmp_path, 110, arw=5e-4, bias=(0.0, 0.0, 1.2e-3), reference=None, static_s=8.0, **GYRO)
    first = rep["findings"][0]
    assert (first["cause"], first["channel"]) == ("gyro_bias", "wz") and _inside(first, 1.2e-3)
    not_obs = " ".join(rep["observability"]["not_observed"])
    assert "scale" in not_obs and "drift" in not_obs


def test_no_bias_source_says_so(tmp_path):
    tr, rep = _diag(tmp_path, 111, arw=5e-4, bias=(1e-3, 0.0, 0.0), reference=None, **GYRO)
    assert [f["cause"] for f in rep["findings"]] == ["gyro_noise"]
    assert any("gyro bias" in s for s in rep["observability"]["not_observed"])


ARRAY = dict(duration=30.0, rate_hz=200.0, positions=DEFAULT_POSITIONS)


def test_array_sensor_position(tmp_path):
    d = [-0.04, 0.0, 0.03]
    tr, rep = _diag(tmp_path, 112, arw=4e-4, position_error={4: d}, **ARRAY)
    first = rep["findings"][0]
    assert (first["cause"], first["sensor"]) == ("sensor_position", 4), rep["findings"]
    assert _inside(first, d), first
    assert rep["extended_model"]["corrections"]["sensor4"]["position"] == pytest.approx(d, abs=0.01)


def test_array_nonrigid_and_clean(tmp_path):
    tr, rep = _diag(tmp_path, 113, arw=4e-4, nonrigid_rms=0.08, **ARRAY)
    first = rep["findings"][0]
    assert first["cause"] == "nonrigid", rep["findings"]
    assert _inside(first, tr["nonrigid_actual_rms"])
    tr, rep = _diag(tmp_path, 114, arw=4e-4, **ARRAY)
    assert [f["cause"] for f in rep["findings"]] == ["gyro_noise"], rep["findings"]


def test_array_accel_noise_is_named_and_sized_not_nonrigid(tmp_path):
    """White accelerometer noise on a rigid array is ``accel_noise``, not ``nonrigid``."""
    sigma = 0.02
    tr, rep = _diag(tmp_path, 116, arw=4e-4, accel_noise=sigma, duration=25.0, rate_hz=250.0,
                    positions=DEFAULT_POSITIONS[[0, 1, 3, 4]])
    causes = [f["cause"] for f in rep["findings"]]
    assert causes == ["gyro_noise", "accel_noise"], rep["findings"]
    acc = rep["findings"][1]
    # 5000 samples x 6 residual dof: the estimate's standard error is about 0.5 %; 5 % is 10 of them
    assert abs(acc["estimate"] / sigma - 1.0) < 0.05, acc
    assert _inside(acc, sigma), acc


def test_array_nonrigid_beyond_accel_noise(tmp_path):
    """A deformation under accelerometer noise is still ``nonrigid`` (first), and the noise is named."""
    tr, rep = _diag(tmp_path, 117, arw=4e-4, nonrigid_rms=0.04, accel_noise=0.03, **ARRAY)
    first = rep["findings"][0]
    assert first["cause"] == "nonrigid", rep["findings"]
    assert _inside(first, tr["nonrigid_actual_rms"]), first
    acc = [f for f in rep["findings"] if f["cause"] == "accel_noise"]
    assert len(acc) == 1 and _inside(acc[0], 0.03), rep["findings"]
    assert [f["cause"] for f in rep["findings"]][1:] == ["gyro_noise", "accel_noise"]


def test_array_accel_noise_on_independent_run(tmp_path):
    """The same on a run of the independent generator (benchmarks/validation/gen_attitude.py: own
    motion, quaternion by DOP853, arrays of 4-8 sensors, 6-9 written digits), never used for tuning."""
    import math

    from benchmarks.validation import gen_attitude as ga

    from jaxdrift import run_attitude_diagnosis as diagnose

    case = ga.make_case({"index": 0, "stratum": "single", "what": ["accel_noise"], "seed": 31},
                        durations=(20.0, 20.0), rates=(400,), max_samples=8000)
    assert case["positions"] is not None and case["effects"][-1]["cause"] == "accel_noise"
    sigma = case["effects"][-1]["value"]
    paths = ga.make_run(case, str(tmp_path))
    rep = diagnose(paths["csv"], paths["sensors"])
    causes = [f["cause"] for f in rep["findings"]]
    assert not SYSTEMATIC & set(causes), rep["findings"]
    acc = [f for f in rep["findings"] if f["cause"] == "accel_noise"]
    assert len(acc) == 1 and _inside(acc[0], sigma), (sigma, rep["findings"])
    assert abs(math.log(acc[0]["estimate"] / sigma)) < math.log(1.1)


def _numbers(text):
    import re

    return re.findall(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?", text)


def test_evidence_cites_the_reported_numbers(tmp_path):
    """Every evidence sentence quotes its finding's estimate as the report holds it (3 digits), and
    the array sentences quote the simulation_error fields they are computed from."""
    fmt = "{:.3g}".format
    reports = [
        _diag(tmp_path, 118, arw=5e-4, bias=(0.0, 0.0, 1.1e-3), scale=(1.03, 1.0, 1.0), curve_rate=0.25, **GYRO)[1],
        _diag(tmp_path, 119, arw=5e-4, rrw=(5e-4, 0.0, 0.0), **GYRO)[1],
        _diag(tmp_path, 117, arw=4e-4, nonrigid_rms=0.04, accel_noise=0.03, **ARRAY)[1],
        _diag(tmp_path, 122, arw=4e-4, position_error={2: [0.05, 0.0, -0.02]}, **ARRAY)[1],
    ]
    seen = set()
    for rep in reports:
        for f in rep["findings"]:
            seen.add(f["cause"])
            est = f["estimate"] if isinstance(f["estimate"], list) else [f["estimate"]]
            nums = _numbers(f["evidence"])
            for v in est:
                assert fmt(v) in nums, (f["cause"], fmt(v), f["evidence"])
            if f["cause"] in ("accel_noise", "nonrigid"):
                rr = rep["simulation_error"]["rigidity_residual"]
                assert fmt(rr["white_rms"]) in nums, f["evidence"]
                if f["cause"] == "accel_noise":
                    # "the rest in quadrature": white^2 - gyro share^2 = estimate^2
                    assert fmt(rr["gyro_noise_rms"]) in nums
                    assert rr["white_rms"] ** 2 - rr["gyro_noise_rms"] ** 2 == pytest.approx(f["estimate"] ** 2, rel=1e-9)
                else:
                    assert fmt(rr["rms_after_corrections"]) in nums
                    assert rr["rms_after_corrections"] ** 2 - rr["white_rms"] ** 2 == pytest.approx(
                        f["estimate"] ** 2, rel=1e-9)
    assert seen >= {"gyro_bias", "gyro_scale", "gyro_bias_drift", "gyro_noise", "nonrigid", "accel_noise",
                    "sensor_position"}, seen


def test_array_gives_bias_without_reference(tmp_path):
    tr, rep = _diag(tmp_path, 115, arw=4e-4, bias=(0.0, -2e-3, 0.0), reference=None, **ARRAY)
    first = rep["findings"][0]
    assert (first["cause"], first["channel"]) == ("gyro_bias", "wy"), rep["findings"]
    assert _inside(first, -2e-3)


# ----------------------------------------------------------------------------- bad input


@pytest.fixture
def good_run(tmp_path):
    tr = make_attitude_run(str(tmp_path), 120, duration=2.0, rate_hz=100.0, arw=1e-3, positions=DEFAULT_POSITIONS)
    return tr


def _rewrite(path, fn):
    with open(path) as fh:
        lines = fh.read().splitlines()
    lines = fn(lines)
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")


def _refused(run, sensors, tmp_path, *needles):
    plots = os.path.join(str(tmp_path), "plots_should_not_exist")
    with pytest.raises(UsageError) as ei:
        run_attitude_diagnosis(run, sensors, plots)
    msg = str(ei.value)
    for n in needles:
        assert n in msg, msg
    assert not os.path.exists(plots)
    return msg


def test_refuses_non_uniform_time(good_run, tmp_path):
    p = good_run["paths"]["run"]

    def fn(lines):
        cells = lines[30].split(",")
        cells[0] = repr(float(cells[0]) + 0.003)
        lines[30] = ",".join(cells)
        return lines

    _rewrite(p, fn)
    from jaxdrift.io import read_attitude_run

    with pytest.raises(UsageError, match=r"line 31, column t: non-uniform"):
        read_attitude_run(p, strict_time=True)


def test_refuses_nan_row(good_run, tmp_path):
    p = good_run["paths"]["run"]

    def fn(lines):
        cells = lines[12].split(",")
        cells[2] = "nan"
        lines[12] = ",".join(cells)
        return lines

    _rewrite(p, fn)
    _refused(p, good_run["paths"]["sensors"], tmp_path, "line 13", "column wy")


def test_refuses_quaternion_far_from_unit(good_run, tmp_path):
    p = good_run["paths"]["run"]

    def fn(lines):
        hdr = lines[0].split(",")
        j = hdr.index("qw")
        cells = lines[7].split(",")
        cells[j] = repr(float(cells[j]) * 1.2 + 0.1)
        lines[7] = ",".join(cells)
        return lines

    _rewrite(p, fn)
    _refused(p, good_run["paths"]["sensors"], tmp_path, "line 8", "norm")


@pytest.mark.parametrize(
    "positions, needle",
    [
        ([[1, 0, 0], [0, 1, 0], [0, 0, 1]], "at least 4"),
        ([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], "collinear"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 3, 0]], "coplanar"),
    ],
)
def test_refuses_bad_sensor_geometry(tmp_path, positions, needle):
    n = 50
    t = np.arange(n) * 0.01
    w = np.zeros((n, 3))
    acc = np.zeros((n, len(positions), 3))
    run = os.path.join(str(tmp_path), "r.csv")
    write_attitude_csv(run, t, w, None, acc)
    sens = os.path.join(str(tmp_path), "s.json")
    with open(sens, "w") as fh:
        json.dump({"positions": positions}, fh)
    _refused(run, sens, tmp_path, "s.json", needle)


def test_refuses_missing_column_and_missing_sensors(tmp_path, good_run):
    p = good_run["paths"]["run"]
    _refused(p, None, tmp_path, "--sensors")
    _rewrite(p, lambda lines: [",".join(c for c in ln.split(",")[:3]) for ln in lines])
    _refused(p, None, tmp_path, "column 'wz'")


# ----------------------------------------------------------------------------- through the CLI


def test_cli_diagnose_writes_report_or_nothing(tmp_path):
    from jaxdrift.cli import main

    tr = make_attitude_run(str(tmp_path), 121, duration=20.0, rate_hz=200.0, arw=5e-4, bias=(0.0, 0.0, 2e-3))
    out = os.path.join(str(tmp_path), "report.json")
    assert main(["diagnose", tr["paths"]["run"], "--json", out]) == 0
    with open(out) as fh:
        rep = json.load(fh)
    assert rep["kind"] == "attitude" and rep["findings"][0]["cause"] == "gyro_bias"
    # bad input: exit 2, no report
    bad = os.path.join(str(tmp_path), "bad.csv")
    with open(tr["paths"]["run"]) as fh:
        lines = fh.read().splitlines()
    lines[5] = lines[5].replace(lines[5].split(",")[1], "", 1)
    with open(bad, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    out2 = os.path.join(str(tmp_path), "report2.json")
    assert main(["diagnose", bad, "--json", out2]) == 2
    assert not os.path.exists(out2)


def test_cli_accel_array_small(tmp_path):
    from jaxdrift.cli import main

    out = os.path.join(str(tmp_path), "aa")
    assert main(["accel-array", "--out", out, "--duration", "6", "--paths", "10"]) == 0
    with open(os.path.join(out, "accel_summary.json")) as fh:
        s = json.load(fh)
    assert s["noise_free"]["max_attitude_error_rad"] < 1e-3
    assert {"accel_reconstruction.png", "accel_noise_growth.png", "accel_highpass.png"} <= set(os.listdir(out))
    assert main(["accel-array", "--out", os.path.join(str(tmp_path), "x"), "--noise", "-1"]) == 2
    assert not os.path.exists(os.path.join(str(tmp_path), "x"))


def test_reference_made_by_holding_the_rates(tmp_path):
    """Another sampling convention: the reference integrates each rate held over its step (exp map)."""
    from jaxdrift.models._ins import gyro_errors, vehicle_motion
    from jaxdrift.models._quaternion import integrate_rates_np

    m = vehicle_motion(131, 41.0, road_rms_deg=0.8)
    dt = 0.005
    t = 3.0 + np.arange(8001) * dt
    w = m.body_rates(t - 3.0)
    q = integrate_rates_np(m.quaternion(t[:1] - 3.0)[0], w, dt)
    rng = np.random.default_rng(131)
    wm = w * np.array([1.0, 1.0, 1.025]) + gyro_errors(rng, len(t), dt, arw=3e-4, bias=(0.0, -9e-4, 0.0))
    p = os.path.join(str(tmp_path), "held.csv")
    write_attitude_csv(p, t, wm, q)
    rep = run_attitude_diagnosis(p, None, None)
    top = {(f["cause"], f.get("channel")): f for f in rep["findings"][:2]}
    assert set(top) == {("gyro_bias", "wy"), ("gyro_scale", "wz")}, rep["findings"]
    assert _inside(top[("gyro_bias", "wy")], -9e-4) and _inside(top[("gyro_scale", "wz")], 1.025)


def test_drift_without_white_noise(tmp_path):
    tr, rep = _diag(tmp_path, 132, rrw=(0.0, 0.0, 4e-4), **GYRO)
    first = rep["findings"][0]
    assert (first["cause"], first["channel"]) == ("gyro_bias_drift", "wz") and _inside(first, 4e-4)
    # no noise is claimed; the reference's residuals may bound it (a detection limit, true of no noise)
    assert all(f["cause"] != "gyro_noise" or f["estimate_kind"] == "upper_bound" for f in rep["findings"])


# ----------------------------------------------------------------------------- array noise estimators


def test_gyro_noise_share_against_simulation():
    """gyro_noise_power (neighbour rates, closed form) against the power of the residual that drawn
    gyro noise makes through W = omega~ omega~ (direct simulation, 20 draws per sample)."""
    from jaxdrift.diagnosis.attitude._array import array_residual, gyro_noise_power
    from jaxdrift.models._quaternion import skew_np

    rng = np.random.default_rng(7)
    n, dt = 3000, 0.005
    t = np.arange(n + 2) * dt
    # slow rates (0.03-0.09 rad/s) against a per-sample noise of 0.02-0.04 rad/s: the regime where
    # the noise's own power in the measured rate matters
    om = 0.3 * np.stack([0.2 * np.sin(2.1 * t), 0.15 * np.cos(3.3 * t + 1), 0.3 * np.sin(0.4 * t) + 0.1], 1)
    sigma = np.array([0.03, 0.02, 0.04])
    r = DEFAULT_POSITIONS
    N = len(r)
    meas = om + rng.normal(size=om.shape) * sigma
    est = gyro_noise_power(meas[:-2], meas[2:], sigma, r)
    corr = np.diag([sigma[1] ** 2 + sigma[2] ** 2, sigma[0] ** 2 + sigma[2] ** 2, sigma[0] ** 2 + sigma[1] ** 2])
    W0 = skew_np(om[1:-1]) @ skew_np(om[1:-1])
    sims = []
    for _ in range(20):
        w = om[1:-1] + rng.normal(size=(n, 3)) * sigma
        dW = skew_np(w) @ skew_np(w) + corr - W0
        res = array_residual(np.einsum("nab,kb->nka", dW, r), r, np.zeros_like(dW))
        sims.append(np.mean(np.sum(res**2, axis=(1, 2))) / (3 * N - 6))
    # 20 x 3000 samples: the simulated mean has a relative standard error near 0.3 %, the
    # estimate (one noisy pair of neighbours per sample) near 1 %
    assert np.mean(est) == pytest.approx(np.mean(sims), rel=0.04)
    # the measured rate squared (what the naive estimate uses) overstates it here by the noise's power
    naive = gyro_noise_power(meas[1:-1], meas[1:-1], sigma, r)
    assert np.mean(naive) > 1.2 * np.mean(sims)  # measured: 1.29


def test_white_rigidity_power_separates_white_from_smooth():
    """White residual power from time differences: white noise of known variance under a 12 Hz
    deformation 4 times stronger, sampled at 200 Hz, in the (3N - 6)-dof residual space."""
    from jaxdrift.diagnosis.attitude._array import array_residual, white_rigidity_power

    rng = np.random.default_rng(8)
    r = DEFAULT_POSITIONS
    N = len(r)
    n, dt, sig = 6000, 0.005, 0.01
    t = np.arange(n) * dt
    defo = 0.04 * np.sin(2 * np.pi * 12.0 * t[:, None, None] + rng.uniform(0, 6, (1, N, 3)))
    resid = array_residual(defo + rng.normal(size=(n, N, 3)) * sig, r, np.zeros((n, 3, 3)))
    blocks = np.array_split(np.arange(n), 20)
    wp = white_rigidity_power(resid, N, blocks)
    assert wp["plateau"] and wp["order"] >= 2
    assert wp["power"] == pytest.approx(sig**2, rel=0.05)
    assert abs(wp["power"] - sig**2) < 4 * wp["se"]
    # the total power is dominated by the deformation: the split matters
    assert np.mean(np.sum(resid**2, axis=(1, 2))) / (3 * N - 6) > 5 * sig**2


def test_noise_free_array_position_interval_has_the_method_floor(tmp_path):
    """A noise-free array (9 written digits) next to a gyro scale. The displaced sensor's
    interval must hold the truth although no noise sets its width: the method part (written resolution,
    the upstream scale's uncertainty, the fit's stopping step) is its floor; apparent displacements of
    the other sensors of a few 1e-8 m lie below that floor and are not reported."""
    from benchmarks.validation import gen_attitude as ga

    from jaxdrift import run_attitude_diagnosis as diagnose
    from jaxdrift.diagnosis.attitude._array import SOLVER_STEP

    case = ga.make_case({"index": 0, "stratum": "pair", "what": ["gyro_scale", "sensor_position"], "seed": 51},
                        durations=(20.0, 20.0), rates=(500,), max_samples=10000)
    case["effects"] = [e for e in case["effects"] if e["cause"] != "gyro_noise"]
    case.update(precision=9, reference_every=1)
    pos = [e for e in case["effects"] if e["cause"] == "sensor_position"][0]
    paths = ga.make_run(case, str(tmp_path))
    rep = diagnose(paths["csv"], paths["sensors"])
    found = [f for f in rep["findings"] if f["cause"] == "sensor_position"]
    assert [f["sensor"] for f in found] == [pos["sensor"]], rep["findings"]
    f = found[0]
    assert _inside(f, pos["value"]), (pos["value"], f)
    half = (np.asarray(f["interval"][1]) - np.asarray(f["interval"][0])) / 2
    assert np.all(half >= SOLVER_STEP["full"]), half
