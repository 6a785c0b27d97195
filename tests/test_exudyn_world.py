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
