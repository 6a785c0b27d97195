"""A degree of freedom the model lacks (issue 48): ``unmodelled_mode``.

The runs are made by a third-party multibody code (Exudyn, ``benchmarks/validation/gen_exudyn.py``):
a car whose engine sits on mounts, diagnosed against the rigid car of the same total mass, centre of
mass and inertia (the model a user has). The mode's part of the residual is checked against its
closed form; the diagnosis must name the mode first with its frequency, mass and place, still find a
sensor effect hidden beside it, and name nothing on the rigid car of the same world."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from jaxdrift.diagnosis.vehicle._mode import _highpass


def test_the_mode_filter_is_the_closed_form():
    """The relative-motion filter ``s^2 / (s^2 + 2 zeta w s + w^2)`` on a sine of acceleration,
    after its start has died out: amplitude and phase as the transfer function's at that frequency
    (first-order hold: exact for an input linear between samples; a sine at 1 kHz is nearly so)."""
    dt, f0, zeta = 1e-3, 9.0, 0.08
    t = np.arange(40000) * dt
    for f in (2.0, 9.0, 30.0):
        x = np.sin(2 * math.pi * f * t)
        y = _highpass(x, f0, zeta, dt)
        s = 2j * math.pi * f
        w = 2 * math.pi * f0
        H = s * s / (s * s + 2 * zeta * w * s + w * w)
        ref = np.abs(H) * np.sin(2 * math.pi * f * t + np.angle(H))
        tail = slice(30000, None)
        assert np.max(np.abs(y[tail] - ref[tail])) < 2e-3 * max(np.abs(H), 0.05), f


def test_the_mode_filter_is_scipys_first_order_hold():
    """The recursion is what ``scipy.signal.cont2discrete(..., method="foh")`` and ``ss2tf`` give
    for the same state-space form (computed here in five times less time)."""
    import scipy.signal

    from jaxdrift.diagnosis.vehicle._mode import _highpass_coeffs

    for f, zeta, dt in ((3.0, 0.1, 1e-3), (12.0, 0.05, 2e-3), (40.0, 0.3, 1 / 200)):
        w = 2 * math.pi * f
        sysc = (np.array([[0.0, 1.0], [-w * w, -2 * zeta * w]]), np.array([[0.0], [-1.0]]),
                np.array([[w * w, 2 * zeta * w]]), np.array([[1.0]]))
        num, den = scipy.signal.ss2tf(*scipy.signal.cont2discrete(sysc, dt, method="foh")[:4])
        got = _highpass_coeffs(f, zeta, dt)
        assert np.allclose(got[0], num[0], rtol=1e-9, atol=1e-12) and np.allclose(got[1], den, rtol=1e-9), f


pytest.importorskip("exudyn")


def _case(tmp_path, engine: dict | None, what: list, seed: int = 7, name: str = "run"):
    """A 10 s run at 500 Hz of the passenger car on a class C road at 15 m/s, pitch and heave
    measured, 1 N of force noise, the engine (or none) and the effects ``what`` as given."""
    from benchmarks.validation import gen_exudyn as ge
    from benchmarks.validation import gen_vehicle as gv
    from benchmarks.validation.exudyn_halfcar import rigid_equivalent

    rng = np.random.default_rng(seed)
    car = {**gv.VEHICLES["passenger"], "g": gv.G}
    if engine is not None:
        m = engine["share"] * car["m3"]
        w = 2 * math.pi * engine["freq"]
        engine = {"mass": m, "x": engine["x"], "k": m * w * w, "d": 2 * engine["zeta"] * m * w,
                  "frequency_hz": engine["freq"], "damping_ratio": engine["zeta"]}
    model = dict(car) if engine is None else rigid_equivalent(car, engine)
    case = {"index": 0, "stratum": "test", "what": [], "seed": seed, "design": "modes", "vehicle_kind": "passenger",
            "car": car, "engine": engine, "model": model, "road_class": "C", "road_interp": "spline7",
            "speed": 15.0, "fs": 500.0, "duration": 10.0, "channels": ["beta", "z3"], "channel_set": "beta_z3",
            "precision": 9, "t0": 0.0, "lead_in": 0.3, "motion_noise": {},
            "effects": list(what) + [{"cause": "force_noise", "value": 1.0}],
            "column_order_seed": int(rng.integers(2**31)), "road_seed": int(rng.integers(2**31)),
            "noise_seed": int(rng.integers(2**31))}
    return ge.make_run(case, str(tmp_path), name=name)


def _diagnose(paths, with_simulation=False, plots_dir=None):
    from jaxdrift.diagnosis.vehicle import diagnose_vehicle_run
    from jaxdrift.io._csvio import read_vehicle_run

    with open(paths["model"]) as fh:
        model = json.load(fh)
    return diagnose_vehicle_run(read_vehicle_run(paths["csv"]), model, with_simulation=with_simulation,
                                plots_dir=plots_dir)


def _bending_body_first(tmp_path, seed: int, index: int, f_true: float | None = None) -> dict:
    """The report of ``gen_exudyn.design_bending(30, seed)[index]`` with the re-simulation (the
    scorecard's setting), asserting that the body finding leads (within 10 % of ``f_true`` where
    given) and that no systematic cause is confirmed."""
    from benchmarks.validation import gen_exudyn as ge

    paths = ge.make_run(ge.design_bending(30, seed)[index], str(tmp_path))
    rep = _diagnose(paths, with_simulation=True)
    first = rep["findings"][0]
    assert first["cause"] == "model_form" and first["axle"] == "body", rep["findings"]
    assert f_true is None or abs(first["frequency_hz"] / f_true - 1) < 0.1, first
    assert not [f for f in rep["findings"] if f["cause"] in SYSTEMATIC and f.get("confirmed")], rep["findings"]
    return rep


SYSTEMATIC = {"force_offset", "force_scale", "force_delay", "force_gain_drift", "force_crosstalk", "parameter_error",
              "model_form", "damper_asymmetry", "progressive_spring", "bump_stop"}


def test_an_engine_on_mounts_is_named_first_with_a_sensor_effect_beside_it(tmp_path):
    """An engine of 10 % of the body 0.8 m ahead of the centre of mass on 11 Hz mounts (damping
    ratio 0.1), and an offset of +60 N on f1: the mode first and confirmed, its frequency within 1 %
    and inside its interval, its mass and place within 5 % and 0.05 m; the offset found and
    confirmed; no other sensor or parameter claim confirmed (before this cause the same kind of run
    confirmed damper errors of x1.7). The extended model's force-driven pitch error above 0.5 Hz
    falls (it carries the mass on its spring)."""
    paths = _case(tmp_path, {"share": 0.10, "x": 0.8, "freq": 11.0, "zeta": 0.1},
                  [{"cause": "force_offset", "channel": "f1", "value": 60.0}])
    rep = _diagnose(paths, with_simulation=True, plots_dir=tmp_path / "plots")
    assert (tmp_path / "plots" / "unmodelled_mode.png").stat().st_size > 10_000
    first = rep["findings"][0]
    assert first["cause"] == "unmodelled_mode" and first["confirmed"], rep["findings"][:3]
    assert abs(first["estimate"] - 11.0) < 0.11 and first["interval"][0] <= 11.0 <= first["interval"][1], first
    with open(paths["truth"]) as fh:
        car_m3 = json.load(fh)["case"]["car"]["m3"]
    me = 0.10 * car_m3
    pl = first["placement"]
    assert abs(pl["mass_kg"] - me) < 0.05 * me, pl
    # the place relative to the whole car's centre of mass (the model's), 0.8 m ahead of the chassis's
    x_true = 0.8 - me * 0.8 / (car_m3 + me)
    assert abs(pl["x_m"] - x_true) < 0.05, pl
    assert set(first["channels"]) == {"heave", "moment"}
    offs = [f for f in rep["findings"] if f["cause"] == "force_offset" and f.get("confirmed")]
    assert len(offs) == 1 and offs[0]["channel"] == "f1" and abs(offs[0]["estimate"] - 60.0) < 3.0, rep["findings"]
    others = [f for f in rep["findings"] if f["cause"] in SYSTEMATIC and f.get("confirmed") and f is not offs[0]]
    assert not others, others
    ext = rep["extended_model"]["unmodelled_mode"]
    assert abs(ext["chassis"]["m3"] + ext["mass_kg"] - rep["extended_model"]["parameters"]["m3"]) < 1e-6
    assert rep["gain"]["after"] < 0.1 * rep["gain"]["before"], rep["gain"]
    be = rep["gain"]["beta_error"]
    assert be["after"]["rms_dynamic"] < 0.8 * be["before"]["rms_dynamic"], be


def test_the_causes_beside_a_mode_are_chosen_on_the_mode_as_last_sized(tmp_path):
    """``vehicle-modes/indep`` run 8 (``gen_exudyn.design_modes(32, 20261218)``): an engine of 10 %
    of the body 0.70 m ahead on 11.15 Hz mounts and a front spring x0.9868, class D road at 18 m/s,
    1 kHz, 17.6 s. The mode is resized beside the causes first chosen, and those causes must then
    be chosen and sized again on it: kept at their sizes on the mode before it moved (0.5 % in
    frequency), they left 5.9 N in the heave channel, and a damper x1.006 and a -64 us delay on f1
    stood in for the rest, confirmed. Now: the spring alone, within 0.2 % of the truth."""
    from benchmarks.validation import gen_exudyn as ge

    paths = ge.make_run(ge.design_modes(32, 20261218)[8], str(tmp_path))
    k3 = next(e["value"] for e in paths["case"]["effects"] if e.get("parameter") == "k3")
    rep = _diagnose(paths)
    assert rep["findings"][0]["cause"] == "unmodelled_mode" and rep["findings"][0]["confirmed"], rep["findings"][:3]
    conf = [f for f in rep["findings"] if f["cause"] in SYSTEMATIC and f.get("confirmed")]
    assert [(f["cause"], f.get("parameter")) for f in conf] == [("parameter_error", "k3")], conf
    assert abs(conf[0]["estimate"] - k3) < 0.002 * k3, conf[0]


def test_a_cause_beside_a_mode_carries_the_modes_frequency_error(tmp_path):
    """``vehicle-modes/indep`` run 27 (an engine of 12 % of the body 0.74 m ahead on 10.5 Hz mounts, a
    front damper x1.0056, class C road at 16 m/s, 500 Hz): the damper's interval carries the mode's
    frequency error as sized beside it (``_mode.settled_half``, ``_mode.mode_shift_var``), holds the
    truth and still excludes no error. With the mode's reported interval, which holds the search's
    move of 0.16 Hz to the final size, it read [0.983, 1.028] while confirmed. Within 1 % of the
    model, it is listed unconfirmed: a difference no engineer acts on (issue #47)."""
    from benchmarks.validation import gen_exudyn as ge

    paths = ge.make_run(ge.design_modes(32, 20261218)[27], str(tmp_path))
    d3 = next(e["value"] for e in paths["case"]["effects"] if e.get("parameter") == "d3")
    rep = _diagnose(paths)
    f = next(f for f in rep["findings"] if f["cause"] == "parameter_error" and f.get("parameter") == "d3")
    assert "unmodelled mode's frequency error" in f["evidence"], f
    assert f["confirmed"] is False and "within 0.01 (ratio) of no effect" in f["evidence"], f
    assert f["interval"][0] <= d3 <= f["interval"][1] and f["interval"][0] > 1.0, (d3, f["interval"])


def test_the_rigid_car_of_the_same_world_names_no_mode(tmp_path):
    """The same car without the engine (the model is then exact): no mode, no confirmed systematic
    finding, the force noise first."""
    rep = _diagnose(_case(tmp_path, None, []))
    assert not [f for f in rep["findings"] if f["cause"] == "unmodelled_mode"], rep["findings"]
    assert not [f for f in rep["findings"] if f["cause"] in SYSTEMATIC and f.get("confirmed")], rep["findings"]
    assert rep["findings"][0]["cause"] == "force_noise"


def test_a_run_without_heave_says_it_could_not_look(tmp_path):
    """Pitch alone: the acceleration under a place of the body is not known, so no mode is looked
    for, and the notes say so."""
    from jaxdrift.diagnosis.vehicle import diagnose_vehicle_run
    from jaxdrift.io._csvio import read_vehicle_run

    paths = _case(tmp_path, {"share": 0.10, "x": 0.8, "freq": 11.0, "zeta": 0.1}, [])
    run = read_vehicle_run(paths["csv"])
    run.channels.pop("z3")
    with open(paths["model"]) as fh:
        model = json.load(fh)
    rep = diagnose_vehicle_run(run, model, with_simulation=False)
    assert not [f for f in rep["findings"] if f["cause"] == "unmodelled_mode"]
    assert any("unmodelled_mode" in n and "pitch and heave" in n for n in rep["notes"]), rep["notes"]


def test_the_force_driven_model_with_the_mounted_mass_follows_exudyn():
    """jaxdrift's force-driven half-car carrying the engine (``MountedMass``, 12 states), driven by
    Exudyn's noise-free tyre forces (1 kHz, 6 s), follows Exudyn's pitch and heave above 0.5 Hz
    (below it the force-driven model drifts, whatever the model): 3x closer than the rigid car
    (measured 3.5e-6 against 1.2e-5 rad, 2.6e-6 against 1.4e-5 m), and closer than the same mount
    10 % stiffer or on the other side of the centre of mass."""
    import tempfile

    from benchmarks.validation import gen_exudyn as ge
    from jaxdrift.diagnosis.vehicle._extend import _dynamic_rms, _force_driven_pitch
    from jaxdrift.io._csvio import read_vehicle_run
    from jaxdrift.models import MountedMass

    c = ge.make_case({"index": 0, "stratum": "test", "what": [], "seed": 11, "design": "modes", "mount": "engine"})
    c.update(effects=[{"cause": "force_noise", "value": 0.0}], fs=1000.0, duration=6.0, precision=12)
    with tempfile.TemporaryDirectory() as tmp:
        run = read_vehicle_run(ge.make_run(c, tmp)["csv"])
    model, e = c["model"], c["engine"]
    xg = e["x"] - e["mass"] * e["x"] / model["m3"]  # from the whole car's centre of mass
    forces = {ch: run[ch] for ch in ("f1", "f2")}
    variants = [MountedMass(0.0, 0.0, 0.0, 0.0), MountedMass(e["mass"], xg, e["k"], e["d"]),
                MountedMass(e["mass"], xg, 1.1 * e["k"], e["d"]), MountedMass(e["mass"], -xg, e["k"], e["d"])]
    ys = _force_driven_pitch(run, [model] * 4, [forces] * 4, None, variants)
    pitch = [_dynamic_rms(y[:, 3] - run["beta"], run.dt) for y in ys]
    heave = [_dynamic_rms(y[:, 2] - run["z3"], run.dt) for y in ys]
    assert pitch[1] < pitch[0] / 3 and heave[1] < heave[0] / 3, (pitch, heave)
    assert pitch[1] < min(pitch[2:]) and heave[1] < min(heave[2:]), (pitch, heave)
    plain = _force_driven_pitch(run, [model], [forces])[0]
    assert np.max(np.abs(plain - ys[0][:, :10])) < 1e-9  # a zero mass is the rigid car


def test_a_chassis_that_bends_is_named_and_confirms_nothing(tmp_path):
    """``vehicle-bending/indep`` run 3 (``gen_exudyn.design_bending(30, 20261221)``): a chassis in two
    parts on a 21.3 Hz hinge, pitch and heave measured, no other effect, the model the rigid car.
    The mode search names a mass on a spring (155 kg at 21.2 Hz, z = 841) that, resized beside the
    causes chosen, grows to 380 kg at 19.9 Hz: withdrawn. The first choice of causes then stood, d4
    x 0.874 confirmed. Now the withdrawn resonance reads as a body that is not rigid: a
    ``model_form`` finding on the body leads (the enforced moment rings at 21.75 Hz), and nothing
    fitted on the rigid model compared below it is sized alike in both bands
    (``_confirm.confirm_below_body``), so nothing is confirmed."""
    from benchmarks.validation import gen_exudyn as ge

    paths = ge.make_run(ge.design_bending(30, 20261221)[3], str(tmp_path))
    rep = _diagnose(paths)
    first = rep["findings"][0]
    assert first["cause"] == "model_form" and first["axle"] == "body", rep["findings"]
    assert first["confirmed"] is False and "withdrawn" not in first  # the finding, not the search's record
    assert abs(first["frequency_hz"] / 21.29 - 1) < 0.1  # where the moment rings (measured 21.75 Hz)
    assert not [f for f in rep["findings"] if f["cause"] in SYSTEMATIC and f.get("confirmed")], rep["findings"]
    others = [f for f in rep["findings"][1:] if f["cause"] in SYSTEMATIC]
    assert others and all("not confirmed" in f["evidence"] for f in others), others


def test_an_offset_beside_a_chassis_that_bends_is_confirmed(tmp_path):
    """``vehicle-bending/indep`` run 29: a chassis bending at 23.8 Hz and an offset of -161.1 N on f1.
    Fitted on the whole band, the rigid model's error swamped it (rss 1.6e11; the offset read
    +1240 N and was dropped, the force noise read 3877 N for 1.27 N). Compared below 0.5 and 0.3 x
    the 24 Hz the enforced moment peaks at, the offset is sized alike (-161.4 N in both) and
    confirmed; the stand-ins each band picks (a rear spring 1.10, a 0.6 ms delay) are not."""
    from benchmarks.validation import gen_exudyn as ge

    case = ge.design_bending(30, 20261221)[29]
    paths = ge.make_run(case, str(tmp_path))
    rep = _diagnose(paths)
    first = rep["findings"][0]
    assert first["cause"] == "model_form" and first["axle"] == "body", rep["findings"]
    conf = [f for f in rep["findings"] if f["cause"] in SYSTEMATIC and f.get("confirmed")]
    assert [(f["cause"], f.get("channel")) for f in conf] == [("force_offset", "f1")], rep["findings"]
    truth = next(e["value"] for e in paths["case"]["effects"] if e["cause"] == "force_offset")
    assert conf[0]["interval"][0] <= truth <= conf[0]["interval"][1], (conf[0], truth)
    noise = next(f for f in rep["findings"] if f["cause"] == "force_noise")
    assert noise["interval"][0] <= 1.2704 <= noise["interval"][1], noise


@pytest.mark.tier2
def test_a_cause_kept_beside_a_chassis_that_bends_is_checked_again_alone(tmp_path):
    """``vehicle-bending/indep`` at the fresh seed 20261231, run 14: a chassis bending at 26.4 Hz and
    an offset of -56.1 N on f2. Below 0.5 and 0.3 x the peak of the enforced moment the checks kept
    m2, a delay on f2 and crosstalk into f2; the two bands sized only the delay alike (-0.28 ms), and
    it was confirmed. Beside the two stand-ins it had passed; refit alone it explains 5 % of what is
    left of the enforced moment (82.38 -> 82.29 N m), below the share a confirmed cause must
    explain. Checked again without the stand-ins, nothing is confirmed (the scorecard's setting,
    with the re-simulation; without it the bands size nothing alike)."""
    rep = _bending_body_first(tmp_path, 20261231, 14)
    delay = next(f for f in rep["findings"] if f["cause"] == "force_delay")
    assert "small unexplained residual" in delay["evidence"], delay


@pytest.mark.tier2
def test_a_chassis_that_bends_is_judged_on_the_channels_it_acts_on(tmp_path):
    """``vehicle-bending/indep`` run 23: a van's chassis bending at 22.7 Hz, a scale of 0.9935 on f1,
    pitch, heave and both spring travels measured. The resonance of negative mass (-88.8 kg, z =
    -2.2e3) lowered the residual of every row by 22 % of what it left, below the share a cause must
    explain, as the spring travels' residual, which no mode touches, counted in it; the rigid model
    then confirmed -6.4 % crosstalk into f1 and a scale of 1.0345 on f1. Judged on the heave and
    moment rows it explains 35 %: the body finding leads, near the bending frequency, and nothing is
    confirmed."""
    _bending_body_first(tmp_path, 20261221, 23, 22.66)


@pytest.mark.tier2
def test_a_mode_that_raises_a_channels_residual_is_withdrawn(tmp_path):
    """``vehicle-bending/indep`` run 28: a van's chassis bending at 29.6 Hz and an offset of +78.5 N
    on f1. The search named a mass of 522 kg at 25.3 Hz; beside the causes chosen with it (an offset
    of +953 N and -8.9 % crosstalk on f1, I x 0.935, all three confirmed) the mode's part raised the
    heave residual from 193 to 382 N RMS, the causes on f1 taking its heave part back. A mass on its
    own spring lowers each channel it shows in (heave 16 to 2000 times on the 38 modes of the modes and
    Exudyn worlds): this one is withdrawn, the body is read as not rigid, and nothing is confirmed."""
    _bending_body_first(tmp_path, 20261221, 28, 29.57)


def test_residual_channels_that_disagree_hold_more_than_noise():
    """The rule that demotes a noise estimate to a bound (``_report._levels_apart``): channels
    within 1.5x of each other, or apart by less than 4 standard errors, agree (the last vehicle card's 22
    runs whose estimate held: 1.25x at most); the whole car's heave at 197 N beside its moment at
    3.2 N does not, and the lowest channel is named for the bound."""
    from jaxdrift.diagnosis.vehicle._report import _levels_apart

    assert _levels_apart({"moment": (1.637, 209), "heave": (1.309, 128)}) is None
    assert _levels_apart({"moment": (3.0, 6), "heave": (6.0, 6)}) is None  # 2x, but 6 dof each
    assert _levels_apart({"moment": (5.2, 291)}) is None  # one channel cannot disagree
    apart = _levels_apart({"moment": (3.22, 486), "heave": (197.2, 481), "spring1": (4.16, 468),
                           "spring2": (2.84, 494)})
    assert apart is not None and apart[0][0] == "spring2" and apart[1][0] == "heave"


@pytest.mark.tier2
def test_a_whole_cars_roll_in_the_heave_is_no_noise_estimate(tmp_path):
    """``vehicle-car3d/indep`` at seed 20261232, run 14: a passenger car in three dimensions, its
    centre of mass 3.7 cm beside the centreline its heave is measured on, a delay of 0.92 ms on f1
    and 2.75 N of force noise. The roll reaches the heave channel alone (197 N there, 2.8-4.2 N on
    the others), and the noise read 98.6 [86.6, 110.9] N as an estimate; now an upper bound from
    the lowest channel, holding the truth and below 10 N; the delay is still found and confirmed."""
    from benchmarks.validation import gen_exudyn as ge

    paths = ge.make_run(ge.design_car3d(30, 20261232)[14], str(tmp_path))
    rep = _diagnose(paths, with_simulation=True)
    assert rep["findings"][0]["cause"] == "force_delay" and rep["findings"][0]["confirmed"], rep["findings"]
    noise = next(f for f in rep["findings"] if f["cause"] == "force_noise")
    assert noise["estimate_kind"] == "upper_bound" and 2.75 <= noise["interval"][1] < 10.0, noise
