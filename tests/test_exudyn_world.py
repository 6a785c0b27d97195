"""The third-party multibody world (issue 48, step 1): the seed's half-car built from Exudyn's parts
(a 2D rigid body, point masses, Cartesian spring-dampers, the road through a spring user function)
agrees with jaxdrift's half-car equations on the same road far below any sensor noise the
generators draw (3e-6 m or rad per sample and up)."""

from __future__ import annotations

import pytest

pytest.importorskip("exudyn")


def test_exudyn_halfcar_agrees_with_jaxdrift():
    """1 s on a class C road at 15 m/s, output at 1 kHz, 10 generalized-alpha steps per sample:
    wheel travel, heave and pitch within 1e-7 (m, rad) and 1e-5 of their range (measured: 1.6e-8 m
    and 5e-7 of the range at most)."""
    from benchmarks.validation.exudyn_halfcar import compare

    res = compare(t_end=1.0)
    for k, s in res["signals"].items():
        assert s["range"] > 1e-3, k  # the road moves the car: the comparison is not trivial
        assert s["max_abs_diff"] < 1e-7 and s["relative"] < 1e-5, (k, s)


def test_engine_on_stiff_mounts_is_the_rigid_car():
    """The engine world's bookkeeping: an engine of 10 % of the body 0.8 m ahead on mounts of 150 Hz
    moves the chassis as the rigid car of ``rigid_equivalent`` (total mass, centre of mass moved,
    inertia by parallel axes) does in the independent generator's half-car: pitch, heave at the
    whole car's centre of mass and wheel travel within 1e-4 of their range (measured 1.6e-5; at
    50 Hz 1.1e-4: the mount's own dynamics, falling as its frequency squared)."""
    import math

    import numpy as np

    from benchmarks.validation import gen_vehicle as gv
    from benchmarks.validation.exudyn_halfcar import rigid_equivalent, simulate_exudyn

    car = {**gv.VEHICLES["passenger"], "g": gv.G}
    me, fm = 0.1 * car["m3"], 150.0
    eng = {"mass": me, "x": 0.8, "k": me * (2 * math.pi * fm) ** 2, "d": 2 * 0.1 * me * 2 * math.pi * fm}
    road = gv.FilteredRoad(np.random.default_rng(3), "C", 60.0)
    ex = simulate_exudyn(car, road, 15.0, -1.0, 2.0, 1000.0, 20, engine=eng)
    rig = rigid_equivalent(car, eng)
    y = gv.simulate(rig, road, 15.0, -1.0, 2.0).sol(ex["t"])
    xc = me * 0.8 / rig["m3"]
    for name, got, ref in (("beta", ex["beta"], y[3]), ("heave", ex["z3"] - xc * np.sin(ex["beta"]), y[2]),
                           ("z1", ex["z1"], y[0])):
        assert np.max(np.abs(got - ref)) < 1e-4 * np.ptp(ref), name
