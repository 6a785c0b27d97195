"""Vehicle diagnosis on runs it was not tuned on.

The runs come from ``generators_scipy`` (scipy LSODA on the seed's equations, its own road), not
from ``jaxdrift.studies._rungen`` which the detectors were developed on, with a van (a != b, heavier,
softer) instead of the seed's car, a rough road whose roughness reaches past the wheel-hop band
(a road spectrum up to 10 cycles/m: the motion's 4th difference is then nearly white, which the
earlier motion-noise test read as sensor noise), other seeds, and the values printed with 9 or 6
significant digits.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

import generators_scipy as gs
from jaxdrift.diagnosis.vehicle._pipeline import diagnose_vehicle_run
from jaxdrift.diagnosis.vehicle._problem import _Problem
from jaxdrift.diagnosis.vehicle._residuals import ResidualPipeline
from jaxdrift.io._csvio import VehicleRun

VAN = {"a": 1.6, "b": 1.9, "m1": 45.0, "m2": 55.0, "m3": 2400.0, "I": 3800.0,
       "k1": 3.2e5, "k2": 3.6e5, "k3": 6.0e4, "k4": 9.0e4,
       "d1": 3.0e2, "d2": 3.0e2, "d3": 5.0e3, "d4": 6.5e3, "g": 9.81}
FORCE_NOISE = 2.0
SYSTEMATIC = {"force_offset", "force_scale", "force_delay", "parameter_error"}


def _printed(x, digits):
    """x as written with ``digits`` significant digits (what a CSV writer with %.{d-1}e does)."""
    return np.array([float(f"{v:.{digits - 1}e}") for v in x])


def _run(cols, digits=None):
    cols = dict(cols)
    t = cols.pop("t")
    if digits is not None:
        cols = {k: _printed(v, digits) for k, v in cols.items()}
    return VehicleRun(path="independent", t=t, channels=cols)


def _make(seed, effects=(), true=None, fs=500.0, duration=8.0):
    p = dict(VAN if true is None else true)
    cols, _ = gs.make_run(p, duration=duration, fs=fs, speed=25.0, road_class="D", seed=seed,
                          effects=effects, noise_sigma=FORCE_NOISE, road_n_max=10.0, road_waves=120)
    return cols


@pytest.fixture(scope="module")
def clean_cols():
    return _make(seed=4101)


def _systematic(rep):
    return [f for f in rep["findings"] if f["cause"] in SYSTEMATIC]


@pytest.mark.parametrize("digits", [9, 6])
def test_clean_rough_road_run_has_no_finding_above_written_precision(clean_cols, digits):
    run = _run(clean_cols, digits)
    prob = _Problem(ResidualPipeline(run), VAN)
    for col, mn in prob.motion_noise.items():
        # noise reported on the motion is at most what printing the digits puts there
        assert mn["sigma"] <= 1.5 * mn["written"], (col, mn)
    rep = diagnose_vehicle_run(run, VAN, with_simulation=False)
    assert _systematic(rep) == [], rep["findings"]
    assert rep["findings"][0]["cause"] == "force_noise"
    assert FORCE_NOISE / 1.5 <= rep["findings"][0]["estimate"] <= 1.5 * FORCE_NOISE


def _measured_within_1_5x(cols, truth: dict, seed: int):
    """The problem of ``cols`` with white noise of ``truth`` (per column) added: each level is
    measured within 1.5x."""
    rng = np.random.default_rng(seed)
    cols = dict(cols)
    for col, s in truth.items():
        cols[col] = cols[col] + s * rng.standard_normal(len(cols[col]))
    prob = _Problem(ResidualPipeline(_run(cols, 9)), VAN)
    for col, s in truth.items():
        est = prob.motion_noise[col]["sigma"]
        assert s / 1.5 <= est <= 1.5 * s, (col, prob.motion_noise[col])
    return prob


def test_white_motion_noise_is_measured_within_1_5x(clean_cols):
    _measured_within_1_5x(clean_cols, {"beta": 3e-6, "z3": 1e-5, "s1": 2e-5, "s2": 2e-5}, 77)


def test_white_motion_noise_is_measured_on_a_short_run():
    """3.5 s at 200 Hz (700 samples, below the 1024 the measurement once asked for): pitch and
    heave noise of 5-9 urad / 20 um, which twice differentiated fill the whole band of the enforced
    moment and heave (a short campaign run read its inertia as 0.48 for 1.06 and its force noise as
    277 N for 4.5 N), is measured within 1.5x; the clean run reads no more than its digits."""
    cols = _make(seed=4102, fs=200.0, duration=3.5)
    prob = _Problem(ResidualPipeline(_run(cols, 9)), VAN)
    assert prob.pipe.n < 1024
    for col, mn in prob.motion_noise.items():
        assert mn["sigma"] <= 1.5 * mn["written"], (col, mn)
    prob = _measured_within_1_5x(cols, {"beta": 8e-6, "z3": 2e-5}, 78)
    assert {"moment", "heave"} <= set(prob.pipe.band)


def _moment_rms(cols):
    run = _run(cols, 9)
    pipe = ResidualPipeline(run)
    from jaxdrift.io._corrections import NO_CORRECTION as zero
    r = pipe.residuals(VAN, zero).channels["moment"]
    return float(np.sqrt(np.mean(r[:-pipe.trim] ** 2)))


def test_inertia_and_delay_at_the_same_residual_size_are_told_apart():
    """An inertia error and a delay on f2 sized to give the same enforced-moment RMS: each run
    names its own cause first, and the other cause is not reported as a finding."""
    seed = 4202
    inertia = _make(seed, true={**VAN, "I": 1.10 * VAN["I"]})
    d0 = 0.004
    probe = _make(seed, effects=[{"cause": "force_delay", "channel": "f2", "value": d0}])
    target, got = _moment_rms(inertia), _moment_rms(probe)
    d1 = d0 * target / got  # the residual of a small delay is linear in it
    delay = _make(seed, effects=[{"cause": "force_delay", "channel": "f2", "value": d1}])
    assert abs(_moment_rms(delay) / target - 1.0) < 0.1
    rep_i = diagnose_vehicle_run(_run(inertia, 9), VAN, with_simulation=False)
    rep_d = diagnose_vehicle_run(_run(delay, 9), VAN, with_simulation=False)
    fi, fd = _systematic(rep_i), _systematic(rep_d)
    assert fi and fi[0]["cause"] == "parameter_error" and fi[0]["parameter"] == "I", rep_i["findings"]
    assert fi[0]["interval"][0] <= 1.10 <= fi[0]["interval"][1]
    assert fd and fd[0]["cause"] == "force_delay" and fd[0]["channel"] == "f2", rep_d["findings"]
    assert fd[0]["interval"][0] <= d1 <= fd[0]["interval"][1]
    assert not any(f["cause"] == "force_delay" for f in fi)
    assert not any(f["cause"] == "parameter_error" and f["parameter"] == "I" for f in fd)
    _check_evidence(rep_i)
    _check_evidence(rep_d)


_EVIDENCE = re.compile(r"its RMS (falls|rises) from (\S+) to (\S+) (N m|N) when it is corrected "
                       r"\(z = (\S+), noise level (\S+) N\)")


def _check_evidence(rep):
    """Each systematic finding's sentence cites the numbers of its own fields."""
    noise = [f for f in rep["findings"] if f["cause"] == "force_noise"]
    for f in _systematic(rep):
        m = _EVIDENCE.search(f["evidence"])
        assert m, f["evidence"]
        verb, a, b, unit, z, sig = m.groups()
        res = f["residual"]
        assert float(a) == float(f"{res['rms_without']:.4g}")
        assert float(b) == float(f"{res['rms_with']:.4g}")
        assert unit == res["unit"]
        assert verb == ("falls" if res["rms_with"] < res["rms_without"] else "rises")
        assert float(z) == round(f["z"], 1)
        if noise:
            assert float(sig) == float(f"{noise[0]['estimate']:.3g}")


def test_evidence_sentences_cite_the_report_numbers():
    cols = _make(4303, effects=[{"cause": "force_offset", "channel": "f1", "value": 80.0}])
    rep = diagnose_vehicle_run(_run(cols, 9), VAN, with_simulation=False)
    assert _systematic(rep)[0]["cause"] == "force_offset"
    _check_evidence(rep)
    em = rep["simulation_error"]["enforced_moment"]
    assert em["band_hz"] == [0.0, 250.0]


def test_a_correction_that_makes_the_simulated_pitch_worse_stays_out():
    """FIELD-NOTES: a spurious inertia x0.55 next to a right finding made the extended model's
    force-driven pitch error 12x worse. Given such a selection (the true 80 N offset on f1 and a
    spurious I x 0.55), the re-simulation check drops the inertia and keeps the offset."""
    from jaxdrift.diagnosis.vehicle._causes import Cause
    from jaxdrift.diagnosis.vehicle._confirm import confirm_by_resimulation
    from jaxdrift.diagnosis.vehicle._problem import _gauss_newton
    from jaxdrift.diagnosis.vehicle._select import Selection

    cols = _make(4404, effects=[{"cause": "force_offset", "channel": "f1", "value": 80.0}])
    prob = _Problem(ResidualPipeline(_run(cols, 9)), VAN)
    causes = [Cause("force_offset", "f1"), Cause("parameter_error", "I")]
    fit = _gauss_newton(prob, causes, np.array([80.0, -0.45]), iters=0)
    sel = Selection(fit, np.eye(2), 1.0, np.array([10.0, 5.0]), {}, [], {}, fit.rss, [fit.rss])
    new, dropped = confirm_by_resimulation(prob, sel)
    assert [c.label for c, *_ in dropped] == ["parameter_error[I]"]
    _, _, channel, before, after, without = dropped[0]
    assert without < 0.9 * after
    assert [c.label for c in new.fit.causes] == ["force_offset[f1]"]
    assert abs(new.fit.theta[0] - 80.0) < 2.0


# --------------------------------------------------------------- road content the forces share
def _shared_run(rng, n, fs, lag_samples=None, content=0.0, noise=1.0):
    """Two forces: independent white noise, plus (``content``) a jump process the rear force meets
    ``lag_samples`` later (a road of straight lines under both wheels)."""
    t = np.arange(n) / fs
    f1 = noise * rng.standard_normal(n)
    f2 = noise * rng.standard_normal(n)
    if content:
        c = np.cumsum(content * rng.standard_normal(n + lag_samples))
        f1 = f1 + c[lag_samples:]
        f2 = f2 + c[:n]
    return VehicleRun("shared.csv", t, {"f1": f1 + 4000.0, "f2": f2 + 4500.0})


def test_shared_top_band_test_holds_its_false_alarm_rate_and_finds_road_content():
    """Independent noise on the two transducers is flagged as shared in at most its promised 1 %
    (100 pairs of 6000 samples: at most 3, the binomial allowance); a road both wheels meet 90 ms
    apart is flagged at that lag where its jumps give half the noise's level in the 4th
    differences (the 4th, 6th and 8th differences of such content agree as white noise's do, so
    only this test tells it from noise)."""
    from jaxdrift.diagnosis.vehicle._detectors import SHARED_ALPHA, force_top_band_shared

    rng = np.random.default_rng(20261205)
    alarms = sum(force_top_band_shared(_shared_run(rng, 6000, 1000.0)) is not None for _ in range(100))
    assert alarms <= 100 * SHARED_ALPHA + 1.645 * np.sqrt(100 * SHARED_ALPHA * (1 - SHARED_ALPHA)) + 1, alarms
    for _ in range(10):
        got = force_top_band_shared(_shared_run(rng, 6000, 1000.0, lag_samples=90, content=1.0))
        assert got is not None and abs(got[0] - 0.090) < 1.5e-3 and got[1] > got[2]


def test_force_noise_on_a_road_of_straight_lines_is_an_upper_bound(tmp_path):
    """The independent generator's road of straight lines between profile points 5 cm apart (the
    seed car at 15 m/s, 1 kHz, 2 N of force noise, pitch and heave): the tyre force jumps at every
    point, and the residual's low band reads 4-5 N (measured on 4 roads). The report must not call
    that an estimate: an upper bound that holds the 2 N, with the shared content named."""
    import jaxdrift
    from benchmarks.validation import gen_vehicle as gv
    from jaxdrift.io._csvio import DEFAULT_MODEL

    case = gv.make_case({"index": 0, "stratum": "noise", "what": [], "seed": 1, "design": "probe"},
                        durations=(8.0, 8.0), rates=(1000,))
    case.update(model={k: float(DEFAULT_MODEL[k]) for k in gv.KEYS}, road_class="C", speed=15.0,
                road_interp="linear", channel_set="beta_z3", channels=["beta", "z3"], motion_noise={},
                effects=[{"cause": "force_noise", "value": 2.0}])
    paths = gv.make_run(case, str(tmp_path), name="straight")
    rep = jaxdrift.diagnose_vehicle_run(jaxdrift.read_vehicle_run(paths["csv"]), jaxdrift.read_model(paths["model"]))
    noise = [f for f in rep["findings"] if f["cause"] == "force_noise"]
    assert len(noise) == 1 and noise[0]["estimate_kind"] == "upper_bound"
    assert noise[0]["interval"][0] == 0.0 and noise[0]["interval"][1] >= 2.0
    assert "share that content" in noise[0]["evidence"]
    assert not [f for f in rep["findings"] if f.get("confirmed") and f["cause"] not in ("force_noise", "none")]
