"""Nonlinear suspension causes: force terms the linear springs and dampers of the model lack.

Each cause is one self-contained class: its name and unit, the extra chassis spring force it adds
per unit of its parameter ``theta`` as a function of the model's own states (``force``), its
plausible range, the estimate it reports, its correction in the extended model (the fields of
:class:`jaxdrift.models.NonlinearSuspension`) and its evidence sentence. All vanish at the static
state, so the static equilibrium stays the linear one.

How a cause shows in the residuals (``signatures``): an extra spring force ``Delta_i(t)`` on axle
``i`` acts on the model like an input. The comparison is linear given the measured motion, so its
change is the linear model's response to ``Delta`` (the same exact discretisation as the
residuals), plus ``Delta`` itself where the channel sums spring forces (moment, heave). In a spring
channel the direct term cancels: the model's prediction from the measured travel carries ``Delta``
too. So the spring channel shows ``Delta`` almost undiminished (the wheel passes the force on),
while moment and heave show only what the small wheel mass makes of it: a spring law error barely
changes the forces the wheels pass on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import final

import numpy as np
from scipy.interpolate import CubicSpline

from ...io._corrections import FORCE_CHANNELS, unclip
from ...io._timebase import true_runs
from .._cause import AbstractCause, SignalDetector, StateForce
from .._diffnoise import mad_sigma
from ._discretise import _poly_coeffs

AXLES = ("front", "rear")


@dataclass
class States:
    """The fitted model's spring travel from its static value ``u`` [m] and rate ``v`` [m/s] per
    axle on the fine grid (positive: compression), with the static travel and the model."""

    u: tuple
    v: tuple
    s0: tuple
    p: dict


class NonlinearCause(AbstractCause, StateForce):
    """A state-dependent force term (abstract; capability :class:`.._cause.StateForce`): ``axle`` 0
    (front, k3/d3) or 1 (rear, k4/d4)."""

    name = ""
    unit = ""
    spring_or_damper = "k"

    def __init__(self, axle: int):
        self.axle = axle

    @property
    def target(self) -> str:
        return f"{self.spring_or_damper}{self.axle + 3}"

    @property
    def label(self) -> str:
        return f"{self.name}[{self.target}]"

    #: capabilities, read instead of the concrete class: a cause the report can name with a
    #: correction (a bare state term cannot: it becomes ``model_form``); a size read off the
    #: profile of the term's travel (a bump stop) rather than refined at the model's states
    nameable = True
    sized_by_travel_profile = False
    #: the nuisance column of the adequacy test (``_adequacy._tests``: front k, front d, rear k,
    #: rear d) that holds the change of the law's mean beside this term, None where the size does
    #: not depend on it
    mean_column: int | None = None
    #: the relative resolution of the cause's size: its 95 % interval is never narrower than +- this
    #: share of the estimate. The statistical interval can fall far below what the model resolves:
    #: with the travel measured, +-1e-5 of the size around estimates off by up to 2.7e-4 (nonlinear
    #: sweep seed 20261204); a stop seen in pitch rate only, +-0.25 % around an estimate 0.32 % low
    #: (``tests/test_diagnose_vehicle_nonlinear.py``, the stop beside an offset). The diagnosis's
    #: model and the generator's are integrated and sampled differently, and a real vehicle's
    #: spring law is no closer to the catalogue's form than that
    resolution: float = 5e-3

    @property
    def said_unseen(self) -> bool:
        """Whether "could not show" speaks for this term (once per cause, not per grid variant)."""
        return self.nameable

    def prepare(self, st: States) -> None:
        """Fix what the term depends on before its size is refined (nothing by default)."""

    def state_words(self) -> tuple[str, str]:  # (state key, phrase) of the state the force depends on
        raise NotImplementedError

    def force(self, st: States) -> np.ndarray:  # extra spring force per unit theta [N]
        raise NotImplementedError

    def bounds(self, st: States) -> tuple[float, float]:
        raise NotImplementedError

    def to_estimate(self, theta: float, st: States) -> float:
        raise NotImplementedError

    def correction(self, theta: float, st: States) -> dict:
        raise NotImplementedError

    def typical(self, st: States) -> float:
        """The largest size engineers meet, in theta: 'could not show' compares with it."""
        raise NotImplementedError

    def smallest(self, st: States) -> float:
        """The smallest size engineers meet, in theta: below it 'could not show' is not said."""
        raise NotImplementedError

    def size_words(self, theta: float, st: States) -> str:
        """A size in theta, in the words of the sizes engineers meet."""
        raise NotImplementedError

    def describe(self, theta: float, st: States) -> str:
        raise NotImplementedError


class DamperAsymmetry(NonlinearCause):
    """Rebound damping ``d (m + theta)``, compression ``d (m - theta)``: ``theta`` the term's size,
    ``m`` the mean damping over the fitted model's ``d`` (``mean``: the adequacy test's linear damper
    column beside the term, set where the term is sized; 1 until then). Reported as the
    rebound/compression ratio ``(m + theta) / (m - theta)``: a law written as "compression d,
    rebound rho d" has a mean ``(1 + rho) / 2`` times its d, and reading the ratio as
    ``(1 + theta) / (1 - theta)`` on such a run gave 3 for 2 where nothing else took the mean.
    The extended model keeps the ratio with the model's mean (a mean error is the linear
    ``parameter_error``, chosen again on the model that has the ratio)."""

    name, unit, spring_or_damper = "damper_asymmetry", "ratio", "d"

    def __init__(self, axle: int, mean: float = 1.0):
        super().__init__(axle)
        self.mean_column = 1 + 2 * axle
        self.mean = mean

    def with_mean(self, mean: float) -> "DamperAsymmetry":
        """The same term read with the mean damping ``mean`` (a new object)."""
        return DamperAsymmetry(self.axle, mean)

    def state_words(self):
        return (f"|s{self.axle + 1}'|", f"the size of the {AXLES[self.axle]} damper's velocity, with opposite "
                "sign in rebound and compression")

    def force(self, st):
        d = st.p["d3" if self.axle == 0 else "d4"]
        return -d * np.abs(st.v[self.axle])

    def bounds(self, st):
        return -0.6, 0.6  # ratio 0.25 ... 4

    def to_estimate(self, theta, st):
        return (self.mean + theta) / (self.mean - theta)

    def correction(self, theta, st):
        return {f"damper_ratio{self.axle + 3}": self.to_estimate(theta, st)}

    def typical(self, st):
        return 0.6 / 2.6  # ratio 1.6

    def smallest(self, st):
        return 0.15 / 2.15  # ratio 1.15

    def size_words(self, theta, st):
        r = (1.0 + abs(theta)) / (1.0 - abs(theta))  # at the model's mean
        return f"a rebound/compression ratio of {r:.3g} (or 1/{r:.3g})"

    def describe(self, theta, st):
        r = self.to_estimate(theta, st)
        which = "stiffer in rebound than in compression" if r > 1 else "stiffer in compression than in rebound"
        return (f"the {AXLES[self.axle]} damper is {which}: rebound/compression ratio {r:.3g} "
                f"({self.target} x {self.mean + theta:.3g} in rebound, x {self.mean - theta:.3g} in compression)")


class ProgressiveSpring(NonlinearCause):
    """Spring force ``k (u + theta u^3)``, u the travel from the static one; theta [1/m^2]."""

    name, unit, spring_or_damper = "progressive_spring", "1/m^2", "k"

    def state_words(self):
        return f"u{self.axle + 1}^3", f"the cube of the {AXLES[self.axle]} spring's travel from its static value"

    def _u99(self, st):
        return max(float(np.quantile(np.abs(st.u[self.axle]), 0.99)), 1e-6)

    def force(self, st):
        k = st.p["k3" if self.axle == 0 else "k4"]
        return k * st.u[self.axle] ** 3

    def bounds(self, st):
        u = self._u99(st)
        return -0.9 / (3 * u * u), 5.0 / (3 * u * u)  # stiffness -90 % ... +500 % at the 99 % travel

    def to_estimate(self, theta, st):
        return theta

    def correction(self, theta, st):
        return {f"cubic{self.axle + 3}": theta}

    def typical(self, st):
        u = self._u99(st)
        return 1.0 / (3 * u * u)  # +100 % stiffness at the run's 99th-percentile travel

    def smallest(self, st):
        u = self._u99(st)
        return 0.2 / (3 * u * u)  # +20 %

    def size_words(self, theta, st):
        u = self._u99(st)
        return f"{100 * 3 * theta * u * u:.3g} % more stiffness at the run's 99th-percentile travel"

    def describe(self, theta, st):
        u = self._u99(st)
        ch = 3 * theta * u * u
        return (f"the {AXLES[self.axle]} spring is {'progressive' if theta > 0 else 'degressive'}: "
                f"force {self.target} (u + {theta:.4g} u^3), its stiffness {100 * ch:+.3g} % at "
                f"{1e3 * u:.3g} mm from the static travel (99 % of the run's travel)")


class BumpStop(NonlinearCause):
    """A stop of stiffness ``theta k`` beyond the compression ``u_b`` from the static travel; u_b
    is chosen from a grid of the run's travel quantiles (``GRID``), theta fitted."""

    name, unit, spring_or_damper = "bump_stop", "N/m", "k"
    GRID = (0.9, 0.95, 0.97, 0.98, 0.99, 0.995)

    sized_by_travel_profile = True
    #: a stop's stiffness rests on the 2-5 % of the samples at the travel's extremes, where an
    #: error of the travel (the model's, or a sensor's noise on a measured one) is largest beside
    #: the penetration: of the 25 stops sized in the nonlinear sweep seed 20261261 (at e27915d;
    #: ``docs/validation/e27915d-bump-stop-tuning-seed20261261.md``) the 24 with an interval under
    #: 10 % scattered by 0.53 % RMS around the truth (up to 1.6 %), and the 0.5 % floor of the other
    #: causes held the truth in 22 of 25. This floor is 1.96 x that scatter
    resolution = 1.0e-2

    def __init__(self, axle: int, q: float, travel: float | None = None):
        super().__init__(axle)
        self.q = q
        #: a travel given (a campaign's stop, the same in every run): kept, never re-read off the states
        self.given = travel is not None
        self.u_b = travel

    @property
    def said_unseen(self) -> bool:  # the stop at the middle of the grid speaks for all of them
        return self.q == 0.97

    def prepare(self, st):
        if not self.given:
            self.fix_travel(st)

    def state_words(self):
        i, ax = self.axle + 1, AXLES[self.axle]
        return f"max(u{i} - u_b, 0)", f"the {ax} spring's compression beyond {1e3 * self.q:.3g} per mille of its travel"

    #: the stop's travel, once fixed (``fix_travel``): the quantile of the linear model's travel
    u_b = None

    def travel(self, st):
        return self.u_b if self.u_b is not None else float(np.quantile(st.u[self.axle], self.q))

    def fix_travel(self, st):
        """Keep the travel of ``st`` while the states move (``_adequacy._refine``)."""
        self.u_b = float(np.quantile(st.u[self.axle], self.q))

    def force(self, st):
        k = st.p["k3" if self.axle == 0 else "k4"]
        return k * np.maximum(st.u[self.axle] - self.travel(st), 0.0)

    def bounds(self, st):
        return 0.0, 30.0

    def to_estimate(self, theta, st):
        return theta * st.p[self.target]

    def correction(self, theta, st):
        return {f"stop_k{self.axle + 3}": self.to_estimate(theta, st), f"stop_u{self.axle + 3}": self.travel(st)}

    def typical(self, st):
        return 10.0

    def smallest(self, st):
        return 3.0

    def size_words(self, theta, st):
        return f"a stop {theta:.3g}x the spring reached on {100 * (1 - self.q):.3g} % of the samples"

    def describe(self, theta, st):
        share = 100 * (1 - self.q)
        return (f"the {AXLES[self.axle]} suspension hits a stop: {self.to_estimate(theta, st):.4g} N/m "
                f"({theta:.3g} x {self.target}) beyond {1e3 * self.travel(st):.3g} mm of compression "
                f"from the static travel (reached on {share:.3g} % of the samples)")


class StateTerm(NonlinearCause):
    """A state-dependent force outside the catalogue (``model_form`` only): a quadratic damper
    ``v |v|`` or a spring stiffer one way ``u^2``."""

    nameable = False

    def __init__(self, axle: int, kind: str):
        super().__init__(axle)
        self.kind = kind
        self.name = "model_form"
        self.spring_or_damper = "d" if kind == "v|v|" else "k"

    def state_words(self):
        i, ax = self.axle + 1, AXLES[self.axle]
        if self.kind == "v|v|":
            return f"s{i}'|s{i}'|", f"the square of the {ax} damper's velocity (a quadratic damper)"
        return f"u{i}^2", f"the square of the {ax} spring's travel (a spring stiffer one way than the other)"

    def force(self, st):
        v, u = st.v[self.axle], st.u[self.axle]
        if self.kind == "v|v|":
            vr = max(float(np.sqrt(np.mean(v * v))), 1e-9)
            return st.p[self.target] * v * np.abs(v) / vr
        ur = max(float(np.sqrt(np.mean(u * u))), 1e-9)
        return st.p[self.target] * u * u / ur

    def bounds(self, st):
        return -math.inf, math.inf


def catalogue() -> list[NonlinearCause]:
    """Every nonlinear cause and state term tried on a run (bump stops at each grid travel)."""
    out: list[NonlinearCause] = []
    for ax in (0, 1):
        out += [DamperAsymmetry(ax), ProgressiveSpring(ax)]
        out += [BumpStop(ax, q) for q in BumpStop.GRID]
        out += [StateTerm(ax, "v|v|"), StateTerm(ax, "u^2")]
    return out


def signal_detectors() -> list[SignalDetector]:
    """The causes read off the measured forces before anything is fitted, one instance per force
    channel, in the order the report lists them."""
    return [*(ForceClipping(ch) for ch in FORCE_CHANNELS), *(TyreLiftOff(ch) for ch in FORCE_CHANNELS)]


def nonlinear_cause_names() -> tuple[str, ...]:
    """The nonlinear causes the diagnosis can name: the nameable ones of :func:`catalogue` and those
    read off the forces (:func:`signal_detectors`)."""
    names = []
    for c in (*catalogue(), *signal_detectors()):
        if getattr(c, "nameable", True) and c.name not in names:
            names.append(c.name)
    return tuple(names)


# ----------------------------------------------------------------------------- states, signatures
def model_states(pipe, p: dict, corr: dict, travel: dict | None = None) -> States:
    """Spring travel and rate of the fitted model driven by the corrected forces (fine grid); the
    measured travel and its rate where there is one, ``travel`` (``{column: samples}``) where given:
    the measured travel without its sensor noise (``_motion_noise.denoised_travel``)."""
    forces_c, _ = pipe._corrected_coeffs(corr, False)
    f3, f4, x = pipe.simulate(p, None, forces_c=forces_c)
    a, b = p["a"], p["b"]
    if pipe.mode == "pitch" and pipe.has_z3:
        s = (pipe.Z - x[:, 0] - b * pipe.S, pipe.Z - x[:, 1] + a * pipe.S)
        ds = (pipe.dZ - x[:, 2] - b * pipe.dS, pipe.dZ - x[:, 3] + a * pipe.dS)
    elif pipe.mode == "pitch":
        s = (x[:, 0] - b * pipe.S, x[:, 1] + a * pipe.S)
        ds = (x[:, 2] - b * pipe.dS, x[:, 3] + a * pipe.dS)
    else:
        s, ds = (x[:, 0], x[:, 1]), (x[:, 2], x[:, 3])
    g, m3 = p["g"], p["m3"]
    s0 = (a * m3 * g / (a + b) / p["k3"], b * m3 * g / (a + b) / p["k4"])
    # where the spring travel is measured the terms take it and its rate: a spring law acts on the
    # real travel, which the linear model overshoots wherever the real law is stiffer (a stop: 61 mm
    # of model travel where the stop begins at 52 mm), and a damper law on the real rate (the
    # model's rate left small damping errors of the same damper beside an asymmetry)
    s, ds = list(s), list(ds)
    for i, nm in enumerate(("s1", "s2")):
        if nm in (travel or {}):
            s[i] = pipe._resample(travel[nm])
            ds[i] = CubicSpline(pipe.tauf, s[i])(pipe.tauf, 1)
        elif pipe.has_s[i]:
            s[i], ds[i] = pipe.s_f[nm], pipe.ds[nm]
    n = len(s[0])
    return States(tuple(np.asarray(s[i][:n]) - s0[i] for i in (0, 1)), tuple(np.asarray(ds[i][:n]) for i in (0, 1)),
                  s0, p)


def travel_response(pipe, p: dict, delta: tuple) -> tuple[tuple, tuple]:
    """Change of the model's spring travel and rate per axle (fine grid) when the extra spring forces
    ``delta = (d3, d4)`` act: the model driven by the measured forces then moves its wheels (and, where
    pitch and heave are not measured, its chassis) differently, and so its travel."""
    d3, d4 = (np.resize(np.asarray(d, dtype=float), pipe.nf) for d in delta)
    e1, e2 = _equivalent_forces(pipe, p, d3, d4)
    forces_c = {"f1": _poly_coeffs(CubicSpline(pipe.tauf, e1)), "f2": _poly_coeffs(CubicSpline(pipe.tauf, e2))}
    _, _, x = pipe.simulate(p, None, linear_part_only=True, forces_c=forces_c)
    sg = -1.0 if (pipe.mode == "pitch" and pipe.has_z3) else 1.0
    return (sg * x[:, 0], sg * x[:, 1]), (sg * x[:, 2], sg * x[:, 3])


def _equivalent_forces(pipe, p: dict, d3: np.ndarray, d4: np.ndarray):
    """Tyre-force inputs that move the linear system as extra spring forces (d3, d4) would."""
    m1, m2, m3, I, a, b = p["m1"], p["m2"], p["m3"], p["I"], p["a"], p["b"]
    if pipe.mode == "pitch" and pipe.has_z3:
        return -d3, -d4
    if pipe.mode == "pitch":
        return (-m1 * (1 / m3 + 1 / m1) * d3 - m1 / m3 * d4,
                -m2 / m3 * d3 - m2 * (1 / m3 + 1 / m2) * d4)
    c = -1 / m3 + a * b / I
    return (m1 * (-(1 / m3 + 1 / m1 + b * b / I) * d3 + c * d4),
            m2 * (c * d3 - (1 / m3 + 1 / m2 + a * a / I) * d4))


def signatures(pipe, p: dict, delta: tuple) -> dict:
    """Change of every residual channel (kept rows not yet cut) when the extra spring forces
    ``delta = (d3, d4)`` (fine grid) are added to the model: see the module docstring."""
    d3, d4 = (np.asarray(d, dtype=float) for d in delta)
    n = pipe.nf
    d3, d4 = np.resize(d3, n), np.resize(d4, n)
    e1, e2 = _equivalent_forces(pipe, p, d3, d4)
    forces_c = {"f1": _poly_coeffs(CubicSpline(pipe.tauf, e1)), "f2": _poly_coeffs(CubicSpline(pipe.tauf, e2))}
    f3, f4, x = pipe.simulate(p, None, linear_part_only=True, forces_c=forces_c)
    U = pipe.U
    ch = {}
    a, b = p["a"], p["b"]
    if pipe.has_beta:
        ch["moment"] = -(pipe.cosb * (b * (f3 + d3) - a * (f4 + d4)))[::U][1:-1]
    if pipe.has_z3:
        ch["heave"] = (f3 + f4 + d3 + d4)[::U][1:-1]
    for i, fs in ((0, f3), (1, f4)):
        if pipe.has_s[i]:
            ch[f"spring{i + 1}"] = fs[::U]
    for i in (1, 2):
        if f"tyre{i}" in pipe.channel_names:
            k, d = (p["k1"], p["d1"]) if i == 1 else (p["k2"], p["d2"])
            ch[f"tyre{i}"] = -(k * x[:, i - 1] + d * x[:, i + 1])[::U]
    pipe._band_filter(ch)
    return ch


class TyreLiftOff(AbstractCause, SignalDetector):
    """The tyre force cannot pull: where the wheel leaves the road the measured force sits at its
    floor (the sensor's zero) instead of going below it. The force-driven comparison takes the
    measured forces as they are, so no residual shows it; the forces themselves do: an atom of
    samples at the floor, where a force that never touches zero thins out towards its minimum.

    Test: with ``m`` the 0.1 % quantile of the force and ``w = 3 sigma + 0.005 F_s`` (sigma the
    force noise, or the spread (MAD) of the samples within ``NEAR_SHARE`` F_s of ``m`` where that is
    lower; F_s the static load), the samples in ``[m, m + w]`` must be at least ``MIN_SHARE``
    of the record in at least ``MIN_STRETCHES`` separate stretches and more than ``ATOM_RATIO``
    times those in ``[m + w, m + 2 w]``, nothing may lie more than ``w`` below ``m`` (a floor: a
    force that only dips towards zero goes on below its 0.1 % quantile), and ``m`` must be within
    ``FLOOR_SHARE`` of the static load from zero (a force offset moves the floor)."""

    name, unit = "tyre_lift_off", "share of samples"
    MIN_SHARE = 0.003
    ATOM_RATIO = 3.0
    FLOOR_SHARE = 0.15
    MIN_STRETCHES = 5
    #: the samples within this share of the static load above the floor give the noise there
    NEAR_SHARE = 0.02

    def __init__(self, channel: str):
        self.channel = channel

    def detect(self, f: np.ndarray, sigma: float) -> dict | None:
        f = np.asarray(f, dtype=float)
        fs0 = float(np.median(f[: max(5, len(f) // 200)]))
        if fs0 <= 0:
            return None
        m = float(np.quantile(f, 0.001))
        # the noise at the floor itself: the forces' top-band level is only an upper bound where
        # they carry real content there (a rough road at a low rate: 24 N read where 0.8 N was
        # written), and so wide a window takes in the steep flanks of every lift-off
        near = f[f <= m + self.NEAR_SHARE * fs0]
        sigma = min(sigma, mad_sigma(near))
        w = 3.0 * sigma + 0.005 * fs0
        if abs(m) > self.FLOOR_SHARE * fs0 or float(f.min()) < m - w:
            return None
        inside = f <= m + w
        k1 = int(inside.sum())
        k2 = int(((f > m + w) & (f <= m + 2 * w)).sum())
        if k1 < self.MIN_SHARE * len(f) or k1 <= self.ATOM_RATIO * k2:
            return None
        flights = int(np.sum(np.diff(inside.astype(int)) == 1) + inside[0])
        if flights < self.MIN_STRETCHES:
            return None
        floor = float(np.median(f[inside]))
        share = k1 / len(f)
        half = 1.96 * share / math.sqrt(max(flights, 1))
        return {"share": share, "floor": floor, "flights": flights, "k_next": k2,
                "interval": [max(share - half, 0.0), min(share + half, 1.0)], "width": w}

    def finding(self, det: dict) -> dict:
        ch, i = self.channel, self.channel[1]
        ev = (f"{ch} sits at its floor of {det['floor']:.3g} N on {100 * det['share']:.3g} % of the samples "
              f"({det['flights']} separate stretches within {det['width']:.3g} N of it; {det['k_next']} samples "
              f"lie in the next {det['width']:.3g} N above, where a force that only comes near zero would have more): "
              f"the tyre leaves the road and cannot pull. The force-driven comparison takes the measured "
              f"forces and is not affected; a road-driven model needs the tyre law with lift-off "
              f"(NonlinearSuspension(lift_off=True)); a measured road height zeta{i} would check the tyre "
              f"law there")
        return {"cause": self.name, "channel": ch, "estimate": float(det["share"]), "unit": self.unit,
                "interval": [float(x) for x in det["interval"]], "evidence": ev + "."}

    def model_terms(self, det: dict) -> dict:
        return {"lift_off": True}


@final
class ForceClipping(AbstractCause, SignalDetector):
    """A force channel saturating at its range: the amplifier or the ADC at the end of its range
    reads its extreme value wherever the force goes beyond it, and the peaks are lost. The forward
    effect (:meth:`forward`, last in the sensor's chain): ``min(f, range)``. The samples themselves
    show it: a channel that sits at exactly its largest (or smallest) value on ``MIN_SAMPLES``
    samples or more, in bursts of two or more in a row, and on :data:`ATOM_RATIO` times as many
    samples as the next value it reads, is pinned there. A smallest value of exactly 0 is a tyre in
    the air (:class:`TyreLiftOff`), not a range. Measured with the forces rounded to steps of 1 to
    100 N (``benchmarks/validation/clip_quantisation.py``) on 16 fresh runs of the independent
    generator (seed 20261511) written with and without a clip on 0.2-2 % of one channel: no false
    alarm on 48 channels at any step; every clip found up to 10 N steps, 14 of 16 at 50 N and 10 of
    16 at 100 N (a step of 0.5-1 % of the peaks, where a clip and a quantised peak look alike).
    ``ATOM_RATIO`` was chosen on the runs of seeds 20261401/3 and 20261501, where without it 9 of 92
    channels read as clipped at 50 N steps.

    The estimate is the range (the pinned value, exact to the logger's resolution: no interval,
    and no part in the joint level of the report's intervals). The inverse (:meth:`corrected`) is
    the channel's correction record with ``clip`` set: the pinned bursts restored from the samples around them
    (:func:`jaxdrift.io._corrections.unclip`) before anything is fitted, and by the same record
    in the series output and durability. What a burst lost beyond the restoration stays unknown;
    the evidence says how much the restoration added."""

    name, unit = "force_clipping", "N"
    MIN_SAMPLES = 5
    #: the pinned value holds at least this many times the samples of the next value the channel
    #: reads (a coarsely quantised peak's top holds about as many as the step below it)
    ATOM_RATIO = 3.0
    restores = True

    def __init__(self, channel: str):
        self.channel = channel

    def forward(self, measured: dict, target: str, value: float, read=None) -> dict:
        """The measured forces with channel ``target`` pinned at ``value`` from above (new arrays)."""
        return {**measured, target: np.minimum(measured[target], value)}

    def detect(self, f: np.ndarray, sigma: float) -> dict | None:
        f = np.asarray(f, dtype=float)
        fin = f[np.isfinite(f)]
        if fin.size < 100:
            return None
        levels, bursts = {}, 0
        for side, v in (("hi", float(fin.max())), ("lo", float(fin.min()))):
            if side == "lo" and v == 0.0:
                continue  # a tyre in the air, not a range
            at = f == v
            runs = [(a, b) for a, b in true_runs(at) if b - a >= 2]
            # an atom, not the top of a coarse quantisation: the value next to it holds far fewer
            inner = fin[fin < v] if side == "hi" else fin[fin > v]
            nxt = int(np.sum(inner == (inner.max() if side == "hi" else inner.min()))) if inner.size else 0
            if sum(b - a for a, b in runs) >= self.MIN_SAMPLES and int(at.sum()) >= self.ATOM_RATIO * nxt:
                levels[side] = v
                bursts += len(runs)
        if not levels:
            return None
        lo, hi = levels.get("lo"), levels.get("hi")
        at = np.isin(f, list(levels.values()))
        beyond = np.abs(unclip(np.arange(f.size), f, lo, hi) - f)  # on the uniform grid of the samples
        return {"lo": lo, "hi": hi, "samples": int(at.sum()), "bursts": bursts, "share": float(at.mean()),
                "beyond": float(beyond.max())}

    def corrected(self, c, det: dict):
        return replace(c, clip=(det["lo"], det["hi"]))

    def finding(self, det: dict) -> dict:
        side = "hi" if det["hi"] is not None else "lo"
        level = det[side]
        ends = " and ".join(f"{'its top' if s == 'hi' else 'its bottom'} at {det[s]:.6g} N"
                            for s in ("hi", "lo") if det[s] is not None)
        ev = (f"{self.channel} sits at exactly {ends} on {det['samples']} samples ({100 * det['share']:.3g} % of the "
              f"record) in {det['bursts']} bursts of two or more: the channel clips at its range and loses its "
              f"peaks. The pinned bursts are restored from the samples around them before anything is fitted (the "
              f"extended model's correction 'clip'), by up to {det['beyond']:.3g} N beyond the range; what a burst "
              f"lost beyond that restoration is unknown.")
        return {"cause": self.name, "channel": self.channel, "estimate": float(level), "unit": self.unit,
                "interval": None, "samples": det["samples"], "evidence": ev}
