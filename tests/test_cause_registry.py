"""One abstract cause (issue 32): every registered cause of both diagnoses is an
``AbstractCause`` whose capabilities are mixins, and nothing in the library dispatches on a
concrete cause class. Parametrised over the registry, so a cause added later is checked too."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import numpy as np
import pytest

from jaxdrift.diagnosis import (AbstractCause, DegreeOfFreedom, ModelParameter, NoiseLevel, RateEffect, SensorEffect, SignalDetector,
                                StateForce, registered_causes)
from jaxdrift.diagnosis.attitude import gyro_forward, gyro_inverse
from jaxdrift.diagnosis.vehicle import cause_names

REGISTRY = registered_causes()
ALL = [(dom, c) for dom, cs in REGISTRY.items() for c in cs]
IDS = [f"{dom}:{c!r}:{i}" for i, (dom, c) in enumerate(ALL)]
CAPABILITIES = (SensorEffect, ModelParameter, StateForce, SignalDetector, NoiseLevel, RateEffect, DegreeOfFreedom)


@pytest.mark.parametrize("dom,cause", ALL, ids=IDS)
def test_every_registered_cause_is_an_abstract_cause(dom, cause):
    assert isinstance(cause, AbstractCause)
    assert not inspect.isabstract(type(cause)), f"{type(cause).__name__} leaves abstract methods"
    assert isinstance(cause.name, str) and cause.unit is not None
    assert repr(cause) == cause.name


def test_the_registry_holds_every_name_the_diagnoses_report():
    vehicle = {c.name for c in REGISTRY["vehicle"] if c.name}
    assert set(cause_names()) | {"force_noise"} <= vehicle
    attitude = [c.name for c in REGISTRY["attitude"]]
    assert len(attitude) == len(set(attitude))
    assert {"gyro_noise", "gyro_bias", "vibration"} <= set(attitude)


@pytest.mark.parametrize("cause", [c for _, c in ALL if isinstance(c, SensorEffect)], ids=repr)
def test_a_sensor_effect_at_theta_zero_changes_nothing(cause):
    from jaxdrift.io._corrections import ForceCorrection

    ident = ForceCorrection()
    assert cause.adjust(ident, 0.0) == ident


@pytest.mark.parametrize("cause", [c for _, c in ALL if isinstance(c, SensorEffect)], ids=repr)
def test_a_sensor_effect_is_applied_by_its_own_forward(cause):
    """The forward effect of a non-zero size changes the measured forces, of zero size not (for a
    time shift, the channel's read times carry it); sizes as the report states them
    (``to_estimate`` of theta 0 and 0.01)."""
    t = np.linspace(0.0, 2.0, 201)
    true = {"f1": 1000.0 + 50.0 * np.sin(3 * t), "f2": 2000.0 + 80.0 * np.cos(2 * t)}

    for value, changes in ((cause.to_estimate(0.0), False), (cause.to_estimate(0.01), True)):
        shift = cause.time_shift(value)

        def read(ch, s=shift):  # the channel being changed reads at its own time
            return {k: np.interp(t - (s if ch == "f1" else 0.0), t, v) for k, v in true.items()}

        read.t = t
        out = cause.forward({k: v.copy() for k, v in true.items()}, "f1", value, read)
        moved = not np.allclose(out["f1"], true["f1"]) or shift != 0.0
        assert moved == changes, (cause, value)


RATE_EFFECTS = [c for _, c in ALL if isinstance(c, RateEffect)]


def test_the_gyro_scale_and_bias_are_rate_effects():
    assert {c.name for c in RATE_EFFECTS} == {"gyro_scale", "gyro_bias"}
    assert len({c.forward_stage for c in RATE_EFFECTS}) == len(RATE_EFFECTS)


@pytest.mark.parametrize("cause", RATE_EFFECTS, ids=repr)
def test_a_rate_effect_is_undone_by_its_inverse(cause):
    """Forward then inverse gives the rates back, for a value per axis and for a path; the value
    that means 'no effect' (a bias of 0, a scale of 1) changes nothing; another value does."""
    rng = np.random.default_rng(3)
    w = rng.normal(size=(500, 3)) * 0.3
    none = 1.0 if cause.name == "gyro_scale" else 0.0
    for value in (np.array([1.03, 0.98, 1.001]) if none else np.array([2e-3, -1e-3, 5e-4]),
                  none + 0.01 * rng.normal(size=(500, 3))):
        fwd = cause.forward(w, value)
        assert not np.allclose(fwd, w)
        np.testing.assert_allclose(cause.inverse(fwd, value), w, rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(cause.forward(w, np.full(3, none)), w)


def test_the_gyro_chain_scales_then_adds_and_is_undone_in_reverse():
    """``gyro_forward`` is the sensor written out by hand (scale x true + additive errors), and
    ``gyro_inverse`` with the same scale and bias gives the true rates back."""
    rng = np.random.default_rng(4)
    w = rng.normal(size=(400, 3))
    scale, bias = np.array([1.02, 0.97, 1.0]), np.array([1e-3, 0.0, -2e-3])
    meas = gyro_forward(w, scale, bias)
    np.testing.assert_array_equal(meas, scale * w + bias)
    np.testing.assert_allclose(gyro_inverse(meas, scale, bias), w, rtol=1e-13, atol=1e-15)


def test_a_gyro_run_generated_by_the_forward_chain_is_found_and_corrected(tmp_path):
    """The contract of the attitude's rate effects on a generated run (seed and sizes not used
    elsewhere): the generator records ``gyro_forward`` of the true rates, the diagnosis names the
    bias and the scale with intervals holding the truth, and its corrections put through
    ``gyro_inverse`` bring the recorded rates back to the true ones up to the white noise."""
    from jaxdrift.diagnosis.attitude import run_attitude_diagnosis
    from jaxdrift.studies._attgen import make_attitude_run

    arw, bias, scale = 3.5e-4, (0.0, 1.2e-3, 0.0), (0.975, 1.0, 1.0)
    tr = make_attitude_run(str(tmp_path), 141, name="run141", arw=arw, bias=bias, scale=scale,
                           duration=40.0, rate_hz=200.0, curve_rate=0.25, road_rms_deg=1.0)
    meas = gyro_forward(tr["w_true"], tr["scale"], tr["gyro_error"])
    rep = run_attitude_diagnosis(tr["paths"]["run"], tr["paths"]["sensors"], None)
    found = {(f["cause"], f.get("channel")): f for f in rep["findings"]}
    for key, true in ((("gyro_bias", "wy"), 1.2e-3), (("gyro_scale", "wx"), 0.975)):
        lo, hi = found[key]["interval"]
        assert lo <= true <= hi, (key, found[key])
    corr = rep["extended_model"]["corrections"]
    s_est = np.array([corr[c]["scale"] for c in ("wx", "wy", "wz")])
    b_est = np.array([corr[c]["bias"] for c in ("wx", "wy", "wz")])
    err_before = meas - tr["w_true"]
    err_after = gyro_inverse(meas, s_est, b_est) - tr["w_true"]
    white = arw / np.sqrt(tr["dt"])  # the per-sample noise the correction cannot take out
    # before: the scale error on the x rate and the y bias stand far above the noise; after, the
    # mean error of each axis is within 5 standard errors of the noise's mean, and the x axis's
    # error no longer follows its rate
    n = len(meas)
    assert abs(err_before[:, 1].mean()) > 20 * white / np.sqrt(n)
    assert np.all(np.abs(err_after.mean(0)) < 5 * white / np.sqrt(n))
    slope = np.polyfit(tr["w_true"][:, 0], err_after[:, 0], 1)[0]
    assert abs(slope) < 0.1 * abs(np.polyfit(tr["w_true"][:, 0], err_before[:, 0], 1)[0])


def test_a_detector_finds_nothing_in_a_force_that_never_lifts():
    (det,) = [c for c in REGISTRY["vehicle"] if isinstance(c, SignalDetector)][:1]
    f = 3000.0 + 100.0 * np.sin(np.linspace(0, 60, 5000))
    assert det.detect(f, 5.0) is None


def test_every_cause_has_one_capability_at_most_of_each_family():
    """Vehicle kinds are a sensor effect or a model parameter, never both; state forces and
    detectors are neither."""
    for c in REGISTRY["vehicle"]:
        caps = [cap.__name__ for cap in CAPABILITIES if isinstance(c, cap)]
        assert len(caps) == 1, (c, caps)


def _concrete_cause_classes() -> set[str]:
    return {type(c).__name__ for _, c in ALL}


def test_nothing_dispatches_on_a_concrete_cause_class():
    """No ``isinstance`` against a concrete cause class anywhere in jaxdrift/ (capabilities are
    asked of the mixins); the check reads the source, so it fails on a new one."""
    names = _concrete_cause_classes()
    root = Path(__file__).resolve().parents[1] / "jaxdrift"
    bad = []
    for path in root.rglob("*.py"):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "isinstance" and len(node.args) == 2:
                arg = node.args[1]
                elts = arg.elts if isinstance(arg, ast.Tuple) else [arg]
                for e in elts:
                    nm = getattr(e, "id", None) or getattr(e, "attr", None)
                    if nm in names:
                        bad.append(f"{path.relative_to(root.parent)}:{node.lineno} isinstance(..., {nm})")
    assert not bad, bad
