"""The residual pipeline: residual channels that vanish for the right model (step 1 of
``docs/diagnosis.md``).

Given the measured pitch the stabilised simulation (A.5) is linear; in relative coordinates it is
a stable 4-state system driven by the forces and the prescribed motion, integrated exactly between
samples for cubic-spline inputs (``_discretise``). The residual channels: ``moment``, ``heave``,
``spring1``/``spring2``, ``tyre1``/``tyre2`` and ``static``.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
import scipy.fft
import scipy.signal
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from ...io._corrections import Corrections
from ...io._csvio import VehicleRun
from ._causes import FORCE_CHANNELS
from ._discretise import _deriv_coeffs, _discretise, _mm, _poly_coeffs, _run_recursion

@dataclass
class Residuals:
    channels: dict[str, np.ndarray]        # raw (physical units)
    f3: np.ndarray
    f4: np.ndarray


class ResidualPipeline:
    """Residual channels of a run for a model and input corrections (see module docstring)."""

    def __init__(self, run: VehicleRun):
        self.run = run
        self.t = run.t
        self.h = run.dt
        self.n = run.n
        self.tau = self.t - self.t[0]
        #: samples at the end left out of the dynamic residuals (room for delays up to trim h)
        self.trim = int(min(max(round(0.25 / self.h), 4), self.n // 10))
        self._fspl_cache: dict = {}
        self._disc_cache: dict = {}
        # Inputs are band-limited (road-driven forces and motion), not piecewise cubic: below
        # 800 Hz the comparison runs on a grid refined by band-limited (FFT) interpolation, where
        # the cubic pieces are accurate; residual rows are taken back at the measured samples.
        self.U = int(max(1, math.ceil(800.0 / (1.0 / self.h) - 1e-9)))
        self.hf = self.h / self.U
        self.nf = (self.n - 1) * self.U + 1
        self.tauf = np.arange(self.nf) * self.hf
        self.has_beta = run.has("beta")
        self.has_z3 = run.has("z3")
        self.has_s = [run.has("s1"), run.has("s2")]
        self.mode = "pitch" if self.has_beta else "free"
        if self.has_beta:
            self._prescribe_pitch()
        if self.has_z3:
            self._prescribe_heave()
        self._road_under_wheels()
        self._spring_travel()
        self.channel_names = self._channel_names()
        #: per residual channel: (cutoff Hz, sos) of a zero-phase low-pass applied to it, set by
        #: :func:`_problem.choose_bands` where the measured motion carries sensor noise
        self.band: dict = {}
        #: extra chassis spring forces (front, rear) on the fine grid that the model carries besides
        #: its linear springs and dampers (a nonlinear suspension cause found by the adequacy test,
        #: ``with_extra``); ``None``: the linear model
        self.extra = None
        self._extra_cache: dict = {}
        #: a mass on a spring-damper the model carries besides its rigid body (``with_mode``,
        #: ``_mode``): its part of the heave and moment channels; ``None``: the rigid body
        self.unmodelled = None
        self._mode_parts: dict = {}

    # ---- step 1: the prescribed motion on the fine grid
    def _prescribe_pitch(self):
        """sin(beta) as cubic pieces on the fine grid (Hermite with the measured rate when there is
        one and no refinement), its derivative, cos(beta) and beta'' at the measured samples."""
        run = self.run
        beta = self._resample(run["beta"])
        S = np.sin(beta)
        if run.has("beta_rate") and self.U == 1:
            sp = CubicHermiteSpline(self.tauf, S, np.cos(beta) * run["beta_rate"])
        else:
            sp = CubicSpline(self.tauf, S)
        self.S_c = _poly_coeffs(sp)
        self.dS_c = _deriv_coeffs(self.S_c)
        self.S = S
        self.dS = sp(self.tauf, 1)
        self.cosb = np.cos(beta)
        self.d2beta = self._second_derivative(run["beta"])

    def _prescribe_heave(self):
        """z3 as cubic pieces on the fine grid, its derivative, and z3'' at the measured samples."""
        z3 = self._resample(self.run["z3"])
        sp = CubicSpline(self.tauf, z3)
        self.Z_c = _poly_coeffs(sp)
        self.dZ_c = _deriv_coeffs(self.Z_c)
        self.Z = z3
        self.dZ = sp(self.tauf, 1)
        self.d2z3 = self._second_derivative(self.run["z3"])

    def _road_under_wheels(self):
        """Road height under the wheels: with pitch and heave measured the wheel states are
        simulated in absolute coordinates, and the tyre law checks the forces directly."""
        self.zeta_f = {}
        self.dzeta = {}
        if self.mode == "pitch" and self.has_z3:
            for name in ("zeta1", "zeta2"):
                if self.run.has(name):
                    zf = self._resample(self.run[name])
                    self.zeta_f[name] = zf
                    self.dzeta[name] = CubicSpline(self.tauf, zf)(self.tauf, 1)

    def _spring_travel(self):
        """Measured spring travel s1/s2 and its derivative on the fine grid."""
        self.s_f = {}
        self.ds = {}
        for i, name in enumerate(("s1", "s2")):
            if self.has_s[i]:
                sf = self._resample(self.run[name])
                sp = CubicSpline(self.tauf, sf)
                self.s_f[name] = sf
                self.ds[name] = sp(self.tauf, 1)

    def _second_derivative(self, x: np.ndarray) -> np.ndarray:
        """x'' at the measured samples 1..n-2 by spectral differentiation of the smoothly
        padded record (see :meth:`_padded_spectrum`).

        Exact for a band-limited record (the motion of a road-driven vehicle is). A plain second
        difference errs by (omega h)^2 / 12 (2 % of the wheel-hop content at 200 Hz, which looks
        like a wrong inertia), Numerov's form by (omega h)^4 / 240: on a true run at 200 Hz the
        enforced moment is 0.2 N m with an 8th-order difference and 0.003 N m this way.
        """
        X, N, m = self._padded_spectrum(x)
        w = 2 * np.pi * np.fft.rfftfreq(N) / self.h
        return scipy.fft.irfft(-(w * w) * X, n=N)[m:m + self.n][1:-1]

    def _rows_numerov(self, x_f: np.ndarray) -> np.ndarray:
        """Fine-grid rows (fine samples 1..nf-2) taken at the measured samples 1..n-2."""
        return x_f[self.U - 1::self.U][: self.n - 2]

    def _padded_spectrum(self, x: np.ndarray):
        """Spectrum of the record padded to a smooth periodic signal: the rest value on the
        left (the run starts at rest) and, on the right, a cubic Hermite from the last value and
        slope back to it, so that value and slope are continuous (a kink would ring across the
        record when the signal is differentiated or interpolated)."""
        x = np.asarray(x, dtype=float)
        m = max(256, 4 * self.trim)
        slope = (3 * x[-1] - 4 * x[-2] + x[-3]) / 2 if len(x) >= 3 else 0.0  # per sample
        u = np.arange(1, m + 1) / (m + 1)
        h00, h10, h01 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u, -2 * u**3 + 3 * u**2
        right = h00 * x[-1] + h10 * slope * (m + 1) + h01 * x[0]
        y = np.concatenate([np.full(m, x[0]), x, right])
        N = scipy.fft.next_fast_len(len(y), real=True)
        y = np.concatenate([y, np.full(N - len(y), x[0])])
        return scipy.fft.rfft(y), N, m

    def _resample(self, x: np.ndarray, shift: float = 0.0, spec=None) -> np.ndarray:
        """``x(t + shift h)`` on the fine grid, by band-limited (FFT) interpolation.

        The record is padded with its first value on the left (the run starts at rest) and a
        smooth blend back to it on the right, so the periodic extension has no jump; the last
        ``trim`` samples are not used in the fit. A shift is an all-pass phase: white noise stays
        white with the same variance (a spline evaluated between samples would smooth it, and a
        spurious sub-sample delay would then look like a better fit).
        """
        if self.U == 1 and shift == 0.0:
            return np.asarray(x, dtype=float)
        X, N, m = self._padded_spectrum(x) if spec is None else spec
        if shift != 0.0:
            X = X * np.exp(1j * 2 * np.pi * np.fft.rfftfreq(N) * shift)
        if self.U == 1:
            return scipy.fft.irfft(X, n=N)[m:m + self.n]
        U = self.U
        Y = np.zeros(N * U // 2 + 1, dtype=complex)
        Y[: len(X)] = X * U
        if N % 2 == 0:
            Y[N // 2] *= 0.5  # the Nyquist bin splits between +- f_N
        y = scipy.fft.irfft(Y, n=N * U)
        return y[m * U:m * U + self.nf]

    def _channel_names(self) -> list[str]:
        out = []
        if self.has_beta:
            out.append("moment")
        if self.has_z3:
            out.append("heave")
        if self.has_s[0]:
            out.append("spring1")
        if self.has_s[1]:
            out.append("spring2")
        for i in (1, 2):
            if f"zeta{i}" in self.zeta_f:
                out.append(f"tyre{i}")
        out.append("static")
        return out

    # ---- step 2: the (corrected) measured forces and the linear system they drive
    def measured(self, ch: str, smooth: bool = False) -> np.ndarray:
        """A measured force channel, or its low-passed version (the instruments, see _Problem)."""
        if not smooth:
            return self.run[ch]
        key = ("smooth", ch)
        if key not in self._fspl_cache:
            fs = 1.0 / self.h
            fc = min(25.0, fs / 8.0)
            sos = scipy.signal.butter(4, fc, fs=fs, output="sos")
            f = self.run[ch]
            # zero phase; padded with the rest value on the left (the run starts at rest)
            self._fspl_cache[key] = scipy.signal.sosfiltfilt(sos, f - f[0], padtype="even") + f[0]
        return self._fspl_cache[key]

    def with_band(self, band: dict) -> "ResidualPipeline":
        """The same pipeline with the channels of ``band`` compared low-passed (``{channel:
        (cutoff Hz, sos)}``; the caches of the forces are shared, the original is unchanged)."""
        new = copy.copy(self)
        new.band = dict(band)
        return new

    def with_extra(self, extra: tuple | None) -> "ResidualPipeline":
        """The same pipeline whose model carries the extra spring forces ``extra = (d3, d4)`` (fine
        grid, [N]; the original is unchanged). Its residuals are the linear model's plus the
        channels' response to them (``_nonlinear.signatures``): the comparison the linear causes
        are chosen on once a nonlinear cause is known, so that they do not stand in for it."""
        new = copy.copy(self)
        new.extra = None if extra is None else tuple(np.asarray(d, dtype=float) for d in extra)
        new._extra_cache = {}
        return new

    def with_mode(self, mode, parts: dict | None = None) -> "ResidualPipeline":
        """The same pipeline whose model carries ``mode`` (``_mode.Mode``: a mass on a
        spring-damper inside the rigid body; ``None``: none) with ``parts``, its part of the
        channels (``_mode.mode_response``, banded as the channels are: it depends on the measured
        motion alone, not on the model's parameters, so it is computed once)."""
        new = copy.copy(self)
        new.unmodelled = mode
        new._mode_parts = {} if mode is None else dict(parts)
        return new

    def _extra_channels(self, p: dict) -> dict:
        """The residual channels' change under ``self.extra`` for the model ``p`` (cached)."""
        from ._nonlinear import signatures  # the signatures module builds on this one

        key = tuple(sorted(p.items()))
        if key not in self._extra_cache:
            if len(self._extra_cache) > 64:
                self._extra_cache.clear()
            self._extra_cache[key] = signatures(self, p, self.extra)
        return self._extra_cache[key]

    def corrected_forces(self, corr: Corrections, smooth: bool = False) -> dict[str, np.ndarray]:
        """True-force estimate on the fine grid (:class:`Corrections`), the delay applied as a
        band-limited (FFT) shift."""
        return corr.unmix(self._read_forces(corr, smooth))

    def _read_forces(self, corr: Corrections, smooth: bool) -> dict[str, np.ndarray]:
        """Each channel's own correction (:meth:`ForceCorrection.finish`), before any crosstalk is
        undone."""
        out = {}
        for ch in FORCE_CHANNELS:
            c = corr[ch]
            key = ("spec", ch, smooth)
            if key not in self._fspl_cache:
                self._fspl_cache[key] = self._padded_spectrum(self.measured(ch, smooth))
            if c.delay == 0.0 and self.U == 1:
                f = self.measured(ch, smooth)
            else:
                f = self._resample(None, c.delay / self.h, spec=self._fspl_cache[key])
            out[ch] = c.finish(f, self.tauf)
        return out

    # ---- the linear systems
    def _system(self, p: dict):
        """(A, B, input names) of the relative-coordinate system for this run's mode."""
        m1, m2, m3, I = p["m1"], p["m2"], p["m3"], p["I"]
        k3, k4, d3, d4, a, b = p["k3"], p["k4"], p["d3"], p["d4"], p["a"], p["b"]
        if self.mode == "pitch" and self.has_z3:
            # states [z1, z2, z1', z2'] with z3 and beta prescribed (wheels decouple)
            # f3 = k3 (Z - z1 - b S) + d3 (Z' - z1' - b S'); z1'' = g + (f3 - f1)/m1
            A = np.zeros((4, 4))
            A[0, 2] = A[1, 3] = 1.0
            A[2, 0], A[2, 2] = -k3 / m1, -d3 / m1
            A[3, 1], A[3, 3] = -k4 / m2, -d4 / m2
            names = ["f1", "f2", "S", "dS", "Z", "dZ", "one"]
            B = np.zeros((4, len(names)))
            B[2, 0] = -1 / m1
            B[3, 1] = -1 / m2
            B[2, 2], B[2, 3] = -k3 * b / m1, -d3 * b / m1
            B[3, 2], B[3, 3] = k4 * a / m2, d4 * a / m2
            B[2, 4], B[2, 5] = k3 / m1, d3 / m1
            B[3, 4], B[3, 5] = k4 / m2, d4 / m2
            B[2, 6] = B[3, 6] = p["g"]
            return A, B, names
        if self.mode == "pitch":
            # states [u1, u2, u1', u2'], u_i = z3 - z_i; f3 = k3 (u1 - b S) + d3 (u1' - b S')
            # u1'' = -(f3 + f4)/m3 - (f3 - f1)/m1, u2'' = -(f3 + f4)/m3 - (f4 - f2)/m2
            names = ["f1", "f2", "S", "dS"]
            # f3 = F3x x + F3w w, f4 = F4x x + F4w w
            F3x = np.array([k3, 0, d3, 0.0])
            F4x = np.array([0, k4, 0, d4])
            F3w = np.array([0, 0, -k3 * b, -d3 * b])
            F4w = np.array([0, 0, k4 * a, d4 * a])
            A = np.zeros((4, 4))
            A[0, 2] = A[1, 3] = 1.0
            B = np.zeros((4, 4))
            A[2] = -(F3x + F4x) / m3 - F3x / m1
            A[3] = -(F3x + F4x) / m3 - F4x / m2
            B[2] = -(F3w + F4w) / m3 - F3w / m1
            B[3] = -(F3w + F4w) / m3 - F4w / m2
            B[2, 0] += 1 / m1
            B[3, 1] += 1 / m2
            return A, B, names
        # free pitch, linearised: states [s1, s2, s1', s2'], f3 = k3 s1 + d3 s1'
        F3x = np.array([k3, 0, d3, 0.0])
        F4x = np.array([0, k4, 0, d4])
        Mx = b * F3x - a * F4x
        A = np.zeros((4, 4))
        A[0, 2] = A[1, 3] = 1.0
        A[2] = -(F3x + F4x) / m3 - F3x / m1 - b * Mx / I
        A[3] = -(F3x + F4x) / m3 - F4x / m2 + a * Mx / I
        B = np.zeros((4, 2))
        B[2, 0] = 1 / m1
        B[3, 1] = 1 / m2
        return A, B, ["f1", "f2"]

    def _input_coeffs(self, name, forces_c):
        if name in ("f1", "f2"):
            return forces_c[name]
        if name == "S":
            return self.S_c
        if name == "dS":
            return self.dS_c
        if name == "Z":
            return self.Z_c
        if name == "dZ":
            return self.dZ_c
        if name == "one":
            c = np.zeros((4, self.nf - 1))
            c[0] = 1.0
            return c
        raise KeyError(name)

    def _initial_state(self, p: dict, zero_ic: bool) -> np.ndarray:
        if zero_ic:
            return np.zeros(4)
        g, a, b, m3 = p["g"], p["a"], p["b"], p["m3"]
        s1 = a * m3 * g / (a + b) / p["k3"]
        s2 = b * m3 * g / (a + b) / p["k4"]
        if self.mode == "pitch" and self.has_z3:
            z1 = self.Z[0] - b * self.S[0] - s1
            z2 = self.Z[0] + a * self.S[0] - s2
            return np.array([z1, z2, self.dZ[0] - b * self.dS[0], self.dZ[0] + a * self.dS[0]])
        if self.mode == "pitch":
            return np.array([s1 + b * self.S[0], s2 - a * self.S[0], b * self.dS[0], -a * self.dS[0]])
        return np.array([s1, s2, 0.0, 0.0])

    def _corrected_coeffs(self, corr: dict, smooth: bool):
        """Spline coefficients (fine grid) and first values of the corrected forces.

        The spline is linear in the data, so offset and scale act on the cached coefficients of
        the (shifted) measured signal: only a new delay needs a new spline.
        """
        coeffs, first = {}, {}
        # a scale changing over the run is not a constant factor on the coefficients
        drifting = self._read_forces(corr, smooth) if any(c.drift != 0.0 for _, c in corr.items()) else {}
        for ch in FORCE_CHANNELS:
            c = corr[ch]
            if c.drift != 0.0:
                f = drifting[ch]
                coeffs[ch], first[ch] = _poly_coeffs(CubicSpline(self.tauf, f)), float(f[0])
                continue
            key = ("coef", ch, smooth, float(c.delay))
            if key not in self._fspl_cache:
                if sum(1 for k in self._fspl_cache if k[0] == "coef") > 16:
                    for k in [k for k in self._fspl_cache if k[0] == "coef"]:
                        del self._fspl_cache[k]
                f = self.corrected_forces(corr.only_delay(), smooth)[ch]
                self._fspl_cache[key] = (_poly_coeffs(CubicSpline(self.tauf, f)), float(f[0]))
            C, f0 = self._fspl_cache[key]
            C = C.copy()
            C[0] -= c.offset
            C *= c.gain
            coeffs[ch] = C
            first[ch] = (f0 - c.offset) * c.gain
        return corr.unmix(coeffs), corr.unmix(first)  # crosstalk: linear, so on the coefficients too

    def simulate(self, p: dict, forces: dict[str, np.ndarray] | None, *, linear_part_only=False,
                 forces_c: dict | None = None):
        """Spring forces (f3, f4) at the samples. ``linear_part_only``: response to the forces
        alone (zero initial state, no prescribed-motion and gravity inputs), for the noise
        impulse responses."""
        key = tuple(sorted(p.items()))
        if key not in self._disc_cache:
            A, B, names = self._system(p)
            if len(self._disc_cache) > 64:
                self._disc_cache.clear()
            self._disc_cache[key] = (_discretise(A, B, self.hf), names)
        (Phi, G), names = self._disc_cache[key]
        if forces_c is None:
            forces_c = {ch: _poly_coeffs(CubicSpline(self.tauf, forces[ch])) for ch in FORCE_CHANNELS}
        # contributions of the prescribed-motion and gravity inputs depend on the parameters
        # only: cached per parameter set
        fkey = (key, "fixed")
        if linear_part_only:
            v = np.zeros((self.nf - 1, 4))
        elif fkey in self._disc_cache:
            v = self._disc_cache[fkey].copy()
        else:
            v = np.zeros((self.nf - 1, 4))
            for j, name in enumerate(names):
                if name in FORCE_CHANNELS:
                    continue
                v += _mm(self._input_coeffs(name, forces_c).T, G[:, :, j])
            self._disc_cache[fkey] = v.copy()
        for j, name in enumerate(names):
            if name in FORCE_CHANNELS:
                v += _mm(forces_c[name].T, G[:, :, j])
        x = _run_recursion(Phi, v, self._initial_state(p, linear_part_only))
        k3, k4, d3, d4, a, b = p["k3"], p["k4"], p["d3"], p["d4"], p["a"], p["b"]
        lin = linear_part_only
        if self.mode == "pitch" and self.has_z3:
            Z = 0 if lin else self.Z
            dZ = 0 if lin else self.dZ
            S = 0 if lin else self.S
            dS = 0 if lin else self.dS
            f3 = k3 * (Z - x[:, 0] - b * S) + d3 * (dZ - x[:, 2] - b * dS)
            f4 = k4 * (Z - x[:, 1] + a * S) + d4 * (dZ - x[:, 3] + a * dS)
        elif self.mode == "pitch":
            S = 0 if lin else self.S
            dS = 0 if lin else self.dS
            f3 = k3 * (x[:, 0] - b * S) + d3 * (x[:, 2] - b * dS)
            f4 = k4 * (x[:, 1] + a * S) + d4 * (x[:, 3] + a * dS)
        else:
            f3 = k3 * x[:, 0] + d3 * x[:, 2]
            f4 = k4 * x[:, 1] + d4 * x[:, 3]
        return f3, f4, x

    # ---- step 3: the residual channels
    def residuals(self, p: dict, corr: dict, *, linear_part_only=False,
                  forces: dict | None = None, smooth: bool = False) -> Residuals:
        """Residual channels at the measured samples (physical units). ``forces``: force
        samples on the measured grid to use instead of the corrected measured ones."""
        if forces is None:
            forces_c, first = self._corrected_coeffs(corr, smooth)
        else:
            forces = {ch: self._resample(forces[ch]) for ch in FORCE_CHANNELS}
            forces_c = None
            first = {ch: forces[ch][0] for ch in FORCE_CHANNELS}
        f3, f4, x = self.simulate(p, forces, linear_part_only=linear_part_only, forces_c=forces_c)
        ch = self._enforced_channels(p, f3, f4, linear_part_only)
        ch.update(self._spring_channels(p, f3, f4, linear_part_only))
        ch.update(self._tyre_channels(p, x, forces, forces_c, linear_part_only))
        self._band_filter(ch)
        if self.extra is not None and not linear_part_only:
            for nm, x in self._extra_channels(p).items():
                ch[nm] = ch[nm] + x
        if not linear_part_only:
            for nm, x in self._mode_parts.items():
                if nm in ch:
                    ch[nm] = ch[nm] - x
        ch["static"] = self._static_channel(p, first, linear_part_only)
        U = self.U
        return Residuals(ch, f3[::U], f4[::U])

    def _enforced_channels(self, p: dict, f3, f4, lin: bool) -> dict:
        """The enforced moment ``I beta'' - cos(beta)(b f3 - a f4)`` and the vertical enforced
        force ``m3 z3'' - (m3 g - f3 - f4)`` at the samples 1..n-2."""
        U = self.U
        ch = {}
        a, b = p["a"], p["b"]
        if self.has_beta:
            M = (self.cosb * (b * f3 - a * f4))[::U]
            ch["moment"] = (0.0 if lin else p["I"] * self.d2beta) - M[1:-1]
        if self.has_z3:
            V = (-(f3 + f4) if lin else p["m3"] * p["g"] - f3 - f4)[::U]
            ch["heave"] = (0.0 if lin else p["m3"] * self.d2z3) - V[1:-1]
        return ch

    def _spring_channels(self, p: dict, f3, f4, lin: bool) -> dict:
        """Simulated chassis spring forces against ``k s + d s'`` of the measured travel."""
        ch = {}
        for i, name in enumerate(("s1", "s2")):
            if self.has_s[i]:
                k, d = (p["k3"], p["d3"]) if i == 0 else (p["k4"], p["d4"])
                fs = f3 if i == 0 else f4
                meas = 0.0 if lin else k * self.s_f[name] + d * self.ds[name]
                ch[f"spring{i + 1}"] = (fs - meas)[::self.U]
        return ch

    def _tyre_channels(self, p: dict, x, forces, forces_c, lin: bool) -> dict:
        """Tyre law ``f_i = k_i (z_i - zeta_i) + d_i (z_i' - zeta_i')``, wheel states z_i simulated
        from the forces with pitch and heave prescribed (states [z1, z2, z1', z2'])."""
        ch = {}
        for i in (1, 2):
            name = f"zeta{i}"
            if name not in self.zeta_f:
                continue
            k, d = (p["k1"], p["d1"]) if i == 1 else (p["k2"], p["d2"])
            # spline values at the fine nodes (the last node repeats its left neighbour: the end of
            # the record is trimmed from the rows)
            fi = forces[f"f{i}"] if forces is not None else np.append(forces_c[f"f{i}"][0], forces_c[f"f{i}"][0][-1])
            zeta = 0.0 if lin else self.zeta_f[name]
            dzeta = 0.0 if lin else self.dzeta[name]
            model = k * (x[:, i - 1] - zeta) + d * (x[:, i + 1] - dzeta)
            ch[f"tyre{i}"] = (fi - model)[::self.U]
        return ch

    def _band_filter(self, ch: dict) -> None:
        """Zero-phase low-pass of the channels whose measured motion carries sensor noise (in place).

        Mirror padding several time constants long: the filter starts from the steady state of the
        first padded value, and on a channel swamped by sensor noise that value is noise; with the
        default short odd padding its step rang well into the record (a pitch-only run with 1e-5 rad
        of noise then named a mass error of 2.5).

        The channel is first tapered to zero over ``0.5 / fc`` at both ends (raised cosine; those
        rows are inside the rows :func:`_problem.choose_bands` leaves out). Even padding still
        starts the filter from the noise's value at the record's end: the differentiated sensor
        noise is 1e5-1e6 times the low band's level, and the filter's start from such a value rang
        through the whole record (measured: a van at 500 Hz with 7.7e-5 rad of pitch noise, enforced
        moment below 1 Hz 76 N m RMS mid-record without the taper, 0.40 N m with it, 5e-5 N m without
        the noise), which read as force noise of 53 N and as damper and spring errors at z = 6-8."""
        for name, (fc, sos) in self.band.items():
            if name not in ch:
                continue
            x = np.array(ch[name], dtype=float)
            q = min(int(math.ceil(0.5 / (fc * self.h))), len(x) // 8)
            if q > 1:
                w = 0.5 - 0.5 * np.cos(np.pi * np.arange(q) / q)
                x[:q] *= w
                x[len(x) - q:] *= w[::-1]
            padlen = min(len(x) - 1, int(math.ceil(6.0 / (fc * self.h))))
            ch[name] = scipy.signal.sosfiltfilt(sos, x, padtype="even", padlen=padlen)

    def _static_channel(self, p: dict, first: dict, lin: bool) -> np.ndarray:
        """The first force samples against the model's static loads (the run starts at rest)."""
        if lin:
            return np.array([first["f1"], first["f2"]])
        g, m3, a, b = p["g"], p["m3"], p["a"], p["b"]
        f1s = p["m1"] * g + a * m3 * g / (a + b)
        f2s = p["m2"] * g + b * m3 * g / (a + b)
        return np.array([first["f1"] - f1s, first["f2"] - f2s])


# ----------------------------------------------------------------------------- channel helpers
def rms(x) -> float:
    """Root mean square (0 for an empty array)."""
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else 0.0


def kept(prob, res: Residuals, nm: str) -> np.ndarray:
    """The rows of channel ``nm`` the comparison uses (the record's end, and a low-passed
    channel's start, left out)."""
    return res.channels[nm][prob.skip[nm]:prob.skip[nm] + prob.rows[nm]]


def telling_channel(prob, before: Residuals, after: Residuals, default: str) -> str:
    """The residual channel where a correction shows most: the largest drop of the residual sum of
    squares in units of the channel's noise (the enforced moment when nothing drops clearly)."""
    best, best_drop = default, 0.0
    for nm in prob.names:
        if nm == "static":
            continue
        a = kept(prob, before, nm) / prob.noise_std[nm]
        b = kept(prob, after, nm) / prob.noise_std[nm]
        drop = float(a @ a - b @ b)
        if drop > best_drop * 1.5 or (best == default and drop > best_drop):
            best, best_drop = nm, drop
    return best
