"""A generated vehicle run with hidden sensor effects, diagnosed and checked: the shared body of the
tests of one sensor cause kind (gain drift, crosstalk)."""

from jaxdrift.diagnosis.vehicle import diagnose_vehicle_run
from jaxdrift.io._csvio import read_vehicle_run, write_vehicle_run
from jaxdrift.studies._rungen import make_run


def diagnosed_with_effects(tmp_path, effects, seed):
    """20 s at 500 Hz, pitch and heave measured, 3 N of force noise (``seed`` fixed): the run's
    systematic findings are exactly ``effects`` (cause and channel), each confirmed with its true
    value inside its 95 % interval. Returns the report."""
    cols, _ = make_run(effects + [{"cause": "force_noise", "value": 3.0}], duration=20.0, fs=500.0,
                       seed=seed, channels=("beta", "z3"))
    path = tmp_path / "run.csv"
    write_vehicle_run(path, cols["t"], {k: v for k, v in cols.items() if k != "t"})
    rep = diagnose_vehicle_run(read_vehicle_run(path), None)
    systematic = [f for f in rep["findings"] if f["cause"] != "force_noise"]
    assert {(f["cause"], f["channel"]) for f in systematic} == {(e["cause"], e["channel"]) for e in effects}
    for e in effects:
        f = next(f for f in systematic if f["cause"] == e["cause"])
        assert f["confirmed"] and f["interval"][0] <= e["value"] <= f["interval"][1], f
    return rep
