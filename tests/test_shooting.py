"""Multiple shooting for the re-simulation check (``_shooting``): a restart moves the vehicle rigidly
(no spring or tyre changes its length) and is a no-op where the simulation already follows the
measured motion; a model with a wrong parameter is judged worse than the right one in every window
length, while the whole-run simulation of both drifts."""

from __future__ import annotations

import numpy as np
import pytest

from jaxdrift.diagnosis.vehicle._extend import _force_driven_pitch
from jaxdrift.diagnosis.vehicle._shooting import channel_errors, restart_state, shooting_states
from jaxdrift.models._halfcar import spring_travel_np
from jaxdrift.io import DEFAULT_MODEL
from jaxdrift.io._csvio import VehicleRun

CAR = dict(DEFAULT_MODEL)


def test_a_restart_moves_the_body_rigidly():
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.normal(0, 0.05, 4), rng.normal(0, 0.2, 4), rng.normal(0, 0.05, 2)])
    m = {"beta": 0.3, "dbeta": -0.7, "z3": 0.11, "dz3": 0.4}
    y = restart_state(x, CAR, m)
    assert [y[3], y[7], y[2], y[6]] == pytest.approx([m["beta"], m["dbeta"], m["z3"], m["dz3"]], abs=1e-15)
    s0, s1 = spring_travel_np(x, CAR["a"], CAR["b"]), spring_travel_np(y, CAR["a"], CAR["b"])
    for ch in ("s1", "s2", "ds1", "ds2"):  # spring lengths and their rates kept
        assert s1[ch] == pytest.approx(s0[ch], abs=1e-12)
    assert y[0] - y[8] == pytest.approx(x[0] - x[8], abs=1e-12)  # tyre deflections kept
    assert y[1] - y[9] == pytest.approx(x[1] - x[9], abs=1e-12)


def _run_of(model, n=3001, dt=0.002, seed=1):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    g = model["g"]
    base = [(model["m1"] + model["m3"] * model["b"] / (model["a"] + model["b"])) * g,
            (model["m2"] + model["m3"] * model["a"] / (model["a"] + model["b"])) * g]
    forces = {}
    for i, ch in enumerate(("f1", "f2")):
        w = np.cumsum(rng.normal(0, 1.0, n))
        w = np.convolve(w - w.mean(), np.ones(25) / 25, mode="same")
        forces[ch] = base[i] + 40.0 * w / np.std(w)
    ys = _force_driven_pitch(VehicleRun(path="x", t=t, channels={"f1": forces["f1"], "f2": forces["f2"]}),
                             [model], [forces])[0]
    sb = np.sin(ys[:, 3])
    cols = {**forces, "beta": ys[:, 3], "s1": ys[:, 2] - ys[:, 0] - model["b"] * sb,
            "s2": ys[:, 2] - ys[:, 1] + model["a"] * sb}
    return VehicleRun(path="x", t=t, channels=cols), forces


def test_restarts_are_a_no_op_on_a_run_the_model_simulates_exactly():
    run, forces = _run_of(CAR)
    full = _force_driven_pitch(run, [CAR], [forces])[0]
    ys = shooting_states(run, [CAR], [forces], 1000)[0]
    assert np.max(np.abs(ys - full)) < 1e-9


def test_the_right_model_beats_a_wrong_one_in_windows():
    """The run made by a car whose k3 is 0.8x the model's: the windowed errors of the right model
    are at the simulation's resolution, a hundred times below the model's, on the pitch and on the
    front spring travel the parameter explains."""
    true = dict(CAR, k3=0.8 * CAR["k3"])
    run, forces = _run_of(true)
    window = 1000  # the no-op test's compiled solve
    right, wrong = (channel_errors(run, y, p, window) for y, p in
                    zip(shooting_states(run, [true, CAR], [forces, forces], window), (true, CAR)))
    assert wrong["beta"] > 100 * right["beta"]
    assert wrong["s1"] > 100 * right["s1"]
