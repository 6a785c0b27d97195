"""The independent sweep's "gains confirmed by re-simulation".

``sweep.gain_measure`` on synthetic per-run results with known gains (the counts, the median ratio,
the runs not confirmed, the effect-free check), and one small generated run with a large systematic
effect diagnosed with the force-driven re-simulation: the extended model's pitch error is lower.
"""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

from benchmarks.validation import gen_vehicle as gv, sweep as sw

CASE = {"vehicle_kind": "van", "road_class": "C", "speed": 20.0, "fs": 500.0, "duration": 10.0,
        "channel_set": "all", "precision": 9, "motion_noise": {}, "model": dict(gv.VEHICLES["van"], g=9.81)}


def _res(i, truth, reported, gain):
    effects = [{"cause": "parameter_error", "parameter": p, "value": 1.2} if c == "parameter_error" else
               {"cause": c, "channel": p, "value": 0.005} if c == "force_delay" else
               {"cause": c, "value": 2.0} for c, p in truth]
    findings = [{"cause": c, "parameter": p, "estimate": 1.2, "interval": [1.1, 1.3]} if c == "parameter_error"
                else {"cause": c, "estimate": 2.0, "interval": [1.5, 2.5]} if c == "force_noise"
                else {"cause": c} for c, p in reported]
    return {"index": i, "kind": "vehicle", "stratum": "single" if truth else "noise", "case": CASE,
            "effects": effects, "findings": findings, "gain": gain,
            "score": sw.score("vehicle", effects, findings), "gen_cpu_s": 1.0, "diag_cpu_s": 1.0}


def _beta(b, a):
    return {"metric": "enforced_moment_rms", "before": 10.0, "after": 1.0, "beta_rms_before": b, "beta_rms_after": a}


def test_gain_measure_counts_on_known_gains():
    I, D, N = ("parameter_error", "I"), ("force_delay", "f1"), ("force_noise", None)
    results = [
        _res(1, [I], [I], _beta(0.02, 0.01)),            # right, confirmed clearly
        _res(2, [I], [I], _beta(0.02, 0.0195)),          # right, confirmed by a hair
        _res(3, [D], [I], _beta(0.02, 0.03)),            # wrong cause, pitch worse: not confirmed
        _res(4, [I], [I], {"metric": "enforced_moment_rms", "before": 1.0, "after": 0.5,
                           "z3_rms_before": 0.01, "z3_rms_after": 0.005}),  # no pitch: the heave
        _res(5, [I], [I], {"metric": "enforced_moment_rms", "before": 1.0, "after": 0.5}),  # no re-simulation
        _res(6, [], [N], _beta(0.01, 0.01)),             # nothing systematic: unchanged
        _res(7, [], [("none", None)], _beta(0.01, 0.011)),  # nothing systematic, yet changed: flagged
        _res(8, [], [I], _beta(0.01, 0.0085)),           # false alarm with a gain
    ]
    g = sw.gain_measure("vehicle", results)
    assert g["with_systematic_finding"] == 6
    assert g["metrics"] == {"beta_rms": 4, "z3_rms": 1}
    assert (g["n"], g["confirmed"], g["clear"]) == (5, 4, 3)
    assert g["median_ratio"] == pytest.approx(0.85)  # of 0.5, 0.975, 1.5, 0.5, 0.85
    r = g["right"]
    assert (r["n"], r["confirmed"], r["clear"]) == (3, 3, 2) and r["median_ratio"] == pytest.approx(0.5)
    assert [x["index"] for x in g["not_confirmed"]] == [3]
    assert g["not_confirmed"][0]["before"] == 0.02 and g["not_confirmed"][0]["after"] == 0.03
    assert g["no_systematic_finding"] == {"n": 2, "after_equals_before": 1, "differ": [7]}
    s = sw.summarise("vehicle", results, {"seed": 0, "command": "x"})
    md = sw.markdown(s)
    assert ("| 4/5 (80.0 %); after < 0.9 x before in 3; median after/before 0.85 "
            "| gains confirmed by re-simulation |") in md
    assert "## Gains not confirmed by re-simulation (1 of 5)" in md and "- run 3 [single]" in md
    assert "| 1/2 (differ: runs 7) |" in md
    # without any re-simulated error (--no-simulation) the row says so
    bare = [dict(x, gain={"metric": "enforced_moment_rms", "before": 1.0, "after": 0.5}) for x in results]
    assert "not measured" in sw.markdown(sw.summarise("vehicle", bare, {"seed": 0, "command": "x"}))


def test_attitude_gain_only_from_the_integrated_rates():
    att = {"index": 0, "findings": [{"cause": "gyro_bias"}], "score": {"right": True}}
    assert sw.resimulated("attitude", dict(att, gain={"metric": "attitude_error_rms", "before": 0.1, "after": 0.01})) \
        == ("attitude_error_rms", 0.1, 0.01)
    rig = {"metric": "rigidity_residual_rms", "before": 0.1, "after": 0.01}
    assert sw.resimulated("attitude", dict(att, gain=rig)) is None
    assert sw.resimulated("attitude", dict(att, gain={"metric": None, "before": None, "after": None})) is None
    # a sensor position is no correction of the rates: with the same attitude error it is checked as
    # unchanged, not counted as a gain that failed
    sp = [{"cause": "sensor_position", "sensor": 2, "value": [0.01, 0.0, 0.0]}]
    gb = [{"cause": "gyro_bias", "channel": "wx", "value": 1e-4}]
    runs = [{"index": i, "stratum": "single", "effects": e, "findings": [dict(x, estimate=x["value"]) for x in e],
             "score": sw.score("attitude", e, [dict(x, estimate=x["value"]) for x in e]),
             "gain": {"metric": "attitude_error_rms", "before": 0.1, "after": a}} for i, e, a in
            ((0, sp, 0.1), (1, gb, 0.01))]
    g = sw.gain_measure("attitude", runs)
    assert (g["n"], g["confirmed"], g["with_systematic_finding"]) == (1, 1, 1)
    assert g["no_systematic_finding"] == {"n": 1, "after_equals_before": 1, "differ": []}


def test_resimulated_pitch_error_falls_with_a_large_offset(tmp_path, monkeypatch):
    """A short run with a 1 % force offset on f1 (force noise kept): the sweep's ``run_one`` with the
    re-simulation reports the offset first and a lower force-driven pitch RMS error after."""
    c = gv.make_case({"index": 0, "stratum": "single", "what": [["force_offset", "f1"]], "seed": 21},
                     durations=(4.0, 4.0), rates=(250,))
    c.update(channel_set="all", channels=list(gv.CHANNEL_SETS["all"]), motion_noise={}, precision=9)
    p = c["model"]
    share = p["m1"] * p["g"] + p["m3"] * p["g"] * p["a"] / (p["a"] + p["b"])
    for e in c["effects"]:
        if e["cause"] == "force_offset":
            e["value"] = 0.05 * share  # u about 0.85 of the range: large
    monkeypatch.setattr(gv, "make_case", lambda case, **kw: c)
    r = sw.run_one("vehicle", {"index": 0, "stratum": "single"}, str(tmp_path), {})
    assert "error" not in r, r.get("traceback")
    assert r["findings"][0]["cause"] == "force_offset" and r["findings"][0]["channel"] == "f1"
    g = r["gain"]
    assert g["beta_rms_after"] < 0.5 * g["beta_rms_before"], g
    assert sw.resimulated("vehicle", r)[0] == "beta_rms"
    assert g["beta_rms_dynamic_after"] < 0.5 * g["beta_rms_dynamic_before"], g
    assert sw.resimulated("vehicle", r, "dynamic")[0] == "beta_rms_dynamic"


def test_dynamic_band_leaves_out_a_random_walk_and_keeps_a_body_mode():
    """The pitch error's dynamic band (above DYNAMIC_BAND_HZ): a random walk (the drift that force
    noise gives) keeps a small share of its RMS, a 1.5 Hz oscillation (a body mode) all of it."""
    import numpy as np

    from jaxdrift.diagnosis.vehicle._extend import DYNAMIC_BAND_HZ, _dynamic_rms, _rms

    dt = 1 / 500
    t = np.arange(int(20 / dt)) * dt
    walk = np.cumsum(np.random.default_rng(7).standard_normal(t.size)) * 1e-5
    mode = 1e-3 * np.sin(2 * np.pi * 1.5 * t)
    assert DYNAMIC_BAND_HZ == 0.5
    assert _dynamic_rms(walk, dt) < 0.2 * _rms(walk)
    assert abs(_dynamic_rms(mode, dt) / _rms(mode) - 1) < 0.02


def test_force_driven_solve_is_shared_between_lengths_and_padding_free():
    """The re-simulation's compiled solve is shared by runs of one rate and similar length (padded
    to a length bucket, the forces held past the end): a shorter run in the same bucket reuses it and
    gets the same states at its samples; and the states match a plain engine solve of the unpadded
    run at its own sample interval, saving at its own times."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    import generators_scipy as gs
    from jaxdrift.diagnosis.vehicle import _extend
    from jaxdrift.io._csvio import VehicleRun
    from jaxdrift.models._halfcar import force_driven_rhs, static_equilibrium
    from jaxdrift.models._params import HalfCarParams
    from jaxdrift.solvers._inputs import SampledSignal
    from jaxdrift.solvers._solve import solve_ode

    cols, _ = gs.make_run(gs.SEED_MODEL, duration=2.8, fs=250.0, speed=20.0, road_class="C", seed=7,
                          channels=("beta",))
    t = np.asarray(cols.pop("t"))
    runs = [VehicleRun(path="x", t=t[:n], channels={k: np.asarray(v)[:n] for k, v in cols.items()})
            for n in (len(t), len(t) - 11)]
    assert _extend._bucket(runs[0].n) == _extend._bucket(runs[1].n) > runs[0].n
    _extend._JIT_CACHE.clear()
    ys = [_extend._force_driven_pitch(r, [gs.SEED_MODEL], [{ch: r[ch] for ch in ("f1", "f2")}])[0] for r in runs]
    assert len(_extend._JIT_CACHE) == 1
    assert ys[0].shape == (runs[0].n, 10) and ys[1].shape == (runs[1].n, 10)
    assert np.array_equal(ys[1], ys[0][:runs[1].n])
    r = runs[0]
    with jax.enable_x64(True):
        p = jax.tree_util.tree_map(lambda v: jnp.asarray(v, dtype=jnp.float64), HalfCarParams.from_dict(gs.SEED_MODEL))
        sig = SampledSignal(0.0, r.dt, np.stack([r["f1"], r["f2"]], axis=1))
        tau = jnp.asarray(r.t - r.t[0])
        def rhs(t, y, args):  # (A.3) written here, not the library's batched solve
            pp, sg = args
            f = sg(t)
            return force_driven_rhs(t, y, pp, f[0], f[1])

        sol = solve_ode(rhs, static_equilibrium(p, "force"), 0.0, float(tau[-1]), saveat=tau,
                        args=(p, sig), dt=r.dt / 4)
        ref = np.asarray(sol.ys)
    assert np.abs(ys[0][:, 3] - ref[:, 3]).max() < 1e-9 * np.abs(ref[:, 3]).max() + 1e-12
    assert np.abs(ys[0] - ref).max() < 1e-9 * np.abs(ref).max()
