"""Durability: rainflow damage against ASTM E1049-85 and fatpack, the derivative filter,
the pitch-spring and step rules, the section forces against generated runs whose true section
forces are known, the Monte-Carlo noise band, and the command line."""

from __future__ import annotations

import json
import hashlib

import numpy as np
import pytest

from jaxdrift.durability import (filtered_derivatives, integration_step, load_statistics, lowpass,
                                 noise_from_differences, pitch_spring_rule, pseudo_damage,
                                 rainflow_cycles, section_forces, turning_points)
from jaxdrift.durability._derivative import derivative
from jaxdrift.io._csvio import DEFAULT_MODEL

ASTM_SIGNAL = [-2.0, 1.0, -3.0, 5.0, -1.0, 3.0, -4.0, 4.0, -2.0]


def _aggregate(ranges, counts):
    out = {}
    for r, c in zip(ranges, counts):
        out[float(r)] = out.get(float(r), 0.0) + float(c)
    return out


def test_rainflow_matches_astm_e1049_example_counted_by_hand():
    # ASTM E1049-85 section 5.4.4 (Fig. 6), counted by hand with the three-point rule:
    # -2..1 (3) and 1..-3 (4) contain the start: half cycles; -1..3 (4) a full cycle when -4 is read;
    # -3..5 (8) contains the start: half; the residue 5..-4..4..-2 gives halves of 9, 8, 6.
    ranges, counts = rainflow_cycles(ASTM_SIGNAL)
    assert _aggregate(ranges, counts) == {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}
    # 0.5 3^5 + 1.5 4^5 + 0.5 6^5 + 8^5 + 0.5 9^5
    assert pseudo_damage(ranges, counts, 5.0) == 67838.0
    assert pseudo_damage(ranges, counts, 1.0) == 0.5 * 3 + 1.5 * 4 + 0.5 * 6 + 8 + 0.5 * 9


def _fatpack_damage(x, k):
    fatpack = pytest.importorskip("fatpack")
    cycles, residue = fatpack.find_rainflow_cycles(turning_points(x))
    full = np.abs(cycles[:, 1] - cycles[:, 0]) if cycles.size else np.zeros(0)
    half = np.abs(np.diff(residue))
    return np.sum(full**k) + 0.5 * np.sum(half**k)


@pytest.mark.parametrize("k", [3.0, 5.0])
def test_damage_agrees_with_fatpack(k):
    """fatpack's four-point count (closed cycles, the residue's ranges as half cycles) is an
    independent implementation; it must give the same pseudo-damage to rounding."""
    rng = np.random.default_rng(3)
    t = np.arange(20000) / 1000.0
    x = 3000 * np.sin(2 * np.pi * 1.3 * t) + 400 * np.sin(2 * np.pi * 11.0 * t) + 60 * rng.standard_normal(t.size)
    assert _fatpack_damage(ASTM_SIGNAL, 5.0) == 67838.0
    ours = pseudo_damage(*rainflow_cycles(x), k)
    assert ours == pytest.approx(_fatpack_damage(x, k), rel=1e-12)


def test_turning_points_do_not_change_the_count():
    import rainflow

    rng = np.random.default_rng(4)
    x = np.round(rng.standard_normal(3000).cumsum(), 1)  # random walk with plateaus
    direct = sorted((r, c) for r, _m, c, _i, _j in rainflow.extract_cycles(x))
    ours = sorted(zip(*rainflow_cycles(x)))
    assert ours == direct
    assert turning_points(x).size < x.size


def test_load_statistics():
    x = np.array([0.0, 2.0, -2.0, 2.0, 0.0])
    s = load_statistics(x, 2.0)
    assert s["max_abs"] == 2.0 and s["rms"] == pytest.approx(np.sqrt(12 / 5))
    assert s["damage"] == pytest.approx(pseudo_damage(*rainflow_cycles(x), 2.0))
    assert s["equivalent_range_N"] == pytest.approx((s["damage"] / 1e6) ** 0.5)


def test_noise_from_differences_recovers_white_noise_under_a_smooth_signal():
    rng = np.random.default_rng(5)
    t = np.arange(20000) / 500.0
    clean = 0.05 * np.sin(2 * np.pi * 0.7 * t) + 0.01 * np.sin(2 * np.pi * 3 * t)
    for sigma in (1e-5, 1.7e-4):
        est = noise_from_differences(clean + sigma * rng.standard_normal(t.size))
        assert abs(est / sigma - 1) < 0.05  # MAD of 20000 correlated 4th differences: SE about 1.5 %
    assert noise_from_differences(clean) < 1e-7


def test_derivative_is_fourth_order_and_filter_keeps_the_band():
    t = np.arange(4001) / 200.0
    w = 2 * np.pi * 22.0  # wheel hop at 200 Hz: 2nd-order differences lose 8 %
    x = np.sin(w * t)
    d = derivative(x, 1 / 200.0)[10:-10] / (w * np.cos(w * t[10:-10]) + 1e-300)
    sel = np.abs(np.cos(w * t[10:-10])) > 0.5
    assert np.max(np.abs(d[sel] - 1)) < 0.01
    g = np.gradient(x, 1 / 200.0)[10:-10] / np.cos(w * t[10:-10]) / w
    assert np.max(np.abs(g[sel] - 1)) > 0.05  # the plain difference would fail the bound above
    y = lowpass(np.sin(2 * np.pi * 2.0 * t), 200.0, 20.0)
    assert np.max(np.abs(y - np.sin(2 * np.pi * 2.0 * t))[200:-200]) < 1e-3  # zero phase, passband


def test_filtered_derivatives_beat_plain_differences_on_noisy_pitch():
    rng = np.random.default_rng(6)
    fs = 500.0
    t = np.arange(int(20 * fs)) / fs
    beta = 0.03 * np.sin(2 * np.pi * 0.4 * t) + 0.004 * np.sin(2 * np.pi * 2.5 * t)
    true_rate = 0.03 * 2 * np.pi * 0.4 * np.cos(2 * np.pi * 0.4 * t) + 0.004 * 2 * np.pi * 2.5 * np.cos(2 * np.pi * 2.5 * t)
    noisy = beta + np.deg2rad(0.01) * rng.standard_normal(t.size)
    _, db, _, info = filtered_derivatives(noisy, 1 / fs)
    assert info["kind"].startswith("butterworth") and 2.5 < info["cutoff_hz"] < 0.4 * fs
    err_f = np.sqrt(np.mean((db - true_rate)[500:-500] ** 2))
    err_p = np.sqrt(np.mean((np.gradient(noisy, 1 / fs) - true_rate)[500:-500] ** 2))
    assert err_f < 0.1 * err_p
    _, _, _, clean = filtered_derivatives(beta, 1 / fs)
    assert clean["kind"] == "none"
    # a measured rate is used (filtered by its own rule) instead of differentiating the angle
    noisy_rate = true_rate + 0.01 * rng.standard_normal(t.size)
    _, db_r, ddb_r, info_r = filtered_derivatives(noisy, 1 / fs, beta_rate=noisy_rate)
    assert info_r["rate_source"] == "measured beta_rate" and [x["signal"] for x in info_r["signals"]] == ["beta", "beta_rate"]
    assert np.sqrt(np.mean((db_r - true_rate)[500:-500] ** 2)) < 0.3 * 0.01


def test_pitch_spring_rule_and_integration_step_by_hand():
    s = pitch_spring_rule(DEFAULT_MODEL)
    # J = 500 + 15 + 15 = 530; 2 pi f_pitch = sqrt(2e5 / 500) = 20 rad/s; k = 530 (0.1 * 20)^2
    assert s["J"] == 530.0 and s["k_rot"] == pytest.approx(2120.0) and s["d_rot"] == pytest.approx(2120.0)
    assert pitch_spring_rule(DEFAULT_MODEL, 100.0)["d_rot"] == pytest.approx(2 * np.sqrt(100.0 * 530.0))
    assert pitch_spring_rule(DEFAULT_MODEL, 100.0, 5.0)["d_rot"] == 5.0
    # tyre time constant d1/k1 = 1 ms is the binding limit of the seed's vehicle
    assert integration_step(DEFAULT_MODEL, 1 / 200) == (pytest.approx(1e-3), 5)
    assert integration_step(DEFAULT_MODEL, 1 / 1000) == (pytest.approx(1e-3), 1)
    assert integration_step(DEFAULT_MODEL, 1 / 2000) == (pytest.approx(5e-4), 1)


def _true_damage(truth, k=5.0):
    s, p = truth["signals"], truth["params"]
    f3 = p["k3"] * s["s1"] + p["d3"] * s["ds1"]
    f4 = p["k4"] * s["s2"] + p["d4"] * s["ds2"]
    return np.array([load_statistics(f3, k)["damage"], load_statistics(f4, k)["damage"]])


@pytest.mark.parametrize("road, fs, pitch_noise_deg", [("B", 200.0, 0.02), ("C", 500.0, 0.01),
                                                               pytest.param("E", 2000.0, 0.02, marks=pytest.mark.tier2)])
def test_stabilised_damage_within_5_percent_of_the_truth(road, fs, pitch_noise_deg):
    from jaxdrift.studies import make_run

    cols, truth = make_run([{"cause": "force_noise", "value": 10.0}], fs=fs, road_class=road, duration=6.0,
                           seed=11, speed=18.0, channels=("beta", "s1", "s2"))
    true = _true_damage(truth)
    rng = np.random.default_rng(12)
    beta = cols["beta"] + np.deg2rad(pitch_noise_deg) * rng.standard_normal(cols["t"].size)
    res = section_forces(cols["t"], cols["f1"], cols["f2"], truth["params"], beta=beta,
                         s1=cols["s1"], s2=cols["s2"])
    dmg = {v: np.array([load_statistics(F[:, j])["damage"] for j in range(2)]) for v, F in res["forces"].items()}
    assert np.all(np.abs(dmg["stabilised"] / true - 1) < 0.05), dmg["stabilised"] / true
    assert np.all(np.abs(dmg["measured"] / true - 1) < 0.05), dmg["measured"] / true
    # without the model's corrections the extended variant is the stabilised one
    np.testing.assert_array_equal(res["forces"]["extended"], res["forces"]["stabilised"])
    if fs == 500.0:  # the filter is what makes it pass: plain differences are far off
        plain = section_forces(cols["t"], cols["f1"], cols["f2"], truth["params"], beta=beta, filter_pitch=False)
        d_plain = np.array([load_statistics(plain["forces"]["stabilised"][:, j])["damage"] for j in range(2)])
        assert np.all(d_plain / true > 1.3), d_plain / true


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    """A 4 s, 200 Hz run with force noise, an offset on f2 and measured pitch (CSV on disk)."""
    from jaxdrift.io._csvio import write_vehicle_run
    from jaxdrift.studies import make_run

    cols, truth = make_run([{"cause": "force_offset", "channel": "f2", "value": 80.0},
                            {"cause": "force_noise", "value": 15.0}],
                           fs=200.0, road_class="C", duration=4.0, seed=21, speed=15.0, channels=("beta",))
    path = tmp_path_factory.mktemp("run") / "run.csv"
    write_vehicle_run(path, cols["t"], {k: v for k, v in cols.items() if k != "t"})
    return path, cols, truth


def test_monte_carlo_band_does_not_depend_on_chunking_and_zero_noise_is_nominal(short_run):
    from jaxdrift.durability import monte_carlo_damage

    _, cols, truth = short_run
    res = section_forces(cols["t"], cols["f1"], cols["f2"], DEFAULT_MODEL, beta=cols["beta"])
    sf = res["section_forces_fn"]
    variants = ["force_driven", "pitch_spring", "stabilised", "extended"]
    # one chunk size throughout (each size is a compilation): paths 0-1 of a 4-path study in two
    # chunks equal a 2-path study's, because a path's noise comes from its global index
    a = monte_carlo_damage(sf, 15.0, 4, variants=variants, chunk=2, progress=False)
    b = monte_carlo_damage(sf, 15.0, 2, variants=variants, chunk=2, progress=False)
    np.testing.assert_array_equal(a[:2], b)
    assert len({float(x) for x in a[:, 2, 0]}) == 4  # every path its own noise draw
    z = monte_carlo_damage(sf, 0.0, 2, variants=variants, chunk=2, progress=False)
    nominal = [[load_statistics(res["forces"][v][:, j])["damage"] for j in range(2)] for v in variants]
    np.testing.assert_allclose(z[0], nominal, rtol=1e-12)
    np.testing.assert_array_equal(z[0], z[1])


def _cli(*args):
    from jaxdrift.cli import main

    return main(["durability", *map(str, args)])


def test_cli_writes_the_outputs(short_run, tmp_path, capsys):
    path, _, _ = short_run
    out = tmp_path / "out"
    assert _cli(path, "--out", out, "--paths", 2, "--quiet", "--seed", 5) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(["durability.json", "section_forces.csv", "section_forces.png",
                            "rainflow_histogram.png", "damage_ratio.png", "jaxdrift-manifest.json"])
    rep = json.loads((out / "durability.json").read_text())
    assert rep["schema"] == "jaxdrift.durability/1" and rep["basquin_k"] == 5.0
    assert set(rep["runs"]) == {"force_driven", "pitch_spring", "stabilised", "extended"}
    assert rep["variants_skipped"] == {"measured": "the run has no s1, s2"}
    for v in ("force_driven", "pitch_spring", "extended"):
        assert rep["damage_ratio_to_stabilised"][v] > 0
        q = rep["monte_carlo"]["damage_ratio_quantiles"][v]
        assert q[0] <= q[1] <= q[2]
    mc = rep["monte_carlo"]
    assert mc["paths"] == 2 and mc["noise_source"] == "diagnosis force_noise finding" and mc["noise_N"] > 0
    # the diagnosis found the f2 offset, so the extended variant's forces were corrected
    assert rep["provenance"]["extended_model"]["corrections"]["f2"]["offset"] == pytest.approx(80.0, abs=15.0)
    assert rep["provenance"]["input_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert rep["derivative_filter"]["kind"] and "cutoff_hz" in rep["derivative_filter"]
    assert rep["pitch_spring"]["torque_max_abs"] > 0
    # the corrections are applied: the extended model's enforced moment is the smaller one
    em = rep["enforced_moment"]
    assert em["extended"]["rms"] < 0.8 * em["stabilised"]["rms"], em
    header = (out / "section_forces.csv").read_text().splitlines()[0].split(",")
    assert header[:3] == ["t", "force_driven_f3", "force_driven_f4"] and "stabilised_enforced_moment" in header
    data = np.loadtxt(out / "section_forces.csv", delimiter=",", skiprows=1)
    assert data.shape == (801, len(header))
    assert load_statistics(data[:, header.index("stabilised_f3")])["damage"] == pytest.approx(
        rep["runs"]["stabilised"]["f3"]["damage"], rel=1e-6)  # the CSV's 10 digits


def test_cli_bad_input_exits_2_and_writes_nothing(short_run, tmp_path, capsys):
    path, _, _ = short_run
    out = tmp_path / "out"
    bad_run = tmp_path / "bad.csv"
    bad_run.write_text("t,f1\n0,1\n0.01,2\n")
    bad_model = tmp_path / "model.json"
    bad_model.write_text(json.dumps({**DEFAULT_MODEL, "k3": -1.0}))
    bad_report = tmp_path / "report.json"
    bad_report.write_text(json.dumps({"schema": "something else"}))
    a_file = tmp_path / "file"
    a_file.write_text("x")
    cases = [
        (bad_run, "--out", out),
        (path, "--out", out, "--model", bad_model),
        (path, "--out", out, "--report", bad_report),
        (path, "--out", out, "--paths", -1),
        (path, "--out", out, "--basquin-k", 0),
        (path, "--out", a_file),
        (tmp_path / "missing.csv", "--out", out),
    ]
    for args in cases:
        assert _cli(*args) == 2, args
        err = capsys.readouterr().err
        assert "error" in err and "Traceback" not in err
        assert not out.exists()
    assert a_file.read_text() == "x"


def test_cli_reads_through_the_shared_reader(short_run, tmp_path, capsys):
    """Unit mistakes are caught before computing (the same checks as diagnose), --units converts
    them, and an --out folder that holds the run under an output's name is refused."""
    path, _, _ = short_run
    lines = path.read_text().splitlines()
    head = lines[0].split(",")
    i1, i2 = head.index("f1"), head.index("f2")
    rows = []
    for ln in lines[1:]:
        c = ln.split(",")
        c[i1], c[i2] = repr(float(c[i1]) / 1e3), repr(float(c[i2]) / 1e3)
        rows.append(",".join(c))
    kn = tmp_path / "kn.csv"
    kn.write_text("\n".join([lines[0], *rows]) + "\n")
    out = tmp_path / "out"
    assert _cli(kn, "--out", out, "--paths", 0, "--quiet") == 2
    err = capsys.readouterr().err
    assert "kN?" in err and "f1" in err and not out.exists()
    clash = tmp_path / "clash"
    clash.mkdir()
    (clash / "section_forces.csv").write_text(path.read_text())
    assert _cli(clash / "section_forces.csv", "--out", clash, "--paths", 0, "--quiet") == 2
    assert "would overwrite the input" in capsys.readouterr().err
    assert (clash / "section_forces.csv").read_text() == path.read_text()


def test_run_without_pitch_gives_the_unstabilised_variants_only(short_run):
    from jaxdrift import VehicleRun, durability_analysis

    _, cols, _ = short_run
    run = VehicleRun(path="<memory>", t=cols["t"], channels={"f1": cols["f1"], "f2": cols["f2"]})
    report = {"findings": [], "extended_model": None}
    res = durability_analysis(run, DEFAULT_MODEL, paths=0, report=report, progress=False)
    s = res.summary
    assert set(res.forces) == {"force_driven", "pitch_spring"}
    assert s["variants_skipped"] == {"stabilised": "the run has no beta", "extended": "the run has no beta",
                                     "measured": "the run has no s1, s2"}
    assert s["reference"] is None and s["damage_ratio_to_stabilised"] == {}
    assert s["monte_carlo"]["paths"] == 0 and s["monte_carlo"]["noise_N"] > 0  # from the forces themselves
    assert s["runs"]["force_driven"]["f3"]["damage"] > 0


def test_band_limited_upsampling_keeps_samples_and_the_wheel_hop():
    from jaxdrift.durability._variants import upsample_forces

    fs, m = 200.0, 5
    t = np.arange(2001) / fs
    x = np.stack([4000 + 500 * np.sin(2 * np.pi * 22.0 * t), 3800 + 300 * np.cos(2 * np.pi * 3.0 * t)], axis=1)
    up = upsample_forces(x, m)
    assert up.shape == ((t.size - 1) * m + 1, 2)
    np.testing.assert_array_equal(up[::m], x)
    tf = np.arange(up.shape[0]) / (fs * m)
    exact = 4000 + 500 * np.sin(2 * np.pi * 22.0 * tf)
    mid = slice(200 * m, -200 * m)
    err_up = np.max(np.abs(up[mid, 0] - exact[mid]))
    err_lin = np.max(np.abs(np.interp(tf, t, x[:, 0])[mid] - exact[mid]))
    assert err_up < 0.01 * 500 and err_lin > 0.05 * 500  # linear interpolation loses ~6 % here
