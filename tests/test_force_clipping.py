"""force_clipping: a force channel saturating at its range (issue 32's proof of the recipe).

Checked on runs of the independent scipy generator (tests/generators_scipy.py): the detector, and a
whole diagnosis whose report must name the range, keep the run whole, fit no sensor effect to the
lost peaks, and hand the series output the same restoration.
"""

from __future__ import annotations

import numpy as np
import pytest

import generators_scipy as gs
from jaxdrift.diagnosis.vehicle._nonlinear import ForceClipping

@pytest.fixture(scope="module")
def base():
    return gs.make_run(gs.SEED_MODEL, duration=8.0, fs=500.0, seed=7101, noise_sigma=2.0, channels=("beta", "z3"))[0]


def test_a_tyre_in_the_air_is_not_a_range(base):
    """A wheel force that reads exactly 0 while its tyre is off the road is the tyre lifting off; a
    generated nonlinear run with 272 such samples on f2 had been refused as clipped. A force
    pinned below its rest at a negative value is a range."""
    x = base["f2"].copy()
    low = x < np.quantile(x, 0.03)
    x[low] = 0.0
    assert ForceClipping("f2").detect(x, 2.0) is None
    x[low] = -250.0
    det = ForceClipping("f2").detect(x, 2.0)
    assert det is not None and det["lo"] == -250.0 and det["hi"] is None
    assert ForceClipping("f1").detect(base["f1"], 2.0) is None  # a sound channel


def test_a_clipped_run_is_named_restored_and_kept_whole(tmp_path, base):
    """f1 clipped at 0.5 % of its samples: the report names force_clipping first with the range,
    analyses every row, fits no sensor effect, and its corrections restore the peaks for the
    series output too."""
    import jaxdrift
    from jaxdrift.diagnosis import vehicle_series

    x = base["f1"]
    hi = float(np.quantile(x, 0.995))
    cols = {**base, "f1": np.minimum(x, hi)}
    path = tmp_path / "clipped.csv"
    with open(path, "w") as fh:
        fh.write(",".join(cols) + "\n")
        for row in zip(*cols.values()):
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
    run = jaxdrift.read_vehicle_run(str(path))
    assert run.n == len(x)
    rep = jaxdrift.diagnose_vehicle_run(run, gs.SEED_MODEL, with_simulation=False)
    first = rep["findings"][0]
    assert (first["cause"], first["channel"], first["estimate"]) == ("force_clipping", "f1", hi), first
    assert not [f for f in rep["findings"] if f["cause"] in ("force_scale", "force_offset", "force_gain_drift",
                                                           "force_delay", "force_crosstalk")], rep["findings"]
    assert rep["extended_model"]["corrections"]["f1"]["clip"] == [None, hi]
    series = vehicle_series(run, gs.SEED_MODEL, rep)
    pinned = cols["f1"] == hi
    left = np.sqrt(np.mean((series["f1_corrected"] - x)[pinned] ** 2))
    lost = np.sqrt(np.mean((cols["f1"] - x)[pinned] ** 2))
    assert left < 0.5 * lost, (left, lost)


def test_durability_drives_its_variants_with_the_restored_forces(base):
    """Durability's section forces take the report's corrections: a clipped channel's bursts are
    restored before its variants are driven (the forces it holds equal the record's restoration)."""
    from jaxdrift.durability._variants import build_section_forces
    from jaxdrift.io import Corrections, ForceCorrection

    t, x = base["t"], base["f1"]
    hi = float(np.quantile(x, 0.995))
    forces = np.stack([np.minimum(x, hi), base["f2"]], axis=1)
    corr = Corrections(f1=ForceCorrection(clip=(None, hi)))
    sf = build_section_forces(t, forces, None, gs.SEED_MODEL, gs.SEED_MODEL, corr,
                              {"k_rot": 0.0, "d_rot": 0.0}, float(t[1] - t[0]))
    held = np.asarray(sf.forces)
    np.testing.assert_array_equal(held[:, 0], corr.f1.restore(t, forces[:, 0]))
    np.testing.assert_array_equal(held[:, 1], base["f2"])
    pinned = forces[:, 0] == hi
    assert np.sqrt(np.mean((held[pinned, 0] - x[pinned]) ** 2)) < 0.5 * np.sqrt(np.mean((hi - x[pinned]) ** 2))
