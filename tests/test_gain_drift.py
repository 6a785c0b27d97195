"""A force transducer's gain drifting over the run: the cause added by the catalogue's recipe
(docs/architecture.md, "Adding a cause"). Its correction against the generator's effect, and the
diagnosis finding it alone and beside an offset."""

import numpy as np
import pytest
from _sensor_runs import diagnosed_with_effects

from jaxdrift.diagnosis.vehicle._causes import FORCE_GAIN_DRIFT, VEHICLE_CAUSES, Cause, _apply, kind_named
from jaxdrift.io._corrections import Corrections, ForceCorrection
from jaxdrift.studies._rungen import apply_sensor_effects


def test_correction_inverts_the_generator_effect():
    """The generator's measured = (1 + r (t - t_mid)) s true + o; the record's correction gives the
    true force back to rounding (an independent formula: the generator writes its own)."""
    t = np.linspace(3.0, 23.0, 2001)
    true = {"t": t, "f1": 2000.0 + 300.0 * np.sin(2.0 * t), "f2": 1500.0 + 100.0 * np.cos(3.0 * t)}
    effects = [{"cause": "force_gain_drift", "channel": "f1", "value": 1.3e-3},
               {"cause": "force_scale", "channel": "f1", "value": 1.02},
               {"cause": "force_offset", "channel": "f1", "value": 40.0}]
    meas = apply_sensor_effects(true, effects, seed=0)
    corr = Corrections(f1=ForceCorrection(offset=40.0, gain=1 / 1.02, drift=1.3e-3))
    back = corr.apply(t, meas)
    assert np.max(np.abs(back["f1"] - true["f1"])) < 1e-9 * np.max(np.abs(true["f1"]))
    assert np.array_equal(back["f2"], meas["f2"])
    # the JSON form carries the drift and reads back the same record
    assert Corrections.from_json(corr.to_json()) == corr
    assert "drift" in corr.to_json()["f1"] and "drift" not in corr.to_json()["f2"]


def test_catalogue_entry():
    assert FORCE_GAIN_DRIFT in VEHICLE_CAUSES and kind_named("force_gain_drift") is FORCE_GAIN_DRIFT
    p, corr = _apply({"a": 1.0}, [Cause(FORCE_GAIN_DRIFT, "f2")], [2e-4])
    assert p == {"a": 1.0} and corr.f2.drift == 2e-4 and corr.f1.is_identity
    with pytest.raises(ValueError, match="unknown cause"):
        kind_named("force_gain_drfit")


@pytest.mark.parametrize("effects,seed", [
    pytest.param([{"cause": "force_gain_drift", "channel": "f2", "value": 8e-4}], 61, marks=pytest.mark.tier2),
    ([{"cause": "force_gain_drift", "channel": "f1", "value": -6e-4},
      {"cause": "force_offset", "channel": "f2", "value": 40.0}], 62),
])
def test_diagnosis_finds_the_drift(tmp_path, effects, seed):
    """20 s at 500 Hz, pitch and heave measured, 3 N of force noise (fixed seeds): the drift is a
    confirmed finding on its channel whose 95 % interval holds the true value, beside the offset."""
    rep = diagnosed_with_effects(tmp_path, effects, seed)
    drift = next(e for e in effects if e["cause"] == "force_gain_drift")
    assert rep["extended_model"]["corrections"][drift["channel"]]["drift"] == pytest.approx(drift["value"], rel=0.05)
