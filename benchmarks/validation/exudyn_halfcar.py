"""The seed's half-car built from a third-party multibody code's parts (Exudyn), a test world that
shares no equations with jaxdrift (``pip install -e ".[multibody]"``; never used by jaxdrift itself).

Parts (Exudyn 1.13): the chassis a 2D rigid body (``NodeRigidBody2D`` + ``ObjectRigidBody2D``, mass
m3, inertia I), each wheel a point mass (``NodePoint2D`` + ``MassPoint2D``), each suspension a
Cartesian spring-damper acting vertically between the wheel and the chassis point at its lever
(b ahead, a behind), each tyre a Cartesian spring-damper from a ground point whose vertical
force follows the road under the tyre (a spring user function), gravity a mass-proportional load.
The plane's Y axis is the paper's z (down), and the body's rotation is minus the paper's pitch; the
suspension springs carry the static preload as the paper's do (no offset). Integrated by Exudyn's
generalized-alpha solver (spectral radius 1, no numerical damping) at ``substeps`` fixed steps per
output sample.

``python benchmarks/validation/exudyn_halfcar.py`` compares it with jaxdrift's half-car
(``jaxdrift.models._halfcar.road_driven_rhs``, integrated by scipy at rtol 1e-10) on one road and
writes ``benchmarks/results/exudyn-halfcar.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(os.path.dirname(HERE)))

from benchmarks.validation import gen_vehicle as gv  # noqa: E402


def simulate_exudyn(p: dict, road, v: float, x0: float, t_end: float, fs: float, substeps: int = 10,
                    engine: dict | None = None, fine: bool = False, bending: dict | None = None) -> dict:
    """Chassis heave (at its own centre of mass) and pitch, wheel travel and rates at ``fs`` on
    [0, t_end] (t = 0: static equilibrium); ``fine``: at every solver step instead. ``engine``: a
    mass ``mass`` on a vertical mount (``k``, ``d``) at ``x`` ahead of the chassis's centre of
    mass, in static equilibrium at the start (its weight carried by the chassis's, so the wheel
    loads are those of the rigid car of total mass); adds ``ze``, its height. ``bending``: the chassis
    is two rigid bodies (``split_chassis``) on a hinge with a rotational spring-damper, preloaded
    so that the rigid car's static pose is its equilibrium (``bend0`` [rad], if given, moves the
    equilibrium's bend by it: the car starts bent, to ring); ``z3`` and ``beta`` are then the height
    of the point the car's centre of mass is at and the rotation of the part that holds it (where a
    pitch sensor sits), and ``y1``/``y2`` the chassis points above the wheels."""
    import exudyn as exu
    from exudyn.itemInterface import (CartesianSpringDamper, MarkerBodyPosition, MarkerNodePosition, MassPoint2D,
                                      NodePoint2D, NodeRigidBody2D, ObjectRigidBody2D)
    from exudyn.itemInterface import CoordinateSpringDamper, MarkerNodeCoordinate, RevoluteJoint2D

    a, b, g = p["a"], p["b"], p["g"]
    rigid = p if engine is None else rigid_equivalent(p, engine)
    z1, z2, zc, beta = gv.equilibrium(rigid)[:4]
    xc = 0.0 if engine is None else engine["mass"] * engine["x"] / (p["m3"] + engine["mass"])
    z3 = zc + xc * math.sin(beta)  # the chassis body's own centre of mass, xc behind the whole car's
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    parts = [{"m": p["m3"], "I": p["I"], "x": 0.0, "lo": -math.inf}] if bending is None else split_chassis(p, bending)
    for q in parts:  # each rigid part of the chassis at the rigid car's static pose
        q["node"] = mbs.AddNode(NodeRigidBody2D(
            referenceCoordinates=[q["x"], 0.0, 0.0],
            initialCoordinates=[q["x"] * (math.cos(beta) - 1.0), z3 - q["x"] * math.sin(beta), -beta]))
        q["body"] = mbs.AddObject(ObjectRigidBody2D(mass=q["m"], inertia=q["I"], nodeNumber=q["node"]))

    def on_chassis(x):  # the part the chassis point x ahead of the centre of mass is on, its local position
        q = max((q for q in parts if q["lo"] <= x), key=lambda q: q["lo"])
        return q, [x - q["x"], 0.0, 0.0]
    body = parts[0]["body"]
    if bending is not None:  # the hinge, and its spring preloaded by the front part's static moment about it
        rear, front = parts
        xh = bending["x_hinge"]
        mbs.AddObject(RevoluteJoint2D(markerNumbers=[
            mbs.AddMarker(MarkerBodyPosition(bodyNumber=q["body"], localPosition=[xh - q["x"], 0.0, 0.0])) for q in parts]))
        s_front = p["m3"] * g * a / (a + b)
        tau = (front["m"] * g * (front["x"] - xh) - s_front * (b - xh)) * math.cos(beta)
        mbs.AddObject(CoordinateSpringDamper(
            markerNumbers=[mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=q["node"], coordinate=2)) for q in parts],
            stiffness=bending["k"], damping=bending["d"], offset=-tau / bending["k"] + bending.get("bend0", 0.0)))
    wheels = []
    for x, z, m in ((b, z1, p["m1"]), (-a, z2, p["m2"])):
        n = mbs.AddNode(NodePoint2D(referenceCoordinates=[x, 0.0], initialCoordinates=[0.0, z]))
        wheels.append((n, mbs.AddObject(MassPoint2D(mass=m, nodeNumber=n))))
    bodies = [q["body"] for q in parts] + [wheels[0][1], wheels[1][1]]
    if engine is not None:
        ye = z3 - engine["x"] * math.sin(beta) + engine["mass"] * g / engine["k"]
        ne = mbs.AddNode(NodePoint2D(referenceCoordinates=[engine["x"], 0.0], initialCoordinates=[0.0, ye]))
        bodies.append(mbs.AddObject(MassPoint2D(mass=engine["mass"], nodeNumber=ne)))
        mbs.AddObject(CartesianSpringDamper(
            markerNumbers=[mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[engine["x"], 0.0, 0.0])),
                           mbs.AddMarker(MarkerNodePosition(nodeNumber=ne))],
            stiffness=[0.0, engine["k"], 0.0], damping=[0.0, engine["d"], 0.0]))
    add_gravity(mbs, bodies, [0.0, g, 0.0])
    def sensor(node, what):
        return node_sensor(mbs, node, what)
    sensors = [sensor(q["node"], "Coordinates") for q in parts]
    if engine is not None:
        sensors.append(sensor(ne, "Coordinates"))
    for i, ((n, _), x) in enumerate(zip(wheels, (b, -a))):  # each wheel under its chassis point
        mw = mbs.AddMarker(MarkerNodePosition(nodeNumber=n))
        q, local = on_chassis(x)
        mc = mbs.AddMarker(MarkerBodyPosition(bodyNumber=q["body"], localPosition=local))
        k, d = (p["k3"], p["d3"]) if i == 0 else (p["k4"], p["d4"])
        # the wheel first: displacement chassis point - wheel = the paper's spring travel s_i
        mbs.AddObject(CartesianSpringDamper(markerNumbers=[mw, mc], stiffness=[0.0, k, 0.0], damping=[0.0, d, 0.0]))
        kt, dt_ = (p["k1"], p["d1"]) if i == 0 else (p["k2"], p["d2"])
        add_tyre(mbs, mw, [x, 0.0, 0.0], 1, kt, dt_, road, x0, v, 0.0 if i == 0 else a + b)
        sensors += [sensor(n, "Coordinates"), sensor(n, "Coordinates_t")]
    data = solve_stored(mbs, sensors, t_end, fs, substeps, fine)
    ch = data[0]
    out = {"t": ch[:, 0], "z3": ch[:, 2], "beta": -ch[:, 3]}
    if bending is not None:
        for q, d in zip(parts, data):
            q["y"], q["phi"] = d[:, 2], d[:, 3]
        home, _ = on_chassis(0.0)
        out.update(z3=home["y"] - home["x"] * np.sin(home["phi"]), beta=-home["phi"])
        for k, x in (("y1", b), ("y2", -a)):
            q, local = on_chassis(x)
            out[k] = q["y"] + local[0] * np.sin(q["phi"])
    data = data[len(parts) - 1:]  # data[0]: the (last) chassis part, then the engine and the wheels
    if engine is not None:
        out["ze"] = data[1][:, 2]
        data = data[1:]
    out.update(z1=data[1][:, 2], v1=data[2][:, 2], z2=data[3][:, 2], v2=data[4][:, 2])
    return out


def add_tyre(mbs, wheel_marker: int, at: list, axis: int, kt: float, dt: float, road, x0: float, v: float,
             lag: float, off: float = 0.0) -> None:
    """A tyre: a spring-damper along ``axis`` from a ground point ``at`` to the wheel, its force
    ``kt (u - e) + dt (du - v de/dx) + off`` with ``(e, de/dx) = road(x0 + v t - lag)`` under it."""
    from exudyn.itemInterface import CartesianSpringDamper, MarkerNodePosition, NodePointGround

    ground = mbs.AddMarker(MarkerNodePosition(nodeNumber=mbs.AddNode(NodePointGround(referenceCoordinates=at))))
    k, d = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
    k[axis], d[axis] = kt, dt

    def tyre(mbs_, t, item, u, du, k_, d_, o_):
        e, de = road(x0 + v * t - lag)
        f = [0.0, 0.0, 0.0]
        f[axis] = kt * (u[axis] - e) + dt * (du[axis] - v * de) + off
        return f
    mbs.AddObject(CartesianSpringDamper(markerNumbers=[ground, wheel_marker], stiffness=k, damping=d,
                                        springForceUserFunction=tyre))


def add_gravity(mbs, bodies: list, g_vector: list) -> None:
    """Gravity ``g_vector`` on every body of ``bodies`` (a mass-proportional load)."""
    from exudyn.itemInterface import LoadMassProportional, MarkerBodyMass

    for obj in bodies:
        mbs.AddLoad(LoadMassProportional(markerNumber=mbs.AddMarker(MarkerBodyMass(bodyNumber=obj)), loadVector=g_vector))


def node_sensor(mbs, node: int, what: str) -> int:
    """A sensor storing ``what`` (an ``exudyn.OutputVariableType`` name) of ``node`` in memory."""
    import exudyn as exu
    from exudyn.itemInterface import SensorNode

    return mbs.AddSensor(SensorNode(nodeNumber=node, storeInternal=True, writeToFile=False,
                                    outputVariableType=getattr(exu.OutputVariableType, what)))


def solve_stored(mbs, sensors: list, t_end: float, fs: float, substeps: int, fine: bool,
                 newton_atol: float | None = None) -> list:
    """Assemble ``mbs``, integrate it by the generalized-alpha solver (spectral radius 1: no
    numerical damping) at ``substeps`` fixed steps per sample of ``fs`` to ``t_end``, and return
    each sensor's stored data (at every step if ``fine``, else at ``fs``). ``newton_atol``: Newton's
    absolute tolerance [N] where Exudyn's default is under the round-off of large internal forces."""
    import exudyn as exu

    mbs.Assemble()
    s = exu.SimulationSettings()
    n_out = int(round(t_end * fs))
    s.timeIntegration.numberOfSteps = n_out * substeps
    s.timeIntegration.endTime = n_out / fs
    s.timeIntegration.generalizedAlpha.spectralRadius = 1.0
    s.timeIntegration.verboseMode = 0
    if newton_atol is not None:
        s.timeIntegration.newton.absoluteTolerance = newton_atol
    s.solution.file.write = False
    s.solution.sensors.writePeriod = 1.0 / fs / (substeps if fine else 1)
    exu.SolveDynamic(mbs, s)
    return [mbs.GetSensorStoredData(k) for k in sensors]


def split_chassis(p: dict, bending: dict) -> list[dict]:
    """The two rigid parts (rear, front) of a bending chassis whose mass ``m3``, centre of mass and
    inertia ``I`` (undeformed) are the rigid car's: the front part ``share`` of the mass, the parts'
    centres at ``lam r sqrt(m_other / m_own)`` ahead of and behind the car's (``r`` its radius of
    gyration: ``lam ** 2`` of ``I`` is in the parts' places, the rest their own inertia, by mass),
    the front part ahead of the hinge at ``x_hinge``. Each: mass ``m``, inertia ``I``, centre
    ``x``, and ``lo`` the chassis's first point on it."""
    m3, I, lam = p["m3"], p["I"], bending["lam"]
    mf = bending["share"] * m3
    mr = m3 - mf
    r = math.sqrt(I / m3)
    own = (1.0 - lam * lam) * I / m3
    return [{"m": mr, "I": own * mr, "x": -lam * r * math.sqrt(mf / mr), "lo": -math.inf},
            {"m": mf, "I": own * mf, "x": lam * r * math.sqrt(mr / mf), "lo": bending["x_hinge"]}]


def hinge(p: dict, bending: dict, f_hz: float, zeta: float) -> dict:
    """``bending`` with the hinge's stiffness ``k`` and damping ``d`` that give the free chassis
    (``bending_modes``) a first bending mode of ``f_hz`` and damping ratio ``zeta``."""
    w = 2 * math.pi * f_hz
    k = w * w / bending_modes(p, bending)["unit"]
    return {**bending, "k": k, "d": 2 * zeta * k / w}


def bending_modes(p: dict, bending: dict) -> dict:
    """Undamped modes of the bending chassis (linear, about the static pose; our own small model,
    not Exudyn's): ``unit`` the free chassis's squared bending frequency [rad^2/s^2] per unit hinge
    stiffness (``k = (2 pi f) ** 2 / unit``), and, where ``bending`` has ``k``, ``car_hz``: the
    frequency of the whole car's mode with the largest share of its potential energy in the hinge
    (what a resonance in the run shows), and its ``hinge_share``. Coordinates: the hinge's height,
    each part's rotation, the wheels' heights."""
    rear, front = split_chassis(p, bending)
    xh, a, b = bending["x_hinge"], p["a"], p["b"]
    rows = [(front["m"], [1, front["x"] - xh, 0, 0, 0]), (front["I"], [0, 1, 0, 0, 0]),
            (rear["m"], [1, 0, rear["x"] - xh, 0, 0]), (rear["I"], [0, 0, 1, 0, 0]),
            (p["m1"], [0, 0, 0, 1, 0]), (p["m2"], [0, 0, 0, 0, 1])]
    M = sum(m * np.outer(j, j) for m, j in rows)
    hinge = np.array([0, 1, -1, 0, 0], float)
    unit = np.linalg.eigvals(np.linalg.solve(M[:3, :3], np.outer(hinge, hinge)[:3, :3])).real.max()
    out = {"unit": float(unit)}
    if "k" in bending:
        springs = [(bending["k"], hinge), (p["k3"], np.array([1, b - xh, 0, -1, 0], float)),
                   (p["k4"], np.array([1, 0, -a - xh, 0, -1], float)), (p["k1"], np.array([0, 0, 0, 1, 0], float)),
                   (p["k2"], np.array([0, 0, 0, 0, 1], float))]
        K = sum(k * np.outer(j, j) for k, j in springs)
        w2, V = np.linalg.eig(np.linalg.solve(M, K))
        share = [bending["k"] * (hinge @ V[:, i].real) ** 2 / (V[:, i].real @ K @ V[:, i].real) for i in range(5)]
        i = int(np.argmax(share))
        out.update(car_hz=float(math.sqrt(w2[i].real) / (2 * math.pi)), hinge_share=float(share[i]))
    return out


def rigid_equivalent(p: dict, engine: dict) -> dict:
    """The rigid car an engine on mounts makes: total mass, centre of mass moved ``xc`` forward
    (``b`` shorter, ``a`` longer by it), inertia about the new centre (parallel axes)."""
    me, xe = engine["mass"], engine["x"]
    M = p["m3"] + me
    xc = me * xe / M
    return {**p, "m3": M, "I": p["I"] + p["m3"] * xc * xc + me * (xe - xc) ** 2, "a": p["a"] + xc, "b": p["b"] - xc}


def compare(seed: int = 1, road_class: str = "C", v: float = 15.0, t_end: float = 5.0, fs: float = 1000.0,
            substeps: int = 10) -> dict:
    """Exudyn's half-car against jaxdrift's equations on one road: the largest differences in heave,
    pitch and wheel travel, against each signal's range."""
    from jaxdrift.io._csvio import DEFAULT_MODEL

    p = {k: float(DEFAULT_MODEL[k]) for k in gv.KEYS}
    x0 = -1.0
    road = gv.FilteredRoad(np.random.default_rng(seed), road_class, x0 + v * (t_end + 0.5) + 1.0)
    t0 = time.time()
    ex = simulate_exudyn(p, road, v, x0, t_end, fs, substeps)
    wall = time.time() - t0
    return {"road_class": road_class, "speed_m_s": v, "duration_s": t_end, "fs_hz": fs, "substeps": substeps,
            "exudyn_wall_s": wall, "signals": against_jaxdrift(p, road, v, x0, ex)}


def against_jaxdrift(p: dict, road, v: float, x0: float, ex: dict) -> dict:
    """The largest differences of ``ex``'s wheel heights, heave and pitch from jaxdrift's half-car
    (``road_driven_rhs``, integrated by scipy's DOP853 at rtol 1e-10 from the static pose) on
    ``road`` at ``ex``'s times, each with the signal's range and their ratio."""
    from scipy.integrate import solve_ivp

    import jax

    from jaxdrift.models._halfcar import road_driven_rhs
    from jaxdrift.models._params import HalfCarParams

    P = HalfCarParams(**p)
    jax.config.update("jax_enable_x64", True)
    f = jax.jit(lambda t, y, e, de: road_driven_rhs(t, y, P, (e[0], e[1]), (de[0], de[1])))

    def rhs(t, y):
        x1 = x0 + v * t
        e1, de1 = road(x1)
        e2, de2 = road(x1 - p["a"] - p["b"])
        return np.asarray(f(t, y, np.array([e1, e2]), np.array([v * de1, v * de2])), float)

    sol = solve_ivp(rhs, (0.0, float(ex["t"][-1])), gv.equilibrium(p), method="DOP853", rtol=1e-10, atol=1e-12,
                    dense_output=True)
    y = sol.sol(ex["t"])
    out = {}
    for k, r in {"z1": y[0], "z2": y[1], "z3": y[2], "beta": y[3]}.items():
        out[k] = {"max_abs_diff": float(np.max(np.abs(ex[k] - r))), "range": float(np.ptp(r)),
                  "relative": float(np.max(np.abs(ex[k] - r)) / np.ptp(r))}
    return out


def main(argv=None, compare=compare, out_name="exudyn-halfcar.json", doc=__doc__, extra=lambda res: []):
    """The comparison's command line (also the whole car's, ``exudyn_car3d``): runs ``compare``,
    writes its JSON with the machine and versions to ``results/out_name`` and prints its lines
    (and ``extra(res)``'s)."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--substeps", type=int, default=10)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(HERE), "results", out_name))
    a = ap.parse_args(argv)
    import exudyn

    res = compare(t_end=a.duration, substeps=a.substeps)
    res.update(machine=platform.platform(), python=platform.python_version(), exudyn=exudyn.__version__)
    with open(a.out, "w") as fh:
        json.dump(res, fh, indent=1)
    for k, s in res["signals"].items():
        print(f"{k}: max |exudyn - jaxdrift| = {s['max_abs_diff']:.3g} ({s['relative']:.2g} of its range)")
    for line in extra(res):
        print(line)
    print(f"Exudyn: {res['exudyn_wall_s']:.1f} s for {a.duration:g} s at {res['fs_hz']:g} Hz x {a.substeps} steps")


if __name__ == "__main__":
    main()
