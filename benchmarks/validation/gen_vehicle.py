"""Independent generator of measured vehicle runs (validation yardstick for ``jaxdrift diagnose``).

Shares no code with jaxdrift (its models, generators or solvers): the half-car is written here from
the seed paper's Appendix A, (A.1) and (A.2) with the tyre forces of (A.1) driven by a road profile
(the "virtual measurement" of Sec. 4), and integrated with scipy ``solve_ivp`` (DOP853, rtol 1e-10,
atol 1e-12, dense output). The ISO 8608 road is synthesised as filtered white noise in space: a
third-order shaping filter ``H(s) = Oc^2 / ((s + O0) (s + Oc)^2)`` (s in rad/m) driven by white
noise, discretised exactly on a 5 cm grid (state h, h', h''), and evaluated between grid points by
the interpolating spline of degree 7 (C6, so the integrator's steps follow the road's content and
not interpolation kinks). Its one-sided displacement PSD
is ``Gd(n0) (n/n0)^-2`` between the cut-on O0 = 2 pi 0.01 rad/m and the tyre-envelope cut-off
Oc = 2 pi 3 rad/m (checked by ``tests/test_independent_validation.py``).

Every file follows docs/measured-data.md: header row, free column order, SI units, z down, the run
starts in static equilibrium on level road (the road is level for x <= 0 and the profile fades in
with a C2 smoothstep), measured force ``scale * f_true(t - delay) + offset + noise``. A run is three
files: ``NAME.csv``, ``NAME_model.json`` (the nominal vehicle given to the diagnosis) and
``NAME_truth.json`` (the hidden effects, with true values, in the report's cause/channel/parameter
names, plus the nuisance draws). ``python gen_vehicle.py --n 20 --seed 1 --out DIR`` writes a design.
"""

from __future__ import annotations

import argparse
import json
import math
import os

import numpy as np
from scipy.integrate import DOP853, OdeSolution, solve_ivp
from scipy.interpolate import make_interp_spline
from scipy.linalg import expm

G = 9.81
#: ISO 8608 displacement PSD at n0 = 0.1 cycles/m [m^3]
ISO_GD0 = {"A": 16e-6, "B": 64e-6, "C": 256e-6, "D": 1024e-6, "E": 4096e-6}
N0 = 0.1
ROAD_O0 = 2 * math.pi * 0.01  # cut-on [rad/m]: wavelengths above 100 m are not road roughness
ROAD_OC = 2 * math.pi * 3.0  # tyre envelope [rad/m]: wavelengths below ~0.3 m are bridged
ROAD_DX = 0.05  # grid of the exact discretisation [m]
#: speeds a driver would choose per road class [m/s] (together 5-35)
SPEEDS = {"A": (15.0, 35.0), "B": (10.0, 35.0), "C": (8.0, 25.0), "D": (5.0, 15.0), "E": (5.0, 10.0)}

#: base vehicles (whole-vehicle half-car: both wheels of an axle lumped), none of them the seed's
#: table; a draw multiplies every value by a factor in [0.9, 1.1]. b: CoG to the front chassis
#: point (wheel 1), a: CoG to the rear one.
VEHICLES = {
    "compact": dict(a=1.50, b=1.00, m1=60.0, m2=55.0, m3=1000.0, I=1200.0, k1=3.6e5, k2=3.6e5,
                    k3=4.0e4, k4=3.5e4, d1=150.0, d2=150.0, d3=2500.0, d4=2200.0),
    "passenger": dict(a=1.60, b=1.10, m1=80.0, m2=70.0, m3=1350.0, I=1900.0, k1=4.4e5, k2=4.4e5,
                      k3=5.0e4, k4=4.4e4, d1=250.0, d2=250.0, d3=3000.0, d4=2800.0),
    "van": dict(a=2.20, b=1.30, m1=110.0, m2=140.0, m3=2600.0, I=5000.0, k1=6.0e5, k2=6.5e5,
                k3=9.0e4, k4=1.4e5, d1=400.0, d2=450.0, d3=5000.0, d4=7000.0),
}
KEYS = ("a", "b", "m1", "m2", "m3", "I", "k1", "k2", "k3", "k4", "d1", "d2", "d3", "d4", "g")
#: parameters whose error changes the chassis motion under force excitation (the tyre k1, k2, d1,
#: d2 only move the contact points, which no channel set here measures; g is not a model error)
PARAMS = ("a", "b", "m1", "m2", "m3", "I", "k3", "k4", "d3", "d4")
CHANNEL_SETS = {
    "forces": (),
    "beta": ("beta",),
    "beta_z3": ("beta", "z3"),
    "beta_s": ("beta", "s1", "s2"),
    "beta_z3_s": ("beta", "z3", "s1", "s2"),
    "beta_rate": ("beta", "beta_rate"),
    "all": ("beta", "beta_rate", "z3", "s1", "s2"),
}
SYSTEMATIC = ("force_offset", "force_scale", "force_delay", "parameter_error")
#: single systematic targets (cause, channel or parameter)
SINGLES = [(c, ch) for c in ("force_offset", "force_scale", "force_delay") for ch in ("f1", "f2")] + \
    [("parameter_error", p) for p in PARAMS]
#: every pair of systematic cause types (same type: the two channels, or two parameters)
PAIRS = [(SYSTEMATIC[i], SYSTEMATIC[j]) for i in range(4) for j in range(i, 4)]
#: nonlinear suspension effects outside the linear model (``design_nonlinear``): an asymmetric
#: damper (rebound/compression ratio), a progressive spring (cubic term), a bump stop, tyre lift-off
NONLINEAR = [("damper_asymmetry", "d3"), ("damper_asymmetry", "d4"), ("progressive_spring", "k3"),
             ("progressive_spring", "k4"), ("bump_stop", "k3"), ("bump_stop", "k4"),
             ("tyre_lift_off", "f1"), ("tyre_lift_off", "f2")]
#: the sensor effects a nonlinear effect is paired with
SENSOR = [(c, ch) for c in ("force_offset", "force_scale", "force_delay") for ch in ("f1", "f2")]
#: a force transducer's gain drifting over the run (``design_gain_drift``), alone and with an offset
GAIN_DRIFT = [("force_gain_drift", "f1"), ("force_gain_drift", "f2")]
#: a share of the other wheel's force read in a channel (``design_crosstalk``)
CROSSTALK = [("force_crosstalk", "f1"), ("force_crosstalk", "f2")]


# ----------------------------------------------------------------------------- road
def filter_psd(n, cls: str):
    """One-sided displacement PSD [m^3] of the shaping filter's output at n [cycles/m]."""
    o = 2 * np.pi * np.asarray(n, float)
    q = 2.0 * math.pi**2 * ISO_GD0[cls] * N0**2
    return 2 * q * ROAD_OC**4 / ((o**2 + ROAD_O0**2) * (o**2 + ROAD_OC**2) ** 2)


def filtered_noise(rng, cls: str, n: int, dx: float = ROAD_DX) -> np.ndarray:
    """``n`` exact samples (h, h', h'') at spacing ``dx`` of the shaping filter driven by white
    noise, started at rest (zero state at x = 0)."""
    o0, oc = ROAD_O0, ROAD_OC
    # h''' = oc^2 w - (o0 + 2 oc) h'' - (2 o0 oc + oc^2) h' - o0 oc^2 h
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0],
                  [-o0 * oc**2, -(2 * o0 * oc + oc**2), -(o0 + 2 * oc)]])
    B = np.array([0.0, 0.0, oc**2])
    # one-sided PSD of h' = w (white, two-sided intensity q) is q / (2 pi^2 n^2): the ISO line
    q = 2.0 * math.pi**2 * ISO_GD0[cls] * N0**2
    # exact discretisation (van Loan): Phi and the covariance of the noise increment
    M = np.zeros((6, 6))
    M[:3, :3] = -A
    M[:3, 3:] = q * np.outer(B, B)
    M[3:, 3:] = A.T
    E = expm(M * dx)
    Phi = E[3:, 3:].T
    Qd = Phi @ E[:3, 3:]
    L = np.linalg.cholesky(0.5 * (Qd + Qd.T))
    xi = (rng.standard_normal((n, 3)) @ L.T).tolist()
    s = np.zeros((n, 3))
    (p00, p01, p02), (p10, p11, p12), (p20, p21, p22) = Phi.tolist()
    h0 = h1 = h2 = 0.0
    rows = [(0.0, 0.0, 0.0)]
    for k in range(1, n):
        x0, x1, x2 = xi[k]
        h0, h1, h2 = (p00 * h0 + p01 * h1 + p02 * h2 + x0, p10 * h0 + p11 * h1 + p12 * h2 + x1,
                      p20 * h0 + p21 * h1 + p22 * h2 + x2)
        rows.append((h0, h1, h2))
    s[:] = rows
    return s


class FilteredRoad:
    """ISO 8608 road of class ``cls`` as filtered white noise on [x_start, x_end] (see module doc).

    ``__call__(x)`` gives (zeta, dzeta/dx) with zeta the road surface in the z-down frame; the
    profile is zero for x <= 0 and fades in over ``ramp`` metres.
    """

    def __init__(self, rng, cls: str, x_end: float, ramp: float = 10.0, dx: float = ROAD_DX,
                 interp: str = "spline7"):
        self.dx, self.ramp, self.interp = dx, ramp, interp
        n = int(math.ceil(x_end / dx)) + 2
        s = filtered_noise(rng, cls, n, dx)
        self.state = s  # h, h', h'' at x = k dx (exact samples of the filtered noise)
        self.n = n
        if interp == "linear":
            # the heights joined by straight lines, as a profilometer's points are: the slope jumps
            # at every grid point, so the tyre force (its damper term) jumps between samples
            self.h = s[:, 0].tolist()
            self.pinned = ()  # the cells under the wheels while a stretch is integrated
            return
        if interp != "spline7":
            raise ValueError(f"road interpolation {interp!r}: spline7 or linear")
        # between the samples: the interpolating spline of degree 7 (C6, so the integrator's
        # steps are set by the road's content, not by kinks); per grid cell its Taylor
        # coefficients at the cell's left end, as Python lists (fast scalar evaluation)
        grid = np.arange(n) * dx
        spl = make_interp_spline(grid, s[:, 0], k=7)
        mid = grid[:-1] + 0.5 * dx
        coef = [spl(grid[:-1])]
        fact = 1.0
        for m in range(1, 8):
            fact *= m
            coef.append((spl(mid if m == 7 else grid[:-1], nu=m)) / fact)
        self.coef = np.stack(coef, axis=1).tolist()

    def raw(self, x: float) -> tuple[float, float]:
        k = int(x / self.dx)
        if k >= self.n - 1:
            raise ValueError(f"road evaluated at x={x} beyond its end")
        if self.interp == "linear":
            for kk in self.pinned:  # a stretch between kinks: each wheel stays in its own cell
                if (kk - 1e-6) * self.dx <= x <= (kk + 1 + 1e-6) * self.dx:
                    k = kk
                    break
            h0, h1 = self.h[k], self.h[k + 1]
            slope = (h1 - h0) / self.dx
            return h0 + slope * (x - k * self.dx), slope
        u = x - k * self.dx
        c = self.coef[k]
        h = c[7]
        dh = 7.0 * c[7]
        for m in range(6, 0, -1):
            h = h * u + c[m]
            dh = dh * u + m * c[m]
        return h * u + c[0], dh

    def __call__(self, x: float) -> tuple[float, float]:
        if x <= 0.0:
            return 0.0, 0.0
        h, dh = self.raw(x)
        if x >= self.ramp:
            return h, dh
        u = x / self.ramp  # C2 smoothstep fade-in: level road, then the profile
        w = u**3 * (10 - 15 * u + 6 * u * u)
        dw = 30 * u * u * (1 - u) ** 2 / self.ramp
        return w * h, dw * h + w * dh

    def profile(self, x: np.ndarray) -> np.ndarray:
        """Heights at many points (tests)."""
        return np.array([self(float(xx))[0] for xx in np.atleast_1d(x)])


# ----------------------------------------------------------------------------- half-car
def equilibrium(p: dict) -> np.ndarray:
    """Static state on level road (zeta = 0) from (A.1), (A.2) with all rates zero."""
    g = p["g"]
    f3 = p["m3"] * g * p["a"] / (p["a"] + p["b"])  # moment balance b f3 = a f4
    f4 = p["m3"] * g * p["b"] / (p["a"] + p["b"])
    z1 = (p["m1"] * g + f3) / p["k1"]
    z2 = (p["m2"] * g + f4) / p["k2"]
    sb = (f4 / p["k4"] - f3 / p["k3"] + z2 - z1) / (p["a"] + p["b"])
    z3 = z1 + f3 / p["k3"] + p["b"] * sb
    return np.array([z1, z2, z3, math.asin(sb), 0.0, 0.0, 0.0, 0.0])


def _suspension_law(p: dict, nl: dict | None):
    """The chassis spring-damper forces ``(f3, f4)`` as functions of (travel, rate) per axle.

    ``nl`` holds the nonlinear suspension effects, each about the static travel ``s0`` so the
    static equilibrium stays the linear one: ``damper_asymmetry`` (rebound/compression damping
    ratio rho, mean damping the model's: compression 2 d / (1 + rho), rebound rho times that),
    ``progressive_spring`` (``k (u + c u^3)``, u = s - s0), ``bump_stop`` (``k_b max(u - u_b, 0)``
    added in compression). Keys ``"d3"``/``"d4"``/``"k3"``/``"k4"`` select the axle."""
    g = p["g"]
    s0 = (p["m3"] * g * p["a"] / (p["a"] + p["b"]) / p["k3"], p["m3"] * g * p["b"] / (p["a"] + p["b"]) / p["k4"])
    laws = []
    for i, (k, d) in enumerate(((p["k3"], p["d3"]), (p["k4"], p["d4"]))):
        rho = (nl or {}).get(("damper_asymmetry", ("d3", "d4")[i]))
        cub = (nl or {}).get(("progressive_spring", ("k3", "k4")[i]))
        stop = (nl or {}).get(("bump_stop", ("k3", "k4")[i]))
        dc = d if rho is None else 2.0 * d / (1.0 + rho)
        if rho is not None and (nl or {}).get(("damper_definition", ("d3", "d4")[i])) == "compression":
            dc = d  # another habit: compression at the catalogue value, rebound rho times it (mean moves)
        dr = d if rho is None else rho * dc
        c = 0.0 if cub is None else cub
        kb, ub = (0.0, 0.0) if stop is None else stop

        def law(s, ds, k=k, dc=dc, dr=dr, c=c, kb=kb, ub=ub, s0=s0[i]):
            u = s - s0
            f = k * s + (dc if ds > 0.0 else dr) * ds
            if c:
                f += k * c * u * u * u
            if kb and u > ub:
                f += kb * (u - ub)
            return f
        laws.append(law)
    return laws


def _rhs_factory(p: dict, road: FilteredRoad, v: float, x0: float, nl: dict | None = None, scale: float = 1.0):
    a, b, m1, m2, m3, I = p["a"], p["b"], p["m1"], p["m2"], p["m3"], p["I"]
    k1, k2, k3, k4, d1, d2, d3, d4, g = (p[k] for k in ("k1", "k2", "k3", "k4", "d1", "d2", "d3", "d4", "g"))
    L = a + b
    sin, cos = math.sin, math.cos
    law3, law4 = _suspension_law(p, nl)
    linear = not nl
    lift = tuple((nl or {}).get("lift_off", ()))

    def rhs(t, y):
        z1, z2, z3, be, v1, v2, v3, vb = y
        x1 = x0 + v * t
        e1, de1 = road(x1)
        e2, de2 = road(x1 - L)
        if scale != 1.0:
            e1, de1, e2, de2 = scale * e1, scale * de1, scale * e2, scale * de2
        f1 = k1 * (z1 - e1) + d1 * (v1 - v * de1)
        f2 = k2 * (z2 - e2) + d2 * (v2 - v * de2)
        if lift:  # the lifting tyre cannot pull
            f1 = max(f1, 0.0) if "f1" in lift else f1
            f2 = max(f2, 0.0) if "f2" in lift else f2
        sb, cb = sin(be), cos(be)
        if linear:
            f3 = k3 * (z3 - z1 - b * sb) + d3 * (v3 - v1 - b * vb * cb)
            f4 = k4 * (z3 - z2 + a * sb) + d4 * (v3 - v2 + a * vb * cb)
        else:
            f3 = law3(z3 - z1 - b * sb, v3 - v1 - b * vb * cb)
            f4 = law4(z3 - z2 + a * sb, v3 - v2 + a * vb * cb)
        return [v1, v2, v3, vb, g + (f3 - f1) / m1, g + (f4 - f2) / m2, g - (f3 + f4) / m3,
                cb * (b * f3 - a * f4) / I]

    return rhs


def simulate(p: dict, road: FilteredRoad, v: float, x0: float, t_end: float, rtol=1e-10, atol=1e-12,
             nl: dict | None = None, scale: float = 1.0):
    """Dense solution of the road-driven half-car on [0, t_end] (t = 0: static equilibrium);
    ``nl``: nonlinear suspension effects (see ``_suspension_law``), ``scale``: road height factor."""
    rhs = _rhs_factory(p, road, v, x0, nl, scale)
    if getattr(road, "interp", "spline7") == "linear":
        return _simulate_between_kinks(rhs, road, p["a"] + p["b"], v, x0, t_end, rtol, atol, equilibrium(p))
    sol = solve_ivp(rhs, (0.0, t_end), equilibrium(p), method="DOP853",
                    rtol=rtol, atol=atol, dense_output=True)
    if not sol.success:
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    return sol


def _simulate_between_kinks(rhs, road, L: float, v: float, x0: float, t_end: float, rtol, atol, y0):
    """A road of straight lines has a kink under a wheel each time the wheel passes a profile point,
    and the tyre force jumps there: one DOP853 integration per stretch between two kinks (either
    wheel), each smooth, joined into one dense solution."""
    dx = road.dx
    kinks = []
    for lag in (0.0, L):  # front wheel at x0 + v t, rear one L behind
        k0 = max(int(math.floor((x0 - lag) / dx)) + 1, 0)
        k1 = int(math.floor((x0 - lag + v * t_end) / dx))
        kinks.append((np.arange(k0, k1 + 1) * dx + lag - x0) / v)
    for edge in (0.0, road.ramp):  # where the fade-in starts and ends
        kinks.append(np.array([(edge - x0) / v, (edge + L - x0) / v]))
    t = np.unique(np.concatenate(kinks + [np.array([0.0, t_end])]))
    t = t[(t >= 0.0) & (t <= t_end)]
    ts, parts, y = [0.0], [], np.asarray(y0, float)
    for ta, tb in zip(t[:-1], t[1:]):
        if tb - ta < 1e-12:
            continue
        tm = 0.5 * (ta + tb)  # each wheel's cell: a stage evaluated at a kink must not see the next one
        road.pinned = tuple(int(math.floor((x0 + v * tm - lag) / dx)) for lag in (0.0, L))
        solver = DOP853(rhs, ta, y, tb, rtol=rtol, atol=atol)
        while solver.status == "running":
            msg = solver.step()
            if solver.status == "failed":
                raise RuntimeError(f"DOP853 failed at t={solver.t}: {msg}")
            ts.append(solver.t)
            parts.append(solver.dense_output())
        y = solver.y
    road.pinned = ()
    return _Dense(OdeSolution(ts, parts))


class _Dense:
    """What ``signals`` reads of a solve_ivp result: ``.sol(t)``."""

    def __init__(self, sol):
        self.sol = sol


def signals(p: dict, road: FilteredRoad, v: float, x0: float, sol, tau: np.ndarray, scale: float = 1.0,
            lift: tuple = ()) -> dict:
    """True signals at times ``tau`` (times <= 0 give the static state); ``scale`` multiplies the
    road heights, ``lift``: the tyre forces (f1, f2) that cannot pull (clipped at 0)."""
    y = np.empty((len(tau), 8))
    neg = tau <= 0.0
    y[neg] = equilibrium(p)
    if (~neg).any():
        y[~neg] = sol.sol(tau[~neg]).T
    x1 = x0 + v * np.maximum(tau, 0.0)
    e1, de1 = np.array([road(float(x)) for x in x1]).T
    e2, de2 = np.array([road(float(x) - p["a"] - p["b"]) for x in x1]).T
    de1 = np.where(neg, 0.0, de1) * scale
    de2 = np.where(neg, 0.0, de2) * scale
    e1, e2 = e1 * scale, e2 * scale
    sb = np.sin(y[:, 3])
    f1 = p["k1"] * (y[:, 0] - e1) + p["d1"] * (y[:, 4] - v * de1)
    f2 = p["k2"] * (y[:, 1] - e2) + p["d2"] * (y[:, 5] - v * de2)
    f1 = np.maximum(f1, 0.0) if "f1" in lift else f1
    f2 = np.maximum(f2, 0.0) if "f2" in lift else f2
    return {
        "f1": f1, "f2": f2,
        "z1": y[:, 0], "z2": y[:, 1], "z3": y[:, 2], "beta": y[:, 3], "beta_rate": y[:, 7],
        "s1": y[:, 2] - y[:, 0] - p["b"] * sb, "s2": y[:, 2] - y[:, 1] + p["a"] * sb,
        "zeta1": e1, "zeta2": e2,
    }


# ----------------------------------------------------------------------------- design
def _loguniform(rng, lo, hi):
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw_effect(rng, cause: str, target: str | None, p: dict, duration: float | None = None) -> dict:
    """One hidden effect of random size, from barely detectable to large (log-uniform)."""
    sign = 1.0 if rng.random() < 0.5 else -1.0
    if cause == "force_gain_drift":  # the scale changes by 0.2-5 % over the run, linearly
        return {"cause": cause, "channel": target, "value": sign * _loguniform(rng, 2e-3, 5e-2) / duration}
    if cause == "force_offset":
        load = p["m1"] * p["g"] + p["m3"] * p["g"] * p["a"] / (p["a"] + p["b"])
        if target == "f2":
            load = p["m2"] * p["g"] + p["m3"] * p["g"] * p["b"] / (p["a"] + p["b"])
        return {"cause": cause, "channel": target, "value": sign * load * _loguniform(rng, 1e-3, 1e-1)}
    if cause == "force_scale":
        return {"cause": cause, "channel": target, "value": 1.0 + sign * _loguniform(rng, 1e-3, 1e-1)}
    if cause == "force_delay":
        return {"cause": cause, "channel": target, "value": sign * _loguniform(rng, 1e-4, 1e-2)}
    if cause == "parameter_error":
        return {"cause": cause, "parameter": target, "value": 1.0 + sign * _loguniform(rng, 5e-3, 0.2)}
    if cause == "force_crosstalk":  # 0.2-5 % of the other wheel's force read in this channel
        return {"cause": cause, "channel": target, "value": sign * _loguniform(rng, 2e-3, 5e-2)}
    # nonlinear suspension effects at sizes engineers meet; the physical size of the last three
    # depends on the run's travel and is set by ``generate`` (a linear pre-run on the same road)
    if cause == "damper_asymmetry":  # rebound/compression ratio in 0.6-1.6 (1 is no effect)
        return {"cause": cause, "parameter": target, "value": _loguniform(rng, 1.15, 1.6) ** sign}
    if cause == "progressive_spring":  # stiffness +20-100 % at the run's 99th-percentile travel
        return {"cause": cause, "parameter": target, "stiffening": float(rng.uniform(0.2, 1.0))}
    if cause == "bump_stop":  # reached on 1-5 % of the samples, 3-10x the spring's stiffness
        return {"cause": cause, "parameter": target, "share": float(rng.uniform(0.01, 0.05)),
                "ratio": float(rng.uniform(3.0, 10.0))}
    if cause == "force_clipping":  # the amplifier's range reached on 0.2-2 % of the samples
        return {"cause": cause, "channel": target, "share": _loguniform(rng, 2e-3, 2e-2)}
    if cause == "tyre_lift_off":  # the road scaled so the tyre leaves it on 1-5 % of the samples
        return {"cause": cause, "channel": target, "share": float(rng.uniform(0.01, 0.05))}
    raise ValueError(cause)


def design(n: int, seed: int) -> list[dict]:
    """``n`` cases, stratified: 10 % effect-free without force noise, 10 % force noise only,
    45 % one systematic effect (cycling through ``SINGLES``), 35 % two (cycling through ``PAIRS``);
    the order is shuffled. Each case carries its own seed; the same (n, seed) gives the same runs."""
    n_clean, n_noise = round(0.10 * n), round(0.10 * n)
    n_single = round(0.45 * n)
    n_pair = n - n_clean - n_noise - n_single
    plan = [("clean", ())] * n_clean + [("noise", ())] * n_noise
    plan += [("single", (SINGLES[i % len(SINGLES)],)) for i in range(n_single)]
    plan += [("pair", PAIRS[i % len(PAIRS)]) for i in range(n_pair)]
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(plan))
    cases = []
    for i, j in enumerate(order):
        kind, what = plan[j]
        cases.append({"index": i, "stratum": kind, "what": [list(w) if isinstance(w, tuple) else w for w in what],
                      "seed": int(rng.integers(2**31))})
    return cases


def _shuffled(plan: list, seed: int, design: str) -> list[dict]:
    """The cases of a design's ``plan`` ((stratum, effects) pairs) in a seeded random order, each
    with its own seed."""
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(plan))
    cases = []
    for i, j in enumerate(order):
        kind, what = plan[j]
        cases.append({"index": i, "stratum": kind, "what": [list(w) if isinstance(w, tuple) else w for w in what],
                      "seed": int(rng.integers(2**31)), "design": design})
    return cases


def design_nonlinear(n: int, seed: int, free_share: float = 0.4) -> list[dict]:
    """``n`` cases for the nonlinear suspension: ``free_share`` effect-free (half without, half
    with force noise), the rest 60 % one nonlinear effect (cycling through ``NONLINEAR``) and 40 %
    a nonlinear effect paired with a sensor effect (cycling through ``SENSOR``); shuffled."""
    n_free = round(free_share * n)
    n_single = round(0.6 * (n - n_free))
    n_pair = n - n_free - n_single
    plan = [("clean", ())] * (n_free // 2) + [("noise", ())] * (n_free - n_free // 2)
    plan += [("single", (NONLINEAR[i % len(NONLINEAR)],)) for i in range(n_single)]
    plan += [("pair", (NONLINEAR[(3 * i + 1) % len(NONLINEAR)], SENSOR[i % len(SENSOR)])) for i in range(n_pair)]
    return _shuffled(plan, seed, "nonlinear")


def design_gain_drift(n: int, seed: int, free_share: float = 0.2) -> list[dict]:
    """``n`` cases for a force transducer's gain drift: ``free_share`` effect-free (half without,
    half with force noise), the rest half the drift alone (``GAIN_DRIFT``), half the drift paired
    with an offset on either channel; shuffled."""
    n_free = round(free_share * n)
    n_single = round(0.5 * (n - n_free))
    n_pair = n - n_free - n_single
    plan = [("clean", ())] * (n_free // 2) + [("noise", ())] * (n_free - n_free // 2)
    plan += [("single", (GAIN_DRIFT[i % 2],)) for i in range(n_single)]
    plan += [("pair", (GAIN_DRIFT[i % 2], ("force_offset", ("f1", "f2")[(i // 2) % 2]))) for i in range(n_pair)]
    return _shuffled(plan, seed, "gain_drift")


def design_crosstalk(n: int, seed: int, free_share: float = 0.2) -> list[dict]:
    """``n`` cases for crosstalk between the force channels: ``free_share`` effect-free (half
    without, half with force noise), the rest half the crosstalk alone (``CROSSTALK``), half paired
    with an offset or a scale on either channel; shuffled."""
    n_free = round(free_share * n)
    n_single = round(0.5 * (n - n_free))
    n_pair = n - n_free - n_single
    plan = [("clean", ())] * (n_free // 2) + [("noise", ())] * (n_free - n_free // 2)
    plan += [("single", (CROSSTALK[i % 2],)) for i in range(n_single)]
    plan += [("pair", (CROSSTALK[i % 2], (("force_offset", "force_scale")[(i // 2) % 2], ("f1", "f2")[(i // 4) % 2])))
             for i in range(n_pair)]
    return _shuffled(plan, seed, "crosstalk")


def design_wide(n: int, seed: int) -> list[dict]:
    """``n`` cases with the habits the other designs lack (``make_case`` draws them apart, from the
    case's own second stream, so the other designs are unchanged): half the roads straight lines
    between profile points 5 cm apart (the tyre force jumps between samples), every road class but
    E at up to 35 m/s, and a force noise of 0.3-5 N whatever the vehicle. Half the cases are
    effect-free with that noise (the noise interval's test), 10 % without noise, the rest one
    systematic effect (``SINGLES``) or two (``PAIRS``); shuffled."""
    n_noise, n_clean = round(0.5 * n), round(0.1 * n)
    n_single = round(0.5 * (n - n_noise - n_clean))
    n_pair = n - n_noise - n_clean - n_single
    plan = [("noise", ())] * n_noise + [("clean", ())] * n_clean
    plan += [("single", (SINGLES[(5 * i) % len(SINGLES)],)) for i in range(n_single)]
    plan += [("pair", PAIRS[(3 * i) % len(PAIRS)]) for i in range(n_pair)]
    return _shuffled(plan, seed, "wide")


def _widen(case: dict, out: dict) -> dict:
    """The wide design's extra draws (``design_wide``), from the case's second stream."""
    rng = np.random.default_rng([case["seed"], 1])
    out["road_interp"] = str(rng.choice(["spline7", "linear"]))
    if out["road_class"] == "E":
        out["road_class"] = str(rng.choice(["B", "C", "D"]))
    out["speed"] = float(rng.uniform(10.0, 35.0))
    sigma = float(_loguniform(rng, 0.3, 5.0))
    fx = [e for e in out["effects"] if e["cause"] != "force_noise"]
    if case["stratum"] != "clean":
        fx.append({"cause": "force_noise", "value": sigma})
    out["effects"] = fx
    return out


def make_case(case: dict, *, durations=(10.0, 120.0), rates=(200, 250, 300, 500, 600, 1000, 1200, 2000),
              max_samples: int | None = None):
    """Draw everything else of a case (vehicle, road, speed, rate, channels, sizes, noise);
    ``max_samples`` shortens the run to at most that many samples (sweeps on a CPU budget)."""
    rng = np.random.default_rng(case["seed"])
    vkind = str(rng.choice(sorted(VEHICLES)))
    nominal = {k: float(v * rng.uniform(0.9, 1.1)) for k, v in VEHICLES[vkind].items()}
    nominal["g"] = G
    cls = str(rng.choice(list(ISO_GD0)))
    speed = float(rng.uniform(*SPEEDS[cls]))
    fs = float(rng.choice(rates))
    dur = float(round(_loguniform(rng, *durations), 1)) if durations[0] < durations[1] else float(durations[0])
    if max_samples and dur * fs > max_samples:
        dur = float(round(max_samples / fs, 1))
    if case["stratum"] in ("clean", "noise"):
        chan = str(rng.choice(sorted(CHANNEL_SETS)))
    else:  # systematic effects need measured motion
        chan = str(rng.choice(sorted(k for k in CHANNEL_SETS if k != "forces")))
    effects = []
    if case["stratum"] == "single":
        effects.append(draw_effect(rng, *case["what"][0], nominal, duration=dur))
    elif case["stratum"] == "pair" and case.get("design") in ("nonlinear", "gain_drift", "crosstalk"):
        effects += [draw_effect(rng, *w, nominal, duration=dur) for w in case["what"]]
    elif case["stratum"] == "pair":
        c1, c2 = case["what"]
        if c1 == c2 and c1 != "parameter_error":
            ch = ["f1", "f2"]
            effects += [draw_effect(rng, c1, ch[0], nominal), draw_effect(rng, c2, ch[1], nominal)]
        else:
            used = set()
            for c in (c1, c2):
                pool = [t for t in (PARAMS if c == "parameter_error" else ("f1", "f2")) if t not in used]
                tgt = str(rng.choice(pool))
                used.add(tgt)
                effects.append(draw_effect(rng, c, tgt, nominal))
    load = nominal["m3"] * G / 2
    if case["stratum"] == "noise" or (case["stratum"] in ("single", "pair") and rng.random() < 0.6):
        effects.append({"cause": "force_noise", "value": load * _loguniform(rng, 3e-5, 3e-3)})
    motion_noise = {}
    if chan != "forces" and rng.random() < 0.3:
        lvl = _loguniform(rng, 1.0, 30.0)
        for c in CHANNEL_SETS[chan]:
            motion_noise[c] = lvl * {"beta": 3e-6, "z3": 3e-6, "s1": 3e-6, "s2": 3e-6, "beta_rate": 3e-5}[c]
    out = {
        **case, "vehicle_kind": vkind, "model": nominal, "road_class": cls, "speed": speed, "fs": fs,
        "duration": dur, "channel_set": chan, "channels": list(CHANNEL_SETS[chan]),
        "precision": int(rng.integers(6, 10)), "t0": float(rng.choice([0.0, round(float(rng.uniform(0, 500)), 3)])),
        "lead_in": float(rng.uniform(0.0, 0.5)), "effects": effects, "motion_noise": motion_noise,
        "column_order_seed": int(rng.integers(2**31)), "road_seed": int(rng.integers(2**31)),
        "noise_seed": int(rng.integers(2**31)),
    }
    return _widen(case, out) if case.get("design") == "wide" else out


# ----------------------------------------------------------------------------- one run
def true_vehicle(case: dict) -> dict:
    p = dict(case["model"])
    for e in case["effects"]:
        if e["cause"] == "parameter_error":
            p[e["parameter"]] *= e["value"]
    return p


NONLINEAR_CAUSES = ("damper_asymmetry", "progressive_spring", "bump_stop", "tyre_lift_off")


def _size_nonlinear(case: dict, p: dict, road, v: float, x0: float, tau: np.ndarray):
    """Set the physical size of the nonlinear effects from a linear pre-run on the same road (in
    place: the truth file then holds them); returns (nl, road scale, lift-off)."""
    nl_eff = [e for e in case["effects"] if e["cause"] in NONLINEAR_CAUSES]
    if not nl_eff:
        return None, 1.0, ()
    # only the drawn tyre lifts off (the other keeps the linear law, as in every other run)
    lift = tuple(e["channel"] for e in nl_eff if e["cause"] == "tyre_lift_off")
    pre = signals(p, road, v, x0, simulate(p, road, v, x0, case["duration"] + 1e-9), tau)
    scale = 1.0
    for e in nl_eff:
        if e["cause"] == "tyre_lift_off":
            ch = e["channel"]
            dyn = pre[ch] - pre[ch][0]
            # road heights x scale: the force's dynamic part scales with them (linear model)
            scale = float(pre[ch][0] / max(-np.quantile(dyn, e["share"]), 1e-9))
            e["road_scale"] = scale
    nl = {"lift_off": lift}
    s0 = (p["m3"] * p["g"] * p["a"] / (p["a"] + p["b"]) / p["k3"],
          p["m3"] * p["g"] * p["b"] / (p["a"] + p["b"]) / p["k4"])
    for e in nl_eff:
        if e["cause"] == "damper_asymmetry":
            nl[(e["cause"], e["parameter"])] = e["value"]
            if e.get("definition"):
                nl[("damper_definition", e["parameter"])] = e["definition"]
        elif e.get("fixed"):  # a vehicle's own law (a campaign's shared cause): the size as given
            i = 0 if e["parameter"] == "k3" else 1
            u = scale * (pre[f"s{i + 1}"] - s0[i])
            if e["cause"] == "bump_stop":
                nl[(e["cause"], e["parameter"])] = (e["value"], e["travel"])
                e["share_linear"] = float(np.mean(u > e["travel"]))  # reached by the linear pre-run
            else:
                nl[(e["cause"], e["parameter"])] = e["value"]
        elif e["cause"] in ("progressive_spring", "bump_stop"):
            i = 0 if e["parameter"] == "k3" else 1
            u = scale * (pre[f"s{i + 1}"] - s0[i])
            if e["cause"] == "progressive_spring":  # 3 c u99^2 = stiffening
                u99 = float(np.quantile(np.abs(u), 0.99))
                e["value"] = e["stiffening"] / (3.0 * u99 * u99)
                e["travel_99"] = u99
                nl[(e["cause"], e["parameter"])] = e["value"]
            else:
                ub = float(np.quantile(u, 1.0 - e["share"]))
                e["value"] = e["ratio"] * p[e["parameter"]]
                e["travel"] = ub
                nl[(e["cause"], e["parameter"])] = (e["value"], ub)
    return nl, scale, lift


def generate(case: dict) -> tuple[dict, dict]:
    """(columns of the measured run, true signals) for a drawn case."""
    p = true_vehicle(case)
    v, fs, T = case["speed"], case["fs"], case["duration"]
    x0 = -v * case["lead_in"]  # the front wheel reaches the rough road after the lead-in
    road = FilteredRoad(np.random.default_rng(case["road_seed"]), case["road_class"], x0 + v * (T + 0.1) + 1.0,
                        interp=case.get("road_interp", "spline7"))
    n = int(round(T * fs)) + 1
    tau = np.arange(n) / fs
    nl, scale, lift = _size_nonlinear(case, p, road, v, x0, tau)
    sol = simulate(p, road, v, x0, T + 1e-9, nl=nl, scale=scale)
    true = signals(p, road, v, x0, sol, tau, scale, lift)
    for e in case["effects"]:
        if e["cause"] == "tyre_lift_off":  # the share of samples the tyre actually spends in the air
            e["value"] = float(np.mean(true[e["channel"]] <= 0.0))
    meas = {"f1": true["f1"].copy(), "f2": true["f2"].copy()}
    # a delayed channel reads every true signal late: its own force and the other's (crosstalk)
    late = {e["channel"]: signals(p, road, v, x0, sol, tau - e["value"], scale, lift)
            for e in case["effects"] if e["cause"] == "force_delay"}
    for ch, sig in late.items():
        meas[ch] = sig[ch]
    for e in case["effects"]:  # crosstalk: the other channel's true force, at this channel's time
        if e["cause"] == "force_crosstalk":
            ch = e["channel"]
            other = "f2" if ch == "f1" else "f1"
            meas[ch] = meas[ch] + e["value"] * late.get(ch, true)[other]
    for e in case["effects"]:
        if e["cause"] == "force_scale":
            meas[e["channel"]] = meas[e["channel"]] * e["value"]
        if e["cause"] == "force_gain_drift":  # 1 + drift (t - t_mid)
            meas[e["channel"]] = meas[e["channel"]] * (1.0 + e["value"] * (tau - 0.5 * tau[-1]))
    for e in case["effects"]:
        if e["cause"] == "force_offset":
            meas[e["channel"]] = meas[e["channel"]] + e["value"]
    nrng = np.random.default_rng(case["noise_seed"])
    for e in case["effects"]:
        if e["cause"] == "force_noise":
            for ch in ("f1", "f2"):
                meas[ch] = meas[ch] + e["value"] * nrng.standard_normal(n)
    for e in case["effects"]:  # the amplifier's range, last in the chain: pinned at its top on ``share``
        if e["cause"] == "force_clipping":
            ch = e["channel"]
            e["value"] = float(np.quantile(meas[ch], 1.0 - e["share"]))
            meas[ch] = np.minimum(meas[ch], e["value"])
    for c in case["channels"]:
        meas[c] = true[c] + case["motion_noise"].get(c, 0.0) * nrng.standard_normal(n)
    cols = {"t": case["t0"] + tau, **meas}
    return cols, true


def _format(x: np.ndarray, digits: int) -> list[str]:
    return [f"{v:.{digits}g}" for v in x.tolist()]


def write_run(out_dir: str, name: str, case: dict, cols: dict) -> dict:
    """Write NAME.csv (shuffled column order, data with ``precision`` significant digits, time
    with 10 decimals so its printing jitter stays below 1e-6 of the step), the nominal model
    and the truth; return the three paths."""
    os.makedirs(out_dir, exist_ok=True)
    names = list(cols)
    np.random.default_rng(case["column_order_seed"]).shuffle(names)
    text = {c: ([f"{v:.10f}" for v in cols[c].tolist()] if c == "t" else _format(cols[c], case["precision"]))
            for c in names}
    paths = {k: os.path.join(out_dir, f"{name}{s}") for k, s in
             (("csv", ".csv"), ("model", "_model.json"), ("truth", "_truth.json"))}
    with open(paths["csv"], "w") as fh:
        fh.write(",".join(names) + "\n")
        fh.write("\n".join(",".join(r) for r in zip(*(text[c] for c in names))) + "\n")
    with open(paths["model"], "w") as fh:
        json.dump({k: case["model"][k] for k in KEYS}, fh, indent=1)
    truth = {"schema": "independent.vehicle/1", "case": case, "effects": case["effects"],
             "systematic": [e for e in case["effects"] if e["cause"] != "force_noise"],
             "true_vehicle": true_vehicle(case)}
    with open(paths["truth"], "w") as fh:
        json.dump(truth, fh, indent=1)
    return paths


def make_run(case: dict, out_dir: str, name: str | None = None, **draw) -> dict:
    """Draw (if needed), simulate and write one run; returns the paths."""
    if "model" not in case:
        case = make_case(case, **draw)
    cols, _ = generate(case)
    return write_run(out_dir, name or f"vehicle_{case['index']:04d}", case, cols)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", required=True)
    ap.add_argument("--durations", type=float, nargs=2, default=(10.0, 120.0))
    a = ap.parse_args(argv)
    for case in design(a.n, a.seed):
        paths = make_run(case, a.out, durations=tuple(a.durations))
        print(paths["csv"], flush=True)


if __name__ == "__main__":
    main()
