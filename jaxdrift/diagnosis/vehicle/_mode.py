"""A resonance the model cannot make: ``unmodelled_mode`` (``docs/diagnosis.md``, "A missing
degree of freedom").

A mass ``m`` on a spring-damper (frequency ``f``, damping ratio ``zeta``) at ``x`` ahead of the
centre of mass (an engine on its mounts, a seat, a payload), inside a model that has it rigidly
fixed to the chassis (its mass in ``m3`` and its ``m x^2`` in ``I``): with pitch and heave
measured, what the rigid model gets wrong is exact and linear. The relative travel ``y`` of the
mass obeys ``y'' + 2 zeta w y' + w^2 y = -a_x`` (``a_x = z3'' - x beta''``, the measured
chassis acceleration under it), and the enforced heave force (``_residuals``) misses ``-m y''``,
the enforced moment ``x m y''``: a second-order high-pass of the measured acceleration at ``x``,
zero far below ``f`` (the mass follows the body), ``m a_x`` far above it (the mass stands still)
and resonant in between. The wheels do not see it (their motion is simulated under the measured
chassis), so it shows in the ``heave`` and ``moment`` channels only.

The search (:func:`find_mode`): the two channels' responses to ``z3''`` and ``beta''`` through
the high-pass, for a grid of frequencies and damping ratios, are regressed on the residual of the
model as given, with every linear cause's sensitivity as nuisance columns (a mode is named only for
what no parameter or sensor effect of the model can make); the best grid point is refined
(frequency, damping, place; the mass by least squares) and tested: its z (sandwich variance of the
force noise through the model) against the search's Bonferroni level, its mass against a practical
floor, its frequency inside the searched band, and out of sample: fitted on alternate stretches of
the record alone, it must lower the residual of the others, with the two halves' frequencies
agreeing. The interval of the frequency is the wider of the noise's and the halves' disagreement.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import ClassVar, final

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.signal
import scipy.stats

from .._cause import AbstractCause, DegreeOfFreedom
from ._detectors import _force_hf_noise
from ._residuals import rms as _rms

#: the channels a chassis-mounted mass shows in (with pitch and heave prescribed)
MODE_CHANNELS = ("heave", "moment")
#: searched band of frequencies [Hz]: from below a seat's to above a chassis bending mode's; the
#: upper end also at most a fifth of the sampling rate and the channels' comparison band
F_LO_HZ = 2.0
F_HI_HZ = 40.0
N_FREQ = 48
ZETAS = (0.03, 0.07, 0.15, 0.3)
#: places tried per frequency in the search's count of tests (the Bonferroni divisor)
N_PLACES = 8
#: familywise false-alarm level of the search
ALPHA = 1e-3
#: smallest mass worth naming, as a share of the model's body mass
MASS_MIN = 0.005
#: largest: a mass on its own spring is a part of the body (an engine is 8-15 %); a fit that wants
#: a third of the body or more is something else the model lacks (a 10 ms delay the nuisance's
#: linear term cannot take, a progressive spring: both read as 28-70 % of the body, measured)
MASS_MAX = 0.3
#: largest damping ratio of a resonance (mounts 0.05-0.2, seats up to 0.4); a fit near critical
#: damping is no resonance (the same two fits went to 0.8 and 1)
ZETA_MAX = 0.5
#: the frequencies fitted on the two halves of alternate stretches agree within this share
FREQ_AGREE = 0.15
#: stretches of the out-of-sample check
STRETCHES = 16
#: a mode explains at least this share of what it leaves (RMS over the weighted heave and moment
#: rows, the channels it acts on), as a confirmed linear cause must of its channel (``_confirm.SHARE_MIN``)
SHARE_MIN = 0.25


@final
class UnmodelledMode(AbstractCause, DegreeOfFreedom):
    """A mass on a spring-damper the model lacks (the registry's one instance: ``MODE``)."""

    name: ClassVar[str] = "unmodelled_mode"
    unit: ClassVar[str] = "Hz"

    def residual_response(self, pipe, mode: "Mode") -> dict:
        return mode_response(pipe, mode)


MODE = UnmodelledMode()


@dataclass(frozen=True)
class Mode:
    """A mass ``mass`` [kg] at ``x`` [m ahead of the centre of mass] on a spring-damper of
    frequency ``freq_hz`` and damping ratio ``zeta``, inside the model's rigid body."""

    mass: float
    x: float
    freq_hz: float
    zeta: float

    @property
    def stiffness(self) -> float:
        return self.mass * (2 * math.pi * self.freq_hz) ** 2

    @property
    def damping(self) -> float:
        return 2 * self.zeta * self.mass * 2 * math.pi * self.freq_hz

    def extended(self, p: dict) -> dict:
        """The extended model's mass and the chassis without it (``p``: the model, whose body
        carries the mass rigidly): the chassis's mass, its centre of mass behind the model's by
        ``m x / (m3 - m)`` and its inertia about its own centre of mass."""
        m3c = p["m3"] - self.mass
        xc = -self.mass * self.x / m3c
        return {"mass_kg": self.mass, "x_m": self.x, "stiffness_n_per_m": self.stiffness,
                "damping_n_s_per_m": self.damping, "frequency_hz": self.freq_hz, "damping_ratio": self.zeta,
                "chassis": {"m3": m3c, "x_cg_m": xc, "I": p["I"] - self.mass * self.x ** 2 - m3c * xc ** 2}}


def _highpass_coeffs(f: float, zeta: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The recursion of ``s^2 / (s^2 + 2 zeta w s + w^2)`` exact for an input linear between
    samples (first-order hold; what ``scipy.signal.cont2discrete(..., method="foh")`` and
    ``ss2tf`` give, five times faster: ``tests/test_unmodelled_mode.py``). State-space form
    ``y'' + 2 zeta w y' + w^2 y = -u``, output ``u + 2 zeta w y' + w^2 y``; the hold's block matrix
    exponential gives ``x[k+1] = Phi x[k] + (g1 - g2) u[k] + g2 u[k+1]``."""
    w = 2 * math.pi * f
    M = np.zeros((4, 4))
    M[0, 1], M[1, 0], M[1, 1], M[1, 2], M[2, 3] = 1.0, -w * w, -2 * zeta * w, -1.0, 1.0 / dt
    E = scipy.linalg.expm(M * dt)
    Phi, g1, g2 = E[:2, :2], E[:2, 2], E[:2, 3]
    b0, b1 = g1 - g2, g2
    C = (w * w, 2 * zeta * w)
    den = np.array([1.0, -(Phi[0, 0] + Phi[1, 1]), Phi[0, 0] * Phi[1, 1] - Phi[0, 1] * Phi[1, 0]])
    # C adj(zI - Phi) (b0 + b1 z) + den (the feedthrough), adj = [[z - P11, P01], [P10, z - P00]]
    adj = (((1.0, -Phi[1, 1]), (0.0, Phi[0, 1])), ((0.0, Phi[1, 0]), (1.0, -Phi[0, 0])))
    num = den.copy()
    for i in range(2):
        for j in range(2):
            num += C[i] * np.convolve(adj[i][j], (b1[j], b0[j]))
    return num, den


def _highpass(acc: np.ndarray, f: float, zeta: float, dt: float) -> np.ndarray:
    """``s^2 / (s^2 + 2 zeta w s + w^2)`` of ``acc`` from rest (:func:`_highpass_coeffs`)."""
    num, den = _highpass_coeffs(f, zeta, dt)
    return scipy.signal.lfilter(num, den, acc)


def _basis(pipe, f: float, zeta: float) -> dict:
    """The heave and moment channels' response (banded as the channels are) to the high-pass of
    ``z3''`` and ``beta''``: ``{(channel, 'z' | 'b'): array}``."""
    u = _highpass(pipe.d2z3, f, zeta, pipe.h)
    v = _highpass(pipe.d2beta, f, zeta, pipe.h)
    out = {}
    for tag, sig in (("z", u), ("b", v)):
        ch = {nm: sig.copy() for nm in MODE_CHANNELS}
        pipe._band_filter(ch)
        for nm in MODE_CHANNELS:
            out[(nm, tag)] = ch[nm]
    return out


def _combine(basis: dict, mass: float, x: float) -> dict:
    """The channels' part of the mode: heave ``-m y'' = m (u - x v)``, moment ``-x`` that."""
    h = mass * (basis[("heave", "z")] - x * basis[("heave", "b")])
    mo = -x * mass * (basis[("moment", "z")] - x * basis[("moment", "b")])
    return {"heave": h, "moment": mo}


def mode_response(pipe, mode: Mode) -> dict:
    """What ``mode`` adds to the heave and moment residual channels of the rigid model."""
    return _combine(_basis(pipe, mode.freq_hz, mode.zeta), mode.mass, mode.x)


def carrying(pipe, mode: Mode | None):
    """``pipe`` whose model carries ``mode`` (None: the rigid body)."""
    return pipe.with_mode(mode, None if mode is None else mode_response(pipe, mode))


def mode_shift_var(prob, fit, mode: Mode, half_hz: float) -> np.ndarray:
    """Per linear cause of ``fit`` (chosen beside ``mode``, which ``prob``'s pipe carries), the
    variance its parameter takes from the mode's own frequency error: the shift of the causes as the
    mode's frequency moves (its mass, place and damping refitted with them: the regression of the
    frequency's column on theirs) times the frequency's standard error, ``half_hz / 1.96``
    (:func:`settled_half`). A cause sized beside a mode is only as sure as the mode. Not with the
    reported interval, which holds the search's move to the final size: ``vehicle-modes/indep`` run
    27's d3, 1.00553 for 1.00556, then read [0.983, 1.028] while confirmed."""
    X = fit.X
    if X is None or not fit.causes or half_hz <= 0:
        return np.zeros(len(fit.causes))

    def col(md: Mode) -> np.ndarray:
        parts = mode_response(prob.pipe, md)
        return np.concatenate([parts[nm][prob.skip[nm]:prob.skip[nm] + prob.rows[nm]] / prob.noise_std[nm]
                               if nm in parts else np.zeros(prob.rows[nm]) for nm in prob.names])

    def d(name, step):
        return (col(replace(mode, **{name: getattr(mode, name) + step}))
                - col(replace(mode, **{name: getattr(mode, name) - step}))) / (2 * step)

    A = np.column_stack([X, d("mass", 1e-3 * mode.mass), d("x", 1e-3), d("zeta", 1e-3 * max(mode.zeta, 0.01))])
    sc = np.linalg.norm(A, axis=0)
    sc[sc == 0] = 1.0
    beta = np.linalg.lstsq(A / sc, d("freq_hz", 1e-4 * mode.freq_hz), rcond=None)[0] / sc
    return (beta[: X.shape[1]] * half_hz / 1.96) ** 2


def settled_half(prob, fit, mode: Mode) -> float:
    """The half-width [Hz] of ``mode``'s frequency as sized beside the causes of ``fit`` (the
    model of ``prob`` carries it): the wider of 1.96 standard errors from the force noise and the
    disagreement of its refits on alternate stretches of the record (:func:`_halves`), both at the
    final causes; the search's move to this size (which the reported interval holds) is no error
    of it."""
    pr, p, r, X = _beside(prob, fit)
    search = _Search(pr, r, X)
    _, se_f = _z(search, mode, max(_force_hf_noise(pr.pipe.run)[0], 1e-9))
    f0, f1 = _halves(pr, r, X, p, mode, search)["freqs"]
    return max(1.96 * se_f, abs(f0 - f1))


def _beside(prob, fit):
    """What a mode is sized on beside the causes of ``fit``: ``(the problem on the rigid model, the
    fitted model, its weighted residual, the causes' columns as nuisance)``."""
    from ._causes import _apply

    pipe = carrying(prob.pipe, None)
    p, corr = _apply(prob.model, fit.causes, fit.theta)
    r = prob.weighted(pipe.residuals(p, corr))
    X = fit.X if fit.X is not None and fit.causes else np.zeros((len(r), 0))
    return prob.with_pipe(pipe), p, r, X


def can_show(pipe) -> bool:
    """A mode shows only where pitch and heave are both measured (the acceleration under any place
    of the body is known)."""
    return bool(pipe.has_beta and pipe.has_z3)


class _Search:
    """The weighted residual, its nuisance columns and the rows' times, for fitting a mode.

    A mode's column is zero outside the heave and moment rows, and the projected residual ``rp``
    is orthogonal to the nuisance basis ``Q``: so ``m . rp = w . rp`` and ``m . m = w . w -
    |Q^T w|^2`` for the projected column ``m`` of ``w``, computed on those rows alone."""

    def __init__(self, prob, r: np.ndarray, nuisance: np.ndarray, rows: np.ndarray | None = None):
        self.prob = prob
        self.pipe = prob.pipe
        n_all = len(r)
        self.rows = np.arange(n_all) if rows is None else rows
        self.r = r[self.rows]
        N = np.column_stack([nuisance[self.rows], np.ones(len(self.rows))]) if nuisance.size else \
            np.ones((len(self.rows), 1))
        self.Q, _ = np.linalg.qr(N)
        self.rp = self._proj(self.r)
        self.pos = {}
        pos = 0
        for nm in prob.names:
            self.pos[nm] = (pos, prob.rows[nm])
            pos += prob.rows[nm]
        self.n_all = n_all
        # the heave and moment rows among the rows searched, per channel: (their place in the
        # searched rows, the channel's entries they are)
        inv = np.full(n_all, -1)
        inv[self.rows] = np.arange(len(self.rows))
        self.hm = {}
        for nm in MODE_CHANNELS:
            if nm in self.pos:
                s0, ln = self.pos[nm]
                k = inv[s0:s0 + ln]
                keep = k >= 0
                self.hm[nm] = (k[keep], np.flatnonzero(keep) + prob.skip[nm])
        self.hm_rows = np.concatenate([k for k, _ in self.hm.values()])
        self.Qh = self.Q[self.hm_rows]
        self.rph = self.rp[self.hm_rows]
        self.rss0 = float(self.rp @ self.rp)
        self._cache: dict = {}

    def _proj(self, x):
        return x - self.Q @ (self.Q.T @ x)

    def _w(self, parts: dict) -> np.ndarray:
        """Channel arrays (heave, moment) as the problem's weighted rows, on the heave and moment
        rows only (``hm_rows``)."""
        prob = self.prob
        return np.concatenate([np.asarray(parts[nm])[ent] / prob.noise_std[nm] if nm in parts else np.zeros(len(ent))
                               for nm, (_, ent) in self.hm.items()])

    def basis_scan(self, f, zeta):
        """:meth:`basis` with the band filter applied before the high-pass (both linear and
        time-invariant; they differ only near the record's ends): for the grid, which only picks
        the refinement's start, at a sixth of the cost."""
        if not hasattr(self, "_pre"):
            pipe = self.pipe
            self._pre = {}
            for tag, acc in (("z", pipe.d2z3), ("b", pipe.d2beta)):
                ch = {nm: np.array(acc, dtype=float) for nm in MODE_CHANNELS}
                pipe._band_filter(ch)
                for nm in MODE_CHANNELS:
                    self._pre[(nm, tag)] = ch[nm]
        num, den = _highpass_coeffs(f, zeta, self.pipe.h)
        return {k: scipy.signal.lfilter(num, den, v) for k, v in self._pre.items()}

    def basis(self, f, zeta):
        key = (round(f, 9), round(zeta, 9))
        cache = self._cache.setdefault("basis", {})
        if key not in cache:
            if len(cache) > 64:
                cache.clear()
            cache[key] = _basis(self.pipe, f, zeta)
        return cache[key]

    def column(self, f, zeta, x) -> np.ndarray:
        """The projected weighted column of a unit mass (all searched rows)."""
        w = np.zeros(len(self.rows))
        w[self.hm_rows] = self._w(_combine(self.basis(f, zeta), 1.0, x))
        return self._proj(w)

    def _gram(self, f, zeta, scan: bool = False):
        """For the four weighted columns ``A`` (heave/moment x z''/beta'') of (f, zeta), projected:
        ``A^T A - (Q^T A)^T (Q^T A)`` and ``A^T rp`` (cached): any column a mode makes is ``A c``
        with ``c = (1, -x, -x, x^2)``, so the fits below need no pass over the rows."""
        key = (round(f, 9), round(zeta, 9), scan)
        cache = self._cache.setdefault("gram", {})
        if key not in cache:
            if len(cache) > 512:
                cache.clear()
            b = self.basis_scan(f, zeta) if scan else self.basis(f, zeta)
            A = np.column_stack([self._w({nm: b[(nm, tag)]}) for nm in MODE_CHANNELS for tag in ("z", "b")])
            QA = self.Qh.T @ A
            cache[key] = (A.T @ A - QA.T @ QA, A.T @ self.rph)
        return cache[key]

    def free_fit(self, f, zeta) -> tuple[float, np.ndarray]:
        """RSS left by the four free columns (heave/moment x z''/beta'') and their coefficients."""
        G, g = self._gram(f, zeta, scan=True)
        c = np.linalg.lstsq(G, g, rcond=None)[0]
        return self.rss0 - float(g @ c), c

    def profile(self, f, zeta, x) -> tuple[float, float]:
        """(RSS, mass) at (f, zeta, x), the mass by least squares."""
        G, g = self._gram(f, zeta)
        c = np.array([1.0, -x, -x, x * x])
        mm = float(c @ G @ c)
        mr = float(c @ g)
        mass = mr / mm if mm > 0 else 0.0
        return self.rss0 - mass * mr, mass


#: the search reaches this multiple of the band the heave and moment residuals are compared in
#: (a mode above the band still shows below it, its high-pass rising as the frequency to the 4th)
ABOVE_BAND = 2.0


def _band_hi(pipe) -> float:
    hi = min(F_HI_HZ, 0.2 / pipe.h)
    for nm in MODE_CHANNELS:
        if nm in pipe.band:
            hi = min(hi, ABOVE_BAND * pipe.band[nm][0])
    return hi


def _compared_below(pipe) -> float:
    """The band the heave and moment residuals are compared in [Hz] (the Nyquist frequency where
    neither is low-passed)."""
    return min([0.5 / pipe.h] + [pipe.band[nm][0] for nm in MODE_CHANNELS if nm in pipe.band])


def _lever(p) -> float:
    return 1.5 * max(p["a"], p["b"])


def _refine(search: _Search, p: dict, f0: float, z0: float, x0: float, xatol: float = 1e-4) -> Mode:
    """The mode of least RSS near (f0, z0, x0): Nelder-Mead over log f and log zeta, the place by a
    bounded scalar search at each (the basis of an (f, zeta) is filtered once; the place only
    combines it), the mass by least squares."""
    lo, hi = F_LO_HZ, _band_hi(search.pipe)
    L = _lever(p)

    def unpack(q):
        return float(np.clip(math.exp(q[0]), lo, hi)), float(np.clip(math.exp(q[1]), 0.005, 1.0))

    def best_x(f, z, x_start):
        res = scipy.optimize.minimize_scalar(lambda x: search.profile(f, z, x)[0], bounds=(-L, L), method="bounded",
                                             options={"xatol": 1e-4})
        cand = [(res.fun, float(res.x)), (search.profile(f, z, x_start)[0], x_start)]
        return min(cand)

    def obj(q):
        return best_x(*unpack(q), x0)[0]

    q0 = np.array([math.log(f0), math.log(z0)])
    simplex = np.vstack([q0, q0 + [0.05, 0.0], q0 + [0.0, 0.3]])
    out = scipy.optimize.minimize(obj, q0, method="Nelder-Mead",
                                  options={"xatol": xatol, "fatol": 1e-9 * max(obj(q0), 1e-300), "maxiter": 200,
                                           "initial_simplex": simplex})
    f, z = unpack(out.x)
    x = best_x(f, z, x0)[1]
    return Mode(search.profile(f, z, x)[1], x, f, z)


def _scan(search: _Search, p: dict) -> tuple[float, float, float] | None:
    """The grid point (f, zeta, x) of least RSS with the four free columns."""
    hi = _band_hi(search.pipe)
    if hi <= F_LO_HZ * 1.2:
        return None
    best = None
    L = _lever(p)
    for f in np.geomspace(F_LO_HZ, hi, N_FREQ):
        for z in ZETAS:
            rss, c = search.free_fit(f, z)
            if best is None or rss < best[0]:
                best = (rss, f, z, c)
    _, f, z, c = best
    # the place from the heave coefficients (c_z = m, c_b = -m x)
    x = float(np.clip(-c[1] / c[0], -L, L)) if c[0] != 0 else 0.0
    return f, z, x


def fit_mode(prob, r: np.ndarray, nuisance: np.ndarray, p: dict, start: Mode | None = None,
             rows: np.ndarray | None = None) -> tuple[Mode | None, _Search]:
    """The best mode for the weighted residual ``r`` with ``nuisance`` columns (on ``rows``)."""
    search = _Search(prob, r, nuisance, rows)
    if start is None:
        g = _scan(search, p)
        if g is None:
            return None, search
        start = Mode(0.0, g[2], g[0], g[1])
    return _refine(search, p, start.freq_hz, start.zeta, start.x), search


def _z(search: _Search, mode: Mode, sigma: float) -> tuple[float, float]:
    """The mass's z (sandwich variance of white force noise of ``sigma`` through the model) and
    the frequency's standard error (the same sandwich over mass, frequency, damping and place)."""
    prob = search.prob
    m = search.column(mode.freq_hz, mode.zeta, mode.x)
    mm = float(m @ m)
    full = np.zeros((search.n_all, 1))
    full[search.rows, 0] = m
    meat = float(prob.sandwich_meat(full)[0, 0])
    se_m = sigma * math.sqrt(max(meat, 1e-300)) / mm
    # the frequency's standard error: finite-difference columns of the four parameters
    g0 = mode.mass * m
    cols = [m]
    for name, step in (("freq_hz", 1e-3 * mode.freq_hz), ("zeta", 1e-3 * max(mode.zeta, 0.01)), ("x", 1e-3)):
        md = replace(mode, **{name: getattr(mode, name) + step})
        cols.append((md.mass * search.column(md.freq_hz, md.zeta, md.x) - g0) / step)
    J = np.column_stack(cols)
    Jf = np.zeros((search.n_all, J.shape[1]))
    Jf[search.rows] = J
    inv = np.linalg.pinv(J.T @ J)
    cov = sigma ** 2 * inv @ prob.sandwich_meat(Jf) @ inv
    return mode.mass / se_m, math.sqrt(max(cov[1, 1], 0.0))


def _halves(prob, r, nuisance, p, mode: Mode, search: _Search) -> dict:
    """Out of sample: the mode refitted on alternate stretches of the record alone, its drop of the
    squared residual on the others (summed over stretches, in standard errors of their spread) and
    the two fits' frequencies."""
    t_row = np.concatenate([np.arange(prob.rows[nm]) for nm in prob.names])
    n_t = max(int(t_row.max()) + 1, 1)
    stretch = np.minimum(t_row * STRETCHES // n_t, STRETCHES - 1)
    drops, freqs = [], []
    for parity in (0, 1):
        fit_rows = np.flatnonzero(stretch % 2 == parity)
        md, _ = fit_mode(prob, r, nuisance, p, start=mode, rows=fit_rows)
        freqs.append(md.freq_hz)
        e0 = search.rp
        e1 = search.rp - md.mass * search.column(md.freq_hz, md.zeta, md.x)
        for k in range(STRETCHES):
            if k % 2 != parity:
                sel = stretch == k
                drops.append(float(e0[sel] @ e0[sel] - e1[sel] @ e1[sel]))
    d = np.array(drops)
    se = float(np.std(d, ddof=1) * math.sqrt(len(d)))
    t = float(d.sum() / se) if se > 0 else float(np.sign(d.sum()) * math.inf)
    return {"t": t, "freqs": freqs}


def _moment_peak(pipe, p: dict, hi: float) -> float:
    """The frequency [Hz] where the rigid model's enforced moment has most power (Welch, 4 s
    segments) inside the searched band: a bending mode's resonance (``vehicle-bending/indep``: within
    5 % of the whole car's bending mode in 12 of 12 runs; the negative-mass fit sits 10-60 % above)."""
    from ...io._corrections import NO_CORRECTION

    x = np.asarray(carrying(pipe, None).residuals(p, NO_CORRECTION).channels["moment"])
    f, pw = scipy.signal.welch(x, 1.0 / pipe.h, nperseg=min(len(x), int(4.0 / pipe.h)))
    sel = (f >= F_LO_HZ) & (f <= hi)
    return float(f[sel][np.argmax(pw[sel])])


def plausible(mode: Mode, p: dict, hi: float) -> bool:
    """A mass on its own spring an engineer would believe: ``MASS_MIN``-``MASS_MAX`` of the body,
    damping ratio at most ``ZETA_MAX``, frequency inside the searched band (not at its edges)."""
    return (MASS_MIN * p["m3"] <= mode.mass <= MASS_MAX * p["m3"] and mode.zeta <= ZETA_MAX
            and F_LO_HZ * 1.05 < mode.freq_hz < hi / 1.05)


def find_mode(prob, p: dict, r: np.ndarray, nuisance: np.ndarray, log: list | None = None) -> dict:
    """Search, size and test a mode in the weighted residual ``r`` of the model ``p`` (nuisance:
    the linear causes' columns). Returns ``{"mode": Mode | None, "z", "se_f", "halves", "note",
    "why"}``: ``mode`` set where every test passes."""
    pipe = prob.pipe
    out = {"mode": None, "note": None, "why": None}
    if not can_show(pipe) or not all(nm in prob.names for nm in MODE_CHANNELS):
        out["note"] = ("Could not show: a mass on its own spring that the model lacks (unmodelled_mode: an engine on "
                       "mounts, a seat, a payload); looking for one needs measured pitch and heave.")
        out["why"] = "channels"
        return out
    mode, search = fit_mode(prob, r, nuisance, p)
    if mode is None:
        out["note"] = (f"Could not show: a resonance the model lacks (unmodelled_mode); the heave and moment "
                       f"residuals are compared below {_compared_below(pipe):.3g} Hz only, too narrow a band to "
                       f"look for one.")
        out["why"] = "band"
        return out
    hi = _band_hi(pipe)
    if hi < F_HI_HZ:
        out["note"] = (f"Could not show: a resonance the model lacks (unmodelled_mode) above {hi:.3g} Hz: the search "
                       f"stops there (a fifth of the sampling rate, or below the band the heave and moment "
                       f"residuals are compared in).")
    sigma = _force_hf_noise(pipe.run)[0]
    z, se_f = _z(search, mode, max(sigma, 1e-9))
    n_tests = N_FREQ * len(ZETAS) * N_PLACES
    crit = math.sqrt(scipy.stats.chi2.ppf(1 - ALPHA / n_tests, 1))
    rss0 = search.rss0
    rss1 = search.profile(mode.freq_hz, mode.zeta, mode.x)[0]
    out.update(mode=None, candidate=mode, z=z, se_f=se_f, crit=crit, rss=(rss0, rss1))
    why = None
    # judged on the heave and moment rows, the only ones its column touches (a linear cause's share is
    # judged on its channel): the spring travels' residual, which no mode lowers, hid a chassis
    # bending at 22.7 Hz (vehicle-bending/indep run 23: 22 % of all rows' residual, 35 % of its own)
    drop = max(rss0 - rss1, 0.0)
    explains = math.sqrt(drop) >= SHARE_MIN * math.sqrt(max(float(search.rph @ search.rph) - drop, 1e-300))
    if not (z > crit):
        why = "z"
    elif not plausible(mode, p, hi):
        why = "implausible"
    elif not explains:
        why = "share"
    else:
        halves = _halves(prob, r, nuisance, p, mode, search)
        out["halves"] = halves
        f0, f1 = halves["freqs"]
        if halves["t"] <= 0.0:
            why = "out_of_sample"
        elif abs(f0 - f1) > FREQ_AGREE * mode.freq_hz:
            why = "halves_frequency"
    if log is not None:
        log.append(f"unmodelled mode: {mode.freq_hz:.4g} Hz zeta {mode.zeta:.3g} x {mode.x:.3g} m mass "
                   f"{mode.mass:.4g} kg, z {z:.3g} (crit {crit:.3g}), rss {rss0:.6g} -> {rss1:.6g}"
                   + (f", halves t {out['halves']['t']:.3g} f {out['halves']['freqs']}" if "halves" in out else "")
                   + (f": not named ({why})" if why else ": named"))
    out["why"] = why
    if why is None:
        out["mode"] = mode
    elif why == "z" and z < -crit and -mode.mass >= MASS_MIN * p["m3"] and explains:
        # a resonance with a negative mass: the body acts heavier above it than below, which no mass
        # on its own spring does (a part of the body carrying an axle's force moves against the rest)
        halves = _halves(prob, r, nuisance, p, mode, search)
        if halves["t"] > 0.0:
            out["not_rigid"] = not_rigid(pipe, p, mode, z, halves)
            if log is not None:
                log.append(f"the body is not rigid: {mode.mass:.4g} kg at {mode.freq_hz:.4g} Hz, halves t {halves['t']:.3g}")
    return out


def not_rigid(pipe, p: dict, mode: Mode, z: float, halves: dict) -> dict:
    """What a body that is not rigid is reported from (``_adequacy.not_rigid_finding``): the
    resonance fitted (``mode``, its ``z`` and out-of-sample ``halves``), the frequency the rigid
    model's enforced moment peaks at and the resonance's RMS part of each channel it shows in."""
    parts = mode_response(pipe, mode)
    return {"candidate": mode, "z": z, "halves": halves, "peak_hz": _moment_peak(pipe, p, _band_hi(pipe)),
            "rms": {nm: float(np.sqrt(np.mean(np.square(parts[nm])))) for nm in MODE_CHANNELS}}


def look_for_mode(prob, model: dict, fit, log: list | None = None) -> dict:
    """:func:`find_mode` on the residual of ``fit`` (the linear causes chosen on the rigid model),
    every linear cause's sensitivity at that fit a nuisance column: a mode is named only for what
    none of them can make, and a large cause (a delay of 10 ms) is taken at its fitted size, not by
    its slope at zero."""
    from ._causes import _candidates

    if not can_show(prob.pipe) or not all(nm in prob.names for nm in MODE_CHANNELS):
        return find_mode(prob, model, np.zeros(0), np.zeros((0, 0)), log)
    causes = list(fit.causes) + [c for c in _candidates(prob.pipe) if c not in fit.causes]
    theta = np.concatenate([np.asarray(fit.theta, dtype=float), np.zeros(len(causes) - len(fit.causes))])
    r, _ = prob.eval(causes, theta)
    J = prob.jacobian(causes, theta)
    norms = np.sqrt(np.sum(J * J, axis=0))
    J = J[:, norms > 1e-12 * max(float(norms.max()) if norms.size else 1.0, 1e-300)]
    return find_mode(prob, model, r, J, log)


def resize_mode(prob, fit, mode: Mode, log: list | None = None) -> Mode | None:
    """The mode refitted beside the chosen linear causes (their columns the nuisance, the residual
    the fitted model's without the mode): the search's nuisance held every linear cause, which takes
    part of a mode's mass (a body mass error is a mode's far-above-resonance limit). None where the
    refit is no longer :func:`plausible` or its frequency moved by more than ``FREQ_AGREE``: the
    mode and the chosen causes then trade one for another, and the mode is not shown."""
    pr, p, r, X = _beside(prob, fit)
    new, _ = fit_mode(pr, r, X, p, start=mode)
    ok = plausible(new, p, _band_hi(pr.pipe)) and abs(new.freq_hz - mode.freq_hz) <= FREQ_AGREE * mode.freq_hz
    if log is not None:
        log.append(f"unmodelled mode resized beside {[c.label for c in fit.causes]}: {new.freq_hz:.4g} Hz zeta "
                   f"{new.zeta:.3g} x {new.x:.3g} m mass {new.mass:.4g} kg" + ("" if ok else ": withdrawn"))
    return new if ok else None


def drops(prob, res) -> dict:
    """Per heave and moment channel, the RMS of the mode's part and of the residual without and with
    it: ``res`` are the residuals of a model carrying the mode (``prob``'s pipeline), the causes
    beside it as fitted with it."""
    out = {}
    for nm in MODE_CHANNELS:
        rows = slice(prob.skip[nm], prob.skip[nm] + prob.rows[nm])
        part, after = np.asarray(prob.pipe._mode_parts[nm])[rows], np.asarray(res.channels[nm])[rows]
        out[nm] = (_rms(part), _rms(after + part), _rms(after))
    return out


#: a channel the mode "shows in": its part there is at least this share of the channel's residual
SHOWS_SHARE = 0.1


def shows_in(d: dict) -> list:
    """The channels of :func:`drops`' ``d`` the mode shows in (its part at least ``SHOWS_SHARE`` of
    the residual without it)."""
    return [nm for nm, (part, before, _) in d.items() if part >= SHOWS_SHARE * before]


def lowers_each(prob, res, log: list | None = None) -> bool:
    """Whether the mode lowers the residual of each channel it shows in (:func:`drops`). A mass on
    its own spring does (the heave residual fell 16 to 2000 times on the 38 modes of the modes and
    Exudyn worlds); a chassis bending at 29.6 Hz read as 522 kg at 25.3 Hz raised it from 193 to
    382 N, an offset and crosstalk on f1 beside it taking the mode's heave part back."""
    d = drops(prob, res)
    ok = all(d[nm][2] < d[nm][1] for nm in shows_in(d))
    if log is not None and not ok:
        log.append(f"unmodelled mode raises a channel's residual beside the causes chosen (part, without, with: {d}): "
                   "withdrawn")
    return ok
