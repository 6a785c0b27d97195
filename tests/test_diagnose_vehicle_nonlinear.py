"""Model adequacy and the nonlinear suspension causes, on runs of the independent generator
(benchmarks/validation/gen_vehicle.py: scipy DOP853 on its own half-car and road, sharing no code
with jaxdrift), and the tyre lift-off detector on synthetic forces."""

from __future__ import annotations


import numpy as np
import pytest

from benchmarks.validation import gen_vehicle as gen

import jaxdrift  # noqa: E402
from jaxdrift.diagnosis.vehicle._nonlinear import TyreLiftOff  # noqa: E402

FORM = {"model_form", "damper_asymmetry", "progressive_spring", "bump_stop", "tyre_lift_off"}


def _case(effects, channels="beta_z3_s", fs=250.0, duration=5.0, noise=0.0):
    model = {k: float(v) for k, v in gen.VEHICLES["passenger"].items()}
    model["g"] = gen.G
    eff = [dict(e) for e in effects] + ([{"cause": "force_noise", "value": noise}] if noise else [])
    return {"index": 0, "stratum": "single", "what": [], "seed": 1, "vehicle_kind": "passenger",
            "model": model, "road_class": "C", "speed": 15.0, "fs": fs, "duration": duration,
            "channel_set": channels, "channels": list(gen.CHANNEL_SETS[channels]), "precision": 9,
            "t0": 0.0, "lead_in": 0.2, "effects": eff, "motion_noise": {},
            "column_order_seed": 1, "road_seed": 777001, "noise_seed": 5}


def _diagnose(tmp_path, case):
    paths = gen.make_run(case, str(tmp_path), "run")
    run = jaxdrift.read_vehicle_run(paths["csv"])
    return jaxdrift.diagnose_vehicle_run(run, jaxdrift.read_model(paths["model"]), with_simulation=False)


def test_rear_damper_asymmetry_is_named_with_its_ratio(tmp_path):
    """A car with rear rebound 1.5x compression, spring travel measured, 2 N force noise: the
    first finding is the rear damper's asymmetry, its estimate within 10 % of the true ratio, its
    correction lowers the residual it is read from, and the extended model carries it."""
    rep = _diagnose(tmp_path, _case([{"cause": "damper_asymmetry", "parameter": "d4", "value": 1.5}], noise=2.0))
    f = rep["findings"][0]
    assert (f["cause"], f["parameter"]) == ("damper_asymmetry", "d4"), rep["findings"]
    assert f["estimate"] == pytest.approx(1.5, rel=0.1)
    assert f["interval"][0] <= 1.5 <= f["interval"][1]
    # the term is fitted on the measured travel's rate: nothing else beside it (on the model's rate
    # a 0.5 % error of d4 stood beside it, and 15 N of 'force noise' for the 2 N written), and the
    # noise level within the 1.5x the validation sweeps ask
    assert [g["cause"] for g in rep["findings"][1:]] == ["force_noise"], rep["findings"]
    noise = rep["findings"][1]
    assert noise["interval"][1] >= 2.0 and noise["estimate"] <= 3.0
    assert f["residual"]["rms_with"] < f["residual"]["rms_without"]
    assert rep["extended_model"]["nonlinear"]["damper_ratio4"] == pytest.approx(f["estimate"])
    # confirmed out of sample (alternate eighths of the record), and counted in the joint interval level
    assert f["confirmed"] is True and "out of sample" in f["evidence"]
    assert f["interval_level"]["findings"] >= 2
    # the run shows it: no 'could not show' for it
    assert not any("damper_asymmetry[d4]" in n for n in rep["notes"] if n.startswith("Could not show"))


def test_bump_stop_size_is_the_generators(tmp_path):
    """A stop 8x the rear spring reached on 3 % of the samples (spring travel measured, no noise):
    the stiffness is read off the measured travel, not the linear model's (which overshoots the
    stop by half again and gives a sixth of the stiffness), with the stop's travel fitted, and
    matches the generator's k_b within 1 %."""
    case = _case([{"cause": "bump_stop", "parameter": "k4", "share": 0.03, "ratio": 8.0}], duration=8.0)
    rep = _diagnose(tmp_path, case)
    truth = case["effects"][0]["value"]
    f = rep["findings"][0]
    assert (f["cause"], f["parameter"]) == ("bump_stop", "k4"), rep["findings"]
    assert f["estimate"] == pytest.approx(truth, rel=0.01)
    assert rep["extended_model"]["nonlinear"]["stop_k4"] == pytest.approx(f["estimate"])


def test_a_confirmed_stop_enters_the_gain_the_series_and_durability(tmp_path):
    """Issue 32, item 4: the extended model carries a confirmed nonlinear cause into what the user
    reads. A stop 8x the rear spring (the independent generator, pitch and spring travel measured):
    the re-simulated pitch with the stop follows the measured one far better than the model without
    it (before this, the extended model's simulation was the linear one and the gain was 1), the
    series output's extended pitch likewise, and durability's extended variant needs a smaller
    enforced moment to follow the measured pitch than the stabilised variant of the model."""
    case = _case([{"cause": "bump_stop", "parameter": "k4", "share": 0.03, "ratio": 8.0}], duration=8.0)
    paths = gen.make_run(case, str(tmp_path), "run")
    run = jaxdrift.read_vehicle_run(paths["csv"])
    model = jaxdrift.read_model(paths["model"])
    rep = jaxdrift.diagnose_vehicle_run(run, model, with_simulation=True)
    assert rep["findings"][0]["cause"] == "bump_stop" and "stop_k4" in rep["extended_model"]["nonlinear"]
    g = rep["gain"]
    assert g["beta_rms_dynamic_after"] < 0.2 * g["beta_rms_dynamic_before"], g
    from jaxdrift.diagnosis import vehicle_series

    cols = vehicle_series(run, model, rep)
    err = lambda c: float(np.sqrt(np.mean((cols[c] - run["beta"]) ** 2)))  # noqa: E731
    assert err("ext_beta") < 0.2 * err("sim_beta")
    sf = jaxdrift.section_forces(run.t, run["f1"], run["f2"], model, beta=run["beta"],
                                 extended=rep["extended_model"])
    lam = sf["enforced_moment"]
    rms = lambda x: float(np.sqrt(np.mean(np.asarray(x)[200:] ** 2)))  # noqa: E731  (past the start transient)
    assert rms(lam["extended"]) < 0.5 * rms(lam["stabilised"]), (rms(lam["extended"]), rms(lam["stabilised"]))


@pytest.mark.slow
def test_effect_free_run_has_no_model_form_finding(tmp_path):
    rep = _diagnose(tmp_path, _case([], noise=2.0))
    assert not [f for f in rep["findings"] if f["cause"] in FORM], rep["findings"]


@pytest.mark.slow
def test_progressive_spring_pitch_only_says_it_could_not_show(tmp_path):
    """A progressive front spring with forces and pitch only: either the run shows it (first
    finding) or the report says it could not and names the spring travel, never both."""
    rep = _diagnose(tmp_path, _case([{"cause": "progressive_spring", "parameter": "k3", "stiffening": 0.5}],
                                    channels="beta", noise=2.0))
    assert not [f for f in rep["findings"] if f["cause"] in FORM - {"progressive_spring"}]
    notes = " ".join(n for n in rep["notes"] if n.startswith("Could not show"))
    found = rep["findings"][0]["cause"] == "progressive_spring"
    said = "progressive_spring[k3] (spring travel s1 would show it)" in notes
    assert found != said, (rep["findings"][:2], notes)


def _smooth_force(n, rng, mean, spread):
    x = np.convolve(rng.standard_normal(n + 200), np.hanning(60), mode="same")[100:100 + n]
    return mean + spread * x / np.std(x)


@pytest.mark.parametrize("seed", range(5))
def test_lift_off_detector_on_synthetic_forces(seed):
    """A force clipped at zero on ~3 % of the samples (2 N noise) is found with its share; the same
    force without the clip (the linear tyre pulls), scaled to reach as low as 3 % above zero, and a
    force far from zero, are not."""
    rng = np.random.default_rng(seed)
    n = 20000
    f = _smooth_force(n, rng, 4000.0, 2100.0)
    f[:100] = 4000.0
    share = float(np.mean(f < 0))
    assert 0.01 < share < 0.06
    det = TyreLiftOff("f1").detect(np.maximum(f, 0.0) + 2.0 * rng.standard_normal(n), 2.0)
    assert det is not None and det["interval"][0] <= share <= det["interval"][1]
    # a force-noise level read off a force with real content near the Nyquist frequency is only
    # an upper bound (30x here): the floor's own spread sets the window, and the lift-off is found
    det = TyreLiftOff("f1").detect(np.maximum(f, 0.0) + 2.0 * rng.standard_normal(n), 60.0)
    assert det is not None and det["interval"][0] <= share <= det["interval"][1]
    assert TyreLiftOff("f1").detect(f + 2.0 * rng.standard_normal(n), 2.0) is None
    assert TyreLiftOff("f1").detect(f + 2.0 * rng.standard_normal(n), 60.0) is None
    near = 4000.0 + (f - 4000.0) * (4000.0 - 120.0) / (4000.0 - f.min())
    assert TyreLiftOff("f1").detect(near + 2.0 * rng.standard_normal(n), 2.0) is None
    assert TyreLiftOff("f1").detect(_smooth_force(n, rng, 4000.0, 500.0), 2.0) is None


def test_could_not_show_follows_the_two_conditions_of_a_finding():
    """The detection limit is the smallest size meeting both conditions of a finding (power over the
    Bonferroni threshold and the practical floor): a term that is significant at tiny sizes but
    whose signature is too small for the floor (pitch seeing a spring law) is 'could not show'; one
    whose limit lies between the smallest and largest usual size is 'smaller than'; one that shows
    the smallest size gets no note."""
    import math
    from types import SimpleNamespace

    import scipy.stats

    from jaxdrift.diagnosis.vehicle import _adequacy as A
    from jaxdrift.diagnosis.vehicle._nonlinear import DamperAsymmetry, States

    n = 4000
    u = 0.02 * np.sin(np.linspace(0, 60, n))
    st = States((u, u), (10 * u, 10 * u), (0.1, 0.1), {"k3": 2e4, "k4": 2e4, "d3": 1500.0, "d4": 1500.0})
    terms = [DamperAsymmetry(0)]
    prob = SimpleNamespace(pipe=SimpleNamespace(has_s=(False, False)))
    m, dof = 12, 2000
    tcrit = scipy.stats.t.isf(A.ALPHA / m / 2, dof)

    def notes(se, s_rms):
        tests = {"moment": {"tests": [(0.0, 0.0, se, dof, 0, 0)], "S": np.full((n, 1), s_rms)}}
        lim = A.detection_limit(0, tests, {"moment": 100.0}, m)
        assert lim == pytest.approx(max((tcrit + A.POWER_Z) * se, A.PRACTICAL * 100.0 / s_rms))
        return " ".join(A._could_not_show(prob, st, terms, tests, {"moment": 100.0}, m)[0])

    tiny_se = 1e-6
    # significant at any size, but the part explained by the largest size (0.23 x 1 N) is under 1 N
    assert "damper_asymmetry[d3] (spring travel s1 would show it)" in notes(tiny_se, 1.0)
    # the floor is met from theta = 0.1 (ratio 1.22): inside the usual sizes
    said = notes(tiny_se, 10.0)
    assert "damper_asymmetry[d3] smaller than a rebound/compression ratio of 1.22" in said
    # shows the smallest usual size (theta 0.07) too: nothing said
    assert notes(tiny_se, 1000.0) == ""
    assert math.isinf(A.detection_limit(0, {"moment": {"tests": [(0, 0, float("nan"), dof, 0, 0)],
                                                       "S": np.ones((n, 1))}}, {"moment": 1.0}, m))


def test_extra_spring_forces_add_their_signature_and_leave_the_original_alone(tmp_path):
    """``ResidualPipeline.with_extra``: the residuals of a model carrying extra spring forces are the
    linear model's plus the channels' response to those forces, computed apart
    (``_nonlinear.signatures``); the original pipeline is unchanged and ``with_extra(None)`` gives it
    back."""
    from jaxdrift.diagnosis.vehicle._nonlinear import signatures
    from jaxdrift.diagnosis.vehicle._residuals import ResidualPipeline
    from jaxdrift.io._corrections import NO_CORRECTION

    case = _case([], channels="beta_z3_s", duration=3.0)
    paths = gen.make_run(case, str(tmp_path), "run")
    run = jaxdrift.read_vehicle_run(paths["csv"])
    model = jaxdrift.read_model(paths["model"])
    pipe = ResidualPipeline(run)
    rng = np.random.default_rng(3)
    extra = (50.0 * rng.standard_normal(pipe.nf), 30.0 * rng.standard_normal(pipe.nf))
    base = pipe.residuals(model, NO_CORRECTION).channels
    with_x = pipe.with_extra(extra).residuals(model, NO_CORRECTION).channels
    sig = signatures(pipe, model, extra)
    assert set(sig) == set(base) - {"static"}
    for nm in sig:
        np.testing.assert_allclose(with_x[nm], base[nm] + sig[nm], rtol=1e-12, atol=1e-9)
        assert np.max(np.abs(sig[nm])) > 0
    assert pipe.extra is None
    again = pipe.with_extra(extra).with_extra(None).residuals(model, NO_CORRECTION).channels
    for nm in base:
        np.testing.assert_array_equal(again[nm], base[nm])


@pytest.mark.slow
def test_a_stop_does_not_hide_a_force_offset(tmp_path):
    """A stop 5x the front spring on 3 % of the samples and an offset of 40 N on f2, pitch and its
    rate measured only: the linear causes are chosen on a model that has the stop, so the offset is
    found (on the linear model alone a moved centre of gravity takes the stop's moment and the
    offset is not seen) and both lead the report."""
    case = _case([{"cause": "bump_stop", "parameter": "k3", "share": 0.03, "ratio": 5.0},
                  {"cause": "force_offset", "channel": "f2", "value": 40.0}], channels="beta_rate",
                 duration=12.0, noise=2.0)
    rep = _diagnose(tmp_path, case)
    first = {(f["cause"], f.get("parameter") or f.get("channel")) for f in rep["findings"][:2]}
    assert first == {("bump_stop", "k3"), ("force_offset", "f2")}, rep["findings"][:3]
    off = next(f for f in rep["findings"] if f["cause"] == "force_offset")
    assert off["interval"][0] <= 40.0 <= off["interval"][1]
    # the stop's travel is not measured here: the stiffness interval spans the travel's profile
    stop = rep["findings"][0] if rep["findings"][0]["cause"] == "bump_stop" else rep["findings"][1]
    assert stop["interval"][0] <= case["effects"][0]["value"] <= stop["interval"][1]


def test_linear_stand_in_for_an_unseen_stop_says_so():
    """Issue 35: where the run could not show a rear stop (no spring travel), a linear rear
    parameter finding says itself that it may stand in for one (not only the notes); a finding on
    the other axle, and a cause the run could show, do not. (On this project's generated runs a
    rear stop of 3-8x seen in pitch or pitch rate is found as the stop itself; the stand-in was
    met on an independent team's runs.)"""
    from jaxdrift.diagnosis.vehicle._report import _stand_ins

    ev = "a rate"
    given = [{"cause": "parameter_error", "parameter": "k4", "estimate": 1.19, "evidence": ev},
             {"cause": "parameter_error", "parameter": "k3", "estimate": 0.95, "evidence": ev},
             {"cause": "force_offset", "channel": "f2", "estimate": 40.0, "evidence": ev}]
    out = _stand_ins(given, [("bump_stop", 1), ("progressive_spring", 1), ("damper_asymmetry", 0)])
    assert out[0]["may_stand_in_for"] == ["bump_stop", "progressive_spring"] and "stand in" in out[0]["evidence"]
    assert "may_stand_in_for" not in out[1] and "may_stand_in_for" not in out[2]
    assert "may_stand_in_for" not in given[0]  # the records given are not changed
    d3 = [{"cause": "parameter_error", "parameter": "d3", "estimate": 1.3, "evidence": ev}]
    d3 = _stand_ins(d3, [("damper_asymmetry", 0), ("bump_stop", 0)])
    assert d3[0]["may_stand_in_for"] == ["damper_asymmetry"]


@pytest.mark.parametrize("channels,ratio", [("beta_z3_s", 2.0), ("beta_z3_s", 0.6), ("beta", 0.6)])
def test_damper_ratio_holds_whatever_share_of_the_mean_the_fit_took_first(tmp_path, channels, ratio):
    """Issue #47, item 3: a damper written "compression d, rebound rho d" (another generator's
    habit: the mean damping (1 + rho) / 2 times d). The adequacy test may run on the model with no
    causes (``select_with_form``), where nothing has taken the mean yet: the ratio is read with the
    mean that the test's own linear damper column finds beside the term, so it is rho there too, as
    on the model whose d4 carries the mean. Read as (1 + theta) / (1 - theta) it was 3.00 for 2
    (travel measured), 0.667 and 0.649 for 0.6, outside their intervals."""
    from benchmarks.validation.gen_vehicle import make_run
    from jaxdrift.diagnosis.vehicle._adequacy import assess_model_form
    from jaxdrift.diagnosis.vehicle._problem import _Problem
    from jaxdrift.diagnosis.vehicle._residuals import ResidualPipeline
    from jaxdrift.io._corrections import NO_CORRECTION

    case = _case([{"cause": "damper_asymmetry", "parameter": "d4", "value": ratio, "definition": "compression"}],
                 channels=channels, duration=8.0)
    paths = make_run(case, str(tmp_path), "run")
    model = jaxdrift.read_model(paths["model"])
    prob = _Problem(ResidualPipeline(jaxdrift.read_vehicle_run(paths["csv"])), model)
    for d4 in (1.0, (1.0 + ratio) / 2):  # the model as given, and with the mean's error fitted
        p = {**model, "d4": d4 * model["d4"]}
        form = assess_model_form(prob, p, NO_CORRECTION, prob.pipe.residuals(p, NO_CORRECTION), True)
        f = [g for g in form["findings"] if g["cause"] == "damper_asymmetry"]
        assert f and f[0]["parameter"] == "d4", form["findings"]
        assert f[0]["estimate"] == pytest.approx(ratio, rel=0.01), (d4, f[0])
        assert f[0]["interval"][0] <= ratio <= f[0]["interval"][1], (d4, f[0])


@pytest.mark.parametrize("effect,fs", [({"cause": "damper_asymmetry", "parameter": "d3", "value": 0.76}, 500.0),
                                       ({"cause": "bump_stop", "parameter": "k4", "share": 0.02, "ratio": 6.0}, 250.0)])
def test_nonlinear_size_holds_with_noise_on_the_measured_travel(tmp_path, effect, fs):
    """Issue #47, item 3: 0.1 mm of white noise on the measured spring travel (a string pot's
    level). A term of the travel's rate read off the noisy record is a function of a regressor with
    errors: the rate's noise folds through the kink of |s'| into the band it is compared in, and a
    damper ratio 0.76 read 0.740 [0.728, 0.751] here (0.759 read 0.716 on a generator run). With
    the noise found and taken out of the travel above its signal's band for the nonlinear terms,
    the interval holds the truth; a stop sized on that travel keeps its size; the report says what
    was taken out."""
    case = _case([effect], channels="beta_s", fs=fs, duration=10.0)
    case["motion_noise"] = {"beta": 3e-6, "s1": 1e-4, "s2": 1e-4}
    rep = _diagnose(tmp_path, case)
    truth = case["effects"][0]["value"]
    f = [g for g in rep["findings"] if g["cause"] == effect["cause"]]
    assert f and f[0]["parameter"] == effect["parameter"], rep["findings"]
    assert f[0]["interval"][0] <= truth <= f[0]["interval"][1], (truth, f[0]["estimate"], f[0]["interval"])
    assert f[0]["estimate"] == pytest.approx(truth, rel=0.03)
    # the size read off the travel as recorded is given beside it, half the difference in the interval
    shift = abs(f[0]["estimate_noisy_travel"] - f[0]["estimate"])
    assert f[0]["interval"][0] <= f[0]["estimate"] - 0.5 * shift + 1e-12 and "as recorded" in f[0]["evidence"]
    took = [n for n in rep["notes"] if "was taken out of it above" in n and "for the nonlinear terms" in n]
    levels = [float(n.split("(about ")[1].split(" m per sample")[0]) for n in took]
    assert len(levels) == 2 and all(abs(x / 1e-4 - 1) < 0.15 for x in levels), took


def test_a_size_pinned_at_the_end_of_its_range_is_not_confirmed(tmp_path):
    """A stop on a 250 Hz run with 0.3 mm of white noise on the measured travel (case 3 of
    ``benchmarks/validation/nonlinear_sizes.py``, seed 778100): its stiffness runs to the end of the
    plausible range, 30 x k4 (5.4 x the truth). That is no size: the finding stays, unconfirmed, and
    says so (named once the travel's noise is taken out for the terms, it was confirmed and went
    into the extended model)."""
    from benchmarks.validation import nonlinear_sizes as ns

    case = ns.case_for(3, 778100)
    case["motion_noise"] = {ch: (3e-4 if ch in ("s1", "s2") else 3e-6) for ch in case["channels"]}
    rep = _diagnose(tmp_path, case)
    f = [g for g in rep["findings"] if g["cause"] == "bump_stop"]
    assert f and f[0]["parameter"] == "k4", rep["findings"]
    assert f[0]["estimate"] == pytest.approx(30 * case["model"]["k4"], rel=1e-6)
    assert f[0]["confirmed"] is False and "not resolved" in f[0]["evidence"]
    assert "stop_k4" not in (rep["extended_model"].get("nonlinear") or {})
