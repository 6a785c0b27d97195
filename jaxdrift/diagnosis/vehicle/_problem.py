"""The weighted residual vector of a set of causes, its noise response (impulse responses,
sandwich variance, low-band noise level) and the instrumental-variable Gauss-Newton fit."""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field

import numpy as np
import scipy.signal

from ._causes import FORCE_CHANNELS, _apply, _clip_theta
from ._detectors import MOTION_COLUMN, NOISE_MIN_N, _force_hf_noise, lowband_cutoff
from ._motion_noise import denoised_travel, measure_motion_noise
from ._residuals import ResidualPipeline, Residuals


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
        #: see choose_bands): row j of channel nm is its entry j + skip[nm]
        self.skip = {nm: 0 for nm in self.names}
        self._ir_cache: dict = {}
        self.ir, self.noise_std = self.impulse_responses(model)
        self.motion_noise, self._motion_resp, shapes = measure_motion_noise(self)
        #: the measured spring travel without the sensor noise found on it, for the nonlinear
        #: terms (``{column: samples}``), and what was taken out (``{column: {"sigma", "cutoff_hz"}}``)
        self.travel_clean, self.travel_noise = denoised_travel(pipe, self.motion_noise)
        band = choose_bands(pipe, model, self.names, self.ir, self.motion_noise, shapes,
                            self.MOTION_NOISE_SHARE)
        if band:
            self._compare_in(band)

    def _compare_in(self, band: dict) -> None:
        """Compare from here on through the same pipeline with the channels of ``band`` low-passed
        (``{channel: (cutoff Hz, sos)}``, every band the comparison is to have).

        The start of a low-passed channel carries the filter's start-up and the end effects of the
        motion's derivatives, spread over about 1/fc: measured (pitch, heave and spring travel with
        3e-5 of white noise, 500 Hz) up to 10x the residual's rms over the first 0.4 s, enough to
        fit spurious causes. Those rows are left out."""
        self.pipe = self.pipe.with_band(band)
        for nm, (fc, _) in band.items():
            s = min(int(math.ceil(1.5 / (fc * self.pipe.h))), (self.rows[nm] + self.skip[nm]) // 4)
            self.rows[nm] += self.skip[nm] - s
            self.skip[nm] = s
        self._ir_cache = {}
        self.ir, self.noise_std = self.impulse_responses(self.model)

    #: the residual channels the body's motion enters (those :meth:`below` low-passes)
    BODY_CHANNELS = ("moment", "heave", "spring1", "spring2")

    def below(self, fc: float) -> "_Problem":
        """The same problem compared only below ``fc`` [Hz] on the channels the body's motion
        enters (each keeps a lower band it already has): where a body that is not rigid still
        moves as one."""
        band = dict(self.pipe.band)
        for nm in self.names:
            if nm in self.BODY_CHANNELS and band.get(nm, (math.inf,))[0] > fc:
                band[nm] = (fc, scipy.signal.butter(8, fc, fs=1.0 / self.pipe.h, output="sos"))
        new = copy.copy(self)
        new.rows, new.skip = dict(self.rows), dict(self.skip)
        new._compare_in(band)
        return new

    def with_pipe(self, pipe: ResidualPipeline) -> "_Problem":
        """The same problem (rows, bands, noise responses) compared through ``pipe``: the same
        pipeline carrying extra spring forces (``ResidualPipeline.with_extra``), which leave the
        linear part, and so the noise responses, unchanged."""
        new = copy.copy(self)
        new.pipe = pipe
        return new

    #: share of the force-noise power that sensor noise on the measured motion may add to a
    #: residual channel before the channel is low-passed
    MOTION_NOISE_SHARE = 0.01

    #: a channel whose low band holds more than this share of sensor noise (as found on the
    #: measured motion) is left out of the force-noise estimate where others are left
    MOTION_LOWBAND_SHARE = 0.25

    def _lowband_channels(self, parts: dict) -> list[str]:
        """The channels the force noise is measured on: those whose low band holds at most
        ``MOTION_LOWBAND_SHARE`` of sensor noise, where there are any. The found noise's low-band
        power is subtracted, but it is an estimate from the top band: sensor noise is white only
        where the motion moves many units of the last written digit per sample, and a slow signal
        written with few digits is a staircase whose low band holds more (measured: z3 written
        with 6 digits, 500 Hz, put 4x the force noise's power into the heave channel's low band
        where the white level predicted half of what was there)."""
        ok = [nm for nm, (xl, pw) in parts.items() if pw <= self.MOTION_LOWBAND_SHARE * float(np.mean(xl * xl))]
        return ok or list(parts)

    def _motion_lowband_power(self, nm: str, sos, k: slice) -> float:
        """Mean power per row that the sensor noise found on the measured motion puts into the
        low band of the weighted channel ``nm`` (taken out of the force-noise estimate: sensor noise
        left in the band would otherwise read as force noise)."""
        pw = 0.0
        for (col, nm2), e in self._motion_resp.items():
            sig = self.motion_noise.get(col, {}).get("sigma", 0.0)
            if nm2 != nm or sig <= 0:
                continue
            ch = {nm: e.copy()}
            self.pipe._band_filter(ch)
            x = ch[nm][self.skip[nm]:self.skip[nm] + self.rows[nm]] / self.noise_std[nm]
            xl = scipy.signal.sosfiltfilt(sos, x)[k]
            pw += sig ** 2 * float(np.mean(xl * xl))
        return pw

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
        """Force-noise level from the residual's low band, and its effective degrees of freedom
        (``lowband_levels``, the sensor noise found on the measured motion taken out)."""
        sigma, _, dof = self.lowband_levels(r, gains, ir)
        return sigma, dof

    def lowband_parts(self, r: np.ndarray, gains: dict | None = None, ir: dict | None = None) -> dict:
        """Per residual channel the force noise is measured on (``_lowband_channels``): its low
        band (``lowband_levels``), the sensor noise's power there, its low-passed noise response
        per force channel and their summed energy (the power per sample unit noise gives it)."""
        gains = gains or {}
        ir = self.ir if ir is None else ir
        fs = 1.0 / self.pipe.h
        fc = lowband_cutoff(fs)
        sos = scipy.signal.butter(6, fc, fs=fs, output="sos")
        blocks = self._blocks(r[:, None])
        parts = {}
        for nm in self.names:
            if nm == "static":
                continue
            x = blocks[nm][:, 0]
            L = len(x)
            k = slice(L // 20, L - L // 20)
            xl = scipy.signal.sosfiltfilt(sos, x)[k]
            parts[nm] = (xl, self._motion_lowband_power(nm, sos, k))
        out = {}
        for nm in self._lowband_channels(parts):
            xl, motion_pw = parts[nm]
            unit, hl = 0.0, {}
            for ch in FORCE_CHANNELS:
                h = ir[(nm, ch)][0] / self.noise_std[nm] * gains.get(ch, 1.0)
                pad = np.zeros(int(4 * fs / fc))
                hl[ch] = scipy.signal.sosfiltfilt(sos, np.concatenate([pad, h, pad]))
                unit += float(np.sum(hl[ch] ** 2))
            out[nm] = (xl, motion_pw, hl, unit)
        return out

    @staticmethod
    def lowband_channel_levels(parts: dict) -> dict:
        """Per channel of ``lowband_parts``, the level its low band gives alone (sensor noise
        taken out) and that level's degrees of freedom: white force noise gives every channel
        one level, an error the model makes in one equation does not (a roll coupled into the
        heave the model is compared on moves the vertical force, not the moment)."""
        out = {}
        for nm, (xl, motion_pw, hl, unit) in parts.items():
            den = unit * len(xl)
            if den <= 0:
                continue
            dof = 2.0 * den * den / max(2.0 * len(xl) * _ccf_energy(hl, hl), 1e-300)
            out[nm] = (math.sqrt(max(float(np.sum(xl * xl)) - motion_pw * len(xl), 0.0) / den), dof)
        return out

    def lowband_levels(self, r: np.ndarray, gains: dict | None = None, ir: dict | None = None,
                       parts: dict | None = None) -> tuple[float, float, float]:
        """Force-noise level from the residual's low band with the sensor noise found on the
        measured motion taken out, the same level with it left in (an upper bound where that
        share is uncertain), and their effective degrees of freedom (the same for both).

        White force noise reaches every residual across the whole band, with a spectrum known
        from the impulse responses; the comparison's own error (interpolation of inputs that
        have content near the Nyquist frequency, the record's ends) sits at high frequencies.
        So the residual is low-passed (zero phase, below min(fs/6, 40 Hz), inside the model's
        bandwidth) and its power compared with the low-passed noise response: sigma^2 =
        sum r_lp^2 / sum (h_lp^2 per row). The first and last 5 % of each channel are left out.
        ``gains``: per force channel, the factor the correction puts on the measured samples
        (1 / scale): noise on the measured samples reaches the residual multiplied by it.
        ``ir``: impulse responses of the fitted parameters (default: the model's); the residual
        keeps the model's row weighting either way. ``parts``: ``lowband_parts(r, gains, ir)``
        where the caller has it already.
        """
        parts = self.lowband_parts(r, gains, ir) if parts is None else parts
        num = den = motion = 0.0
        for xl, motion_pw, hl, unit in parts.values():
            num += float(np.sum(xl * xl))
            motion += motion_pw * len(xl)
            den += unit * len(xl)
        # Var(sum_a sum_t x_a(t)^2) = 2 sigma^4 sum_{a,b} sum_{t,t'} c_ab(t - t')^2, with c_ab the
        # cross-covariance of residual channels a and b: they see the same force noise, so the
        # cross terms count as much as the auto terms (leaving them out overstated the degrees
        # of freedom by about 1.5 with pitch and both spring travels). The sum of c_ab^2 over all
        # lags does not depend on the channels' relative alignment.
        var_num = 0.0
        for xa, _, ha, _ in parts.values():
            for xb, _, hb, _ in parts.values():
                var_num += 2.0 * math.sqrt(len(xa) * len(xb)) * _ccf_energy(ha, hb)
        if den <= 0:
            return 0.0, 0.0, 1.0
        dof = 2.0 * den * den / max(var_num, 1e-300)
        return math.sqrt(max(num - motion, 0.0) / den), math.sqrt(max(num, 0.0) / den), dof


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


def _ccf_energy(ha: dict, hb: dict) -> float:
    """The sum over all lags of the squared cross-covariance of two residual channels under unit
    white force noise (their noise responses ``ha``, ``hb`` per force channel): what their squared
    low bands' covariance is made of (``_Problem.lowband_levels``)."""
    ccf = 0.0
    for ch in FORCE_CHANNELS:
        ccf = ccf + scipy.signal.correlate(ha[ch], hb[ch], mode="full", method="fft")
    return float(np.sum(ccf ** 2))


def choose_bands(pipe: ResidualPipeline, model: dict, names, ir: dict, motion_noise: dict, shapes: dict,
                 share: float) -> dict:
    """The residual channels to low-pass because their measured motion carries sensor noise:
    ``{channel: (cutoff Hz, sos)}`` (empty for clean motion records). Pure.

    The residuals differentiate the measured motion (``I beta''``, ``m3 z3''``, ``d s'``), so
    white sensor noise of standard deviation s reaches them with a power spectrum growing as
    (2 pi f)^4 (or (2 pi f)^2), while force noise reaches them through the model and fades at
    high frequencies. Even 1e-6 rad of pitch noise (a CSV written with 6 decimals) swamps
    the enforced moment above a few tens of Hz. The sensor noise is measured in the top band
    of each residual channel (``_motion_noise.measure_motion_noise``), the force noise from the
    forces' 4th differences; each channel keeps the band where the sensor noise adds at most
    ``share`` of the force-noise power.
    """
    run = pipe.run
    h = pipe.h
    sig_f = max(_force_hf_noise(run)[0], NOISE_MIN_N)
    p = model
    gains = {"moment": lambda w: p["I"] * w * w, "heave": lambda w: p["m3"] * w * w,
             "spring1": lambda w: np.abs(p["k3"] + 1j * w * p["d3"]),
             "spring2": lambda w: np.abs(p["k4"] + 1j * w * p["d4"])}
    band = {}
    for nm in names:
        if nm not in gains:
            continue
        col, gain = MOTION_COLUMN[nm], gains[nm]
        sig_m = motion_noise.get(col, {}).get("sigma", 0.0)
        others = [(c2, motion_noise[c2]["sigma"]) for (c2, nm2) in shapes
                  if nm2 == nm and c2 != col and motion_noise.get(c2, {}).get("sigma", 0.0) > 0]
        if sig_m <= 0 and not others:
            continue
        nfft = 1 << int(np.ceil(np.log2(max(4 * len(ir[(nm, "f1")][0]), 1024))))
        Hf = sum(np.abs(np.fft.rfft(ir[(nm, ch)][0], nfft)) ** 2 for ch in FORCE_CHANNELS)
        f = np.fft.rfftfreq(nfft, h)
        motion = sig_m ** 2 * gain(2 * np.pi * f) ** 2
        for c2, s2 in others:
            # noise found on another column reaching this channel (pitch noise moves the spring
            # points): its PSD per unit variance against the force noise's, |H|^2 2/fs
            fw, G = shapes[(c2, nm)]
            motion = motion + s2 ** 2 * np.interp(f, fw, G) * (h / 2.0)
        bad = motion > share * sig_f ** 2 * Hf
        bad[0] = False
        if not np.any(bad):
            continue
        fc = float(f[np.argmax(bad)])
        if fc >= 0.45 / h:
            continue
        fc = max(fc, 1.0)
        band[nm] = (fc, scipy.signal.butter(8, fc, fs=1.0 / h, output="sos"))
    return band
