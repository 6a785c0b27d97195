"""A whole car in three dimensions, built from a third-party multibody code's parts (Exudyn), on a
road whose left and right tracks differ, measured as a half-car (issue 48): the axles' tyre forces
summed, pitch, and heave on the car's centreline. A test world only (``pip install -e
".[multibody]"``; never used by jaxdrift itself).

Parts (Exudyn 1.13): the chassis a 3D rigid body (``NodeRigidBodyRxyz`` + ``ObjectRigidBody``, mass
m3, pitch inertia I, roll inertia ``Ixx``, yaw ``Ixx + I``) whose centre of mass sits ``y_cg`` to
the side of the centreline (a driver, a fuel tank: the one thing that couples roll into heave and
pitch); four wheels, point masses (``NodePoint`` + ``MassPoint``, half the half-car's axle mass
each) at half the track ``track`` either side of the centreline; each suspension a Cartesian
spring-damper acting vertically between a wheel and the chassis point above it (half the axle's
stiffness and damping); each tyre a Cartesian spring-damper from a ground point whose vertical force
follows its own track of the road (a spring user function). Axes: x forward, z the paper's z
(down), y = z x x; the body's rotation about y is the paper's pitch. The car starts in its static
equilibrium on the level lead-in (``equilibrium3d``, exact in the angles; Exudyn's own static solver
does not converge on a car nothing holds in x, y or yaw), integrated by the generalized-alpha
solver (spectral radius 1) at ``substeps`` fixed steps per output sample.

With the centre of mass on the centreline the car is its half-car exactly (to second order in the
angles): the sums of each axle's forces make heave and pitch, and roll is a motion of its own. So
``python benchmarks/validation/exudyn_car3d.py`` drives it on two different tracks and compares its
heave, pitch and mean wheel travel with jaxdrift's half-car (``road_driven_rhs``, scipy at rtol
1e-10) on the mean of the two tracks (``benchmarks/results/exudyn-car3d.json``).
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


def simulate_car3d(p: dict, roads, v: float, x0: float, t_end: float, fs: float, shape: dict,
                   substeps: int = 10, fine: bool = False) -> dict:
    """The car of half-car parameters ``p`` (each axle's mass, stiffness and damping shared by its two
    corners) with ``shape`` (``track`` [m], ``y_cg`` [m], ``Ixx`` [kg m^2]) on ``roads`` (the left
    and right tracks, each ``road(x) -> (zeta, dzeta/dx)``) at ``fs`` on [0, t_end] (at every
    solver step if ``fine``). Returns ``t``; ``z3`` (the centreline's height at the centre of
    mass's station) and ``beta`` (pitch); ``roll``; per axle ``z1``/``z2`` and ``v1``/``v2`` (the
    mean of its wheels' heights and rates), ``s1``/``s2`` (its mean spring travel) and ``f1``/``f2``
    (its tyre forces summed)."""
    import exudyn as exu
    from exudyn.itemInterface import (CartesianSpringDamper, MarkerBodyPosition, MarkerNodePosition, MassPoint,
                                      NodePoint, NodeRigidBodyRxyz, ObjectRigidBody)

    a, b, g, yc = p["a"], p["b"], p["g"], shape["y_cg"]
    z3, roll0, beta, wz = equilibrium3d(p, shape)
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    nb = mbs.AddNode(NodeRigidBodyRxyz(referenceCoordinates=[0.0] * 6,
                                       initialCoordinates=[0.0, 0.0, z3, roll0, beta, 0.0]))
    body = mbs.AddObject(ObjectRigidBody(mass=p["m3"], inertia=[shape["Ixx"], p["I"], shape["Ixx"] + p["I"],
                                                                              0.0, 0.0, 0.0], nodeNumber=nb))
    bodies, corners = [body], []
    m, k, d = per_corner(p, "m1", "m2"), per_corner(p, "k3", "k4"), per_corner(p, "d3", "d4")
    kt, dt_ = per_corner(p, "k1", "k2"), per_corner(p, "d1", "d2")
    for i, (x, y, _) in enumerate(corner_points(p, shape)):  # left (y < 0: z down, x forward), then right
        axle, side = divmod(i, 2)
        n = mbs.AddNode(NodePoint(referenceCoordinates=[x, y, 0.0], initialCoordinates=[0.0, 0.0, wz[i]]))
        bodies.append(mbs.AddObject(MassPoint(mass=m[i], nodeNumber=n)))
        mw = mbs.AddMarker(MarkerNodePosition(nodeNumber=n))
        mc = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[x, y, 0.0]))
        # the wheel first: chassis point - wheel = the spring travel
        mbs.AddObject(CartesianSpringDamper(markerNumbers=[mw, mc], stiffness=[0.0, 0.0, k[i]],
                                            damping=[0.0, 0.0, d[i]]))
        c = {"node": n, "x": x, "y": y, "axle": axle, "kt": float(kt[i]), "dt": float(dt_[i]), "road": roads[side],
             "lag": 0.0 if axle == 0 else a + b}
        add_tyre(mbs, mw, [x, y, 0.0], 2, c["kt"], c["dt"], c["road"], x0, v, c["lag"])
        corners.append(c)
    add_gravity(mbs, bodies, [0.0, 0.0, g])
    sensors = [node_sensor(mbs, nb, what) for what in ("Position", "RotationMatrix")]
    for c in corners:
        sensors += [node_sensor(mbs, c["node"], what) for what in ("Coordinates", "Coordinates_t")]
    data = solve_stored(mbs, sensors, t_end, fs, substeps, fine)
    t = data[0][:, 0]
    pos, R = data[0][:, 1:4], data[1][:, 1:10].reshape(-1, 3, 3)  # body -> global, row by row
    centre = pos + R @ np.array([0.0, -yc, 0.0])  # the centreline below (above) the centre of mass
    out = {"t": t, "z3": centre[:, 2], "beta": np.arcsin(-R[:, 2, 0]),
           "roll": np.arctan2(R[:, 2, 1], R[:, 2, 2])}
    acc = {k: np.zeros_like(t) for k in ("z1", "z2", "v1", "v2", "s1", "s2", "f1", "f2")}
    for i, c in enumerate(corners):
        zw = data[2 + 2 * i][:, 3]  # the node's displacement in z (its reference height is 0)
        vw = data[3 + 2 * i][:, 3]
        top = (pos + R @ np.array([c["x"], c["y"], 0.0]))[:, 2]
        e, de = np.array([c["road"](x0 + v * ti - c["lag"]) for ti in t]).T
        j = str(c["axle"] + 1)
        acc["z" + j] += 0.5 * zw
        acc["v" + j] += 0.5 * vw
        acc["s" + j] += 0.5 * (top - zw)
        acc["f" + j] += c["kt"] * (zw - e) + c["dt"] * (vw - v * de)
    return {**out, **acc}


def corner_points(p: dict, shape: dict) -> np.ndarray:
    """The chassis points above the wheels, relative to the centre of mass (front left, front
    right, rear left, rear right; x forward, y to the right)."""
    w, yc = shape["track"], shape["y_cg"]
    return np.array([[x, y - yc, 0.0] for x in (p["b"], -p["a"]) for y in (-0.5 * w, 0.5 * w)])


def per_corner(p: dict, front: str, rear: str) -> np.ndarray:
    """Each corner's half of its axle's half-car value (``p[front]``, ``p[rear]``), in
    ``corner_points``' order."""
    return np.repeat([0.5 * p[front], 0.5 * p[rear]], 2)


def equilibrium3d(p: dict, shape: dict):
    """The car's static pose on level road, exact in the angles (Exudyn's ``Rxyz`` rotation
    ``Rx(roll) Ry(pitch)``): the centre of mass's height, roll, pitch and the four wheels' heights.
    Each corner carries half its axle's spring and tyre."""
    from exudyn.rigidBodyUtilities import RotXYZ2RotationMatrix
    from scipy.optimize import fsolve

    g, r = p["g"], corner_points(p, shape)
    k, kt, mw = per_corner(p, "k3", "k4"), per_corner(p, "k1", "k2"), per_corner(p, "m1", "m2")

    def residual(q):
        zc, phi, th, *zw = q
        R = np.asarray(RotXYZ2RotationMatrix([phi, th, 0.0]))
        arm = r @ R.T  # each point's offset from the centre of mass, in the global frame
        f = -k * (zc + arm[:, 2] - np.asarray(zw))  # the springs' vertical forces on the chassis
        torque = np.cross(arm, np.stack([0 * f, 0 * f, f], axis=1)).sum(axis=0)
        return [p["m3"] * g + f.sum(), torque[0], torque[1], *(mw * g - f - kt * np.asarray(zw))]

    z1, z2, z3, beta = gv.equilibrium(p)[:4]
    q = fsolve(residual, [z3, 0.0, beta, z1, z1, z2, z2], xtol=1e-13)
    if np.max(np.abs(residual(q))) > 1e-6 * p["m3"] * g:
        raise RuntimeError(f"no static equilibrium found for {p}, {shape}")
    return float(q[0]), float(q[1]), float(q[2]), [float(x) for x in q[3:]]


def roll_mode(p: dict, shape: dict) -> dict:
    """The car's linear modes about its static pose (our own small model, not Exudyn's; coordinates
    the centre of mass's height, roll, pitch and the four wheels' heights): ``frequency_hz`` and
    ``roll_share`` of the mode with the largest share of its kinetic energy in roll."""
    r = corner_points(p, shape)
    M = np.diag([p["m3"], shape["Ixx"], p["I"], *per_corner(p, "m1", "m2")])
    K = np.zeros((7, 7))
    for i, ((x, y, _), k, kt) in enumerate(zip(r, per_corner(p, "k3", "k4"), per_corner(p, "k1", "k2"))):
        j = np.zeros(7)
        j[:3] = 1.0, y, -x  # the chassis point's height: z + y roll - x pitch
        j[3 + i] = -1.0
        K += k * np.outer(j, j)
        K[3 + i, 3 + i] += kt
    w2, V = np.linalg.eig(np.linalg.solve(M, K))
    share = [M[1, 1] * V[1, i].real ** 2 / (V[:, i].real @ M @ V[:, i].real) for i in range(7)]
    i = int(np.argmax(share))
    return {"frequency_hz": float(math.sqrt(w2[i].real) / (2 * math.pi)), "roll_share": float(share[i])}


class MeanRoad:
    """The mean of two tracks ``(zeta, dzeta/dx)``: what a half-car's one wheel per axle sees."""

    def __init__(self, left, right):
        self.left, self.right = left, right

    def __call__(self, x):
        (e1, d1), (e2, d2) = self.left(x), self.right(x)
        return 0.5 * (e1 + e2), 0.5 * (d1 + d2)


def compare(seed: int = 1, road_class: str = "C", v: float = 15.0, t_end: float = 5.0, fs: float = 1000.0,
            substeps: int = 10, track: float = 1.5) -> dict:
    """The car (centre of mass on its centreline) on two independent tracks against jaxdrift's
    half-car on their mean: the largest differences in heave, pitch and mean wheel travel, against
    each signal's range, and the roll the half-car does not have."""
    from benchmarks.validation.exudyn_halfcar import against_jaxdrift
    from jaxdrift.io._csvio import DEFAULT_MODEL

    p = {k: float(DEFAULT_MODEL[k]) for k in gv.KEYS}
    x0 = -1.0
    rng = np.random.default_rng(seed)
    length = x0 + v * (t_end + 0.5) + p["a"] + p["b"] + 1.0
    left, right = (gv.FilteredRoad(rng, road_class, length) for _ in range(2))
    shape = {"track": track, "y_cg": 0.0, "Ixx": 0.3 * p["I"]}
    t0 = time.time()
    ex = simulate_car3d(p, (left, right), v, x0, t_end, fs, shape, substeps)
    wall = time.time() - t0
    return {"road_class": road_class, "speed_m_s": v, "duration_s": t_end, "fs_hz": fs, "substeps": substeps,
            "track_m": track, "roll_range_rad": float(np.ptp(ex["roll"])), "exudyn_wall_s": wall,
            "signals": against_jaxdrift(p, MeanRoad(left, right), v, x0, ex)}


def main(argv=None):
    from benchmarks.validation import exudyn_halfcar

    exudyn_halfcar.main(argv, compare, "exudyn-car3d.json", __doc__, lambda res: [
        f"roll (the half-car has none): {res['roll_range_rad']:.3g} rad peak to peak"])


if __name__ == "__main__":
    main()
