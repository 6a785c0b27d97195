"""Crosstalk between the force channels (``force_crosstalk``): a share of the other wheel's force
read in a channel. The kind was added by the recipe in ``CauseKind``'s docstring: its class and
nothing else outside tests and docs. Its correction against its own forward effect and against an
independent solve, and the diagnosis finding it alone and beside another sensor effect."""

import numpy as np
import pytest
from _sensor_runs import diagnosed_with_effects

from jaxdrift.diagnosis.vehicle import VEHICLE_CAUSES, apply_causes, kind_named
from jaxdrift.diagnosis.vehicle._causes import Cause
from jaxdrift.io._corrections import Corrections, unmix
from jaxdrift.studies._rungen import apply_sensor_effects

XT = kind_named("force_crosstalk")


def _true(t):
    return {"t": t, "f1": 3000.0 + 300.0 * np.sin(2.0 * t), "f2": 2500.0 + 200.0 * np.cos(3.0 * t)}


def test_the_correction_undoes_the_forward_effect():
    """Crosstalk both ways beside a scale and an offset: the kinds' forward effects (the generator)
    and the record their corrections build give the true forces back to rounding; the record's
    JSON carries ``leak`` and reads back the same record."""
    t = np.linspace(3.0, 23.0, 2001)
    true = _true(t)
    effects = [{"cause": "force_crosstalk", "channel": "f2", "value": 0.03},
               {"cause": "force_crosstalk", "channel": "f1", "value": -0.012},
               {"cause": "force_scale", "channel": "f2", "value": 1.02},
               {"cause": "force_offset", "channel": "f1", "value": 40.0}]
    meas = apply_sensor_effects(true, effects, seed=0)
    # the generator's order: crosstalk before the channel's own gain and offset
    assert np.allclose(meas["f2"], 1.02 * (true["f2"] + 0.03 * true["f1"]), rtol=0, atol=1e-9)
    assert np.allclose(meas["f1"], true["f1"] - 0.012 * true["f2"] + 40.0, rtol=0, atol=1e-9)
    causes = [Cause(XT, "f2"), Cause(XT, "f1"), Cause("force_scale", "f2"), Cause("force_offset", "f1")]
    theta = [0.03, -0.012, 1 / 1.02 - 1, 40.0]
    _, corr = apply_causes({}, causes, theta)
    back = corr.apply(t, meas)
    for ch in ("f1", "f2"):
        assert np.max(np.abs(back[ch] - true[ch])) < 1e-9 * np.max(np.abs(true[ch]))
    assert corr.to_json()["f2"]["leak"] == 0.03 and Corrections.from_json(corr.to_json()) == corr


def test_unmix_is_the_two_by_two_solve():
    """The closed form against numpy's solve of ``[[1, l1], [l2, 1]] f = g``, sample by sample."""
    rng = np.random.default_rng(5)
    g = rng.normal(size=(2, 50))
    l1, l2 = 0.04, -0.07
    f1, f2 = unmix(g[0], g[1], l1, l2)
    ref = np.linalg.solve(np.array([[1.0, l1], [l2, 1.0]]), g)
    assert np.allclose(np.stack([f1, f2]), ref, rtol=1e-13, atol=1e-13)
    g1, g2 = g
    a, b = unmix(g1, g2, 0.0, 0.0)
    assert a is g1 and b is g2  # no crosstalk: no arithmetic at all


def test_a_delayed_channel_reads_the_other_at_its_own_time():
    """A channel that lags reads the other channel's force as late as its own: the generator's
    forward effect and the correction agree to the linear interpolation's error."""
    fs = 500.0
    t = np.arange(0.0, 10.0, 1 / fs)
    d = 0.004
    late = _true(t - d)
    meas = apply_sensor_effects(_true(t), [{"cause": "force_delay", "channel": "f2", "value": d},
                                           {"cause": "force_crosstalk", "channel": "f2", "value": 0.05}],
                                seed=0, delayed={"f2": {"f1": late["f1"], "f2": late["f2"]}})
    assert np.allclose(meas["f2"], late["f2"] + 0.05 * late["f1"], rtol=0, atol=1e-9)
    _, corr = apply_causes({}, [Cause("force_delay", "f2"), Cause(XT, "f2")], [d, 0.05])
    back = corr.apply(t, meas)
    inner = slice(10, -10)
    # linear interpolation of a 300 N sine at 3 rad/s, 2 ms steps: error <= h^2/8 * 9 * 300 N
    assert np.max(np.abs(back["f2"][inner] - _true(t)["f2"][inner])) < 0.02


def test_registered_and_off_the_default_draws():
    assert XT in VEHICLE_CAUSES and XT.is_sensor and XT.target_key == "channel"
    from jaxdrift.studies import draw_effects

    assert all(e["cause"] != "force_crosstalk" for s in range(40) for e in draw_effects(s))
    drawn = draw_effects(3, kinds=["force_crosstalk"], noise=False)
    assert drawn[0]["cause"] == "force_crosstalk" and 0.01 <= abs(drawn[0]["value"]) <= 0.05


@pytest.mark.parametrize("effects,seed", [
    pytest.param([{"cause": "force_crosstalk", "channel": "f2", "value": 0.03}], 71, marks=pytest.mark.tier2),
    ([{"cause": "force_crosstalk", "channel": "f1", "value": -0.02},
      {"cause": "force_offset", "channel": "f2", "value": 60.0}], 72),
])
def test_the_diagnosis_finds_the_crosstalk(tmp_path, effects, seed):
    """20 s at 500 Hz, pitch and heave measured, 3 N of force noise (fixed seeds): the crosstalk is
    a confirmed finding on its channel whose 95 % interval holds the true share, beside the offset,
    and the extended model's correction carries it as ``leak``."""
    rep = diagnosed_with_effects(tmp_path, effects, seed)
    xt = next(e for e in effects if e["cause"] == "force_crosstalk")
    assert rep["extended_model"]["corrections"][xt["channel"]]["leak"] == pytest.approx(xt["value"], rel=0.05)
