"""One abstract cause (issue 32): every registered cause of both diagnoses is an
``AbstractCause`` whose capabilities are mixins, and nothing in the library dispatches on a
concrete cause class. Parametrised over the registry, so a cause added later is checked too."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import numpy as np
import pytest

from jaxdrift.diagnosis import (AbstractCause, ModelParameter, NoiseLevel, SensorEffect, SignalDetector, StateForce,
                                registered_causes)
from jaxdrift.diagnosis.vehicle import cause_names

REGISTRY = registered_causes()
ALL = [(dom, c) for dom, cs in REGISTRY.items() for c in cs]
IDS = [f"{dom}:{c!r}:{i}" for i, (dom, c) in enumerate(ALL)]
CAPABILITIES = (SensorEffect, ModelParameter, StateForce, SignalDetector, NoiseLevel)


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
