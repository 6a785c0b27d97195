"""Vehicle diagnosis with white sensor noise on the measured motion, and selections that forward
selection alone gets wrong.

Runs from the independent generator (``benchmarks/validation/gen_vehicle.py``: scipy DOP853, its
own ISO 8608 road, vehicles other than the seed's), with seeds not used for tuning (the diagnosis
was tuned on design seeds 31 and 777; the committed sweep uses 20261201).
"""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

from benchmarks.validation import gen_vehicle as gv

import jaxdrift  # noqa: E402

SYSTEMATIC = {"force_offset", "force_scale", "force_delay", "parameter_error"}


def _diagnose(tmp_path, seed, **over):
    case = gv.make_case({"index": 0, "stratum": "single", "what": [["force_offset", "f1"]], "seed": seed},
                        durations=(20.0, 20.0), rates=(500,))
    case.update(over)
    paths = gv.make_run(case, str(tmp_path), f"run{seed}")
    run = jaxdrift.read_vehicle_run(paths["csv"])
    model = jaxdrift.read_model(paths["model"])
    rep = jaxdrift.diagnose_vehicle_run(run, model, with_simulation=False)
    return rep, case


def _target(f):
    return f["cause"], f.get("channel") or f.get("parameter")


NOISY_MOTION = dict(road_class="C", speed=22.0, fs=500.0, duration=20.0,
                    channel_set="beta_z3", channels=["beta", "z3"], precision=8,
                    motion_noise={"beta": 6e-5, "z3": 6e-5})


@pytest.mark.parametrize("seed", [5151, pytest.param(5152, marks=pytest.mark.tier2)])
def test_strong_motion_noise_alone_is_no_systematic_finding(tmp_path, seed):
    """6e-5 rad / m of white noise on pitch and heave (500 Hz, road C) and 1 N of force noise, no
    effect: the low-passed channels must not ring with the differentiated noise (before the taper
    such a run named a damper x0.58 at z = 6 and a force noise of 53 N)."""
    rep, _ = _diagnose(tmp_path, seed, **NOISY_MOTION, effects=[{"cause": "force_noise", "value": 1.0}])
    systematic = [f for f in rep["findings"] if f["cause"] in SYSTEMATIC]
    assert not systematic, rep["findings"]
    assert rep["findings"][0]["cause"] in ("force_noise", "none")
    noise = [f["estimate"] for f in rep["findings"] if f["cause"] == "force_noise"]
    assert all(s < 10.0 for s in noise), noise  # not the 53 N of the ringing filter


def test_small_delay_under_motion_noise_is_named_not_a_parameter(tmp_path):
    """A 0.4 ms delay on f1 under the same motion noise: named first, its interval holds it."""
    delay = 4e-4
    rep, _ = _diagnose(tmp_path, 5153, **NOISY_MOTION,
                       effects=[{"cause": "force_delay", "channel": "f1", "value": delay},
                                {"cause": "force_noise", "value": 1.0}])
    first = rep["findings"][0]
    assert _target(first) == ("force_delay", "f1"), rep["findings"]
    assert first["interval"][0] <= delay <= first["interval"][1]


def test_offset_and_scale_are_not_replaced_by_a_mass_and_equal_offsets(tmp_path):
    """An offset on f1 and a scale on f2, pitch only, 200 Hz: forward selection took an offset on
    f2 for the scale's static part and mended the rest with equal offsets and a chassis-mass
    error; the best-subset check finds the two causes that explain the run."""
    rep, _ = _diagnose(tmp_path, 5154, road_class="A", speed=28.0, fs=200.0,
                       duration=12.0, channel_set="beta", channels=["beta"], precision=9, motion_noise={},
                       effects=[{"cause": "force_offset", "channel": "f1", "value": -100.0},
                                {"cause": "force_scale", "channel": "f2", "value": 1.03},
                                {"cause": "force_noise", "value": 0.3}])
    first_two = {_target(f) for f in rep["findings"][:2]}
    assert first_two == {("force_offset", "f1"), ("force_scale", "f2")}, rep["findings"]
    off = next(f for f in rep["findings"] if _target(f) == ("force_offset", "f1"))
    assert off["interval"][0] <= -100.0 <= off["interval"][1]


def test_offsets_on_both_forces_are_two_offsets_not_one_and_gravity(tmp_path):
    """Offsets of +60 N on f1 and -65 N on f2, pitch only, 200 Hz: with g a candidate the report
    said one offset of -104 N and g x1.009 (the same span); g is no longer a candidate."""
    rep, _ = _diagnose(tmp_path, 5155, road_class="D", speed=9.0, fs=200.0, duration=12.0,
                       channel_set="beta", channels=["beta"], precision=7, motion_noise={},
                       effects=[{"cause": "force_offset", "channel": "f1", "value": 60.0},
                                {"cause": "force_offset", "channel": "f2", "value": -65.0},
                                {"cause": "force_noise", "value": 1.5}])
    first_two = {_target(f) for f in rep["findings"][:2]}
    assert first_two == {("force_offset", "f1"), ("force_offset", "f2")}, rep["findings"]
    assert not any(f.get("parameter") == "g" for f in rep["findings"])
    for f in rep["findings"][:2]:
        true = 60.0 if f["channel"] == "f1" else -65.0
        assert f["interval"][0] <= true <= f["interval"][1], f


SMALL_NOISE = dict(road_class="D", speed=12.0, fs=1000.0, duration=12.0, channel_set="all",
                   channels=["beta", "z3", "s1", "s2"], precision=8, motion_noise={})


@pytest.mark.parametrize("seed,level", [pytest.param(5161, 0.3, marks=pytest.mark.tier2), (5162, 0.2)])
def test_small_force_noise_is_reported_at_1000_hz(tmp_path, seed, level):
    """0.2-0.3 N of force noise next to an offset, 1000 Hz, rough road D, motion written with 8
    digits: below the old 0.5 N floor, and the forces' 4th differences hold road content (so
    they do not confirm it). Only content above 960 Hz folds into the low band, so the level is
    reported, within 1.5x and inside its interval (it was not reported before)."""
    effects = [{"cause": "force_offset", "channel": "f1", "value": 20.0},
               {"cause": "force_noise", "value": level}]
    rep, _ = _diagnose(tmp_path, seed, **SMALL_NOISE, effects=effects)
    got = [_target(f) for f in rep["findings"]]
    assert got[0] == ("force_offset", "f1"), rep["findings"]
    noise = [f for f in rep["findings"] if f["cause"] == "force_noise"]
    assert noise, rep["findings"]
    lo, hi = noise[0]["interval"]
    assert lo <= level <= hi and 1 / 1.5 <= noise[0]["estimate"] / level <= 1.5, noise[0]


def test_noise_free_500_hz_rough_run_reports_no_noise(tmp_path):
    """The same rule on a run without force noise (500 Hz, road E, 6 digits): no noise level, the
    offset alone, and the noise stated as an upper bound [0, b] (issue 35: never silence) with b
    under 1 N. (The low band reads 0.13 N here, from the rounding of the motion written with 6
    digits: the rule asks for 8.)"""
    over = dict(SMALL_NOISE, fs=500.0, road_class="E", speed=9.0, precision=6)
    rep, _ = _diagnose(tmp_path, 5163, **over,
                       effects=[{"cause": "force_offset", "channel": "f1", "value": 20.0}])
    assert [f["cause"] for f in rep["findings"]] == ["force_offset", "force_noise"], rep["findings"]
    bound = rep["findings"][1]
    assert bound["estimate_kind"] == "upper_bound" and bound["interval"][0] == 0.0
    assert bound["estimate"] <= bound["interval"][1] < 1.0, bound


@pytest.mark.parametrize("seed,level,fs,road", [(5171, 0.7, 500.0, "C"), (5172, 1.5, 250.0, "D"),
                                                     pytest.param(5173, 4.0, 500.0, "B", marks=pytest.mark.tier2)])
def test_effect_free_run_always_states_its_noise(tmp_path, seed, level, fs, road):
    """Issue 35: an effect-free run with 0.7-4 N of force noise says something about it: a level
    whose interval holds the truth, or an upper bound [0, b] with b at least the truth."""
    over = dict(road_class=road, speed=15.0, fs=fs, duration=10.0, channel_set="all",
                channels=["beta", "z3", "s1", "s2"], precision=8, motion_noise={})
    rep, _ = _diagnose(tmp_path, seed, **over, effects=[{"cause": "force_noise", "value": level}])
    noise = [f for f in rep["findings"] if f["cause"] == "force_noise"]
    assert noise, rep["findings"]
    lo, hi = noise[0]["interval"]
    assert lo <= level <= hi, noise[0]
    if noise[0]["estimate_kind"] == "upper_bound":
        assert lo == 0.0


def test_out_of_sample_check_tells_a_fitted_noise_from_a_cause():
    """The confirmation's out-of-sample check (``_confirm.out_of_sample_t``: sized on alternate
    stretches, judged on the others) on a coloured residual (AR(1), 0.95; 4000 samples) and a
    coloured regressor: a correction fitted to the noise alone passes in 60 of 200 draws here (at
    most 80 allowed: a third, and 1.645 binomial standard deviations), where the whole-run fit
    always 'improves' it; a true cause of 0.4 of the noise's RMS passes in all 200 (at least 196),
    one of 0.25 in 189."""
    import numpy as np
    import scipy.signal

    from jaxdrift.diagnosis.vehicle._confirm import out_of_sample_t

    rng = np.random.default_rng(1)

    def coloured(n):
        return scipy.signal.lfilter([1.0], [1.0, -0.95], rng.standard_normal(n))

    spurious = true = 0
    for _ in range(200):
        noise, g = coloured(4000), coloured(4000)
        th = (noise @ g) / (g @ g)
        spurious += out_of_sample_t(noise, noise - th * g) > 0
        a = noise + 0.4 * g * np.std(noise) / np.std(g)
        th = (a @ g) / (g @ g)
        true += out_of_sample_t(a, a - th * g) > 0
    assert spurious <= 80, spurious
    assert true >= 196, true
