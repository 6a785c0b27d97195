"""A test world nobody here wrote the equations of: runs of a car whose engine sits on mounts,
simulated by a third-party multibody code (Exudyn, ``exudyn_halfcar.py``), diagnosed against the
rigid car of the same total mass, centre of mass and inertia (what a user's model is). The engine
is a degree of freedom the model lacks: the runs measure what the diagnosis says about a model-form
error (issue 48), and whether sensor effects hidden beside it are still found.

A case (``design``): a vehicle of ``gen_vehicle.VEHICLES`` (each value x 0.9-1.1), an engine of
8-12 % of the body's mass on mounts of 8-15 Hz (damping ratio 0.05-0.2) at the centre of mass or
0.5-1.0 of the front lever ahead of it, an ISO 8608 road of class B-D at 10-25 m/s (straight lines
between profile points on half the runs), 500 or 1000 Hz, 10-20 s, pitch and heave (and on half the
runs both spring travels) measured, 0.5-3 N of force noise, and on half the runs one sensor effect
(an offset, scale or delay on f1 or f2, ``gen_vehicle.draw_effect``). The files follow
docs/measured-data.md as ``gen_vehicle`` writes them; the truth lists the sensor effects and the
force noise (the scorecard's truth) and the engine under ``model_form``.

``design_modes``: the model-form world (scorecard ``vehicle-modes/indep``): an engine (8-15 Hz), a
seat or payload (4-8 % of the body on 3-6 Hz, damping ratio 0.15-0.35, from half the rear lever
behind the centre of mass to 0.3 of the front one ahead) or the rigid car, each alone, with a sensor
effect, or (engine and seat) with an error of a chassis spring or damper (the car simulated with
the true one, the model given the drawn one).

``design_bending``: the bending-chassis world (scorecard ``vehicle-bending/indep``): the chassis in
two parts on a hinge (a first bending mode of 15-30 Hz), pitch and heave measured on the part that
holds the centre of mass, alone, with a sensor effect or with a chassis spring or damper error.

``design_car3d``: the whole-car world (scorecard ``vehicle-car3d/indep``): a car in three dimensions
(``exudyn_car3d.py``) on left and right tracks that differ (``CAR3D``), measured as a half-car, the
model given its half-car; the centre of mass up to 4 cm to the side couples its roll into heave and
pitch. Its strata are the bending world's.

``design_struts``: the inclined-strut world (scorecard ``vehicle-struts/indep``): each suspension a
strut (``exudyn_struts.py``) leaning 6-20 deg forward or back, the wheels on control arms 0.1-0.3 m
below the centre of mass, the model given the struts' half-car equivalent at the static pose; what
remains (the struts' forces turning with pitch and travel, the preload's side force, the wheels
moving with the body) is the model-form error, with no cause of its own. Strata as the bending
world's.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import CubicSpline

from benchmarks.validation import gen_vehicle as gv
from benchmarks.validation.exudyn_car3d import roll_mode, simulate_car3d
from benchmarks.validation.exudyn_halfcar import bending_modes, hinge, rigid_equivalent, simulate_exudyn
from benchmarks.validation.exudyn_struts import simulate_struts, strut_pose

SUBSTEPS = 10


def design(n: int, seed: int) -> list[dict]:
    """``n`` cases: half effect-free (force noise only), half one sensor effect; shuffled."""
    plan = [("noise", ())] * (n - n // 2) + [("single", (gv.SENSOR[i % len(gv.SENSOR)],)) for i in range(n // 2)]
    rng = np.random.default_rng([seed, 0xE40])
    order = rng.permutation(len(plan))
    return [{"index": i, "stratum": plan[j][0], "what": [list(w) for w in plan[j][1]], "seed": int(rng.integers(2**31)),
             "design": "exudyn"} for i, j in enumerate(order)]


#: the masses on their own spring a real car carries (``design_modes``): share of the body's mass,
#: mount frequency [Hz], damping ratio, and place (share of the front lever ``b`` ahead of the
#: chassis's centre of mass; negative: share of the rear lever ``a`` behind it)
MOUNTS = {"engine": {"share": (0.08, 0.12), "freq": (8.0, 15.0), "zeta": (0.05, 0.2), "place": (0.5, 1.0)},
          "seat": {"share": (0.04, 0.08), "freq": (3.0, 6.0), "zeta": (0.15, 0.35), "place": (-0.5, 0.3)}}
#: the parameter errors of the model-form world (the chassis springs and dampers: the rigid
#: equivalent carries the rest)
MODE_PARAMS = ("k3", "k4", "d3", "d4")


def design_modes(n: int, seed: int) -> list[dict]:
    """``n`` cases of the model-form world: 50 % an engine on mounts, 30 % a seat or payload on its
    spring, 20 % the rigid car (no mode: the effect-free check); each alone with force noise, or
    with one sensor effect, or (engine and seat) one error of a chassis spring or damper."""
    rng = np.random.default_rng([seed, 0xE41])
    plan = []
    for i in range(n):
        u = (i + 0.5) / n
        mount = "engine" if u < 0.5 else ("seat" if u < 0.8 else "rigid")
        kinds = ("noise", "single") if mount == "rigid" else ("noise", "single", "param")
        plan.append((mount, kinds[i % len(kinds)]))
    order = rng.permutation(n)
    out = []
    for i, j in enumerate(order):
        mount, stratum = plan[j]
        what = [list(gv.SENSOR[int(rng.integers(len(gv.SENSOR)))])] if stratum == "single" else (
            [["parameter_error", MODE_PARAMS[int(rng.integers(len(MODE_PARAMS)))]]] if stratum == "param" else [])
        out.append({"index": i, "stratum": f"{mount}/{stratum}", "what": what, "seed": int(rng.integers(2**31)),
                    "design": "modes", "mount": mount})
    return out


#: the bending chassis (``design_bending``): the front part's share of the body's mass, the parts'
#: places (``exudyn_halfcar.split_chassis``), the hinge (share of the radius of gyration ahead of
#: the centre of mass, either side), the free chassis's first bending frequency [Hz] and damping ratio
BENDING = {"share": (0.4, 0.6), "lam": (0.6, 0.8), "hinge": (0.05, 0.3), "freq": (15.0, 30.0), "zeta": (0.02, 0.08)}


def design_bending(n: int, seed: int) -> list[dict]:
    """``n`` cases of the bending-chassis world (issue 48's chassis with a first bending mode at
    15-30 Hz, the model given the rigid car of the same mass, centre of mass and inertia): a third
    each alone with force noise, with one sensor effect, or with an error of a chassis spring or
    damper."""
    return _thirds(n, [seed, 0xE42], "bending")


def design_car3d(n: int, seed: int) -> list[dict]:
    """``n`` cases of the whole-car world (``CAR3D``: a car in three dimensions on a road whose left
    and right tracks differ, measured as a half-car, the model given its half-car): a third each
    alone with force noise, with one sensor effect, or with an error of a chassis spring or damper
    (of both corners of the axle)."""
    return _thirds(n, [seed, 0xE43], "car3d")


def design_struts(n: int, seed: int) -> list[dict]:
    """``n`` cases of the inclined-strut world (``STRUTS``: the model given the struts' half-car
    equivalent): a third each alone with force noise, with one sensor effect, or with an error of a
    strut's spring or damper (the truth its wheel rate's or damping's ratio)."""
    return _thirds(n, [seed, 0xE44], "struts")


def _thirds(n: int, salt: list, design: str) -> list[dict]:
    rng = np.random.default_rng(salt)
    kinds = ("noise", "single", "param")
    order = rng.permutation(n)
    out = []
    for i, j in enumerate(order):
        stratum = kinds[j % 3]
        what = [list(gv.SENSOR[int(rng.integers(len(gv.SENSOR)))])] if stratum == "single" else (
            [["parameter_error", MODE_PARAMS[int(rng.integers(len(MODE_PARAMS)))]]] if stratum == "param" else [])
        out.append({"index": i, "stratum": f"{design}/{stratum}", "what": what, "seed": int(rng.integers(2**31)),
                    "design": design})
    return out


#: the whole car (``design_car3d``): track [m], the centre of mass's distance to the side of the
#: centreline [m] (either side), roll inertia as a share of ``m3 (track / 2) ** 2``, and the
#: correlation of the right track's profile with the left's (0: independent tracks)
CAR3D = {"track": (1.4, 1.7), "y_cg": (0.0, 0.04), "roll_share": (0.4, 0.8), "coherence": (0.0, 0.9)}


#: the inclined struts (``design_struts``): each strut's angle from the vertical [rad] (either way,
#: front and rear drawn apart), its length [m], and the wheels' depth below the centre of mass [m]
STRUTS = {"theta": (0.1, 0.35), "L": (0.35, 0.6), "H": (0.1, 0.3)}


def _struts(rng) -> dict:
    S = STRUTS
    return {"kind": "struts", "theta": [float(rng.choice([-1.0, 1.0]) * rng.uniform(*S["theta"])) for _ in range(2)],
            "L": [float(rng.uniform(*S["L"])) for _ in range(2)], "H": float(rng.uniform(*S["H"]))}


def _car3d(rng, car: dict) -> dict:
    C = CAR3D
    w = float(rng.uniform(*C["track"]))
    shape = {"kind": "car3d", "track": w, "y_cg": float(rng.choice([-1.0, 1.0]) * rng.uniform(*C["y_cg"])),
             "Ixx": float(rng.uniform(*C["roll_share"]) * car["m3"] * (0.5 * w) ** 2),
             "coherence": float(rng.uniform(*C["coherence"]))}
    return {**shape, "roll_hz": roll_mode(car, shape)["frequency_hz"]}


def _bending(rng, car: dict) -> dict:
    """A bending chassis for ``car`` (``BENDING``), its hinge spring set for the drawn free frequency;
    ``frequency_hz`` is the whole car's mode that bends the hinge (``bending_modes``)."""
    B = BENDING
    r = math.sqrt(car["I"] / car["m3"])
    bd = {"share": float(rng.uniform(*B["share"])), "lam": float(rng.uniform(*B["lam"])),
          "x_hinge": float(rng.choice([-1.0, 1.0]) * rng.uniform(*B["hinge"]) * r)}
    f, zeta = float(rng.uniform(*B["freq"])), float(rng.uniform(*B["zeta"]))
    bd = {**hinge(car, bd, f, zeta), "free_hz": f, "damping_ratio": zeta, "kind": "bending"}
    bd["frequency_hz"] = bending_modes(car, bd)["car_hz"]
    return bd


def _mount(rng, car: dict, kind: str) -> dict | None:
    """A mass on its spring of the kind ``kind`` (``MOUNTS``), or None for the rigid car."""
    if kind == "rigid":
        return None
    m = MOUNTS[kind]
    me = float(rng.uniform(*m["share"]) * car["m3"])
    f_mount = float(rng.uniform(*m["freq"]))
    zeta = float(rng.uniform(*m["zeta"]))
    u = float(rng.uniform(*m["place"]))
    xe = u * car["b"] if u >= 0 else u * car["a"]
    return {"mass": me, "x": xe, "k": me * (2 * math.pi * f_mount) ** 2, "d": 2 * zeta * me * 2 * math.pi * f_mount,
            "frequency_hz": f_mount, "damping_ratio": zeta, "kind": kind}


def make_case(case: dict) -> dict:
    rng = np.random.default_rng(case["seed"])
    vkind = str(rng.choice(sorted(gv.VEHICLES)))
    car = {k: float(v * rng.uniform(0.9, 1.1)) for k, v in gv.VEHICLES[vkind].items()}
    car["g"] = gv.G
    bending = car3d = struts = None
    if case.get("design") == "modes":
        engine = _mount(rng, car, case["mount"])
    elif case.get("design") == "bending":
        engine, bending = None, _bending(rng, car)
    elif case.get("design") == "car3d":
        engine, car3d = None, _car3d(rng, car)
    elif case.get("design") == "struts":
        engine, struts = None, _struts(rng)
    else:  # the first world's draws, unchanged
        me = float(rng.uniform(0.08, 0.12) * car["m3"])
        f_mount = float(rng.uniform(8.0, 15.0))
        zeta = float(rng.uniform(0.05, 0.2))
        xe = 0.0 if rng.random() < 0.5 else float(rng.uniform(0.5, 1.0) * car["b"])
        engine = {"mass": me, "x": xe, "k": me * (2 * math.pi * f_mount) ** 2,
                  "d": 2 * zeta * me * 2 * math.pi * f_mount, "frequency_hz": f_mount, "damping_ratio": zeta}
    cls = str(rng.choice(["B", "C", "D"]))
    speed = float(rng.uniform(10.0, 25.0))
    fs = float(rng.choice([500.0, 1000.0]))
    dur = float(round(rng.uniform(10.0, 20.0), 1))
    chans = ["beta", "z3"] + (["s1", "s2"] if rng.random() < 0.5 else [])
    model = dict(car) if engine is None else rigid_equivalent(car, engine)
    if struts:
        model = strut_pose(car, struts)["equivalent"]
    effects = [gv.draw_effect(rng, *w, model, duration=dur) for w in case["what"]]
    true_car = dict(car)
    for e in effects:  # a chassis spring or damper the model has wrong: the car is simulated with the true one
        if e["cause"] == "parameter_error":
            true_car[e["parameter"]] = car[e["parameter"]] * e["value"]
            if struts:  # the truth: the ratio of the strut's wheel rate (damping) to the model's
                e["value"] = strut_pose(true_car, struts)["equivalent"][e["parameter"]] / model[e["parameter"]]
    effects.append({"cause": "force_noise", "value": float(math.exp(rng.uniform(math.log(0.5), math.log(3.0))))})
    return {**case, "vehicle_kind": vkind, "car": true_car, "engine": engine, "bending": bending, "car3d": car3d,
            "struts": struts, "model": model,
            "road_class": cls,
            "road_interp": str(rng.choice(["spline7", "linear"])), "speed": speed, "fs": fs, "duration": dur,
            "channels": chans, "channel_set": "_".join(chans), "precision": int(rng.integers(7, 10)), "t0": 0.0,
            "lead_in": float(rng.uniform(0.2, 0.5)), "effects": effects, "motion_noise": {},
            "column_order_seed": int(rng.integers(2**31)), "road_seed": int(rng.integers(2**31)),
            "noise_seed": int(rng.integers(2**31))}


def generate(case: dict) -> dict:
    """The measured columns of a case (gen_vehicle's contract)."""
    v, fs, T = case["speed"], case["fs"], case["duration"]
    x0 = -v * case["lead_in"]
    rng = np.random.default_rng(case["road_seed"])
    road = gv.FilteredRoad(rng, case["road_class"], x0 + v * (T + 0.2) + 1.0, interp=case["road_interp"])
    if case.get("car3d"):
        fine = _car3d_signals(case, road, gv.FilteredRoad(rng, case["road_class"], x0 + v * (T + 0.2) + 1.0,
                                                          interp=case["road_interp"]), x0)
    elif case.get("struts"):
        fine = simulate_struts(case["car"], road, v, x0, T, fs, case["struts"], SUBSTEPS, fine=True)
    else:
        fine = _halfcar_signals(case, road, x0)
    tf = fine["t"]
    n = int(round(T * fs)) + 1
    tau = np.arange(n) / fs
    idx = np.arange(n) * SUBSTEPS
    cols = {"t": case["t0"] + tau}
    delay = {e["channel"]: e["value"] for e in case["effects"] if e["cause"] == "force_delay"}
    for ch in ("f1", "f2"):
        x = CubicSpline(tf, fine[ch])(np.maximum(tau - delay[ch], 0.0)) if ch in delay else fine[ch][idx]
        for e in case["effects"]:
            if e.get("channel") == ch and e["cause"] == "force_scale":
                x = x * e["value"]
        for e in case["effects"]:
            if e.get("channel") == ch and e["cause"] == "force_offset":
                x = x + e["value"]
        cols[ch] = x
    nrng = np.random.default_rng(case["noise_seed"])
    sig = next(e["value"] for e in case["effects"] if e["cause"] == "force_noise")
    for ch in ("f1", "f2"):
        cols[ch] = cols[ch] + sig * nrng.standard_normal(n)
    for c in case["channels"]:
        cols[c] = fine[c][idx]
    return cols


def _halfcar_signals(case: dict, road, x0: float) -> dict:
    """The planar car's (engine, bending chassis) signals at every solver step."""
    car, eng, v, fs, T = case["car"], case["engine"], case["speed"], case["fs"], case["duration"]
    sim = simulate_exudyn(car, road, v, x0, T, fs, SUBSTEPS, engine=eng, fine=True, bending=case.get("bending"))
    tf = sim["t"]
    L = car["a"] + car["b"]
    e1, de1 = np.array([road(x0 + v * t) for t in tf]).T
    e2, de2 = np.array([road(x0 + v * t - L) for t in tf]).T
    fine = {"f1": car["k1"] * (sim["z1"] - e1) + car["d1"] * (sim["v1"] - v * de1),
            "f2": car["k2"] * (sim["z2"] - e2) + car["d2"] * (sim["v2"] - v * de2)}
    xc = 0.0 if eng is None else eng["mass"] * eng["x"] / case["model"]["m3"]
    sb = np.sin(sim["beta"])
    fine["z3"] = sim["z3"] - xc * sb  # the rigid car's centre of mass, on the chassis
    fine["beta"] = sim["beta"]
    if case.get("bending"):  # the travel between the wheel and the chassis point above it
        fine["s1"], fine["s2"] = sim["y1"] - sim["z1"], sim["y2"] - sim["z2"]
    else:
        fine["s1"] = sim["z3"] - sim["z1"] - car["b"] * sb
        fine["s2"] = sim["z3"] - sim["z2"] + car["a"] * sb
    fine["t"] = tf
    return fine


def _car3d_signals(case: dict, left, other, x0: float) -> dict:
    """The whole car's signals at every solver step, measured as a half-car; its right track is
    ``coherence`` of the left one's profile and the rest ``other``'s (same class, same variance)."""
    c = case["car3d"]
    right = MixedRoad(left, other, c["coherence"])
    return simulate_car3d(case["car"], (left, right), case["speed"], x0, case["duration"], case["fs"], c, SUBSTEPS,
                          fine=True)


class MixedRoad:
    """``c`` of one track plus ``sqrt(1 - c^2)`` of an independent one: a profile of the same
    spectrum whose correlation with the first is ``c``."""

    def __init__(self, first, other, c: float):
        self.first, self.other, self.c, self.s = first, other, c, math.sqrt(1.0 - c * c)

    def __call__(self, x):
        (e1, d1), (e2, d2) = self.first(x), self.other(x)
        return self.c * e1 + self.s * e2, self.c * d1 + self.s * d2


def make_run(case: dict, out_dir: str, name: str | None = None) -> dict:
    """Draw (if needed), simulate and write one run (``gen_vehicle.write_run``); returns the paths."""
    if "model" not in case:
        case = make_case(case)
    cols = generate(case)
    paths = gv.write_run(out_dir, name or f"exudyn_{case['index']:04d}", case, cols)
    return {**paths, "case": case}
