"""The contract every registered vehicle cause keeps, one case per cause: a run generated with that
cause's effect alone (the independent generator, ``benchmarks/validation/gen_vehicle.py``, with its
own integrator and road) is diagnosed; the cause is named first with the right target, its interval
holds the true size, it is confirmed, and the extended model carries its correction.

The registries (``jaxdrift.diagnosis.vehicle.cause_names``: the linear kinds, the nonlinear
catalogue and the causes read off the forces) decide which causes there are: a cause added to a registry without a
case here fails ``test_every_registered_cause_has_a_case``.
Each case runs a full diagnosis without the re-simulation (about a minute for all eleven).
"""

from __future__ import annotations

import json

import pytest

import jaxdrift
from benchmarks.validation import gen_vehicle as gen
from jaxdrift.diagnosis.vehicle import cause_names

#: one clear case per cause: (the effect as the generator takes it, the finding's target key,
#: the true size as the finding states it (None: the generator's own, from the truth file))
CASES = {
    "force_offset": ({"cause": "force_offset", "channel": "f2", "value": 60.0}, "channel", 60.0),
    "force_scale": ({"cause": "force_scale", "channel": "f1", "value": 0.95}, "channel", 0.95),
    "force_delay": ({"cause": "force_delay", "channel": "f1", "value": 0.003}, "channel", 0.003),
    "force_gain_drift": ({"cause": "force_gain_drift", "channel": "f2", "value": 0.004}, "channel", 0.004),
    "force_crosstalk": ({"cause": "force_crosstalk", "channel": "f2", "value": 0.03}, "channel", 0.03),
    "parameter_error": ({"cause": "parameter_error", "parameter": "k3", "value": 0.9}, "parameter", None),
    "damper_asymmetry": ({"cause": "damper_asymmetry", "parameter": "d4", "value": 1.5}, "parameter", 1.5),
    "progressive_spring": ({"cause": "progressive_spring", "parameter": "k4", "stiffening": 0.8}, "parameter", None),
    "bump_stop": ({"cause": "bump_stop", "parameter": "k3", "share": 0.03, "ratio": 6.0}, "parameter", None),
    "tyre_lift_off": ({"cause": "tyre_lift_off", "channel": "f2", "share": 0.03}, "channel", None),
    "force_clipping": ({"cause": "force_clipping", "channel": "f1", "share": 0.01}, "channel", None),
}


def _case(effect):
    model = {k: float(v) for k, v in gen.VEHICLES["passenger"].items()}
    model["g"] = gen.G
    return {"index": 0, "stratum": "single", "what": [], "seed": 1, "vehicle_kind": "passenger", "model": model,
            "road_class": "C", "speed": 15.0, "fs": 250.0, "duration": 10.0, "channel_set": "beta_z3_s",
            "channels": list(gen.CHANNEL_SETS["beta_z3_s"]), "precision": 9, "t0": 0.0, "lead_in": 0.2,
            "effects": [dict(effect), {"cause": "force_noise", "value": 2.0}], "motion_noise": {},
            "column_order_seed": 1, "road_seed": 777001, "noise_seed": 5}


def test_every_registered_cause_has_a_case():
    assert set(CASES) == set(cause_names()), (
        "a registered cause without a contract case (or a case for a cause no registry holds)")


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_generated_run_of_one_cause_is_found_and_corrected(tmp_path, name):
    effect, key, size = CASES[name]
    case = _case(effect)
    paths = gen.make_run(case, str(tmp_path), "run")
    run = jaxdrift.read_vehicle_run(paths["csv"])
    rep = jaxdrift.diagnose_vehicle_run(run, jaxdrift.read_model(paths["model"]), with_simulation=False)
    if size is None:  # sized by the generator from the run's own travel: its truth file holds it
        with open(paths["truth"]) as fh:
            truth = json.load(fh)
        size = next(e for e in truth["effects"] if e["cause"] == name)["value"]
    first = next(f for f in rep["findings"] if f["cause"] not in ("force_noise",))
    assert (first["cause"], first.get(key)) == (name, effect.get(key)), rep["findings"]
    lo, hi = first["interval"] or (first["estimate"],) * 2  # no interval: a value read exactly
    assert lo <= size <= hi or abs(first["estimate"] - size) <= 0.05 * abs(size), (first, size)
    assert first.get("confirmed", True) is True, first
    ext = rep["extended_model"]
    assert ext.get("corrections") or ext.get("parameters") or ext.get("nonlinear"), ext
