"""Diagnosis of a measured vehicle run: what the simulation gets wrong, why, and the gain.

The method (``docs/diagnosis.md`` explains and justifies it):

1. **Residuals that vanish for the right model.** The half-car (seed, Appendix A) driven by the
   measured wheel forces has rigid modes (heave, pitch) that drift, but its *relative* motion (the
   chassis springs) is stable. Given the measured pitch, the stabilised simulation (A.5) is linear;
   written in the relative coordinates ``u_i = z3 - z_i`` it is a stable 4-state linear system
   driven by ``f1, f2, sin(beta)`` and ``(sin beta)'``. It gives the chassis spring forces
   ``f3, f4`` at every sample, and from them the residual channels:

   * ``moment`` (needs ``beta``): the enforced moment ``lambda = I beta'' - cos(beta)(b f3 - a f4)``
     at every sample, with ``beta''`` a spectral derivative of the smoothly padded record (a plain
     finite difference would leave a ~2 % error at 200 Hz that looks like a wrong inertia);
   * ``heave`` (needs ``z3``): the vertical enforced force ``m3 z3'' - (m3 g - f3 - f4)``, same form;
   * ``spring1``/``spring2`` (need ``s1``/``s2``): simulated ``f3`` against ``k3 s1 + d3 s1'``;
   * ``static``: the first sample against the model's static loads ``f1 = m1 g + a m3 g/(a+b)``,
     ``f2 = m2 g + b m3 g/(a+b)``.

   Without a measured pitch the pitch is eliminated instead (linearised, free pitch), which keeps
   the relative motion stable.

   The system is integrated exactly between samples for cubic-spline inputs (matrix exponential of
   the system augmented with the polynomial basis), then run as a diagonal recursion
   (``scipy.signal.lfilter``). Below 800 Hz the inputs are first refined by band-limited (FFT)
   interpolation: road-driven signals are band-limited, not piecewise cubic.

2. **Causes as parameters.** Each cause is a parameter of the pipeline: ``true force =
   (measured(t + delay) - offset) / scale``, ``true parameter = ratio x model``. The residual is
   exactly linear in offsets and ``1/scale``, and smooth in delays and ratios. Force noise enters
   every residual linearly, through impulse responses that are computed from the pipeline itself,
   so the noise covariance of the residuals is known up to ``sigma^2``.

3. **Which cause.** Rows are weighted to unit noise variance per ``sigma^2``; the causes are
   compared by the reduction of the residual sum of squares (forward selection, joint
   Gauss-Newton refit), each accepted only if its Wald statistic, with the sandwich variance of
   the coloured residual noise, passes a Bonferroni-corrected 0.1 % level. Candidates whose fit is
   not significantly worse than the chosen one are reported as indistinguishable; keys the
   available signals do not see at all are reported as not identifiable. The noise level comes
   from the low band of the residual left after the fit (``_Problem.lowband_noise``), where the
   comparison's own discretisation error does not reach.

4. **Gain**: enforced-moment RMS (or the available residual) before and after, and the
   force-driven pitch error before and after.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.fft
import scipy.linalg
import scipy.signal
import scipy.stats
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from ...io._csvio import DEFAULT_MODEL, MODEL_KEYS, VehicleRun

__all__ = [
    "Cause",
    "ResidualPipeline",
    "diagnose_vehicle_run",
    "DRIFT_THRESHOLD_RAD",
    "SCHEMA",
]

SCHEMA = "jaxdrift.diagnosis/1"
#: pitch error at which the force-driven simulation is said to have drifted off (0.5 deg)
DRIFT_THRESHOLD_RAD = math.radians(0.5)

FORCE_CHANNELS = ("f1", "f2")


# --------------------------------------------------------------------------------------------
# causes


@dataclass(frozen=True)
class Cause:
    """One candidate cause: ``kind`` in force_offset/force_scale/force_delay/parameter_error and
    the channel (f1/f2) or model key it acts on."""

    kind: str
    target: str

    @property
    def label(self) -> str:
        return f"{self.kind}[{self.target}]"

    # internal coordinate theta (0 = no effect) <-> reported estimate
    def to_estimate(self, theta: float) -> float:
        if self.kind == "force_scale":
            return 1.0 / (1.0 + theta)  # theta = 1/scale - 1
        if self.kind == "parameter_error":
            return 1.0 + theta  # theta = ratio - 1
        return theta

    def unit(self) -> str:
        return {"force_offset": "N", "force_scale": "ratio", "force_delay": "s",
                "parameter_error": "ratio"}[self.kind]

    def fd_step(self, dt: float) -> float:
        return {"force_offset": 1.0, "force_scale": 1e-3, "force_delay": 0.1 * dt,
                "parameter_error": 1e-3}[self.kind]


def _apply(model: dict, causes: list[Cause], theta) -> tuple[dict, dict]:
    """(parameters, corrections) for the causes at theta."""
    p = dict(model)
    corr = {ch: {"offset": 0.0, "kappa": 0.0, "delay": 0.0} for ch in FORCE_CHANNELS}
    for c, th in zip(causes, theta):
        th = float(th)
        if c.kind == "parameter_error":
            p[c.target] = model[c.target] * (1.0 + th)
        elif c.kind == "force_offset":
            for ch in (FORCE_CHANNELS if c.target == "both" else (c.target,)):
                corr[ch]["offset"] += th
        elif c.kind == "force_scale":
            corr[c.target]["kappa"] += th
        elif c.kind == "force_delay":
            corr[c.target]["delay"] += th
    return p, corr


# --------------------------------------------------------------------------------------------
# exact discretisation of a linear system driven by piecewise-cubic inputs


def _discretise(A: np.ndarray, B: np.ndarray, h: float):
    """Phi = exp(A h) and G[p] = int_0^h exp(A (h - s)) B s^p ds, p = 0..3 (shape (4, nx, nu)).

    One matrix exponential of the system augmented with the input and its three derivatives
    (the 4th derivative vanishes on a cubic piece): for ``z = [x, u, u', u'', u''']``,
    ``x(h) = E01 u(0) + E02 u'(0) + E03 u''(0) + E04 u'''(0)`` and ``u^(p)(0) = p! c_p``.
    """
    nx, nu = B.shape
    N = nx + 4 * nu
    M = np.zeros((N, N))
    M[:nx, :nx] = A
    M[:nx, nx:nx + nu] = B
    for i in range(3):
        r0 = nx + i * nu
        M[r0:r0 + nu, r0 + nu:r0 + 2 * nu] = np.eye(nu)
    E = scipy.linalg.expm(M * h)
    Phi = E[:nx, :nx]
    G = np.empty((4, nx, nu))
    fact = (1.0, 1.0, 2.0, 6.0)
    for p in range(4):
        G[p] = E[:nx, nx + p * nu:nx + (p + 1) * nu] * fact[p]
    return Phi, G


def _mm(X: np.ndarray, M: np.ndarray) -> np.ndarray:
    """X @ M for a tall X and a tiny M, through real BLAS calls only (complex ones are slow
    here when threads contend)."""
    if np.iscomplexobj(X) or np.iscomplexobj(M):
        Xr, Xi = np.real(X), np.imag(X)
        Mr, Mi = np.real(M), np.imag(M)
        return (Xr @ Mr - Xi @ Mi) + 1j * (Xr @ Mi + Xi @ Mr)
    return X @ M


def _run_recursion(Phi: np.ndarray, v: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """x_{k+1} = Phi x_k + v_k, x_0 given; v of shape (n-1, nx). Returns (n, nx).

    Diagonalises Phi and runs each mode through ``lfilter`` (a C loop): the chassis-spring modes
    are distinct (over)damped ones, so the eigenvectors are well conditioned; a plain loop is
    the fallback otherwise.
    """
    n = v.shape[0] + 1
    lam, V = np.linalg.eig(Phi)
    if np.linalg.cond(V) < 1e8:
        Vi = np.linalg.inv(V)
        w = _mm(v, Vi.T)  # (n-1, nx)
        w0 = Vi @ x0
        out = np.empty((n, len(lam)), dtype=complex)
        for i, l in enumerate(lam):
            u = np.concatenate([[w0[i]], w[:, i]])
            out[:, i] = scipy.signal.lfilter([1.0], [1.0, -l], u)
        x = _mm(out, V.T).real
        return x
    x = np.empty((n, len(x0)))
    x[0] = x0
    for k in range(n - 1):
        x[k + 1] = Phi @ x[k] + v[k]
    return x


def _poly_coeffs(sp) -> np.ndarray:
    """Ascending local coefficients (4, n-1) of a scipy cubic piecewise polynomial."""
    c = sp.c
    return c[::-1]


def _deriv_coeffs(c: np.ndarray) -> np.ndarray:
    """Ascending coefficients of the derivative of a cubic (the cubic term becomes zero)."""
    out = np.zeros_like(c)
    out[0], out[1], out[2] = c[1], 2 * c[2], 3 * c[3]
    return out


def _numerov(m: np.ndarray) -> np.ndarray:
    """(m_{k-1} + 10 m_k + m_{k+1}) / 12 for k = 1..n-2."""
    return (m[:-2] + 10.0 * m[1:-1] + m[2:]) / 12.0


def _d2(y: np.ndarray, h: float) -> np.ndarray:
    return (y[2:] - 2.0 * y[1:-1] + y[:-2]) / (h * h)


# --------------------------------------------------------------------------------------------
# the residual pipeline


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
        U = self.U
        if self.has_beta:
            beta = self._resample(run["beta"])
            S = np.sin(beta)
            if run.has("beta_rate") and U == 1:
                sp = CubicHermiteSpline(self.tauf, S, np.cos(beta) * run["beta_rate"])
            else:
                sp = CubicSpline(self.tauf, S)
            self.S_c = _poly_coeffs(sp)
            self.dS_c = _deriv_coeffs(self.S_c)
            self.S = S
            self.dS = sp(self.tauf, 1)
            self.cosb = np.cos(beta)
            self.d2beta = self._second_derivative(run["beta"])
        if self.has_z3:
            z3 = self._resample(run["z3"])
            sp = CubicSpline(self.tauf, z3)
            self.Z_c = _poly_coeffs(sp)
            self.dZ_c = _deriv_coeffs(self.Z_c)
            self.Z = z3
            self.dZ = sp(self.tauf, 1)
            self.d2z3 = self._second_derivative(run["z3"])
        # road height under the wheels: with pitch and heave measured the wheel states are
        # simulated in absolute coordinates, and the tyre law checks the forces directly
        self.zeta_f = {}
        self.dzeta = {}
        if self.mode == "pitch" and self.has_z3:
            for name in ("zeta1", "zeta2"):
                if run.has(name):
                    zf = self._resample(run[name])
                    self.zeta_f[name] = zf
                    self.dzeta[name] = CubicSpline(self.tauf, zf)(self.tauf, 1)
        self.s_f = {}
        self.ds = {}
        for i, name in enumerate(("s1", "s2")):
            if self.has_s[i]:
                sf = self._resample(run[name])
                sp = CubicSpline(self.tauf, sf)
                self.s_f[name] = sf
                self.ds[name] = sp(self.tauf, 1)
        self.channel_names = self._channel_names()
        #: per residual channel: (cutoff Hz, sos) of a zero-phase low-pass applied to it, set by
        #: :meth:`_Problem.limit_bands` where the measured motion carries sensor noise
        self.band: dict = {}

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

    # ---- inputs
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

    def corrected_forces(self, corr: dict, smooth: bool = False) -> dict[str, np.ndarray]:
        """True-force estimate on the fine grid: (measured(t + delay) - offset) * (1 + kappa)."""
        out = {}
        for ch in FORCE_CHANNELS:
            c = corr[ch]
            key = ("spec", ch, smooth)
            if key not in self._fspl_cache:
                self._fspl_cache[key] = self._padded_spectrum(self.measured(ch, smooth))
            if c["delay"] == 0.0 and self.U == 1:
                f = self.measured(ch, smooth)
            else:
                f = self._resample(None, c["delay"] / self.h, spec=self._fspl_cache[key])
            out[ch] = (f - c["offset"]) * (1.0 + c["kappa"])
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
        for ch in FORCE_CHANNELS:
            c = corr[ch]
            key = ("coef", ch, smooth, float(c["delay"]))
            if key not in self._fspl_cache:
                if sum(1 for k in self._fspl_cache if k[0] == "coef") > 16:
                    for k in [k for k in self._fspl_cache if k[0] == "coef"]:
                        del self._fspl_cache[k]
                f = self.corrected_forces({ch: {"offset": 0.0, "kappa": 0.0, "delay": c["delay"]}
                                           for ch in FORCE_CHANNELS}, smooth)[ch]
                self._fspl_cache[key] = (_poly_coeffs(CubicSpline(self.tauf, f)), float(f[0]))
            C, f0 = self._fspl_cache[key]
            C = C.copy()
            C[0] -= c["offset"]
            C *= 1.0 + c["kappa"]
            coeffs[ch] = C
            first[ch] = (f0 - c["offset"]) * (1.0 + c["kappa"])
        return coeffs, first

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
        lin = linear_part_only
        U = self.U
        ch = {}
        a, b = p["a"], p["b"]
        if self.has_beta:
            M = (self.cosb * (b * f3 - a * f4))[::U]
            ch["moment"] = (0.0 if lin else p["I"] * self.d2beta) - M[1:-1]
        if self.has_z3:
            V = (-(f3 + f4) if lin else p["m3"] * p["g"] - f3 - f4)[::U]
            ch["heave"] = (0.0 if lin else p["m3"] * self.d2z3) - V[1:-1]
        for i, name in enumerate(("s1", "s2")):
            if self.has_s[i]:
                k, d = (p["k3"], p["d3"]) if i == 0 else (p["k4"], p["d4"])
                fs = f3 if i == 0 else f4
                meas = 0.0 if lin else k * self.s_f[name] + d * self.ds[name]
                ch[f"spring{i + 1}"] = (fs - meas)[::U]
        for i in (1, 2):
            name = f"zeta{i}"
            if name not in self.zeta_f:
                continue
            # tyre law f_i = k_i (z_i - zeta_i) + d_i (z_i' - zeta_i'), wheel states z_i simulated
            # from the forces with pitch and heave prescribed (states [z1, z2, z1', z2'])
            k, d = (p["k1"], p["d1"]) if i == 1 else (p["k2"], p["d2"])
            # spline values at the fine nodes (the last node repeats its left neighbour: the end of
            # the record is trimmed from the rows)
            fi = forces[f"f{i}"] if forces is not None else np.append(forces_c[f"f{i}"][0], forces_c[f"f{i}"][0][-1])
            zeta = 0.0 if lin else self.zeta_f[name]
            dzeta = 0.0 if lin else self.dzeta[name]
            model = k * (x[:, i - 1] - zeta) + d * (x[:, i + 1] - dzeta)
            ch[f"tyre{i}"] = (fi - model)[::U]
        g, m3 = p["g"], p["m3"]
        f1s = p["m1"] * g + a * m3 * g / (a + b)
        f2s = p["m2"] * g + b * m3 * g / (a + b)
        for name, (fc, sos) in self.band.items():
            # Mirror padding several time constants long: the filter starts from the steady state
            # of the first padded value, and on a channel swamped by sensor noise that value is
            # noise; with the default short odd padding its step rang well into the record (a
            # pitch-only run with 1e-5 rad of noise then named a mass error of 2.5).
            x = ch[name]
            padlen = min(len(x) - 1, int(math.ceil(6.0 / (fc * self.h))))
            ch[name] = scipy.signal.sosfiltfilt(sos, x, padtype="even", padlen=padlen)
        if lin:
            ch["static"] = np.array([first["f1"], first["f2"]])
        else:
            ch["static"] = np.array([first["f1"] - f1s, first["f2"] - f2s])
        return Residuals(ch, f3[::U], f4[::U])


# --------------------------------------------------------------------------------------------
# weighting, noise impulse responses, fitting


def _diff_sigma(x: np.ndarray, k: int) -> float:
    """Robust white-noise level from the k-th difference (var = C(2k, k) sigma^2 for white noise)."""
    d = np.diff(x, k)
    mad = np.median(np.abs(d - np.median(d))) * 1.4826
    return float(mad / math.sqrt(math.comb(2 * k, k)))


def _hf_noise_sigma(f: np.ndarray) -> float:
    """Robust white-noise level from the 4th difference; an upper bound when the signal itself
    has content near the Nyquist frequency."""
    return _diff_sigma(f, 4)


def _force_hf_noise(run) -> tuple[float, float, float]:
    """Force-noise level from both forces' 4th differences, with its 95 % interval (an upper
    bound: the forces' own content near the Nyquist frequency counts as noise)."""
    sigma = float(np.sqrt(np.mean([_hf_noise_sigma(run[ch]) ** 2 for ch in FORCE_CHANNELS])))
    half = 1.96 * 1.6 / math.sqrt(2 * (run.n - 4))
    return sigma, sigma * (1 - half), sigma * (1 + half)


#: residual channel -> the measured motion it differentiates
MOTION_COLUMN = {"moment": "beta", "heave": "z3", "spring1": "s1", "spring2": "s2"}


def _motion_noise_sigma(x: np.ndarray) -> float:
    """White sensor noise on a measured motion channel, or 0 where none shows.

    White noise gives the same level from the 4th and the 8th differences; the motion's own
    content, at frequencies below the Nyquist frequency, is suppressed far more by the 8th
    (on true road-driven runs their ratio is 0.3-0.5 at 200 Hz and below 0.05 at 500 Hz and
    above). The 8th-difference level is taken as the noise where the ratio says white noise
    dominates the top band."""
    if len(x) < 64:
        return 0.0
    s4, s8 = _diff_sigma(x, 4), _diff_sigma(x, 8)
    return s8 if s4 > 0 and s8 >= 0.6 * s4 else 0.0


def lowband_cutoff(fs: float) -> float:
    """Upper edge [Hz] of the band where the force noise is measured (see lowband_noise)."""
    return min(fs / 6.0, 40.0)


class _Problem:
    """Weighted residual vector r(theta) for a set of causes, and the noise response.

    Rows are scaled so that white force noise of standard deviation sigma gives each row the
    variance sigma^2 (for the given model).
    """

    def __init__(self, pipe: ResidualPipeline, model: dict):
        self.pipe = pipe
        self.model = model
        self.names = pipe.channel_names
        n, K = pipe.n, pipe.trim
        # rows kept per channel: moment/heave rows k = 1..n-2 (row j is sample j + 1), spring rows
        # are samples; the last K samples are left out (delays shift the record's end)
        self.offset = {"moment": 1, "heave": 1, "spring1": 0, "spring2": 0, "tyre1": 0, "tyre2": 0,
                       "static": 0}
        self.rows = {}
        for nm in self.names:
            if nm == "static":
                self.rows[nm] = 2
            else:
                self.rows[nm] = n - K - self.offset[nm]
        #: leading entries of a channel left out of the rows (the start of a band-limited channel,
        #: see limit_bands): row j of channel nm is its entry j + skip[nm]
        self.skip = {nm: 0 for nm in self.names}
        self._ir_cache: dict = {}
        self.ir, self.noise_std = self.impulse_responses(model)
        self.limit_bands()

    #: share of the force-noise power that sensor noise on the measured motion may add to a
    #: residual channel before the channel is low-passed
    MOTION_NOISE_SHARE = 0.01

    def limit_bands(self):
        """Low-pass the residual channels whose measured motion carries sensor noise.

        The residuals differentiate the measured motion (``I beta''``, ``m3 z3''``, ``d s'``), so
        white sensor noise of standard deviation s reaches them with a power spectrum growing as
        (2 pi f)^4 (or (2 pi f)^2), while force noise reaches them through the model and fades at
        high frequencies. Even 1e-6 rad of pitch noise (a CSV written with 6 decimals) swamps
        the enforced moment above a few tens of Hz. The sensor noise is estimated from the 4th
        differences of each motion channel (``_motion_noise_sigma``), the force noise from the
        forces' 4th differences; each channel keeps
        the band where the sensor noise adds at most ``MOTION_NOISE_SHARE`` of the force-noise
        power. Clean motion records keep the full band (no filter).
        """
        pipe = self.pipe
        run = pipe.run
        h = pipe.h
        sig_f = max(_force_hf_noise(run)[0], NOISE_MIN_N)
        p = self.model
        gains = {"moment": lambda w: p["I"] * w * w, "heave": lambda w: p["m3"] * w * w,
                 "spring1": lambda w: np.abs(p["k3"] + 1j * w * p["d3"]),
                 "spring2": lambda w: np.abs(p["k4"] + 1j * w * p["d4"])}
        band = {}
        for nm in self.names:
            if nm not in gains:
                continue
            col, gain = MOTION_COLUMN[nm], gains[nm]
            sig_m = _motion_noise_sigma(run[col])
            if sig_m <= 0:
                continue
            nfft = 1 << int(np.ceil(np.log2(max(4 * len(self.ir[(nm, "f1")][0]), 1024))))
            Hf = sum(np.abs(np.fft.rfft(self.ir[(nm, ch)][0], nfft)) ** 2 for ch in FORCE_CHANNELS)
            f = np.fft.rfftfreq(nfft, h)
            bad = sig_m ** 2 * gain(2 * np.pi * f) ** 2 > self.MOTION_NOISE_SHARE * sig_f ** 2 * Hf
            bad[0] = False
            if not np.any(bad):
                continue
            fc = float(f[np.argmax(bad)])
            if fc >= 0.45 / h:
                continue
            fc = max(fc, 1.0)
            band[nm] = (fc, scipy.signal.butter(8, fc, fs=1.0 / h, output="sos"))
        if band:
            pipe.band = band
            # The start of a low-passed channel carries the filter's start-up and the end effects
            # of the motion's derivatives, spread over about 1/fc: measured (pitch, heave and
            # spring travel with 3e-5 of white noise, 500 Hz) up to 10x the residual's rms over
            # the first 0.4 s, enough to fit spurious causes. Those rows are left out.
            for nm, (fc, _) in band.items():
                s = int(math.ceil(1.5 / (fc * h)))
                s = min(s, self.rows[nm] // 4)
                self.skip[nm] = s
                self.rows[nm] -= s
            self._ir_cache.clear()
            self.ir, self.noise_std = self.impulse_responses(self.model)

    def impulse_responses(self, p: dict):
        """Per residual channel and force channel: response to a unit force sample."""
        key = tuple(sorted(p.items()))
        if key in self._ir_cache:
            return self._ir_cache[key]
        pipe = self.pipe
        n = pipe.n
        k0 = n // 2
        L = min(n // 2 - 2, max(int(round(3.0 / pipe.h)), 50))
        ir = {}
        for ch in FORCE_CHANNELS:
            forces = {c: np.zeros(n) for c in FORCE_CHANNELS}
            forces[ch][k0] = 1.0
            res = pipe.residuals(p, None, linear_part_only=True, forces=forces)
            for name, r in res.channels.items():
                if name == "static":
                    continue
                off = self.offset[name]
                pre = 20
                if name in pipe.band:  # the zero-phase filter spreads the response both ways
                    pre += int(3.0 / (pipe.band[name][0] * pipe.h))
                lo = max(k0 - off - pre, 0)
                hi = min(k0 - off + L, len(r))
                ir[(name, ch)] = (r[lo:hi].copy(), lo - (k0 - off))  # (response, first lag)
        std = {}
        for name in self.names:
            if name == "static":
                std[name] = 1.0
                continue
            v = sum(float(np.sum(ir[(name, ch)][0] ** 2)) for ch in FORCE_CHANNELS)
            std[name] = math.sqrt(v) if v > 0 else 1.0
        if len(self._ir_cache) > 64:
            self._ir_cache.clear()
        self._ir_cache[key] = (ir, std)
        return ir, std

    def weighted(self, res: Residuals) -> np.ndarray:
        std = self.noise_std
        return np.concatenate([res.channels[nm][self.skip[nm]:self.skip[nm] + self.rows[nm]] / std[nm]
                               for nm in self.names])

    def eval(self, causes, theta, smooth: bool = False) -> tuple[np.ndarray, Residuals]:
        theta = _clip_theta(causes, theta, self.pipe)
        p, corr = _apply(self.model, causes, theta)
        res = self.pipe.residuals(p, corr, smooth=smooth)
        return self.weighted(res), res

    def jacobian(self, causes, theta, which=None):
        """Sensitivities of the weighted residual, computed on the low-passed forces.

        These are the *instruments* of the fit: a sensitivity computed from the noisy forces
        carries the noise itself (a damper that passes less noise "fits" better), which biases
        the estimates and invalidates the tests; the low-passed forces keep the signal and drop
        most of the noise, so ``J^T r = 0`` is a consistent (instrumental-variable) estimate.
        """
        which = range(len(causes)) if which is None else which
        theta = np.asarray(theta, dtype=float)
        r0, _ = self.eval(causes, theta, smooth=True)
        cols = []
        for i in which:
            step = causes[i].fd_step(self.pipe.h)
            th = np.array(theta, dtype=float)
            th[i] += step
            r1, _ = self.eval(causes, th, smooth=True)
            cols.append((r1 - r0) / step)
        return np.column_stack(cols) if cols else np.zeros((len(r0), 0))

    def _blocks(self, X):
        blocks = {}
        pos = 0
        for nm in self.names:
            ln = self.rows[nm]
            blocks[nm] = X[pos:pos + ln]
            pos += ln
        return blocks

    def sandwich_meat(self, X: np.ndarray) -> np.ndarray:
        """X^T Sigma_w X per sigma^2, from the impulse responses: for each force channel and
        force sample k, A[k] = sum_rows X[row] d r_w[row] / d eps_k; meat = sum A^T A."""
        n = self.pipe.n
        pdim = X.shape[1]
        meat = np.zeros((pdim, pdim))
        blocks = self._blocks(X)
        ks = np.arange(n)
        for ch in FORCE_CHANNELS:
            Acc = np.zeros((n, pdim))
            for nm in self.names:
                Xb = blocks[nm]
                if nm == "static":
                    Acc[0] += Xb[0 if ch == "f1" else 1]
                    continue
                h, lag0 = self.ir[(nm, ch)]
                h = h / self.noise_std[nm]
                off = self.offset[nm] + self.skip[nm]  # row j is sample j + off
                # d r_w[j] / d eps_k = h[(j + off - k) - lag0]; full[m] = sum_j X[j] h[L-1-(m-j)]
                # so A[k] = full[L - 1 - off + k + lag0]
                m = len(h) - 1 - off + ks + lag0
                for q in range(pdim):
                    full = scipy.signal.fftconvolve(Xb[:, q], h[::-1], mode="full")
                    ok = (m >= 0) & (m < len(full))
                    Acc[ks[ok], q] += full[m[ok]]
            meat += Acc.T @ Acc
        return meat

    def lowband_noise(self, r: np.ndarray, gains: dict | None = None, ir: dict | None = None) -> tuple[float, float]:
        """Force-noise level from the residual's low band, and its effective degrees of freedom.

        White force noise reaches every residual across the whole band, with a spectrum known
        from the impulse responses; the comparison's own error (interpolation of inputs that
        have content near the Nyquist frequency, the record's ends) sits at high frequencies.
        So the residual is low-passed (zero phase, below min(fs/6, 40 Hz), inside the model's
        bandwidth) and its power compared with the low-passed noise response: sigma^2 =
        sum r_lp^2 / sum (h_lp^2 per row). The first and last 5 % of each channel are left out.
        ``gains``: per force channel, the factor the correction puts on the measured samples
        (1 / scale): noise on the measured samples reaches the residual multiplied by it.
        ``ir``: impulse responses of the fitted parameters (default: the model's); the residual
        keeps the model's row weighting either way.
        """
        gains = gains or {}
        ir = self.ir if ir is None else ir
        fs = 1.0 / self.pipe.h
        fc = lowband_cutoff(fs)
        sos = scipy.signal.butter(6, fc, fs=fs, output="sos")
        blocks = self._blocks(r[:, None])
        num = den = 0.0
        hls, lens = {}, {}
        for nm in self.names:
            if nm == "static":
                continue
            x = blocks[nm][:, 0]
            L = len(x)
            k = slice(L // 20, L - L // 20)
            xl = scipy.signal.sosfiltfilt(sos, x)[k]
            unit = 0.0
            for ch in FORCE_CHANNELS:
                h = ir[(nm, ch)][0] / self.noise_std[nm] * gains.get(ch, 1.0)
                pad = np.zeros(int(4 * fs / fc))
                hls[(nm, ch)] = scipy.signal.sosfiltfilt(sos, np.concatenate([pad, h, pad]))
                unit += float(np.sum(hls[(nm, ch)] ** 2))
            lens[nm] = len(xl)
            num += float(np.sum(xl * xl))
            den += unit * len(xl)
        # Var(sum_a sum_t x_a(t)^2) = 2 sigma^4 sum_{a,b} sum_{t,t'} c_ab(t - t')^2, with c_ab the
        # cross-covariance of residual channels a and b: they see the same force noise, so the
        # cross terms count as much as the auto terms (leaving them out overstated the degrees
        # of freedom by about 1.5 with pitch and both spring travels). The sum of c_ab^2 over all
        # lags does not depend on the channels' relative alignment.
        var_num = 0.0
        for a in lens:
            for b in lens:
                ccf = 0.0
                for ch in FORCE_CHANNELS:
                    ccf = ccf + scipy.signal.correlate(hls[(a, ch)], hls[(b, ch)], mode="full", method="fft")
                var_num += 2.0 * math.sqrt(lens[a] * lens[b]) * float(np.sum(ccf ** 2))
        if den <= 0:
            return 0.0, 1.0
        sigma2 = num / den
        dof = 2.0 * den * den / max(var_num, 1e-300)
        return math.sqrt(max(sigma2, 0.0)), dof


def _theta_bounds(c: Cause, pipe) -> tuple[float, float]:
    """The physically plausible range of a cause's parameter (offsets are unbounded)."""
    if c.kind == "parameter_error":
        return -0.6, 1.5
    if c.kind == "force_scale":
        return -0.5, 1.0
    if c.kind == "force_delay":
        lim = 0.5 * pipe.trim * pipe.h
        return -lim, lim
    return -math.inf, math.inf


def _clip_theta(causes, theta, pipe):
    th = np.array(theta, dtype=float)
    for i, c in enumerate(causes):
        lo, hi = _theta_bounds(c, pipe)
        th[i] = min(max(th[i], lo), hi)
    return th


def _at_bound(c: Cause, theta: float, pipe) -> bool:
    """The fit pushed the cause to the edge of its plausible range: the data want more than any
    real effect of this kind gives, so the cause does not explain them (its interval there would
    be meaningless)."""
    lo, hi = _theta_bounds(c, pipe)
    tol = 1e-9 * (1.0 + abs(theta))
    return theta <= lo + tol or theta >= hi - tol


@dataclass
class Fit:
    causes: list
    theta: np.ndarray
    r: np.ndarray
    res: Residuals
    rss: float
    X: np.ndarray = field(default=None)


def _proj(X: np.ndarray, r: np.ndarray) -> float:
    """Squared norm of the projection of r onto the columns of X."""
    if X.shape[1] == 0:
        return 0.0
    b, *_ = np.linalg.lstsq(X, r, rcond=None)
    v = X @ b
    return float(v @ v)


def _gauss_newton(prob: _Problem, causes, theta0, iters=6) -> Fit:
    """Instrumental-variable Gauss-Newton: drive X^T r(theta) to zero, X the instruments."""
    theta = _clip_theta(causes, theta0, prob.pipe)
    r, res = prob.eval(causes, theta)
    X = None
    for _ in range(iters):
        if not causes:
            break
        X = prob.jacobian(causes, theta)
        step, *_ = np.linalg.lstsq(X, -r, rcond=None)
        q0 = _proj(X, r)
        lam = 1.0
        ok = False
        for _ in range(6):
            th_new = _clip_theta(causes, theta + lam * step, prob.pipe)
            r_new, res_new = prob.eval(causes, th_new)
            if _proj(X, r_new) < q0:
                ok = True
                break
            lam *= 0.5
        if not ok:
            break
        moved = np.abs(th_new - theta)
        theta, r, res = th_new, r_new, res_new
        tol = np.array([1e-6 * c.fd_step(prob.pipe.h) * 1e3 for c in causes])
        if np.all(moved < tol):
            break
    if causes:
        X = prob.jacobian(causes, theta)
    return Fit(list(causes), theta, r, res, float(r @ r), X)


# --------------------------------------------------------------------------------------------
# cause selection


#: familywise significance level of the cause tests (Bonferroni over the candidates)
ALPHA = 1e-3
#: causes smaller than these are not worth reporting (far below any sensor's specification)
PRACTICAL = {"force_offset": 0.05, "force_scale": 2e-4, "force_delay": None, "parameter_error": 2e-4}


def _practical(c: Cause, pipe) -> float:
    thr = PRACTICAL[c.kind]
    return 1e-3 * pipe.h if thr is None else thr


def _candidates(pipe: ResidualPipeline) -> list[Cause]:
    out = []
    for ch in FORCE_CHANNELS:
        out += [Cause("force_offset", ch), Cause("force_scale", ch), Cause("force_delay", ch)]
    # the same offset on both forces: indistinguishable from a mass error without heave data
    out.append(Cause("force_offset", "both"))
    for key in MODEL_KEYS:
        out.append(Cause("parameter_error", key))
    return out


def _lin_rss(X: np.ndarray, r: np.ndarray) -> float:
    if X.shape[1] == 0:
        return float(r @ r)
    beta, *_ = np.linalg.lstsq(X, r, rcond=None)
    e = r - X @ beta
    return float(e @ e)


@dataclass
class Selection:
    fit: Fit
    cov: np.ndarray
    sigma: float
    z: np.ndarray
    alternatives: dict
    not_identifiable: list
    weakly_identifiable: dict
    rss0: float
    rss_path: list


def _covariance(prob: _Problem, X: np.ndarray, sigma2: float) -> np.ndarray:
    XtX = X.T @ X
    inv = np.linalg.pinv(XtX)
    meat = prob.sandwich_meat(X)
    return sigma2 * inv @ meat @ inv


def _systematic_rss(prob: _Problem, fit: "Fit", sigma2: float) -> float:
    """RSS plus the noise RSS that the fit's causes hide by passing less noise than the base model
    does (in the base weighting): a parameter that damps the noise response, or a force scale
    whose correction shrinks the measured samples, and with them their noise. Only a penalty:
    passing more noise already costs RSS."""
    if sigma2 <= 0:
        return fit.rss
    p, corr = _apply(prob.model, fit.causes, fit.theta)
    ir = prob.impulse_responses(p)[0]
    noise = 0.0
    for nm in prob.names:
        if nm == "static":
            noise += prob.rows[nm]
            continue
        v = sum((1.0 + corr[ch]["kappa"]) ** 2 * float(np.sum(ir[(nm, ch)][0] ** 2)) for ch in FORCE_CHANNELS)
        noise += prob.rows[nm] * v / prob.noise_std[nm] ** 2
    base = sum(prob.rows[nm] for nm in prob.names)
    return fit.rss + sigma2 * max(base - noise, 0.0)


_BOTH = Cause("force_offset", "both")


def _redundant(c: Cause, chosen) -> bool:
    """True when adding ``c`` to ``chosen`` would not widen the span of the fit: an equal offset
    on both forces next to an offset already chosen, or ``c`` itself."""
    if c in chosen:
        return True
    return c == _BOTH and any(x.kind == "force_offset" for x in chosen)


def _normalise(prob: _Problem, fit: "Fit") -> "Fit":
    """An equal offset on both forces next to a single-channel offset is two channel offsets:
    report it so (the same span, the same residual)."""
    causes = list(fit.causes)
    if _BOTH not in causes:
        return fit
    singles = [c for c in causes if c.kind == "force_offset" and c != _BOTH]
    if not singles:
        return fit
    ib = causes.index(_BOTH)
    other = next(ch for ch in FORCE_CHANNELS if ch != singles[0].target)
    theta = np.array(fit.theta, dtype=float)
    i1 = causes.index(singles[0])
    theta[i1] += theta[ib]
    causes[ib] = Cause("force_offset", other)
    return _gauss_newton(prob, causes, theta)


def _swap_pass(prob: _Problem, fit: "Fit", active, sig2: float, log=None) -> "Fit":
    """Exchange step of the stepwise selection: forward selection can lock in a cause that only
    stood in for two others (a scale for an offset while a delay was not yet in). For each chosen
    cause, refit without it, screen the others linearly in its place, refine the best two, and
    take an exchange that lowers the systematic residual by more than the 95 % level of one
    parameter's worth of noise."""
    improved = True
    rounds = 0
    while improved and rounds < 2 and len(fit.causes) > 1:
        improved = False
        rounds += 1
        cur = _systematic_rss(prob, fit, sig2)
        for i in range(len(fit.causes)):
            keep = [j for j in range(len(fit.causes)) if j != i]
            others = [fit.causes[j] for j in keep]
            f_o = _gauss_newton(prob, others, fit.theta[keep], iters=3)
            Xo = f_o.X if others else np.zeros((len(f_o.r), 0))
            scores = []
            for c in active:
                if c == fit.causes[i] or _redundant(c, others):
                    continue
                col = prob.jacobian(others + [c], np.append(f_o.theta, 0.0), which=[len(others)])[:, 0]
                scores.append((_proj(np.column_stack([Xo, col]), f_o.r), c))
            scores.sort(key=lambda s_: -s_[0])
            best = None
            for _, c in scores[:2]:
                f_c = _gauss_newton(prob, others + [c], np.append(f_o.theta, 0.0))
                if any(_at_bound(cc, th, prob.pipe) for cc, th in zip(f_c.causes, f_c.theta)):
                    continue
                v = _systematic_rss(prob, f_c, sig2)
                if best is None or v < best[0]:
                    best = (v, c, f_c)
            q = scipy.stats.chi2.ppf(0.95, 1) * max(sig2, 1e-300)
            if log is not None and best is not None:
                log.append(f"swap? {fit.causes[i].label}: screened {[c.label for _, c in scores[:3]]}, "
                           f"best {best[1].label} {best[0]:.6g} vs {cur:.6g}")
            if best is not None and best[0] < cur - q:
                if log is not None:
                    log.append(f"swap {fit.causes[i].label} -> {best[1].label}: rss {cur:.6g} -> {best[0]:.6g}")
                fit = _normalise(prob, best[2])
                improved = True
                break
    return fit


def _select(prob: _Problem, max_causes: int = 3, log=None) -> Selection:
    pipe = prob.pipe
    cands = _candidates(pipe)
    base = _gauss_newton(prob, [], [])
    n_rows = len(base.r)
    r0 = base.r
    # identifiability of each candidate at the base point
    J = prob.jacobian(cands, np.zeros(len(cands)))
    norms = np.sqrt(np.sum(J * J, axis=0))
    scale_ref = np.max(norms) if norms.size else 1.0
    not_ident = [c for c, nv in zip(cands, norms) if nv <= 1e-12 * max(scale_ref, 1e-300)]
    active = [c for c, nv in zip(cands, norms) if nv > 1e-12 * max(scale_ref, 1e-300)]
    Jc = {c: J[:, i] for i, c in enumerate(cands)}
    crit = scipy.stats.chi2.ppf(1 - ALPHA / max(len(active), 1), 1)
    fit = base
    path = [base.rss]
    hf_sigma = _force_hf_noise(pipe.run)[0]
    alternatives = {}
    chosen: list[Cause] = []
    dynamic = n_rows > 2
    while len(chosen) < max_causes and dynamic:
        # screen with a linear fit of (chosen + c) on the current residual
        Xc = fit.X if chosen else np.zeros((n_rows, 0))
        scores = []
        for c in active:
            if _redundant(c, chosen):
                continue
            if chosen:
                col = prob.jacobian(chosen + [c], np.append(fit.theta, 0.0), which=[len(chosen)])[:, 0]
            else:
                col = Jc[c]
            Jc[c] = col
            gain_lin = _proj(np.column_stack([Xc, col]), fit.r) - _proj(Xc, fit.r)
            scores.append((gain_lin, c))
        if not scores:
            break
        scores.sort(key=lambda s: -s[0])
        # refine the best few nonlinearly; rank them by the residual beyond the noise they are
        # expected to carry (a heavier wheel or a softer damper passes less noise: that must not
        # count as a better explanation)
        # (the noise level: the smaller of two upper bounds, the low band of the current residual
        # still holding what is not yet explained, and the forces' 4th differences)
        sig2_now = min(prob.lowband_noise(fit.r)[0], hf_sigma) ** 2 if dynamic else 0.0
        refined = []
        for gain_lin, c in scores[:3]:
            f_c = _gauss_newton(prob, chosen + [c], np.append(fit.theta, 0.0))
            if _at_bound(c, f_c.theta[-1], pipe):
                if log is not None:
                    log.append(f"step {len(chosen) + 1}: {c.label} left out: its fit sits at the edge of "
                               f"its plausible range ({c.to_estimate(f_c.theta[-1]):.6g})")
                continue
            refined.append((_systematic_rss(prob, fit, sig2_now) - _systematic_rss(prob, f_c, sig2_now), c, f_c))
        if not refined:
            break
        refined.sort(key=lambda s: -s[0])
        gain, c_best, f_best = refined[0]
        p = len(f_best.causes)
        sigma2 = f_best.rss / max(n_rows - p, 1)
        cov = _covariance(prob, f_best.X, sigma2)
        var = cov[-1, -1]
        z2 = f_best.theta[-1] ** 2 / var if var > 0 else 0.0
        est = c_best.to_estimate(f_best.theta[-1])
        size = abs(f_best.theta[-1])
        thr = _practical(c_best, pipe)
        if log is not None:
            log.append(f"step {len(chosen) + 1}: best {c_best.label} est {est:.6g} z2 {z2:.3g} "
                       f"(crit {crit:.3g}) rss {fit.rss:.6g} -> {f_best.rss:.6g}; next: " +
                       ", ".join(f"{c.label}:{g:.4g}" for g, c, _ in refined[1:]))
        if z2 < crit or size < thr:
            break
        # alternatives: candidates whose fit is not significantly worse
        infl = float(prob.sandwich_meat(f_best.X[:, -1:])[0, 0] / (f_best.X[:, -1] @ f_best.X[:, -1]))
        q = scipy.stats.chi2.ppf(0.95, 1) * sigma2 * max(infl, 1.0)
        alts = []
        for g_c, c, f_c in refined[1:]:
            if g_c >= gain - q:
                se_c = math.sqrt(max(_covariance(prob, f_c.X, sigma2)[-1, -1], 0.0))
                iv = _finding_for(c, f_c.theta[-1], se_c, _practical(c, pipe))["interval"]
                alts.append((c, float(c.to_estimate(f_c.theta[-1])), iv))
        for g_lin, c in scores[3:]:
            if g_lin >= gain - q:
                alts.append((c, None, None))
        alternatives[c_best] = alts
        chosen.append(c_best)
        fit = f_best
        if _BOTH in chosen and len([c for c in chosen if c.kind == "force_offset"]) > 1:
            # {equal offsets, offset on f1} is {offsets on f1 and f2}: report it so
            alts_b = alternatives.pop(_BOTH, [])
            fit = _normalise(prob, fit)
            new = next(c for c in fit.causes if c not in chosen)
            alternatives[new] = [alt for alt in alts_b if alt[0] not in fit.causes]
            chosen = list(fit.causes)
        path.append(fit.rss)
    if dynamic and len(fit.causes) > 1:
        sig2_now = min(prob.lowband_noise(fit.r)[0], hf_sigma) ** 2
        before = list(fit.causes)
        fit = _swap_pass(prob, fit, active, sig2_now, log)
        if fit.causes != before:
            alternatives = {c: a for c, a in alternatives.items() if c in fit.causes}
            chosen = list(fit.causes)
            path.append(fit.rss)
    # backward elimination: a cause chosen early can lose its significance once later causes
    # explain the same residual; drop the weakest until all pass, refitting each time
    while True:
        p = len(fit.causes)
        sigma2 = fit.rss / max(n_rows - p, 1)
        if not p:
            cov, z = np.zeros((0, 0)), np.zeros(0)
            break
        cov = _covariance(prob, fit.X, sigma2)
        z = fit.theta / np.sqrt(np.maximum(np.diag(cov), 1e-300))
        # causes too small to matter, and causes pushed to the edge of their plausible range
        small = [i for i, c in enumerate(fit.causes)
                 if abs(fit.theta[i]) < _practical(c, pipe) or _at_bound(c, fit.theta[i], pipe)]
        weakest = small[0] if small else int(np.argmin(np.abs(z)))
        if not small and z[weakest] ** 2 >= crit:
            break
        if log is not None:
            log.append(f"drop {fit.causes[weakest].label} (z2 {z[weakest] ** 2:.3g})")
        keep = [i for i in range(p) if i != weakest]
        dropped = fit.causes[weakest]
        alternatives.pop(dropped, None)
        fit = _gauss_newton(prob, [fit.causes[i] for i in keep], fit.theta[keep])
    # exact confounding, whatever the noise: a candidate whose signature lies in the span of the
    # chosen causes can take the place of each chosen cause it loads on (without z3, an offset on
    # f2 next to m3 does what an offset on f1 does). Noise-free runs make the tie exact, so the
    # significance test above cannot see it.
    if dynamic and fit.causes:
        X = fit.X
        for c in active:
            if c in fit.causes or _redundant(c, fit.causes):
                continue
            col = prob.jacobian(fit.causes + [c], np.append(fit.theta, 0.0), which=[len(fit.causes)])[:, 0]
            nc = float(np.sqrt(col @ col))
            if nc <= 0:
                continue
            b, *_ = np.linalg.lstsq(X, col, rcond=None)
            if np.sqrt(np.sum((col - X @ b) ** 2)) > 1e-3 * nc:
                continue
            for j, cj in enumerate(fit.causes):
                if abs(b[j]) * np.sqrt(X[:, j] @ X[:, j]) < 0.05 * nc:
                    continue
                alts = alternatives.setdefault(cj, [])
                if any(alt[0] == c for alt in alts):
                    continue
                # the same span with c in place of cj: its estimate and standard error from the
                # linear relation
                se_c = math.sqrt(max(cov[j, j], 0.0)) / abs(b[j])
                iv = _finding_for(c, fit.theta[j] / b[j], se_c, _practical(c, pipe))["interval"]
                alts.append((c, float(c.to_estimate(fit.theta[j] / b[j])), iv))
                if log is not None:
                    log.append(f"confounded: {c.label} can replace {cj.label}")
    # rank: most significant first
    if len(fit.causes) > 1:
        order = np.argsort(-np.abs(z))
        fit = Fit([fit.causes[i] for i in order], fit.theta[order], fit.r, fit.res, fit.rss,
                  fit.X[:, order])
        cov = cov[np.ix_(order, order)]
        z = z[order]
    # weak identifiability: the 95 % half-width a single-cause fit would have at this noise level
    weak = {}
    if dynamic:
        for c in active:
            if c.kind != "parameter_error" or c in chosen:
                continue
            col = Jc.get(c)
            if col is None:
                continue
            nn = float(col @ col)
            if nn <= 0:
                continue
            var = sigma2 * float(prob.sandwich_meat(col[:, None])[0, 0]) / nn**2
            weak[c.target] = 1.96 * math.sqrt(var)
    return Selection(fit, cov, math.sqrt(sigma2), z, alternatives, not_ident, weak,
                     base.rss, path)


# --------------------------------------------------------------------------------------------
# force-driven simulation (the engine) and the noise-only pitch envelope


def _force_driven_pitch(run: VehicleRun, models: list, forces: list) -> list:
    """States of the force-driven model (A.3) driven by ``forces``, from each model's static
    equilibrium, for several (model, forces) pairs at once (vmapped).

    The engine's DOPRI5 with a fixed step: the sample interval, halved until it is at most
    1 ms. The measured forces are linear between samples, so steps on the sample grid never
    straddle a kink; 1 ms keeps the stiffest mode (the wheel on its damper, about -700 1/s)
    well inside the method's stability region. Returns one ``(n, 10)`` array per pair.
    """
    import jax
    import jax.numpy as jnp

    from ...models._halfcar import static_equilibrium
    from ...solvers._inputs import SampledSignal
    from ...models._params import HalfCarParams

    sub = int(math.ceil(run.dt / 1e-3 - 1e-9))
    with jax.enable_x64(True):
        ps = [jax.tree_util.tree_map(lambda v: jnp.asarray(v, dtype=jnp.float64),
                                     HalfCarParams.from_dict(m)) for m in models]
        params = jax.tree_util.tree_map(lambda *x: jnp.stack(x), *ps)
        values = jnp.stack([jnp.stack([jnp.asarray(f["f1"]), jnp.asarray(f["f2"])], axis=1)
                            for f in forces])
        sig = jax.vmap(lambda v: SampledSignal(0.0, run.dt, v))(values)  # a batch of signals
        y0 = jax.vmap(lambda p: static_equilibrium(p, "force"))(params)
        tau = jnp.asarray(run.t - run.t[0])
        ys, codes = _jit_force_solve(params, sig, y0, tau, float(tau[-1]), run.dt / sub)
        ys = np.asarray(ys)
        codes = np.asarray(codes)
    if np.any(codes != 0):
        raise RuntimeError(f"force-driven simulation failed (result codes {codes.tolist()})")
    return [ys[i] for i in range(len(models))]


def _force_rhs(t, y, args):
    from ...models._halfcar import force_driven_rhs

    params, sig = args
    f = sig(t)
    return force_driven_rhs(t, y, params, f[0], f[1])


def _jit_force_solve_impl(params, sig, y0, ts, t1, dt):
    import jax

    from ...solvers._solve import solve_ode

    def one(p, sg, y):
        sol = solve_ode(_force_rhs, y, 0.0, t1, saveat=ts, args=(p, sg), dt=dt)
        return sol.ys, sol.result

    return jax.vmap(one)(params, sig, y0)


_JIT_CACHE: dict = {}


def _jit_force_solve(params, sig, y0, ts, t1, dt):
    import equinox as eqx

    if "f" not in _JIT_CACHE:
        _JIT_CACHE["f"] = eqx.filter_jit(_jit_force_solve_impl)
    return _JIT_CACHE["f"](params, sig, y0, ts, t1, dt)


def _linear_force_system(p: dict):
    """Linearised force-driven half-car (A.3 without the contact points, which do not feed
    back): states [z1, z2, z3, beta, rates], inputs [f1, f2]."""
    m1, m2, m3, I = p["m1"], p["m2"], p["m3"], p["I"]
    k3, k4, d3, d4, a, b = p["k3"], p["k4"], p["d3"], p["d4"], p["a"], p["b"]
    # f3 = K3 q + D3 q', f4 = K4 q + D4 q'
    K3 = np.array([-k3, 0, k3, -b * k3])
    D3 = np.array([-d3, 0, d3, -b * d3])
    K4 = np.array([0, -k4, k4, a * k4])
    D4 = np.array([0, -d4, d4, a * d4])
    A = np.zeros((8, 8))
    A[:4, 4:] = np.eye(4)
    rows = [(K3 / m1, D3 / m1), (K4 / m2, D4 / m2), (-(K3 + K4) / m3, -(D3 + D4) / m3),
            ((b * K3 - a * K4) / I, (b * D3 - a * D4) / I)]
    for i, (K, D) in enumerate(rows):
        A[4 + i, :4] = K
        A[4 + i, 4:] = D
    B = np.zeros((8, 2))
    B[4, 0] = -1 / m1
    B[5, 1] = -1 / m2
    return A, B


def noise_pitch_std(p: dict, h: float, n: int) -> np.ndarray:
    """Standard deviation of the force-driven pitch error per unit force-noise sigma at the
    samples: propagated covariance of the linearised model, each noise sample held over its
    interval (exact for the linear model). Shape (n,)."""
    A, B = _linear_force_system(p)
    Phi, G = _discretise(A, B, h)
    Gam = G[0]
    var = np.zeros(n)
    acc = 0.0
    x = Gam.copy()  # response one step after a unit sample, both channels (8, 2)
    for k in range(1, n):
        acc += float(x[3, 0] ** 2 + x[3, 1] ** 2)
        var[k] = acc
        x = Phi @ x
    return np.sqrt(var)


# --------------------------------------------------------------------------------------------
# the report


def _rms(x) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x))) if x.size else 0.0


def _chi2_sigma_interval(sigma: float, dof: float) -> tuple[float, float]:
    lo = sigma * math.sqrt(dof / scipy.stats.chi2.ppf(0.975, dof))
    hi = sigma * math.sqrt(dof / scipy.stats.chi2.ppf(0.025, dof))
    return lo, hi


def _finding_for(c: Cause, theta: float, se: float, floor: float = 0.0) -> dict:
    """The finding with its 95 % interval: the statistical half-width 1.96 se combined with the
    comparison's numerical resolution ``floor`` (in theta units; without noise se is only the
    discretisation floor of the residual, which says nothing about the estimate's own error)."""
    est = c.to_estimate(theta)
    half = math.hypot(1.96 * se, floor)
    lo_t, hi_t = theta - half, theta + half
    if c.kind == "force_scale":
        # estimate = 1 / (1 + theta): decreasing
        lo, hi = c.to_estimate(min(hi_t, 10.0)), c.to_estimate(max(lo_t, -0.99))
    else:
        lo, hi = c.to_estimate(lo_t), c.to_estimate(hi_t)
    out = {"cause": c.kind}
    if c.kind == "parameter_error":
        out["parameter"] = c.target
    else:
        out["channel"] = c.target
    out.update({"estimate": float(est), "unit": c.unit(), "interval": [float(lo), float(hi)]})
    return out


def _alternatives_json(alts) -> list[dict]:
    """``indistinguishable_from`` entries in the report's terms (an equal offset on both forces
    is one entry per channel, as the contract names channels f1/f2)."""
    out = []
    for a, est, iv in alts:
        for tgt in (FORCE_CHANNELS if a.target == "both" else (a.target,)):
            d = {"parameter": tgt} if a.kind == "parameter_error" else {"channel": tgt}
            d["cause"] = a.kind
            if est is not None:
                d["estimate"] = est
            if iv is not None:
                d["interval"] = [float(iv[0]), float(iv[1])]
            out.append(d)
    return out


def _describe(c: Cause, est: float) -> str:
    if c.kind == "force_offset":
        where = "both forces" if c.target == "both" else c.target
        return f"an offset of {est:+.4g} N on {where}"
    if c.kind == "force_scale":
        return f"a scale of {est:.5g} on {c.target}"
    if c.kind == "force_delay":
        return f"a delay of {est * 1e3:+.4g} ms on {c.target}"
    return f"{c.target} = {est:.5g} x the model value"


_CHANNEL_WORDS = {"moment": "enforced moment", "heave": "vertical enforced force",
                  "spring1": "front spring force residual", "spring2": "rear spring force residual",
                  "tyre1": "front tyre force residual", "tyre2": "rear tyre force residual",
                  "static": "static load at the first sample"}
_CHANNEL_UNITS = {"moment": "N m", "heave": "N", "spring1": "N", "spring2": "N", "tyre1": "N", "tyre2": "N",
                  "static": "N"}


def _telling_channel(prob: "_Problem", before: "Residuals", after: "Residuals", default: str) -> str:
    """The residual channel where a correction shows most: the largest drop of the residual sum of
    squares in units of the channel's noise (the enforced moment when nothing drops clearly)."""
    best, best_drop = default, 0.0
    for nm in prob.names:
        if nm == "static":
            continue
        rows = prob.rows[nm]
        a = before.channels[nm][:rows] / prob.noise_std[nm]
        b = after.channels[nm][:rows] / prob.noise_std[nm]
        drop = float(a @ a - b @ b)
        if drop > best_drop * 1.5 or (best == default and drop > best_drop):
            best, best_drop = nm, drop
    return best


def diagnose_vehicle_run(run: VehicleRun, model: dict | None = None, plots_dir=None,
                         *, with_simulation: bool = True, log: list | None = None) -> dict:
    """Diagnose a vehicle run against a model; returns the report (``docs/measured-data.md``).

    ``model``: dict of the seed's keys (default: the seed's table). ``plots_dir``: write the
    figures there. ``with_simulation``: run the force-driven simulation for the pitch error
    (the slowest part; tests of the cause logic may skip it).
    """
    model = dict(DEFAULT_MODEL if model is None else model)
    pipe = ResidualPipeline(run)
    prob = _Problem(pipe, model)
    sel = _select(prob, log=log)
    fit = sel.fit
    n_rows = len(fit.r)
    dynamic = n_rows > 2

    # ---- residuals before / after (physical units)
    zero = {ch: {"offset": 0.0, "kappa": 0.0, "delay": 0.0} for ch in FORCE_CHANNELS}
    res0 = pipe.residuals(model, zero)
    p_ext, corr_ext = _apply(model, fit.causes, fit.theta)
    res1 = pipe.residuals(p_ext, corr_ext)

    def kept(res, nm):
        return res.channels[nm][:prob.rows[nm]]

    # ---- noise level
    notes = []
    if dynamic:
        sigma, dof = prob.lowband_noise(
            fit.r, {ch: 1.0 + corr_ext[ch]["kappa"] for ch in FORCE_CHANNELS},
            prob.impulse_responses(p_ext)[0])
        lo, hi = _chi2_sigma_interval(sigma, dof)
        noise_found = sigma > NOISE_MIN_N
        fc = lowband_cutoff(1.0 / run.dt)
        noise_src = (f"below {fc:.3g} Hz, inside the model's bandwidth, the residual left after the "
                     f"fit has the power that white force noise of {sigma:.3g} N would give it "
                     f"(worth {dof:.0f} independent samples; the full-band residual corresponds "
                     f"to {sel.sigma:.3g} N including the comparison's own discretisation error)")
        hf, hf_lo, hf_hi = _force_hf_noise(run)
        if pipe.band and hf < sigma:
            # Sensor noise on the measured motion left in the band adds to the residual's low band
            # and reads as force noise; the forces' own 4th differences do not see it. Both are
            # upper bounds: the smaller one is reported.
            lo, hi = hf_lo, hf_hi
            noise_src = (f"the 4th differences of the forces give {hf:.3g} N; the residual's low band, "
                         f"which here also holds the sensor noise of the measured motion, gives "
                         f"{sigma:.3g} N; the smaller of these two upper bounds is reported")
            sigma = hf
    else:
        sigma, lo, hi = _force_hf_noise(run)
        noise_found = sigma > NOISE_MIN_N
        noise_src = (f"no pitch, heave or spring travel to compare with: the 4th differences of the "
                     f"forces give {sigma:.3g} N, an upper bound (the forces' own content near the "
                     f"Nyquist frequency counts as noise here)")
        notes.append("The run has neither beta, z3 nor s1/s2: only the static load and the force "
                     "noise can be checked.")

    # ---- findings
    corrections = {ch: {"offset": float(corr_ext[ch]["offset"]),
                        "scale": float(1.0 / (1.0 + corr_ext[ch]["kappa"])),
                        "delay": float(corr_ext[ch]["delay"])} for ch in FORCE_CHANNELS}
    findings = []
    se = np.sqrt(np.maximum(np.diag(sel.cov), 0.0)) if len(fit.causes) else np.zeros(0)
    names = prob.names
    main = "moment" if "moment" in names else next((nm for nm in names if nm != "static"), "static")
    for i, c in enumerate(fit.causes):
        est = c.to_estimate(fit.theta[i])
        # residual RMS of the main channel without this cause (others kept)
        others = [j for j in range(len(fit.causes)) if j != i]
        p_o, corr_o = _apply(model, [fit.causes[j] for j in others], fit.theta[others])
        r_without = pipe.residuals(p_o, corr_o)
        ch_i = _telling_channel(prob, r_without, res1, main) if dynamic else main
        a_rms = _rms(kept(r_without, ch_i))
        b_rms = _rms(kept(res1, ch_i))
        ev = (f"{_describe(c, est)} explains the {_CHANNEL_WORDS[ch_i]}: its RMS falls from "
              f"{a_rms:.4g} to {b_rms:.4g} {_CHANNEL_UNITS[ch_i]} when it is corrected "
              f"(z = {abs(sel.z[i]):.1f}, noise level {sigma:.3g} N)")
        alts = sel.alternatives.get(c, [])
        if alts:
            ev += "; the data cannot tell it from " + ", ".join(
                _describe(a, e) if e is not None else a.label for a, e, _ in alts)
        targets = [c.target] if not (c.kind == "force_offset" and c.target == "both") else list(FORCE_CHANNELS)
        for tgt in targets:
            f = _finding_for(Cause(c.kind, tgt) if c.target == "both" else c, fit.theta[i], se[i],
                             _practical(c, pipe))
            f["evidence"] = ev + "."
            f["z"] = float(abs(sel.z[i]))
            if alts:
                f["indistinguishable_from"] = _alternatives_json(alts)
            findings.append(f)
    if not dynamic and sigma > 0:
        # forces only: the static load at the first sample is all there is to check
        st = res0.channels["static"]
        for i, ch in enumerate(FORCE_CHANNELS):
            z = float(st[i] / sigma)
            if abs(z) > 3.5:  # two tests, well beyond the 95 % level: a static load error
                findings.append({
                    "cause": "force_offset", "channel": ch, "estimate": float(st[i]), "unit": "N",
                    "interval": [float(st[i] - 1.96 * sigma), float(st[i] + 1.96 * sigma)],
                    "evidence": (f"at the first sample (vehicle at rest) {ch} differs from the "
                                 f"model's static load by {st[i]:+.4g} N ({abs(z):.1f} noise "
                                 f"levels); with forces alone this cannot be told from a mass or "
                                 f"lever-arm error of the model."),
                    "z": abs(z),
                    "indistinguishable_from": [{"cause": "parameter_error", "parameter": k}
                                               for k in ("m3", "m1" if ch == "f1" else "m2", "a", "b", "g")]})
                corrections[ch]["offset"] = float(st[i])
    if noise_found:
        findings.append({"cause": "force_noise", "estimate": float(sigma), "unit": "N",
                         "interval": [float(lo), float(hi)],
                         "evidence": noise_src[0].upper() + noise_src[1:] + "."})
    if not findings:
        findings.append({"cause": "none", "evidence": (
            "no systematic cause passes the test and " + noise_src +
            ", indistinguishable from the numerical floor of the comparison.")})

    # ---- not identifiable / weakly identifiable parameters
    ni = sorted({c.target for c in sel.not_identifiable if c.kind == "parameter_error"})
    if ni:
        notes.append("Not identifiable from these signals (they do not enter the force-driven "
                     "equations or the measured channels): " + ", ".join(ni) + ".")
    weak = {k: v for k, v in sel.weakly_identifiable.items() if v > 0.02}
    if weak:
        notes.append("Weakly identifiable: a single error in " + ", ".join(
            f"{k} smaller than {100 * v:.2g} %" for k, v in sorted(weak.items(), key=lambda kv: kv[1]))
            + " would not be detected in this run" +
            ("" if any(run.has(s) for s in ("s1", "s2")) else
             " (spring stiffness and damping barely change the spring forces the wheels pass on; "
             "measured spring travel s1/s2 would show them)") + ".")
    if dynamic and not run.has("z3"):
        notes.append("Without z3 a chassis-mass error, a gravity error and equal offsets on both "
                     "forces differ only in their small dynamic signature.")
    for name, (fc, _) in sorted(prob.pipe.band.items()):
        col = MOTION_COLUMN[name]
        notes.append(f"White sensor noise on the measured {col} (about {_motion_noise_sigma(run[col]):.2g} "
                     f"{'rad' if col == 'beta' else 'm'} per sample) swamps its derivatives: the {name} "
                     f"residual is compared below {fc:.3g} Hz only, and what shows only above that "
                     "(wheel hop, fast delays) is not seen.")

    # ---- extended model and gain
    params_ext = {k: float(p_ext[k]) for k in MODEL_KEYS}
    if dynamic and fit.causes:
        main = _telling_channel(prob, res0, res1, main)
    metric = {"moment": "enforced_moment_rms", "heave": "vertical_enforced_force_rms",
              "spring1": "spring_force_residual_rms", "spring2": "spring_force_residual_rms",
              "tyre1": "tyre_force_residual_rms", "tyre2": "tyre_force_residual_rms",
              "static": "static_load_error_rms"}[main]
    gain = {"metric": metric, "before": _rms(kept(res0, main)), "after": _rms(kept(res1, main)),
            "unit": _CHANNEL_UNITS[main]}
    if not dynamic:
        st = res0.channels["static"]
        gain["after"] = _rms([st[i] - corrections[ch]["offset"] for i, ch in enumerate(FORCE_CHANNELS)])

    sim_err = {}
    if "moment" in names:
        inertia = model["I"] * pipe.d2beta[:prob.rows["moment"]]
        lam = kept(res0, "moment")
        sim_err["enforced_moment"] = {"rms": _rms(lam), "max_abs": float(np.max(np.abs(lam))),
                                      "inertia_term_rms": _rms(inertia)}
    if "heave" in names:
        mu = kept(res0, "heave")
        sim_err["vertical_enforced_force"] = {"rms": _rms(mu), "max_abs": float(np.max(np.abs(mu))),
                                              "inertia_term_rms": _rms(model["m3"] * pipe.d2z3)}
    sims = {}
    if with_simulation and (run.has("beta") or run.has("z3")):
        forces0 = {ch: run[ch] for ch in FORCE_CHANNELS}
        forces1 = {ch: v[::pipe.U] for ch, v in pipe.corrected_forces(corr_ext).items()}
        y0, y1 = _force_driven_pitch(run, [model, p_ext], [forces0, forces1])
        sims = {"before": y0, "after": y1}
        env_unit = noise_pitch_std(model, run.dt, run.n)
        sims["pitch_std_unit"] = env_unit
        env = 1.96 * sigma * env_unit
        for label, ys in (("before", y0), ("after", y1)):
            if run.has("beta"):
                err = ys[:, 3] - run["beta"]
                above = np.flatnonzero(np.abs(err) > DRIFT_THRESHOLD_RAD)
                entry = {"rms": _rms(err), "max_abs": float(np.max(np.abs(err))),
                         "drift_off_time_s": float(run.t[above[0]] - run.t[0]) if above.size else None,
                         "drift_threshold_rad": DRIFT_THRESHOLD_RAD,
                         "outside_noise_envelope_fraction": float(np.mean(np.abs(err) > env))}
                if label == "before":
                    sim_err["beta"] = entry
                else:
                    gain["beta_error"] = {"before": sim_err["beta"], "after": entry}
            if run.has("z3"):
                ez = ys[:, 2] - run["z3"]
                entry = {"rms": _rms(ez), "max_abs": float(np.max(np.abs(ez)))}
                if label == "before":
                    sim_err["z3"] = entry
                else:
                    gain["z3_error"] = {"before": sim_err["z3"], "after": entry}
        if run.has("beta"):
            gain["beta_rms_before"] = gain["beta_error"]["before"]["rms"]
            gain["beta_rms_after"] = gain["beta_error"]["after"]["rms"]

    report = {
        "schema": SCHEMA,
        "kind": "vehicle",
        "simulation_error": sim_err,
        "findings": findings,
        "extended_model": {"parameters": params_ext, "corrections": corrections},
        "gain": gain,
        "run": {"file": str(run.path), "samples": run.n, "dt_s": run.dt,
                "duration_s": float(run.t[-1] - run.t[0]),
                "channels": sorted(run.channels), "residual_channels": names},
        "notes": notes,
    }
    if plots_dir is not None:
        write_vehicle_plots(plots_dir, run, model, p_ext, pipe, prob, res0, res1, sims,
                            sigma, report)
    return report


#: below this force-noise level [N] no noise is reported (about 1e-4 of the seed's static load;
#: the low-band estimate of a noise-free run stays below about 0.2 N)
NOISE_MIN_N = 0.5


# --------------------------------------------------------------------------------------------
# figures


def write_vehicle_plots(plots_dir, run, model, p_ext, pipe, prob, res0, res1, sims, sigma,
                        report) -> list[str]:
    """The pictures an engineer looks at; returns the paths written.

    * ``motion.png``: measured pitch (and heave) against the force-driven simulation before and
      after the extension;
    * ``enforced_moment.png``: the enforced moment before/after against the inertia term I beta''
      (or the vertical enforced force against m3 z3'');
    * ``residual_envelope.png``: the residual after the fit against the 95 % noise-only band, and
      the force-driven pitch error against the noise-only drift envelope;
    * ``tyre_forces.png`` (runs with the road height): the tyre-law residual of each wheel before
      and after, against the noise-only band.
    """
    import os

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    os.makedirs(plots_dir, exist_ok=True)
    t = run.t - run.t[0]
    paths = []

    def save(fig, name):
        fig.tight_layout()
        path = os.path.join(plots_dir, name)
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)

    if sims:
        rows = [c for c in ("beta", "z3") if run.has(c)]
        fig, axes = plt.subplots(len(rows), 1, figsize=(9, 3.2 * len(rows)), squeeze=False)
        for ax, c in zip(axes[:, 0], rows):
            idx = 3 if c == "beta" else 2
            scale = 180 / np.pi if c == "beta" else 1.0
            unit = "deg" if c == "beta" else "m"
            ax.plot(t, run[c] * scale, "k", lw=1.2, label="measured")
            ax.plot(t, sims["before"][:, idx] * scale, "C3", lw=0.9, label="force-driven, model")
            ax.plot(t, sims["after"][:, idx] * scale, "C0", lw=0.9, label="force-driven, extended")
            ax.set_ylabel(f"{c} [{unit}]")
            lim = np.max(np.abs(run[c] * scale))
            ax.set_ylim(-3 * lim - 1e-12 + np.mean(run[c] * scale), 3 * lim + 1e-12 + np.mean(run[c] * scale))
            ax.legend(loc="upper left", fontsize=8)
        axes[-1, 0].set_xlabel("t [s]")
        axes[0, 0].set_title("Measured motion against the force-driven simulation")
        save(fig, "motion.png")

    main = "moment" if "moment" in prob.names else ("heave" if "heave" in prob.names else None)
    if main is not None:
        tt = t[1:1 + prob.rows[main]]
        if main == "moment":
            inertia = model["I"] * pipe.d2beta[:prob.rows[main]]
            lab, unit = "inertia term I beta''", "N m"
        else:
            inertia = model["m3"] * pipe.d2z3[:prob.rows[main]]
            lab, unit = "inertia term m3 z3''", "N"
        fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
        axes[0].plot(tt, inertia, "0.4", lw=0.7)
        axes[0].set_ylabel(f"{lab} [{unit}]")
        axes[0].set_title("Enforced " + ("moment (A.5)" if main == "moment" else "vertical force")
                          + " against the inertia term")
        axes[1].plot(tt, res0.channels[main][:prob.rows[main]], "C3", lw=0.7, label="model")
        axes[1].plot(tt, res1.channels[main][:prob.rows[main]], "C0", lw=0.7, label="extended model")
        axes[1].set_ylabel(f"enforced [{unit}]")
        axes[1].set_xlabel("t [s]")
        axes[1].legend(loc="upper left", fontsize=8)
        save(fig, "enforced_moment.png")

    nplot = (main is not None) + bool(sims and run.has("beta"))
    if nplot:
        fig, axes = plt.subplots(nplot, 1, figsize=(9, 3.2 * nplot), squeeze=False)
        k = 0
        if main is not None:
            ax = axes[k, 0]
            k += 1
            tt = t[1:1 + prob.rows[main]]
            band = 1.96 * sigma * prob.noise_std[main]
            ax.plot(tt, res1.channels[main][:prob.rows[main]], "C0", lw=0.6, label="residual, extended model")
            ax.fill_between(tt, -band, band, color="0.8", alpha=0.7, label="95 % noise-only band")
            ax.set_ylabel(f"{main} residual")
            ax.legend(loc="upper left", fontsize=8)
            ax.set_title("Residual against the noise level")
        if sims and run.has("beta"):
            ax = axes[k, 0]
            env = 1.96 * sigma * sims["pitch_std_unit"] * 180 / np.pi
            ax.fill_between(t, -env, env, color="0.8", alpha=0.7, label="95 % noise-only drift envelope")
            ax.plot(t, (sims["before"][:, 3] - run["beta"]) * 180 / np.pi, "C3", lw=0.8, label="pitch error, model")
            ax.plot(t, (sims["after"][:, 3] - run["beta"]) * 180 / np.pi, "C0", lw=0.8, label="pitch error, extended")
            ax.set_ylabel("pitch error [deg]")
            ax.legend(loc="upper left", fontsize=8)
        axes[-1, 0].set_xlabel("t [s]")
        save(fig, "residual_envelope.png")

    tyres = [nm for nm in prob.names if nm.startswith("tyre")]
    if tyres:
        fig, axes = plt.subplots(len(tyres), 1, figsize=(9, 3.2 * len(tyres)), squeeze=False, sharex=True)
        for ax, nm in zip(axes[:, 0], tyres):
            tt = t[:prob.rows[nm]]
            band = 1.96 * sigma * prob.noise_std[nm]
            ax.fill_between(tt, -band, band, color="0.8", alpha=0.7, label="95 % noise-only band")
            ax.plot(tt, res0.channels[nm][:prob.rows[nm]], "C3", lw=0.6, label="model")
            ax.plot(tt, res1.channels[nm][:prob.rows[nm]], "C0", lw=0.6, label="extended model")
            wheel = "front" if nm == "tyre1" else "rear"
            ax.set_ylabel(f"{wheel} tyre residual [N]")
            ax.legend(loc="upper left", fontsize=8)
        axes[0, 0].set_title("Measured wheel force minus the tyre law k (z - zeta) + d (z' - zeta')")
        axes[-1, 0].set_xlabel("t [s]")
        save(fig, "tyre_forces.png")
    return paths
