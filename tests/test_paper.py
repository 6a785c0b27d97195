"""The section-4 study on the engine: the virtual measurement against scipy DOP853, the excitation
modes against each other, the study's outputs and the CLI's bad-input handling."""

from __future__ import annotations

import json
import os

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from test_halfcar import a4_matrix_rhs  # the paper's matrix form (A.4) in numpy

from jaxdrift.models._params import HalfCarParams
from jaxdrift.models._road import RoadProfile, iso8608_road
from jaxdrift.studies._study import (
    SOLVER_FIXED,
    SOLVER_LOOSE,
    StudyConfig,
    run_force_paths,
    run_paper_study,
    simulate_forces,
    simulate_prescribed_pitch,
    virtual_measurement,
    write_paper_outputs,
)
from jaxdrift.cli import main as cli_main

T = 2.0
P = HalfCarParams()


@pytest.fixture(scope="module")
def measured():
    road = iso8608_road("D", seed=0)
    inputs = road.sampled_wheel_inputs(20.0, P.a + P.b, T)
    vm = virtual_measurement(P, inputs, T)  # the study's settings: compiled once for both
    return inputs, vm


class _ExactRoad(eqx.Module):
    """The analytic road (sum of cosines) under both wheels, as inputs for the road mode."""

    road: RoadProfile
    speed: float
    wheelbase: float

    def __call__(self, t):
        return self.road.wheel_inputs(t, self.speed, self.wheelbase)


def _road_np(road, s):
    """Independent numpy evaluation of the profile: C2 quintic ramp times the cosine sum."""
    n, a, ph, L = np.asarray(road.n), np.asarray(road.amp), np.asarray(road.phase), road.ramp_length
    if s < 0:
        return 0.0, 0.0
    arg = 2 * np.pi * n * s + ph
    val, der = np.sum(a * np.cos(arg)), -np.sum(2 * np.pi * n * a * np.sin(arg))
    u = min(s / L, 1.0)
    w, dw = u**3 * (10 - 15 * u + 6 * u**2), (30 * u**2 * (1 - u) ** 2 / L if u < 1 else 0.0)
    return w * val, dw * val + w * der


def test_road_mode_on_the_engine_matches_scipy_dop853():
    """Road mode (A.4) on the engine (DOPRI5, rtol 1e-10) = scipy DOP853 (rtol 1e-12) on the
    paper's matrix form and an independent numpy evaluation of the same analytic road."""
    road = iso8608_road("D", seed=0, n_components=32)
    speed, wb, T1 = 20.0, P.a + P.b, 0.6
    vm = virtual_measurement(P, _ExactRoad(road, speed, wb), T1, rtol=1e-10, atol=1e-12)
    ts = np.asarray(vm.ts)[::20]  # every 20 ms

    def rhs(t, x):
        (z1, d1), (z2, d2) = _road_np(road, speed * t), _road_np(road, speed * t - wb)
        return a4_matrix_rhs(x, P, (z1, z2), (speed * d1, speed * d2))

    ref = solve_ivp(rhs, (0, T1), np.asarray(vm.x[0]), method="DOP853", rtol=1e-12, atol=1e-13, t_eval=ts)
    assert ref.success
    got = np.asarray(vm.x)[::20]
    assert np.ptp(ref.y[3]) > 0.01  # the road really pitches the car
    np.testing.assert_allclose(got[:, :4], ref.y[:4].T, atol=2e-8)  # positions [m], pitch [rad]
    np.testing.assert_allclose(got[:, 4:], ref.y[4:].T, atol=2e-6)  # velocities


def test_measured_forces(measured):
    _, vm = measured
    f = np.asarray(vm.forces)
    assert f[0] == pytest.approx([(P.m1 + P.m3 / 2) * P.g] * 2, rel=1e-9)  # static equilibrium
    assert f.min() < 0 and f.max() > 9e3  # the road is rough enough to unload the tyres


def test_force_mode_driven_by_measured_forces_reproduces_the_motion(measured):
    """Step 2 on the engine (fixed 1 ms DOPRI5, forces linear between the 1 kHz samples)."""
    _, vm = measured
    save_ts = np.asarray(vm.ts)[::10]
    sol = simulate_forces(P, vm.force_signal(), save_ts, SOLVER_FIXED)
    ref = np.asarray(vm.x)[::10]
    err_beta = np.degrees(np.abs(np.asarray(sol.ys[:, 3]) - ref[:, 3]))
    err_z3 = np.abs(np.asarray(sol.ys[:, 2]) - ref[:, 2])
    assert err_beta.max() < 2e-3 and err_z3.max() < 1e-5, (err_beta.max(), err_z3.max())
    # the contact states reconstruct the road from the forces
    np.testing.assert_allclose(np.asarray(sol.ys[:, 8:10]), np.asarray(vm.zeta)[::10], atol=2e-4)


def test_enforced_moment_small_for_the_true_model_large_for_a_perturbed_one(measured):
    """Step 5: prescribing the measured beta to the unperturbed model with undisturbed forces
    needs almost no moment (<1 % of the inertia term); the paper's perturbed model needs much more."""
    _, vm = measured
    ts = np.asarray(vm.ts)
    _, lam, inertia = simulate_prescribed_pitch(P, vm.force_signal(), vm.pitch_signal(), ts, SOLVER_FIXED)
    lam, inertia = np.asarray(lam), np.asarray(inertia)
    assert np.abs(inertia).max() > 3e3
    assert np.abs(lam).max() < 0.01 * np.abs(inertia).max()
    _, lam_p, _ = simulate_prescribed_pitch(P.paper_perturbed(), vm.force_signal(), vm.pitch_signal(), ts, SOLVER_FIXED)
    assert np.abs(np.asarray(lam_p)).max() > 10 * np.abs(lam).max()


@pytest.mark.slow  # ~1.5 min (three compilations); the section-4 notebook test (tier2, CI) runs the study too
def test_study_end_to_end_small(measured, tmp_path):
    cfg = StudyConfig(duration=T, n_noise=2, n_models=2, n_compare=2, n_spring=1, pitch_spring_stiffness=(1e3,),
                      compare_solvers=(SOLVER_LOOSE,), progress=False)
    res = run_paper_study(cfg, log=lambda m: None)
    s = res["summary"]
    # undisturbed forces do not drift off within 2 s; the noisy paths are independent samples
    assert s["drift_off_beta_s"]["undisturbed"] == "inf"
    noisy = res["main"].ys[res["kinds"] == "noisy"]
    assert np.max(np.abs(noisy[0, :, 1] - noisy[1, :, 1])) > 0
    m = s["enforced_moment_Nm"]
    assert m["unperturbed_undisturbed"]["abs_max"] < 0.01 * m["inertia_term"]["abs_max"]
    assert m["perturbed_noisy"]["abs_max"] > 5 * m["unperturbed_undisturbed"]["abs_max"]
    assert s["measurement"]["sigma_N"] == pytest.approx(0.002 * s["measurement"]["f_max_N"])
    files = write_paper_outputs(res, tmp_path)
    for name in ("fig4_road_forces.png", "fig5_z3_beta.png", "fig6_noise_samples.png", "fig7_perturbed_models.png",
                 "fig8_enforced_moment.png", "fig_pitch_spring.png", "summary.json", "solver_comparison.md"):
        assert name in files and os.path.getsize(tmp_path / name) > 0
    loaded = json.loads((tmp_path / "summary.json").read_text(), parse_constant=lambda c: pytest.fail(c))
    assert loaded["drift_definition"].startswith("drift-off time")
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".paper-")]  # no leftovers


def test_mismatched_inputs_raise(measured):
    inputs, vm = measured
    with pytest.raises(ValueError, match="mismatched"):
        virtual_measurement(P, inputs, 2 * T)
    with pytest.raises(ValueError, match="3 models but 2 sigmas"):
        run_force_paths(vm, np.asarray(vm.ts)[::100], [P, P, P], [0.0, 1.0])
    from jaxdrift.solvers._inputs import SampledSignal

    one_channel = SampledSignal(0.0, 1e-3, jnp.zeros((10, 1)))
    with pytest.raises(ValueError, match="2 channels"):
        simulate_forces(P, one_channel, np.linspace(0, 0.009, 5))
    with pytest.raises(ValueError, match="'m3'"):
        virtual_measurement(HalfCarParams(m3=-1.0), inputs, T)


# ---------------------------------------------------------------------------------------------
# CLI: bad input -> exit 2, a message naming the problem, nothing written
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "content, extra, message",
    [
        ('{"m1": -15}', [], "'m1'"),
        ('{"k5": 1}', [], "'k5'"),
        ('{"m1": 15,\n "k3": }', [], "line 2"),
        ('[1, 2]', [], "JSON object"),
        ('{"I": 0}', [], "'I'"),
        ("{}", ["--road-class", "Z"], "road-class"),
        ("{}", ["--samples", "1"], "samples"),
        ("{}", ["--duration", "-3"], "duration"),
    ],
)
def test_paper_cli_bad_input(tmp_path, capsys, content, extra, message):
    pfile = tmp_path / "model.json"
    pfile.write_text(content)
    out = tmp_path / "out"
    rc = cli_main(["paper", "--out", str(out), "--params", str(pfile), *extra])
    err = capsys.readouterr().err
    assert rc == 2
    assert message in err
    assert not out.exists()


def test_cli_missing_params_and_bad_out(tmp_path, capsys):
    rc = cli_main(["paper", "--out", str(tmp_path / "o"), "--params", str(tmp_path / "nope.json")])
    assert rc == 2 and "nope.json" in capsys.readouterr().err
    f = tmp_path / "file"
    f.write_text("x")
    rc = cli_main(["pointmass", "--out", str(f)])
    assert rc == 2 and "not a folder" in capsys.readouterr().err
    rc = cli_main(["pointmass", "--out", str(tmp_path / "p"), "--eta", "-1"])
    assert rc == 2 and "--eta" in capsys.readouterr().err
    assert not (tmp_path / "p").exists()


@pytest.mark.slow
def test_paper_cli_quick_end_to_end(tmp_path):
    rc = cli_main(["paper", "--out", str(tmp_path), "--quick", "--no-progress"])
    assert rc == 0
    s = json.loads((tmp_path / "summary.json").read_text())
    names = [r["solver"] for r in s["solver_comparison"]]
    assert names == ["dopri5 rtol 1e-4", "dopri5 rtol 1e-8", "dopri5 fixed 1 ms"]
    assert (tmp_path / "solver_comparison.md").read_text().count("| dopri5") == 3


@pytest.mark.slow
def test_pointmass_cli_end_to_end(tmp_path):
    rc = cli_main(["pointmass", "--out", str(tmp_path), "--paths", "500", "--duration", "10", "--no-progress"])
    assert rc == 0
    s = json.loads((tmp_path / "pointmass_summary.json").read_text())
    assert [c["eta"] for c in s["cases"]] == [0.0, 0.5]
    assert (tmp_path / "fig2_pointmass_std.png").stat().st_size > 0
