"""Vibration told apart from the gyro's white noise.

A multirotor's motors shake the gyro at their rotation frequencies and harmonics: broadband up to the
sampling rate, and only while they run. The k-th differences that measure white noise cannot tell
that from noise, so a vibrating log read as noise states a noise level tens of times a MEMS gyro's
datasheet and weights the reference fit as if that noise integrated like a random walk (it does not:
vibration averages out between reference rows), and the bias it holds is lost.

:func:`vibration_step` measures the level of the differences (the order the white-noise estimate
chose) in windows of :data:`WINDOW_S` along every segment, on the rates as recorded
(:func:`._noise.recorded_rates`). White noise has one level everywhere
(the windows' levels scatter by a few tens of percent); vibration comes and goes with the motors.
A window more than :data:`VIBRATION_RATIO` times the quietest window's level vibrates. Where windows
vibrate:

- the white noise is measured on the quiet windows (within :data:`QUIET_RATIO` of the quietest),
  an *estimate* when they hold at least :data:`QUIET_MIN_ROWS` rows, else the quietest window's
  level is an *upper bound*;
- a ``vibration`` finding names the spans, the level per axis (RMS of the high-frequency rate, the
  differences' level) and the spectrum's peak frequencies (Welch, over the vibrating windows);
- the reference fit weighs its intervals by what their residuals show, and its intervals are the
  cluster-robust (block) ones (:mod:`._pipeline`).

Where every window vibrates alike, the spectrum decides: a white gyro's spectrum is flat above the
motion, a motor's has peaks (:data:`PEAK_RATIO` times the median level); the noise is then an
upper bound and the vibration is named over the whole run.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import stats

from .._diffnoise import white_factor
from ._causes import GYRO_NOISE, VIBRATION
from ._common import CHANNELS, fmt
from ._noise import recorded_rates
from ._records import Said, Vibration

__all__ = ["vibration_step", "WINDOW_S", "VIBRATION_RATIO", "QUIET_RATIO", "QUIET_MIN_ROWS", "PEAK_RATIO"]

#: window of the level measurement [s] (at least 64 rows)
WINDOW_S = 0.5
#: a window whose differences' level is over this factor of the quietest window's vibrates
VIBRATION_RATIO = 3.0
#: windows within this factor of the quietest are quiet (their pooled level is the white noise)
QUIET_RATIO = 1.6
#: quiet rows needed for the white noise to be an estimate (else an upper bound)
QUIET_MIN_ROWS = 100
#: a spectral line over this factor of the spectrum's median above the motion band is a peak
PEAK_RATIO = 8.0
#: at most this many peak frequencies are reported
N_PEAKS = 4


def _window_levels(run, segments, k, rows, min_rows=None):
    """Per window (rows ``rows`` long, inside one segment; a segment's last, shorter window too
    where it has ``min_rows``): (i0, i1, per-axis variance of the k-th differences over C(2k, k)),
    on the rates as recorded (:func:`._noise.recorded_rates`), in per-grid-sample units."""
    ck = white_factor(k)
    min_rows = rows if min_rows is None else min_rows
    out = []
    for a, b in segments:
        for i0 in range(a, b, rows):
            i1 = min(i0 + rows, b)
            if i1 - i0 < min_rows:
                continue
            x, dtr = recorded_rates(run, i0, i1)
            d = np.diff(x, k, axis=0)
            out.append((i0, i1, np.mean(d * d, axis=0) / ck * (dtr / run["dt"])))
    return out


def _spectrum(w, windows, dt):
    """Welch spectrum (summed over the axes) over the given windows, averaged; (f, P per axis)."""
    from scipy.signal import welch

    nper = min(256, windows[0][1] - windows[0][0])
    ps = []
    for i0, i1, _ in windows:
        x = w[i0:i1] - np.mean(w[i0:i1], axis=0)
        f, p = welch(x, fs=1.0 / dt, nperseg=nper, axis=0)
        ps.append(p)
    return f, np.mean(ps, axis=0)


def _peaks(f, p, f_min):
    """Peak frequencies of the axis-summed spectrum above ``f_min``: local maxima over PEAK_RATIO
    times the median level there, strongest first."""
    tot = p.sum(1)
    band = f >= f_min
    if band.sum() < 8:
        return [], 0.0
    med = float(np.median(tot[band]))
    idx = [i for i in np.nonzero(band)[0][1:-1]
           if tot[i] >= tot[i - 1] and tot[i] >= tot[i + 1] and tot[i] > PEAK_RATIO * med]
    idx.sort(key=lambda i: -tot[i])
    return [float(f[i]) for i in idx[:N_PEAKS]], (float(tot[idx[0]] / med) if idx else 1.0)


def _spans(windows, mask, t):
    out = []
    for (i0, i1, _), m in zip(windows, mask):
        if not m:
            continue
        if out and out[-1][2] == i0:
            out[-1][1], out[-1][2] = float(t[i1 - 1]), i1
        else:
            out.append([float(t[i0]), float(t[i1 - 1]), i1])
    return [[a, b] for a, b, _ in out]


def vibration_step(run, noise):
    """Vibration found and named, the white noise re-measured where the gyro is quiet (see the
    module's docstring). Returns ``(noise, vibration, said)``: the revised
    :class:`._records.GyroNoise`, the :class:`._records.Vibration` (None where the levels are one
    white noise) and its note."""
    wn = noise.wn
    if wn is None or not noise.found:
        return noise, None, Said()
    # at least order 4: a difference of that order keeps a vibration near the Nyquist frequency and
    # damps a hand's or a vehicle's motion (below a tenth of the rate) by 50 times and more
    dt, w, t, k = run["dt"], run["w"], run["t"], max(int(wn["order"]), 4)
    rows = max(64, int(round(WINDOW_S / dt)))
    win = _window_levels(run, noise.segments, k, rows)
    if len(win) < 4:
        return noise, None, Said()
    lev = np.array([math.sqrt(float(np.mean(v))) for _, _, v in win])  # pooled over the axes
    # never below the file's rounding (a gyro written in coarse steps has windows of zero differences)
    quiet_level = max(float(lev.min()), 3.0 * noise.floor)
    vib = lev > VIBRATION_RATIO * quiet_level
    f_min = min(10.0, 0.1 / dt)  # above the motion band
    if vib.any():
        quiet = lev <= QUIET_RATIO * quiet_level
        f, p = _spectrum(w, [x for x, m in zip(win, vib) if m], dt)
        peaks, _ = _peaks(f, p, f_min)
        spans = _spans(win, vib, t)
    else:
        f, p = _spectrum(w, win, dt)
        peaks, _ = _peaks(f, p, f_min)
        if not peaks:
            return noise, None, Said()
        quiet = np.zeros(len(win), bool)
        vib = np.ones(len(win), bool)
        spans = [[float(t[win[0][0]]), float(t[win[-1][1] - 1])]]
    var_vib = np.mean([v for (_, _, v), m in zip(win, vib) if m], axis=0)
    level = np.sqrt(var_vib)
    n_quiet = int(quiet.sum()) * rows
    if n_quiet >= QUIET_MIN_ROWS:
        var_q = np.mean([v for (_, _, v), m in zip(win, quiet) if m], axis=0)
        n_eff = n_quiet - k
        half = 1.96 * math.sqrt(2.0 * math.comb(4 * k, 2 * k) / white_factor(k) ** 2 / max(n_eff, 1))
        vq = float(np.mean(var_q))
        N = math.sqrt(vq * dt)
        quiet_spans = _spans(win, quiet, t)
        where = ", ".join(f"{fmt(a)}..{fmt(b)} s" for a, b in quiet_spans[:4]) + (" ..." if len(quiet_spans) > 4 else "")
        # (the noise's sigma_axis stays the differences' level: the vibration is in the rates the scale fit
        # regresses on, as much an error of the regressor as the white noise)
        sig_q = np.sqrt(var_q)
        var_rate = max(vq * dt, noise.floor**2 * dt, 1e-24)
        finding = {
            "cause": GYRO_NOISE.name, "estimate_kind": "estimate", "estimate": N, "unit": GYRO_NOISE.unit,
            "interval": [N * math.sqrt(max(1.0 - half, 0.0)), N * math.sqrt(1.0 + half)],
            "evidence": (f"measured where the gyro is quiet ({n_quiet} rows: t = {where}), away from the "
                         f"vibration: order-{k} differences white with per-sample std "
                         f"{', '.join(fmt(v) for v in sig_q)} rad/s (wx, wy, wz); N = {fmt(N)} rad/sqrt(s) "
                         f"= {fmt(np.degrees(N) * 60)} deg/sqrt(h)"),
        }
    else:
        N = quiet_level * math.sqrt(dt)
        var_rate = max(quiet_level**2 * dt, noise.floor**2 * dt, 1e-24)
        # the quietest window is the one whose noise happened to read lowest: the largest white noise
        # that could read that low in the quietest of len(win) windows at 95 % (Bonferroni over the
        # windows; the level's variance over 3 axes of rows - k differences has the relative spread s)
        s = math.sqrt(2.0 * math.comb(4 * k, 2 * k) / white_factor(k) ** 2 / max(3 * (rows - k), 1))
        z = float(stats.norm.isf(0.05 / len(win)))
        N_up = N / math.sqrt(max(1.0 - z * s, 0.05))
        finding = {
            "cause": GYRO_NOISE.name, "estimate_kind": "upper_bound", "estimate": N, "unit": GYRO_NOISE.unit,
            "interval": [0.0, N_up],
            "evidence": (f"an upper bound, N <= {fmt(N_up)} rad/sqrt(s): the quietest {fmt(rows * dt)} s of the run "
                         f"read {fmt(N)}, and a white noise of up to {fmt(N_up)} could read that low in the quietest "
                         f"of {len(win)} windows (95 %); the gyro vibrates "
                         f"{'everywhere' if not quiet.any() else 'almost everywhere'}, so no span shows its white "
                         f"noise alone"),
        }
    peak_txt = (f"; spectral peaks at {', '.join(fmt(x) for x in peaks)} Hz" if peaks else "")
    span_txt = ", ".join(f"{fmt(a)}..{fmt(b)} s" for a, b in spans[:6]) + (" ..." if len(spans) > 6 else "")
    vib_rows = int(vib.sum()) * rows
    f_entry, z = VIBRATION.finding(
        float(level.max()), None,
        f"the rates' high-frequency content is {fmt(float(level.max()) / math.sqrt(max(var_rate / dt, 1e-300)))} "
        f"times the white noise over {fmt(vib_rows * dt)} s (t = {span_txt}): per-sample level "
        f"{', '.join(fmt(v) for v in level)} rad/s (wx, wy, wz){peak_txt}. Vibration averages out between "
        f"reference rows: the reference fit weighs its intervals by their own residuals",
        0.0, level_per_axis=[float(v) for v in level], peak_frequencies_hz=peaks, spans_s=spans,
        duration_s=float(vib_rows * dt))
    note = (f"vibration: {', '.join(CHANNELS)} levels {', '.join(fmt(v) for v in level)} rad/s per sample "
            f"over {fmt(vib_rows * dt)} s; the gyro noise is "
            + ("measured on its quiet spans" if finding["estimate_kind"] == "estimate" else "an upper bound"))
    if run.get("w_unmeasured") is not None:
        # rates logged as means over their own windows are carried onto the grid by their integral,
        # exact at every window's end (:func:`jaxdrift.io._timebase.resample_windows`): the vibration
        # is motion the reference sees too, not an error of the scale's regressor; only the white
        # noise of the quiet spans (or its bound) is
        noise = replace(noise, sigma_axis=sig_q if n_quiet >= QUIET_MIN_ROWS else np.full(3, quiet_level))
    return (replace(noise, var_rate=var_rate, finding=finding),
            Vibration(spans=spans, level=level, peaks=peaks, rows=vib_rows, finding=f_entry), Said(notes=(note,)))
