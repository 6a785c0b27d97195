"""The independent generators of ``benchmarks/validation/`` checked on their own.

Oracles: the ISO 8608 line and the shaping filter's exact PSD for the road (Welch estimate within a
stated statistical bound); jaxdrift's half-car right-hand side and static equilibrium on one
effect-free case (an oracle for the generator only, never the other way round); finite
differences for the quaternion kinematics and the body acceleration; the data contract
(docs/measured-data.md) for columns, units, digits, the time grid and the truth's names.
The marked-slow test runs a small sweep and asserts the diagnosis's targets (docs/validation.md).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import welch

ROOT = Path(__file__).resolve().parents[1]

from benchmarks.validation import gen_attitude as ga, gen_vehicle as gv, sweep as sw

SPEC_CAUSES = {"none", "force_noise", "force_offset", "force_scale", "force_delay", "parameter_error",
               "gyro_noise", "gyro_bias", "gyro_scale", "gyro_bias_drift", "sensor_position",
               "accel_noise", "nonrigid"}


def _case(stratum, what, seed, **kw):
    c = gv.make_case({"index": 0, "stratum": stratum, "what": what, "seed": seed},
                     durations=(3.0, 3.0), rates=(200,))
    c.update(kw)
    return c


# ----------------------------------------------------------------------------- road
def test_road_psd_matches_iso8608_and_filter():
    """Welch PSD of 20 km of class C road: band means within 4 standard errors of the shaping
    filter's exact PSD; that PSD within 6 % of the ISO 8608 line from 0.05 to 0.5 cycles/m (above,
    the tyre envelope bridges short wavelengths by design)."""
    dx = gv.ROAD_DX
    h = gv.filtered_noise(np.random.default_rng(11), "C", 400_000, dx)[4000:, 0]  # past start-up
    nper = 4096
    n, G = welch(h, fs=1.0 / dx, nperseg=nper, window="hann", detrend="linear")
    segments = 2 * len(h) // nper - 1  # 50 % overlap
    exact = gv.filter_psd(n, "C")
    for lo, hi in ((0.05, 0.1), (0.1, 0.2), (0.2, 0.5), (0.5, 1.0), (1.0, 3.0)):
        band = (n >= lo) & (n < hi)
        ratio = G[band] / exact[band]
        # Hann, 50 % overlap: a bin's relative variance about 1 / (0.95 K); Hann makes neighbouring
        # bins correlated, so only every other bin counts as independent
        se = 1.0 / math.sqrt(0.95 * segments * max(band.sum() / 2, 1))
        assert abs(ratio.mean() - 1.0) < 4 * se, (lo, hi, ratio.mean(), se)
    nn = np.geomspace(0.05, 0.5, 50)
    iso = gv.ISO_GD0["C"] * (nn / gv.N0) ** -2
    assert np.all(np.abs(gv.filter_psd(nn, "C") / iso - 1) < 0.06)
    # class ratios are the ISO ones (factor 4 per class)
    assert gv.filter_psd(0.3, "E") / gv.filter_psd(0.3, "A") == pytest.approx(256.0)


def test_road_level_start_and_interpolation():
    road = gv.FilteredRoad(np.random.default_rng(2), "D", 200.0, ramp=10.0)
    assert road(-1.0) == (0.0, 0.0) and road(0.0) == (0.0, 0.0)
    x = np.arange(300, 3000) * road.dx
    assert np.allclose([road.raw(float(v))[0] for v in x], road.state[300:3000, 0], rtol=0, atol=1e-14)
    # slope: the spline's derivative against a central difference
    xs = np.linspace(20.0, 150.0, 200)
    d = [(road(v + 1e-5)[0] - road(v - 1e-5)[0]) / 2e-5 for v in xs]
    assert np.allclose(d, [road(v)[1] for v in xs], rtol=1e-5, atol=1e-8)


# ----------------------------------------------------------------------------- half-car
def test_halfcar_against_jaxdrift_model():
    """Oracle in one direction: jaxdrift's (A.4) right-hand side and static equilibrium give the
    generator's derivatives along one of its effect-free trajectories."""
    from jaxdrift.models._halfcar import road_driven_rhs, static_equilibrium
    from jaxdrift.models._params import HalfCarParams

    c = _case("clean", [], 5, road_class="D", speed=12.0)
    p = gv.true_vehicle(c)
    P = HalfCarParams(**p)
    assert np.allclose(gv.equilibrium(p), np.asarray(static_equilibrium(P, "road")), rtol=1e-12, atol=1e-15)
    road = gv.FilteredRoad(np.random.default_rng(c["road_seed"]), c["road_class"], 60.0)
    sol = gv.simulate(p, road, c["speed"], -1.0, 3.0)
    rhs = gv._rhs_factory(p, road, c["speed"], -1.0)
    for t in np.linspace(0.05, 3.0, 25):
        y = sol.sol(t)
        x1 = -1.0 + c["speed"] * t
        e1, de1 = road(x1)
        e2, de2 = road(x1 - p["a"] - p["b"])
        ref = np.asarray(road_driven_rhs(t, y, P, (e1, e2), (c["speed"] * de1, c["speed"] * de2)))
        assert np.allclose(rhs(t, y), ref, rtol=1e-10, atol=1e-9)
    # the run moves (a rough road), so the comparison is not trivial
    assert np.ptp(sol.sol(np.linspace(0, 3, 300))[3]) > 1e-4


def test_integration_converged():
    """The generator's tolerance (rtol 1e-10) against a 100x tighter solve: pitch and forces agree
    to below 1e-9 of their range, the 9th significant digit (measured: 5e-12 and 2e-11)."""
    c = _case("clean", [], 8, road_class="C", speed=20.0)
    p = gv.true_vehicle(c)
    road = gv.FilteredRoad(np.random.default_rng(3), "C", 80.0)
    tau = np.linspace(0, 2.0, 401)
    s1 = gv.signals(p, road, 20.0, 0.0, gv.simulate(p, road, 20.0, 0.0, 2.0), tau)
    s2 = gv.signals(p, road, 20.0, 0.0, gv.simulate(p, road, 20.0, 0.0, 2.0, rtol=1e-12, atol=1e-14), tau)
    assert np.max(np.abs(s1["beta"] - s2["beta"])) < 1e-9 * np.ptp(s2["beta"])
    assert np.max(np.abs(s1["f1"] - s2["f1"])) < 1e-9 * np.ptp(s2["f1"])


def test_linear_road_between_kinks():
    """A road of straight lines between profile points (the wide design): heights at the points are
    the filtered noise's, the slope is constant in each cell, and the integration between kinks
    (one DOP853 per stretch) agrees with solve_ivp across the kinks at a 100x tighter tolerance,
    whose step control finds each kink itself: pitch and forces to 1e-9 of their range. The tyre
    force jumps at the kinks (its damper term), as on a measured road of straight lines."""
    from scipy.integrate import solve_ivp

    c = _case("clean", [], 8, road_class="C", speed=20.0)
    p = gv.true_vehicle(c)
    road = gv.FilteredRoad(np.random.default_rng(3), "C", 40.0, interp="linear")
    x = np.arange(300, 400) * road.dx
    assert np.allclose([road.raw(float(v))[0] for v in x], road.state[300:400, 0], rtol=0, atol=1e-15)
    mid = x + 0.37 * road.dx
    assert np.allclose([road.raw(float(v))[1] for v in mid], np.diff(road.state[300:401, 0]) / road.dx)
    x0, T = 5.0, 0.6  # from inside the fade-in to past it (x 5-17 m)
    tau = np.linspace(0.0, T, 601)
    s1 = gv.signals(p, road, 20.0, x0, gv.simulate(p, road, 20.0, x0, T), tau)
    ref = solve_ivp(gv._rhs_factory(p, road, 20.0, x0), (0.0, T), gv.equilibrium(p), method="DOP853",
                    rtol=1e-12, atol=1e-14, dense_output=True)
    s2 = gv.signals(p, road, 20.0, x0, ref, tau)
    for k in ("beta", "z3", "f1", "f2"):
        assert np.max(np.abs(s1[k] - s2[k])) < 1e-9 * np.ptp(s2[k]), k
    # the front tyre force jumps by -d1 v (change of slope) where the front wheel passes a point
    sol = gv.simulate(p, road, 20.0, x0, T)
    for k in (250, 251, 300):
        tk = (k * road.dx - x0) / 20.0
        f = gv.signals(p, road, 20.0, x0, sol, np.array([tk - 1e-9, tk + 1e-9]))["f1"]
        ds = (road.state[k + 1, 0] - road.state[k, 0] - road.state[k, 0] + road.state[k - 1, 0]) / road.dx
        assert f[1] - f[0] == pytest.approx(-p["d1"] * 20.0 * ds, rel=1e-3)


def test_wide_design_draws_the_other_habits():
    """The wide design: half its roads straight lines, classes A-D at 10-35 m/s, 0.3-5 N of force
    noise on every run but the noise-free ones, and the other designs' draws unchanged by it."""
    cases = [gv.make_case(c, durations=(10.0, 40.0), max_samples=2000) for c in gv.design_wide(40, 7)]
    interp = [c["road_interp"] for c in cases]
    assert 10 <= interp.count("linear") <= 30 and set(interp) == {"linear", "spline7"}
    assert all(c["road_class"] != "E" and 10.0 <= c["speed"] <= 35.0 for c in cases)
    noise = [e["value"] for c in cases for e in c["effects"] if e["cause"] == "force_noise"]
    assert len(noise) == sum(c["stratum"] != "clean" for c in cases) and 0.3 <= min(noise) and max(noise) <= 5.0
    assert sum(c["stratum"] == "noise" for c in cases) == 20
    std = gv.make_case(gv.design(4, 7)[0])
    assert "road_interp" not in std


# ----------------------------------------------------------------------------- contract
@pytest.mark.parametrize("what", [("force_offset", "f1"), ("force_scale", "f2"), ("force_delay", "f1"),
                                  ("parameter_error", "I"), None])
def test_vehicle_run_follows_contract(tmp_path, what):
    import jaxdrift

    stratum = "single" if what else "clean"
    c = _case(stratum, [list(what)] if what else [], 21, channel_set="all",
              channels=list(gv.CHANNEL_SETS["all"]), fs=300.0, motion_noise={}, precision=9, t0=123.456)
    c["effects"] = [e for e in c["effects"] if e["cause"] != "force_noise"]
    cols, true = gv.generate(c)
    paths = gv.write_run(str(tmp_path), "r", c, cols)
    with open(paths["csv"]) as fh:
        header = fh.readline().strip().split(",")
    assert set(header) == {"t", "f1", "f2", "beta", "beta_rate", "z3", "s1", "s2"}
    run = jaxdrift.read_vehicle_run(paths["csv"])
    assert not run.warnings
    t = np.asarray(run.t)
    dt = np.diff(t)
    assert np.max(np.abs(dt / (1 / 300.0) - 1)) < 1e-6 and abs(t[0] - 123.456) < 1e-9
    with open(paths["model"]) as fh:
        model = json.load(fh)
    assert sorted(model) == sorted(gv.KEYS) and all(v > 0 for v in model.values())
    with open(paths["truth"]) as fh:
        truth = json.load(fh)
    assert {e["cause"] for e in truth["effects"]} <= SPEC_CAUSES
    for e in truth["effects"]:
        if e["cause"] == "parameter_error":
            assert e["parameter"] in model
        elif e["cause"] != "force_noise":
            assert e["channel"] in ("f1", "f2")
    p = gv.true_vehicle(c)
    # effects as the spec defines them: measured(t) = scale * true(t - delay) + offset
    sig = {e.get("channel"): e for e in truth["effects"]}
    for ch in ("f1", "f2"):
        meas = np.asarray(run[ch])
        e = sig.get(ch)
        expect = true[ch]
        if e and e["cause"] == "force_offset":
            expect = true[ch] + e["value"]
        elif e and e["cause"] == "force_scale":
            expect = true[ch] * e["value"]
        elif e and e["cause"] == "force_delay":
            road = gv.FilteredRoad(np.random.default_rng(c["road_seed"]), c["road_class"],
                                   -c["speed"] * c["lead_in"] + c["speed"] * 3.2 + 1.0)
            sol = gv.simulate(p, road, c["speed"], -c["speed"] * c["lead_in"], 3.0 + 1e-9)
            expect = gv.signals(p, road, c["speed"], -c["speed"] * c["lead_in"], sol,
                                np.arange(len(t)) / 300.0 - e["value"])[ch]
        # 9 significant digits: within half a unit of the 9th digit, 5e-9 relative
        assert np.allclose(meas, expect, rtol=5.0001e-9, atol=0), ch
    # static equilibrium at the first sample: f1 + f2 = (m1 + m2 + m3) g for the true vehicle
    if what is None or what[0] == "parameter_error":
        W = (p["m1"] + p["m2"] + p["m3"]) * p["g"]
        assert abs(run["f1"][0] + run["f2"][0] - W) < 1e-8 * W
    assert abs(run["beta_rate"][0]) < 1e-12


@pytest.mark.parametrize("digits", [6, 9])
def test_vehicle_digits(tmp_path, digits):
    c = _case("clean", [], 4, precision=digits, channel_set="beta", channels=["beta"], motion_noise={})
    paths = gv.write_run(str(tmp_path), "r", c, gv.generate(c)[0])
    with open(paths["csv"]) as fh:
        lines = fh.read().splitlines()
    col = lines[0].split(",").index("f1")
    vals = [ln.split(",")[col] for ln in lines[1:]]
    assert max(len(v.replace("-", "").replace(".", "").lstrip("0")) for v in vals) == digits


def test_design_is_stratified_and_reproducible():
    cases = gv.design(200, 20261201)
    assert cases == gv.design(200, 20261201)
    singles = {tuple(c["what"][0]) for c in cases if c["stratum"] == "single"}
    assert singles == set(gv.SINGLES)
    assert {tuple(c["what"]) for c in cases if c["stratum"] == "pair"} == set(gv.PAIRS)
    assert sum(c["stratum"] in ("clean", "noise") for c in cases) == 40
    att = ga.design(100, 20261201)
    assert {c["what"][0] for c in att if c["stratum"] == "single"} == set(ga.SINGLES)
    assert {tuple(c["what"]) for c in att if c["stratum"] == "pair"} == set(ga.PAIRS)


# ----------------------------------------------------------------------------- attitude
def _att_case(what, seed, **kw):
    c = ga.make_case({"index": 0, "stratum": "single" if what else "clean", "what": what, "seed": seed},
                     durations=(12.0, 12.0), rates=(200,))
    c.update(kw)
    return c


def test_attitude_kinematics_and_accelerometers(tmp_path):
    """Quaternion: unit norm and q' = q (x) (0, w) / 2 by central differences; accelerometers:
    S^T x_C'' from a finite difference of the global velocity S v_b, gravity correction (3.3)."""
    c = _att_case([], 3, static_s=3.0, reference_every=1, sign_flips=False, positions=ga.draw_array(
        np.random.default_rng(1)).tolist(), effects=[], precision=9)
    motion = ga.Motion(np.random.default_rng(c["motion_seed"]), c["static_s"])
    h = 5e-4  # central differences: truncation error about h^2/6 times the third derivative, < 2e-6
    tau = np.arange(16001) * h
    q = ga.attitude(motion, np.array([1.0, 0, 0, 0]), tau)
    assert np.max(np.abs(np.linalg.norm(q, axis=1) - 1)) < 1e-9
    w, dw = motion.rates(tau)
    dq = (q[2:] - q[:-2]) / (2 * h)
    q0, q1, q2, q3 = q[1:-1].T
    x, y, z = w[1:-1].T
    expect = 0.5 * np.stack([-q1 * x - q2 * y - q3 * z, q0 * x + q2 * z - q3 * y,
                             q0 * y - q1 * z + q3 * x, q0 * z + q1 * y - q2 * x], 1)
    assert np.max(np.abs(dq - expect)) < 1e-5
    # rates and their derivative
    e = 1e-6
    assert np.allclose((motion.rates(tau + e)[0] - motion.rates(tau - e)[0]) / (2 * e), dw, atol=1e-6)
    # body acceleration: d/dt (S v_b) against S (v_b' + w x v_b)
    S = ga.rotation(q)
    V, dV = motion.speed(tau)
    vb = np.stack([V, 0 * V, 0 * V], 1)
    vg = np.einsum("nij,nj->ni", S, vb)
    fd = (vg[2:] - vg[:-2]) / (2 * h)
    an = np.einsum("nij,nj->ni", S, np.stack([dV, 0 * V, 0 * V], 1) + np.cross(w, vb))[1:-1]
    assert np.max(np.abs(fd - an)) < 1e-4
    # static start, level: gravity-corrected accelerations and rates vanish
    cols, _ = ga.generate(c)
    acc0 = np.array([cols[k][0] for k in cols if k.startswith("a")])
    assert np.max(np.abs(acc0)) < 1e-9 + 9.81 * 0.05  # tilted by the initial roll/pitch (<= 0.03 rad)
    assert abs(cols["wx"][0]) < 1e-15


def test_attitude_rigid_array_and_effects(tmp_path):
    """Without effects the array is rigid (the relative accelerations are an exact linear map of
    the relative positions); a sensor_position error breaks it only at its sensor; the files
    follow the contract and the attitude reader takes them."""
    from jaxdrift.diagnosis.attitude._diagnose import read_attitude_run, read_sensors

    r = ga.draw_array(np.random.default_rng(5))
    base = dict(static_s=0.0, reference_every=10, sign_flips=True, positions=r.tolist(), precision=9)
    c = _att_case([], 7, **base, effects=[])
    cols, _ = ga.generate(c)
    N = len(r)
    acc = np.stack([np.stack([cols[f"a{i + 1}{a}"] for a in "xyz"], -1) for i in range(N)], 1)
    X = np.hstack([np.ones((N, 1)), r])
    resid = acc - np.einsum("ij,njk->nik", X @ np.linalg.pinv(X), acc)
    assert np.max(np.abs(resid)) < 1e-9
    e = {"cause": "sensor_position", "sensor": 2, "value": [0.05, 0.0, -0.02]}
    c2 = dict(c, effects=[e])
    cols2, _ = ga.generate(c2)
    acc2 = np.stack([np.stack([cols2[f"a{i + 1}{a}"] for a in "xyz"], -1) for i in range(N)], 1)
    diff = np.abs(acc2 - acc).max(axis=(0, 2))
    assert diff[1] > 1e-3 and np.all(np.delete(diff, 1) < 1e-12)
    paths = ga.write_run(str(tmp_path), "a", c2, cols2, {})
    run = read_attitude_run(paths["csv"])
    assert run["acc"].shape[1] == N and run["q_ref"] is not None
    assert np.allclose(read_sensors(paths["sensors"], N), r)
    with open(paths["truth"]) as fh:
        truth = json.load(fh)
    assert {x["cause"] for x in truth["effects"]} <= SPEC_CAUSES


def test_gyro_effects_sizes():
    """Bias, scale and noise land on the rates as the spec defines them."""
    c = _att_case(["gyro_bias"], 9, reference_every=0, positions=None, static_s=0.0, precision=9)
    eff = [{"cause": "gyro_noise", "value": 1e-3}, {"cause": "gyro_bias", "channel": "wy", "value": 0.01},
           {"cause": "gyro_scale", "channel": "wz", "value": 1.02}]
    c["effects"] = eff
    cols, _ = ga.generate(c)
    motion = ga.Motion(np.random.default_rng(c["motion_seed"]), 0.0)
    tau = np.arange(len(cols["t"])) / 200.0
    w, _ = motion.rates(tau)
    err = np.stack([cols["wx"] - w[:, 0], cols["wy"] - w[:, 1] - 0.01, cols["wz"] - 1.02 * w[:, 2]], 1)
    n = len(tau)
    sd = 1e-3 / math.sqrt(1 / 200.0)
    assert np.all(np.abs(err.mean(0)) < 4 * sd / math.sqrt(n))
    assert np.all(np.abs(err.std(0) / sd - 1) < 4 / math.sqrt(2 * n))


# ----------------------------------------------------------------------------- scorer
def test_scorer_rules():
    eff = [{"cause": "force_delay", "channel": "f2", "value": 0.004},
           {"cause": "force_noise", "value": 2.0}]
    f = [{"cause": "parameter_error", "parameter": "I", "estimate": 1.1, "interval": [1.0, 1.2],
          "indistinguishable_from": [{"cause": "force_delay", "channel": "f2"}]},
         {"cause": "force_delay", "channel": "f2", "estimate": 0.0041, "interval": [0.0039, 0.0043]},
         {"cause": "force_noise", "estimate": 3.5, "interval": [3.0, 4.0]}]
    s = sw.score("vehicle", eff, f)
    assert not s["right"] and s["right_or_declared"]
    assert [c["covered"] for c in s["coverage"]] == [True, False]
    assert s["coverage"][1]["within_1.5x"] is False
    s = sw.score("vehicle", [{"cause": "force_noise", "value": 2.0}], f[2:])
    assert s["false_alarm"] is False and s["coverage"][0]["within_1.5x"] is False
    assert sw.score("vehicle", [], f)["false_alarm"] is True
    pair = [{"cause": "force_delay", "channel": "f2", "value": 0.004},
            {"cause": "parameter_error", "parameter": "I", "value": 1.15}]
    assert sw.score("vehicle", pair, f)["right"]
    sp = [{"cause": "sensor_position", "sensor": 2, "value": [0.01, 0.0, -0.02]}]
    fs = [{"cause": "sensor_position", "sensor": 2, "estimate": [0.01, 0.0, -0.02],
           "interval": [[0.0, -0.01, -0.03], [0.02, 0.01, -0.025]]}]
    s = sw.score("attitude", sp, fs)
    assert s["right"] and not s["coverage"][0]["covered"]  # z = -0.02 lies above -0.025


# ----------------------------------------------------------------------------- the targets
@pytest.mark.slow
@pytest.mark.parametrize("kind,n", [("vehicle", 14), ("attitude", 10)])
def test_small_sweep_meets_issue_targets(tmp_path, kind, n):
    """A small sweep (seed 777, not the committed one) against the diagnosis's targets (docs/validation.md)."""
    sw.main(["--kind", kind, "--n", str(n), "--seed", "777", "--out", str(tmp_path), "--jobs", "1"])
    with open(tmp_path / f"{kind}.json") as fh:
        s = json.load(fh)
    assert s["errors"] == 0
    assert s["single"]["right_first"] >= math.ceil(0.95 * s["single"]["n"])
    assert s["pair"]["both_in_first_two"] >= math.ceil(0.9 * s["pair"]["n"])
    assert s["effect_free"]["false_alarms"] <= math.floor(0.05 * s["effect_free"]["n"])
    assert s["coverage"]["runs_all_covered"] >= math.ceil(0.9 * s["coverage"]["runs"])


def test_size_ranges():
    """The sweep's size scale (0 barely detectable .. 1 large) matches the generators' draws."""
    rng = np.random.default_rng(0)
    model = dict(gv.VEHICLES["van"], g=9.81)
    case = {"model": model, "effects": []}
    for cause, tgt in gv.SINGLES + gv.CROSSTALK:
        u = [sw.size_u(gv.draw_effect(rng, cause, tgt, model), case) for _ in range(200)]
        assert -1e-9 <= min(u) and max(u) <= 1 + 1e-9 and max(u) - min(u) > 0.8, (cause, tgt)
    for cause in ga.SYSTEMATIC:
        u = []
        for seed in range(40):
            c = ga.make_case({"index": 0, "stratum": "single", "what": [cause], "seed": seed}, max_samples=20000)
            u += [sw.size_u(e, c) for e in c["effects"] if e["cause"] == cause]
        assert -1e-9 <= min(u) and max(u) <= 1 + 1e-9 and max(u) - min(u) > 0.6, cause


def test_array_and_drift_effects_sizes():
    """accel_noise, nonrigid and gyro_bias_drift land on the data with the truth's sizes (each
    checked against the effect-free run of the same case, within 4 standard errors)."""
    r = ga.draw_array(np.random.default_rng(8))
    c = _att_case([], 12, static_s=0.0, reference_every=0, positions=r.tolist(), precision=9, effects=[])
    base, _ = ga.generate(c)
    n, N = len(base["t"]), len(r)
    acc0 = np.stack([base[f"a{i + 1}{a}"] for i in range(N) for a in "xyz"], 1)
    noisy, _ = ga.generate(dict(c, effects=[{"cause": "accel_noise", "value": 0.02}]))
    d = np.stack([noisy[f"a{i + 1}{a}"] for i in range(N) for a in "xyz"], 1) - acc0
    assert abs(d.std() / 0.02 - 1) < 4 / math.sqrt(2 * d.size) and abs(d.mean()) < 4 * 0.02 / math.sqrt(d.size)
    bent, extra = ga.generate(dict(c, effects=[{"cause": "nonrigid", "value": 0.1}]))
    d = np.stack([bent[f"a{i + 1}{a}"] for i in range(N) for a in "xyz"], 1) - acc0
    assert extra["nonrigid_rms_added"] == pytest.approx(0.1, rel=1e-12)
    assert np.sqrt(np.mean(d**2)) == pytest.approx(0.1, rel=1e-6)  # 9 digits of ~10 m/s^2 values
    assert 0 < extra["nonrigid_rms_beyond_rigid"] < 0.1
    K, dt = 1e-3, 1 / 200.0
    drift, _ = ga.generate(dict(c, positions=None, effects=[{"cause": "gyro_bias_drift", "channel": "wz", "value": K}]))
    b = np.asarray(drift["wz"]) - np.asarray(base["wz"])
    inc = np.diff(b)
    assert abs(b[0]) < 1e-12 and np.allclose(drift["wx"], base["wx"])
    assert abs(inc.std() / (K * math.sqrt(dt)) - 1) < 4 / math.sqrt(2 * len(inc))
