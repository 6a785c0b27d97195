"""A half-car whose suspensions are inclined struts, built from a third-party multibody code's parts
(Exudyn), a test world only (issue 48; ``pip install -e ".[multibody]"``, never used by jaxdrift).

Parts (Exudyn 1.13): the chassis a 2D rigid body, each wheel a point mass held in x to the chassis
point it hangs from (a stiff, damped horizontal Cartesian spring: the control arm), each suspension
a strut (``SpringDamper``: a spring-damper along the line between its ends, the paper's vertical
one turned by ``theta``) from the wheel to a top mount ``L`` along that line on the chassis, each
tyre a vertical spring-damper from a ground point whose force follows the road (a user function).
The wheels hang ``H`` below the centre of mass. Axes as ``exudyn_halfcar``: X forward, Y the paper's
z (down), the body's rotation minus the paper's pitch.

What a half-car lacks here: the strut's force turns with it, so its vertical share and its moment
about the centre of mass change with pitch and travel; the preload's side force makes a negative
stiffness across the strut (``F / L`` per metre); the wheels move forward and back with the pitching
body. A user's model is the strut's half-car equivalent at the static pose (``strut_equivalent``):
each wheel rate ``k cos^2 + F / L sin^2`` removed (``k`` along the strut), each damper ``d cos^2``;
all the rest is the model-form error this world measures.

``python benchmarks/validation/exudyn_struts.py`` drives it on one road against jaxdrift's half-car
with the equivalent and writes ``benchmarks/results/exudyn-struts.json``.
"""

from __future__ import annotations

import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(os.path.dirname(HERE)))

from benchmarks.validation import gen_vehicle as gv  # noqa: E402
from benchmarks.validation.exudyn_halfcar import add_gravity, add_tyre, node_sensor, solve_stored  # noqa: E402

#: the control arm that holds each wheel in x: stiffness [N/m] and damping ratio on the wheel's mass
ARM_K, ARM_ZETA = 2.0e7, 0.3
#: Newton's absolute tolerance [N]: the control arms' balanced side forces (about 1 kN) leave a
#: round-off residual of about 3e-9 N, over Exudyn's default, which stalls its Newton iteration
NEWTON_ATOL = 1e-7


def _rot(phi: float) -> np.ndarray:
    c, s = math.cos(phi), math.sin(phi)
    return np.array([[c, -s], [s, c]])


def strut_pose(p: dict, shape: dict) -> dict:
    """The static pose of the car of strut stiffnesses ``p["k3"] / cos^2`` (and dampers ``d / cos^2``)
    and its half-car equivalent. ``shape``: ``theta`` (each strut's angle from the vertical, front
    and rear, positive: its top ahead of the wheel), ``L`` (strut lengths), ``H`` (the wheels below
    the centre of mass). The pose is the equivalent half-car's static one (``gv.equilibrium``), and
    every preload (strut lengths, control arms, tyres) is set to hold it exactly; the equivalent's
    ``a`` and ``b`` are the ones the axles' static loads give (what weighing the car tells a user:
    the struts' lines of action move them by millimetres). Returns
    ``equivalent`` (the half-car parameters) and the pose's parts (``hang``/``top``: each strut's
    ends on the chassis, in its own frame; ``W``: the hang points in the global frame)."""
    th, Ls, H, g = shape["theta"], shape["L"], shape["H"], p["g"]
    ks = [p[k] / math.cos(t) ** 2 for k, t in zip(("k3", "k4"), th)]
    ds = [p[k] / math.cos(t) ** 2 for k, t in zip(("d3", "d4"), th)]
    F = [p["m3"] * g * p["a"] / (p["a"] + p["b"]) / math.cos(th[0]), p["m3"] * g * p["b"] / (p["a"] + p["b"]) / math.cos(th[1])]
    th_eff, lever = list(th), (p["a"], p["b"])
    for _ in range(20):  # a fixed point: the rates hold F and the struts' angles at the pose, F and the angles the pose
        eq = {**p, "a": lever[0], "b": lever[1]}
        for i, (k, d) in enumerate((("k3", "d3"), ("k4", "d4"))):
            c2 = math.cos(th_eff[i]) ** 2
            eq[k] = ks[i] * c2 - F[i] / Ls[i] * (1.0 - c2)
            eq[d] = ds[i] * c2
        z1, z2, z3, beta = gv.equilibrium(eq)[:4]
        R = _rot(-beta)
        xs, zw = (p["b"], -p["a"]), (z1, z2)
        axis = [np.array([math.sin(t), -math.cos(t)]) for t in th]  # each strut's line, up from the wheel
        hang = [np.array([xs[i], (H + zw[i] - z3 + xs[i] * math.sin(beta)) / math.cos(beta)]) for i in range(2)]
        top = [hang[i] + Ls[i] * axis[i] for i in range(2)]  # the chassis point each wheel hangs from, the strut's top
        W, T, u = [R @ w for w in hang], [R @ t for t in top], [R @ a for a in axis]
        cross = [T[i][0] * u[i][1] - T[i][1] * u[i][0] + W[i][1] * u[i][0] for i in range(2)]
        F_new = [float(f) for f in np.linalg.solve([[u[0][1], u[1][1]], cross], [-p["m3"] * g, 0.0])]
        th_new = [math.atan2(u[i][0], -u[i][1]) for i in range(2)]
        v = [-F_new[i] * u[i][1] for i in range(2)]  # the axles' static loads: the corner weights give a and b
        lever_new = ((p["a"] + p["b"]) * v[0] / (v[0] + v[1]), (p["a"] + p["b"]) * v[1] / (v[0] + v[1]))
        done = (max(abs(F_new[i] - F[i]) for i in range(2)) < 1e-12 * p["m3"] * g
                and max(abs(th_new[i] - th_eff[i]) for i in range(2)) < 1e-14
                and max(abs(lever_new[i] - lever[i]) for i in range(2)) < 1e-14)
        F, th_eff, lever = F_new, th_new, lever_new
        if done:
            break
    else:
        raise RuntimeError(f"no static pose found for {p}, {shape}")
    tyre = [p["m1"] * g - F[0] * u[0][1], p["m2"] * g - F[1] * u[1][1]]
    return {"equivalent": eq, "z": (z1, z2, z3, beta), "W": W, "u": u, "F": F, "ks": ks, "ds": ds,
            "tyre": tyre, "hang": hang, "top": top}


def simulate_struts(p: dict, road, v: float, x0: float, t_end: float, fs: float, shape: dict,
                    substeps: int = 10, fine: bool = False) -> dict:
    """The strut car (``strut_pose``) on ``road`` at ``fs`` on [0, t_end] (every solver step if
    ``fine``), from its static pose. Returns ``t``, ``z3``, ``beta``, ``z1``/``z2``, ``v1``/``v2``,
    ``s1``/``s2`` (the paper's travel ``z3 - z1 - b sin beta`` and ``z3 - z2 + a sin beta``) and
    ``f1``/``f2`` (the tyre forces)."""
    mbs, sensors, wheels, P = _build(p, road, v, x0, shape)
    data = solve_stored(mbs, sensors, t_end, fs, substeps, fine, NEWTON_ATOL)
    t = data[0][:, 0]
    out = {"t": t, "z3": data[0][:, 2], "beta": -data[0][:, 3]}
    sb = np.sin(out["beta"])
    eq = P["equivalent"]
    for i, (w, x) in enumerate(zip(wheels, (eq["b"], -eq["a"]))):  # the travel as the model defines it
        j = str(i + 1)
        zw, vw = data[1 + 2 * i][:, 2], data[2 + 2 * i][:, 2]
        e, de = np.array([road(x0 + v * ti - w["lag"]) for ti in t]).T
        out["z" + j], out["v" + j] = zw, vw
        out["s" + j] = out["z3"] - zw - x * sb
        out["f" + j] = w["kt"] * (zw - e) + w["dt"] * (vw - v * de) + w["off"]
    return out


def linear_stiffness(p: dict, shape: dict) -> np.ndarray:
    """Exudyn's own linearisation of the strut car at its static pose, the control arms condensed
    out (the chassis held in x, which nothing in the car resists): the stiffness matrix over the
    chassis's height, its rotation (minus the paper's pitch) and the two wheels' heights."""
    import exudyn as exu

    mbs = _build(p, lambda x: (0.0, 0.0), 0.0, 0.0, shape)[0]
    mbs.Assemble()
    K = np.asarray(mbs.ComputeLinearizedSystem(exu.SimulationSettings())[1])
    r, x = [1, 2, 4, 6], [3, 5]  # (chassis x, y, rotation, wheel 1 x, y, wheel 2 x, y)
    return K[np.ix_(r, r)] - K[np.ix_(r, x)] @ np.linalg.solve(K[np.ix_(x, x)], K[np.ix_(x, r)])


def _build(p: dict, road, v: float, x0: float, shape: dict):
    """The strut car's Exudyn system at its static pose: ``(mbs, sensors, wheels, strut_pose(p, shape))``."""
    import exudyn as exu
    from exudyn.itemInterface import (CartesianSpringDamper, MarkerBodyPosition, MarkerNodePosition, MassPoint2D,
                                      NodePoint2D, NodeRigidBody2D, ObjectRigidBody2D, SpringDamper)

    P = strut_pose(p, shape)
    z1, z2, z3, beta = P["z"]
    H, g = shape["H"], p["g"]
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    nb = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[0.0, 0.0, 0.0], initialCoordinates=[0.0, z3, -beta]))
    body = mbs.AddObject(ObjectRigidBody2D(mass=p["m3"], inertia=p["I"], nodeNumber=nb))
    bodies, wheels = [body], []
    L = p["a"] + p["b"]
    for i, (zi, m, kt, dt_) in enumerate(((z1, p["m1"], p["k1"], p["d1"]), (z2, p["m2"], p["k2"], p["d2"]))):
        X = float(P["W"][i][0])
        n = mbs.AddNode(NodePoint2D(referenceCoordinates=[X, H], initialCoordinates=[0.0, zi]))
        bodies.append(mbs.AddObject(MassPoint2D(mass=m, nodeNumber=n)))
        mw = mbs.AddMarker(MarkerNodePosition(nodeNumber=n))
        w_loc, t_loc, u = P["hang"][i], P["top"][i], P["u"][i]
        mc = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[float(w_loc[0]), float(w_loc[1]), 0.0]))
        mt = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[float(t_loc[0]), float(t_loc[1]), 0.0]))
        F = P["F"][i]  # the strut's compression at rest: the spring is that much longer unloaded
        mbs.AddObject(SpringDamper(markerNumbers=[mw, mt], referenceLength=shape["L"][i] + F / P["ks"][i],
                                   stiffness=P["ks"][i], damping=P["ds"][i]))
        arm = F * u[0]  # the control arm's force on the wheel at rest (the strut's side push balanced)
        mbs.AddObject(CartesianSpringDamper(markerNumbers=[mw, mc], stiffness=[ARM_K, 0.0, 0.0],
                                            damping=[2 * ARM_ZETA * math.sqrt(ARM_K * m), 0.0, 0.0],
                                            offset=[-arm / ARM_K, 0.0, 0.0]))
        lag = 0.0 if i == 0 else L
        off = P["tyre"][i] - kt * zi  # the tyre's force at rest minus its spring's (round-off: a, b are the corner weights')
        add_tyre(mbs, mw, [X, H, 0.0], 1, kt, dt_, road, x0, v, lag, off)
        wheels.append({"node": n, "kt": kt, "dt": dt_, "lag": lag, "off": off})
    add_gravity(mbs, bodies, [0.0, g, 0.0])
    sensors = [node_sensor(mbs, nb, "Coordinates")]
    for w in wheels:
        sensors += [node_sensor(mbs, w["node"], "Coordinates"), node_sensor(mbs, w["node"], "Coordinates_t")]
    return mbs, sensors, wheels, P


def compare(seed: int = 1, road_class: str = "C", v: float = 15.0, t_end: float = 5.0, fs: float = 1000.0,
            substeps: int = 10, theta=(0.25, -0.2), L=(0.5, 0.45), H: float = 0.2) -> dict:
    """The strut car against jaxdrift's half-car with its equivalent (``strut_pose``) on one road:
    the largest differences in heave, pitch and wheel travel, against each signal's range."""
    from benchmarks.validation.exudyn_halfcar import against_jaxdrift
    from jaxdrift.io._csvio import DEFAULT_MODEL

    p = {k: float(DEFAULT_MODEL[k]) for k in gv.KEYS}
    x0 = -1.0
    road = gv.FilteredRoad(np.random.default_rng(seed), road_class, x0 + v * (t_end + 0.5) + p["a"] + p["b"] + 1.0)
    shape = {"theta": list(theta), "L": list(L), "H": H}
    t0 = time.time()
    ex = simulate_struts(p, road, v, x0, t_end, fs, shape, substeps)
    wall = time.time() - t0
    eq = strut_pose(p, shape)["equivalent"]
    return {"road_class": road_class, "speed_m_s": v, "duration_s": t_end, "fs_hz": fs, "substeps": substeps,
            "shape": shape, "equivalent": {k: eq[k] for k in ("k3", "k4", "d3", "d4")}, "exudyn_wall_s": wall,
            "signals": against_jaxdrift(eq, road, v, x0, ex)}


def main(argv=None):
    from benchmarks.validation import exudyn_halfcar

    exudyn_halfcar.main(argv, compare, "exudyn-struts.json", __doc__, lambda res: [
        f"equivalent: {res['equivalent']}"])


if __name__ == "__main__":
    main()
