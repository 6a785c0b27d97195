"""Logger faults before causes (issue 35): a force channel that goes dead or sticks for 10-40 % of a
run is found with its span, the run is analysed on its sound part, and no cause is fitted to the
silence. A channel that clips is not a logger fault: the reader keeps its whole record, and the
diagnosis reads and restores the clipping (``force_clipping``, tests/test_force_clipping.py).
Runs simulated by scipy (tests/generators_scipy.py), faults written here."""

from __future__ import annotations

import numpy as np
import pytest

import generators_scipy as gs
from jaxdrift.io import load_run
from jaxdrift.io._faults import find_faults


@pytest.fixture(scope="module")
def bases():
    return [gs.make_run(gs.SEED_MODEL, duration=8.0, fs=500.0, seed=7100 + k, noise_sigma=2.0,
                        channels=("beta", "z3"))[0] for k in range(3)]


def _fault(cols, kind, ch, start, length):
    """The run with the fault, and the fault's true span [t0, t1] (for a clip: from the first to
    the last sample past the range)."""
    x = cols[ch].copy()
    t = cols["t"]
    a, b = start, start + length
    span = (t[a], t[b - 1])
    if kind == "dropout":
        x[a:b] = 0.0
    elif kind == "stuck":
        x[a:b] = x[a]
    else:  # clipped: a rough stretch drives the amplifier past a range the rest never reaches
        m = x.mean()
        x[a:b] = m + 4.0 * (x[a:b] - m)
        rest = np.r_[x[:a], x[b:]]
        top = rest.max() + 0.25 * (x[a:b].max() - rest.max())
        over = np.flatnonzero(x > top)
        span = (t[over[0]], t[over[-1]])
        x = np.minimum(x, top)
    return {**cols, ch: x}, span


def test_faults_found_with_their_span_on_30_runs(bases):
    rng = np.random.default_rng(7199)
    hits, n = 0, 0
    for i in range(30):
        cols = bases[i % 3]
        kind = ("dropout", "stuck")[i % 2]
        ch = ("f1", "f2")[(i // 2) % 2]
        N = len(cols["t"])
        length = int(rng.uniform(0.1, 0.4) * N)
        start = int(rng.integers(0, N - length))
        bad, (ta, tb) = _fault(cols, kind, ch, start, length)
        found = find_faults(bad["t"], bad, ["f1", "f2"])
        ok = [f for f in found if f["channel"] == ch and f["kind"] == kind]
        n += 1
        if ok and len(found) == len(ok) == 1:
            t0, t1 = ok[0]["span_s"]
            hits += abs(t0 - ta) <= 0.01 and abs(t1 - tb) <= 0.01
    assert hits >= 0.95 * n, (hits, n)


def test_no_fault_on_sound_runs(bases):
    for cols in bases:
        assert find_faults(cols["t"], cols, ["f1", "f2"]) == []
    # without noise too, and written with six significant digits (a logger's resolution)
    clean = gs.make_run(gs.SEED_MODEL, duration=8.0, fs=500.0, seed=7150, channels=("beta",))[0]
    rounded = {k: (np.array([float(f"{v:.6g}") for v in x]) if k in ("f1", "f2") else x) for k, x in clean.items()}
    assert find_faults(clean["t"], rounded, ["f1", "f2"]) == []


def test_a_clipped_channel_is_not_a_logger_fault(bases):
    """Clipping costs a channel its peaks, not its record: the reader finds no fault and keeps
    every row (the diagnosis reads it as ``force_clipping``)."""
    bad, _ = _fault(bases[1], "clipped", "f1", 800, 1200)
    assert find_faults(bad["t"], bad, ["f1", "f2"]) == []


def test_dead_channel_is_named_and_no_cause_fitted_to_it(tmp_path, bases):
    """f2 dies for the last 30 % (a loose connector): the report names it first with its span,
    the run is analysed on the rest, and no gain drift or scale is read on f2."""
    from jaxdrift.diagnosis.vehicle import diagnose_vehicle_run

    cols = bases[0]
    N = len(cols["t"])
    bad, _ = _fault(cols, "dropout", "f2", int(0.7 * N), N - int(0.7 * N))
    path = tmp_path / "dead.csv"
    _write(path, bad)
    run = load_run(str(path))
    assert run.t[-1] < cols["t"][int(0.7 * N)]
    rep = diagnose_vehicle_run(run, gs.SEED_MODEL, with_simulation=False)
    first = rep["findings"][0]
    assert first["cause"] == "channel_fault" and first["channel"] == "f2" and first["kind"] == "dropout"
    assert first["span_s"][0] == pytest.approx(cols["t"][int(0.7 * N)], abs=0.01)
    assert not [f for f in rep["findings"] if f.get("channel") == "f2"
                and f["cause"] in ("force_gain_drift", "force_scale")], rep["findings"]
    assert rep["run"]["time_base"]["logger_faults"][0]["channel"] == "f2"


def _write(path, cols):
    names = list(cols)
    with open(path, "w") as fh:
        fh.write(",".join(names) + "\n")
        for row in zip(*(cols[c] for c in names)):
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
