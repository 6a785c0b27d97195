"""An independent generator of "true" vehicle runs: scipy ``odeint`` (LSODA) on the seed's equations.

Written from the seed paper's Appendix A (A.1), (A.2) and (4.3) in plain numpy, sharing no code
with jaxdrift's model or engine, so that the diagnosis is not only tested against our own
integrator. The road (hills plus ISO 8608 roughness as a sum of cosines, the rear wheel on the
front wheel's road delayed by the wheelbase) is also written here from scratch.

The measured channels follow ``docs/measured-data.md``: measured force
``f_meas(t) = scale * f_true(t - delay) + offset + noise``; the run starts at rest in static
equilibrium on level road (the road is zero behind x = 0 and ramps in smoothly).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import odeint

SEED_MODEL = {
    "a": 1.0, "b": 1.0, "m1": 15.0, "m2": 15.0, "m3": 750.0, "I": 500.0,
    "k1": 2.0e5, "k2": 2.0e5, "k3": 1.0e5, "k4": 1.0e5,
    "d1": 2.0e2, "d2": 2.0e2, "d3": 1.0e4, "d4": 1.0e4, "g": 9.81,
}

# ISO 8608 displacement PSD at n0 = 0.1 cycles/m [m^3], classes A..E
_GD0 = {"A": 16e-6, "B": 64e-6, "C": 256e-6, "D": 1024e-6, "E": 4096e-6}


class ScipyRoad:
    """Road height h(x) (up positive) = taper(x) * (hills(x) + roughness(x))."""

    def __init__(self, rng, road_class="B", hills=True, n_min=0.02, n_max=2.5, n_waves=60,
                 ramp=15.0):
        n = np.geomspace(n_min, n_max, n_waves + 1)
        nc = np.sqrt(n[1:] * n[:-1])
        dn = np.diff(n)
        gd = _GD0[road_class] * (nc / 0.1) ** -2
        self.amp = np.sqrt(2.0 * gd * dn)
        self.k = 2 * np.pi * nc
        self.phase = rng.uniform(0, 2 * np.pi, n_waves)
        if hills:
            lam = rng.uniform(150.0, 400.0, 3)
            self.h_amp = rng.uniform(0.3, 0.7, 3)
            self.h_k = 2 * np.pi / lam
            self.h_phase = rng.uniform(0, 2 * np.pi, 3)
        else:
            self.h_amp = np.zeros(0)
            self.h_k = np.zeros(0)
            self.h_phase = np.zeros(0)
        self.ramp = ramp

    def _raw(self, x):
        x = np.atleast_1d(x)[:, None]
        r = np.sum(self.amp * np.cos(self.k * x + self.phase), axis=1)
        dr = np.sum(-self.amp * self.k * np.sin(self.k * x + self.phase), axis=1)
        # hills start from 0 with zero slope: A (1 - cos(k x + p) ...) shifted to vanish at 0
        h = np.sum(self.h_amp * (np.cos(self.h_phase) - np.cos(self.h_k * x + self.h_phase)), axis=1)
        dh = np.sum(self.h_amp * self.h_k * np.sin(self.h_k * x + self.h_phase), axis=1)
        return r + h, dr + dh

    def tabulate(self, x_max, dx=0.002):
        """Tabulate (height, slope) on a fine grid; later calls interpolate linearly (the
        shortest wavelength is 0.4 m, so the error is below 1e-4 relative)."""
        grid = np.arange(-5.0, x_max + 5.0, dx)
        self._grid = grid
        self._tab = self.exact(grid)

    def __call__(self, x):
        if getattr(self, "_grid", None) is not None:
            x = np.atleast_1d(np.asarray(x, dtype=float))
            return np.interp(x, self._grid, self._tab[0]), np.interp(x, self._grid, self._tab[1])
        return self.exact(x)

    def pair(self, x1, x2):
        """(h1, h1', h2, h2') at two points, lean for the integrator's right-hand side."""
        X = np.array([[x1], [x2]])
        arg = self.k * X + self.phase
        r = np.cos(arg) @ self.amp
        dr = -(np.sin(arg) @ (self.amp * self.k))
        if self.h_amp.size:
            ha = self.h_k * X + self.h_phase
            r = r + (np.cos(self.h_phase) - np.cos(ha)) @ self.h_amp
            dr = dr + np.sin(ha) @ (self.h_amp * self.h_k)
        out = []
        for i, x in enumerate((x1, x2)):
            if x <= 0.0:
                out += [0.0, 0.0]
            elif x >= self.ramp:
                out += [float(r[i]), float(dr[i])]
            else:
                u = x / self.ramp
                w = u**3 * (10 - 15 * u + 6 * u**2)
                dw = 30 * u**2 * (1 - u) ** 2 / self.ramp
                out += [w * float(r[i]), dw * float(r[i]) + w * float(dr[i])]
        return out

    def exact(self, x):
        """(height, slope) at x (arrays)."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        u = np.clip(x / self.ramp, 0.0, 1.0)
        w = u**3 * (10 - 15 * u + 6 * u**2)  # C2 smoothstep: level road before x = 0
        dw = np.where((x > 0) & (x < self.ramp), 30 * u**2 * (1 - u) ** 2 / self.ramp, 0.0)
        r, dr = self._raw(x)
        return w * r, dw * r + w * dr


def _rhs(t, y, p, road, v):
    """(A.2) with (A.1) and the road contact forces (4.3); y = [z1,z2,z3,beta, rates]."""
    z1, z2, z3, be, dz1, dz2, dz3, dbe = y
    h1, dh1, h2, dh2 = road.pair(v * t, v * t - (p["a"] + p["b"]))
    # z points down: a hill of height h is zeta = -h, so zeta' = -h'(x) v
    f1 = p["k1"] * (z1 + h1) + p["d1"] * (dz1 + dh1 * v)
    f2 = p["k2"] * (z2 + h2) + p["d2"] * (dz2 + dh2 * v)
    sb, cb = math.sin(be), math.cos(be)
    f3 = p["k3"] * (z3 - z1 - p["b"] * sb) + p["d3"] * (dz3 - dz1 - p["b"] * dbe * cb)
    f4 = p["k4"] * (z3 - z2 + p["a"] * sb) + p["d4"] * (dz3 - dz2 + p["a"] * dbe * cb)
    return [
        dz1, dz2, dz3, dbe,
        p["g"] + (f3 - f1) / p["m1"],
        p["g"] + (f4 - f2) / p["m2"],
        p["g"] - (f3 + f4) / p["m3"],
        cb * (p["b"] * f3 - p["a"] * f4) / p["I"],
    ]


def _equilibrium(p):
    """Static state on level road: f3 = a m3 g/(a+b), f4 = b m3 g/(a+b), beta from (A.1)."""
    g = p["g"]
    f3 = p["a"] * p["m3"] * g / (p["a"] + p["b"])
    f4 = p["b"] * p["m3"] * g / (p["a"] + p["b"])
    f1 = p["m1"] * g + f3
    f2 = p["m2"] * g + f4
    z1, z2 = f1 / p["k1"], f2 / p["k2"]
    # z3 - z1 - b s = f3/k3 and z3 - z2 + a s = f4/k4
    s = ((z2 + f4 / p["k4"]) - (z1 + f3 / p["k3"])) / (p["a"] + p["b"])
    z3 = z1 + f3 / p["k3"] + p["b"] * s
    return np.array([z1, z2, z3, np.arcsin(s), 0, 0, 0, 0])


def make_run(true_params, *, duration=20.0, fs=500.0, speed=15.0, road_class="B", hills=True,
             seed=0, effects=(), noise_sigma=0.0, channels=("beta", "z3", "s1", "s2"), road_n_max=2.5,
             road_waves=60):
    """Simulate a true run with scipy and apply the sensor effects.

    ``true_params``: dict of the seed's keys (the *true* vehicle). ``effects``: list of dicts
    ``{"cause": "force_offset"|"force_scale"|"force_delay", "channel": "f1"|"f2",
    "value": float}``. Returns (columns dict with ``t``, ``f1``, ``f2`` and the requested
    ``channels``; dict of true (noise-free, effect-free) signals).
    """
    p = dict(true_params)
    rng = np.random.default_rng(seed)
    road = ScipyRoad(rng, road_class=road_class, hills=hills, n_max=road_n_max, n_waves=road_waves)
    n = int(round(duration * fs)) + 1
    t = np.arange(n) / fs
    y0 = _equilibrium(p)
    v = float(speed)
    y = _integrate(p, road, v, y0, t)
    def forces_at(tt, yy):
        x1 = v * tt
        x2 = v * tt - (p["a"] + p["b"])
        h1, dh1 = road(x1)
        h2, dh2 = road(x2)
        f1 = p["k1"] * (yy[:, 0] + h1) + p["d1"] * (yy[:, 4] + dh1 * v)
        f2 = p["k2"] * (yy[:, 1] + h2) + p["d2"] * (yy[:, 5] + dh2 * v)
        return f1, f2, -h1, -h2
    f1, f2, zeta1, zeta2 = forces_at(t, y)
    true = {"t": t, "f1": f1, "f2": f2, "z1": y[:, 0], "z2": y[:, 1], "z3": y[:, 2],
            "beta": y[:, 3], "beta_rate": y[:, 7], "zeta1": zeta1, "zeta2": zeta2}
    sb = np.sin(y[:, 3])
    true["s1"] = y[:, 2] - y[:, 0] - p["b"] * sb
    true["s2"] = y[:, 2] - y[:, 1] + p["a"] * sb
    meas = {"f1": f1.copy(), "f2": f2.copy()}
    # delays first (on the true signal), then scale, then offset: f = s * true(t - d) + o
    for e in effects:
        if e["cause"] == "force_delay":
            ch = e["channel"]
            d = float(e["value"])
            tt = t - d
            # re-integrate densely: the true force at t - d from the continuous solution
            yy = _integrate(p, road, v, y0, tt)
            fa, fb, _, _ = forces_at(np.maximum(tt, 0.0), yy)
            meas[ch] = fa if ch == "f1" else fb
    for e in effects:
        if e["cause"] == "force_scale":
            meas[e["channel"]] = meas[e["channel"]] * float(e["value"])
    for e in effects:
        if e["cause"] == "force_offset":
            meas[e["channel"]] = meas[e["channel"]] + float(e["value"])
    if noise_sigma > 0:
        nrng = np.random.default_rng(seed + 1_000_003)
        meas["f1"] = meas["f1"] + noise_sigma * nrng.standard_normal(n)
        meas["f2"] = meas["f2"] + noise_sigma * nrng.standard_normal(n)
    cols = {"t": t, "f1": meas["f1"], "f2": meas["f2"]}
    for c in channels:
        cols[c] = true[c]
    return cols, true


def _integrate(p, road, v, y0, tt):
    """LSODA (odeint) at tight tolerances; times t <= 0 give the rest state."""
    tt = np.asarray(tt, dtype=float)
    out = np.empty((len(tt), 8))
    neg = tt <= 0
    out[neg] = y0
    tp = tt[~neg]
    if tp.size:
        order = np.argsort(tp)
        grid = np.concatenate([[0.0], tp[order]])
        y, info = odeint(_rhs, y0, grid, args=(p, road, v), tfirst=True, rtol=1e-10,
                         atol=1e-12, mxstep=1_000_000, full_output=True)
        if info["message"] != "Integration successful.":
            raise RuntimeError(info["message"])
        res = np.empty((tp.size, 8))
        res[order] = y[1:]
        out[~neg] = res
    return out
