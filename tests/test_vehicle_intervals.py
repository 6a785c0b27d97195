"""The vehicle report's intervals: method component and joint (Sidak) level."""

import math

import numpy as np
import pytest
import scipy.stats

from jaxdrift.diagnosis.vehicle._causes import FORCE_NOISE, Cause, _finding_for, method_half
from jaxdrift.diagnosis._intervals import joint_intervals


def test_single_finding_keeps_its_95_interval():
    f = _finding_for(Cause("force_offset", "f1"), 10.0, 0.5)
    before = list(f["interval"])
    (f,) = joint_intervals([f])
    assert f["interval"] == before
    assert "interval_level" not in f
    half = math.hypot(1.96 * 0.5, method_half("force_offset", 10.0))
    assert f["interval"] == pytest.approx([10.0 - half, 10.0 + half])


@pytest.mark.parametrize("k", [2, 3, 4])
def test_joint_factor_is_sidak(k):
    fs = [_finding_for(Cause("force_delay", "f2"), 1e-3, 1e-4) for _ in range(k)]
    half0 = fs[0]["interval"][1] - fs[0]["estimate"]
    given = [dict(f) for f in fs]
    fs_new = joint_intervals(fs)
    assert fs == given  # the findings given are not changed
    fs = fs_new
    z = scipy.stats.norm.ppf(1 - (1 - 0.95 ** (1 / k)) / 2)
    for f in fs:
        assert f["interval"][1] - f["estimate"] == pytest.approx(half0 * z / scipy.stats.norm.ppf(0.975), rel=1e-12)
        assert f["interval_level"]["findings"] == k
    assert {2: 2.236, 3: 2.388}.get(k, z) == pytest.approx(z, abs=1e-3)


def test_upper_bound_keeps_zero_and_alternatives_widen():
    noise = {"cause": "force_noise", "estimate": 2.0, "interval": [0.0, 2.5]}
    f = _finding_for(Cause("force_offset", "f1"), 10.0, 0.5)
    f["indistinguishable_from"] = [{"cause": "force_offset", "channel": "f2", "estimate": -20.0,
                                    "interval": [-21.0, -19.0]}]
    f, noise = joint_intervals([f, noise])
    assert noise["interval"][0] == 0.0 and noise["interval"][1] > 2.5
    alt = f["indistinguishable_from"][0]["interval"]
    assert alt[0] < -21.0 and alt[1] > -19.0


def test_noise_method_component_is_relative():
    assert FORCE_NOISE.method_rel > 0
    assert method_half("force_noise", 2.0) == pytest.approx(2 * method_half("force_noise", 1.0))


def test_joint_coverage_monte_carlo():
    """Three findings with exact standard errors: all three true values inside together in 95 %
    of draws (4000 draws, fixed seed; 3-sigma binomial band 0.940-0.960), where the marginal
    intervals alone manage 0.95^3 = 0.857."""
    rng = np.random.default_rng(20261201)
    se = np.array([0.3, 2e-4, 0.01])
    truth = np.array([5.0, 1e-3, 0.05])
    causes = [Cause("force_offset", "f1"), Cause("force_delay", "f1"), Cause("parameter_error", "I")]
    n, joint, marginal = 4000, 0, 0
    assert all(c.kind.method_rel == 0.0 for c in causes)  # the statistical part alone
    for _ in range(n):
        est = truth + se * rng.standard_normal(3)
        fs = [_finding_for(c, e, s) for c, e, s in zip(causes, est, se)]
        tv = [c.to_estimate(t) for c, t in zip(causes, truth)]
        marginal += all(f["interval"][0] <= t <= f["interval"][1] for f, t in zip(fs, tv))
        fs = joint_intervals(fs)
        joint += all(f["interval"][0] <= t <= f["interval"][1] for f, t in zip(fs, tv))
    band = 3 * math.sqrt(0.95 * 0.05 / n)
    assert abs(joint / n - 0.95) < band, joint / n
    assert abs(marginal / n - 0.95 ** 3) < 3 * math.sqrt(0.857 * 0.143 / n), marginal / n


def test_vector_box_goes_to_the_joint_level_per_component():
    """A sensor position's box (each of 3 components at 0.95^(1/3)) next to a scalar finding:
    each component goes to 0.95^(1/6)."""
    q = lambda lv: scipy.stats.norm.ppf(0.5 + 0.5 * lv)  # noqa: E731
    pos = {"cause": "sensor_position", "estimate": [0.0, 1.0, 2.0],
           "interval": [[-1.0, 0.0, 1.0], [1.0, 2.0, 3.0]]}
    scale = {"cause": "gyro_scale", "estimate": 1.0, "interval": [0.9, 1.1]}
    pos, scale = joint_intervals([pos, scale])
    f = q(0.95 ** (1 / 6)) / q(0.95 ** (1 / 3))
    assert pos["interval"][1] == pytest.approx([f, 1 + f, 2 + f])
    assert scale["interval"][1] - 1.0 == pytest.approx(0.1 * q(0.95 ** 0.5) / q(0.95))
