"""The contract every registered attitude cause keeps, one case per cause (the attitude side of
``tests/test_cause_contract.py``): a run of the independent generator
(``benchmarks/validation/gen_attitude.py``, its own motion, integrator and sensor chain) with that
cause alone, beside white gyro noise, is diagnosed; the cause is named (first among the systematic
findings where it is one), its 95 % interval holds the true size, and a correctable cause's
correction is in the extended model.

``jaxdrift.diagnosis.registered_causes()["attitude"]`` decides which causes there are: a cause
added there without a case here, or without a named test elsewhere (``ELSEWHERE``: the causes that
need a run the generator does not make), fails ``test_every_registered_attitude_cause_has_a_case``.
Seeds 9301-9307 and the sizes are used nowhere else.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from benchmarks.validation import gen_attitude as ga
from jaxdrift import run_attitude_diagnosis
from jaxdrift.diagnosis import registered_causes

SYSTEMATIC = {"gyro_bias", "gyro_scale", "gyro_bias_drift", "sensor_position", "nonrigid"}

#: cause -> (seed, the effect's fields besides the cause, the finding's key field)
CASES = {
    "gyro_noise": (9301, {"value": 4.0e-4}, None),
    "gyro_bias": (9302, {"channel": "wy", "value": 1.5e-3}, "channel"),
    "gyro_scale": (9303, {"channel": "wz", "value": 1.03}, "channel"),
    "gyro_bias_drift": (9304, {"channel": "wx", "value": 4.0e-4}, "channel"),
    "sensor_position": (9305, {"sensor": 2, "value": [0.012, -0.015, 0.006]}, "sensor"),
    "nonrigid": (9306, {"value": 0.1}, None),
    "accel_noise": (9307, {"value": 0.03}, None),
}
#: causes the generator cannot make, and the test (file, function) that generates and finds each
ELSEWHERE = {
    "vibration": ("test_attitude_vibration.py", "test_vibration_is_named_and_the_bias_kept"),
    "reference_inconsistent": ("test_attitude_real.py",
                               "test_vibration_is_a_bound_and_does_not_hide_a_bias_and_a_reset_is_named"),
}


def test_every_registered_attitude_cause_has_a_case():
    names = {c.name for c in registered_causes()["attitude"]}
    assert set(CASES) | set(ELSEWHERE) == names, "a registered attitude cause without a contract case"
    here = Path(__file__).resolve().parent
    for file, func in ELSEWHERE.values():
        tree = ast.parse((here / file).read_text())
        assert func in {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}, (file, func)


def _inside(interval, true) -> bool:
    lo, hi = np.asarray(interval[0], float), np.asarray(interval[1], float)
    return bool(np.all((lo <= np.asarray(true)) & (np.asarray(true) <= hi)))


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_generated_run_of_one_attitude_cause_is_found(tmp_path, name):
    seed, fields, key = CASES[name]
    case = ga.make_case({"index": 0, "stratum": "single", "what": [] if name == "gyro_noise" else [name],
                         "seed": seed}, durations=(60.0, 60.0), rates=(200,))
    effect = {"cause": name, **fields}
    noise = {"cause": "gyro_noise", "value": 3.0e-4}
    case["effects"] = [effect] if name == "gyro_noise" else [noise, effect]
    case["reference_every"] = 1
    if name in ("sensor_position", "nonrigid", "accel_noise") and case["positions"] is None:
        case["positions"] = ga.draw_array(np.random.default_rng(seed)).tolist()
    paths = ga.make_run(case, str(tmp_path), "run")
    rep = run_attitude_diagnosis(paths["csv"], paths["sensors"])
    mine = [f for f in rep["findings"] if f["cause"] == name
            and (key is None or f.get(key) == fields[key])]
    assert len(mine) == 1, rep["findings"]
    f = mine[0]
    assert _inside(f["interval"], fields["value"]), (f["estimate"], f["interval"], fields["value"])
    if name in SYSTEMATIC:
        first = next(g for g in rep["findings"] if g["cause"] in SYSTEMATIC)
        assert first is f or first == f, rep["findings"]
    corr = rep["extended_model"]["corrections"]
    if name == "gyro_bias":
        assert corr["wy"]["bias"] == f["estimate"]
    elif name == "gyro_scale":
        assert corr["wz"]["scale"] == f["estimate"]
    elif name == "sensor_position":  # the correction is the displacement, the others' none
        assert corr["sensor2"]["position"] == f["estimate"]
        assert all(v["position"] == [0.0, 0.0, 0.0] for k, v in corr.items() if k.startswith("sensor") and k != "sensor2")
