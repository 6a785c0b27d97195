"""White sensor noise on the measured motion, measured in the top band of the residual channels
that differentiate it, against the pipeline's own response shapes and its own floor.

Rough-road motion is broadband up to and beyond the wheel-hop band, so a test on the motion alone
cannot tell it from sensor noise (the earlier 4th-against-8th-difference test read 3e-5 m of noise
into spring travel written with 9 digits). The model knows better: driven by the measured forces it
predicts the motion, so what the measured motion carries beyond the prediction, with the spectrum
white noise would give after the pipeline's differentiation, is the sensor noise. Three shapes come
from the pipeline itself (so they include its interpolation and differentiation):

* the channel's response to unit white noise on both forces,
* its response to unit white noise on the column (a second pipeline on the run with a small white
  probe added),
* for the spring channels, the pipeline's own floor: the residual of the run with the spring travel
  replaced by the model's simulated travel (effect-free and noise-free by construction, at the same
  rate, duration and channel set), which holds only the comparison's discretisation error.
"""

from __future__ import annotations

import numpy as np

from ...io._csvio import VehicleRun
from ...io._corrections import FORCE_CHANNELS, NO_CORRECTION
from ._detectors import (MOTION_COLUMN, TOP_BAND, _welch, noise_fit, transfer_psd, welch_segment, welch_segments,
                         written_noise_sigma)
from ._residuals import ResidualPipeline

#: share of the residual's top-band power the sensor-noise term must explain before the noise
#: counts as found; below it the term is more likely the comparison's own error than noise
MOTION_NOISE_MIN_SHARE = 0.5

#: where the pipeline's floor is measured (spring channels), noise this many times the level the
#: floor alone reads as counts as found whatever its share of the top band (force noise may dominate)
FLOOR_FACTOR = 3.0

#: the motion term must also stand out of the Welch estimate's own scatter by this many standard
#: errors (on clean runs with 20 N of force noise the fit gives it 10 % of the top band by chance)
MOTION_NOISE_MIN_Z = 4.0

#: the shortest record the noise is measured on: 8 Welch segments of the shortest length (64), 15
#: with half overlap; the fit's own z (``MOTION_NOISE_MIN_Z``, from the segments' number) guards
#: the short ones. At 16 segments (1024 samples, the gate before) a 3-5 s run at 200-300 Hz went
#: unmeasured: its pitch noise of 5-9 urad, differentiated twice, filled the whole band, the force
#: noise read 277 N for 4.5 N and the inertia 0.48 for 1.06 (measured on generated campaigns);
#: measured, the comparison is band-limited and the inertia reads 1.054
MOTION_NOISE_MIN_SAMPLES = 8 * 64

_ZERO = NO_CORRECTION


def simulated_travel(pipe: ResidualPipeline, p: dict) -> dict[str, np.ndarray]:
    """Spring travel s1, s2 the model simulates from the measured forces and prescribed motion, at
    the measured samples."""
    forces_c, _ = pipe._corrected_coeffs(_ZERO, False)
    _, _, x = pipe.simulate(p, None, forces_c=forces_c)
    a, b = p["a"], p["b"]
    if pipe.mode == "pitch" and pipe.has_z3:
        s1, s2 = pipe.Z - x[:, 0] - b * pipe.S, pipe.Z - x[:, 1] + a * pipe.S
    elif pipe.mode == "pitch":
        s1, s2 = x[:, 0] - b * pipe.S, x[:, 1] + a * pipe.S
    else:
        s1, s2 = x[:, 0], x[:, 1]
    return {"s1": s1[::pipe.U], "s2": s2[::pipe.U]}


def _with(run: VehicleRun, cols: dict) -> VehicleRun:
    return VehicleRun(path=run.path, t=run.t, channels={**run.channels, **cols})


def measure_motion_noise(prob) -> tuple[dict, dict, dict]:
    """Per measured motion column: ``{"sigma", "estimate", "share", "written", "floor"}``, the
    residual channels' responses to unit white noise on each column (``{(column, channel): r}``)
    and their PSD per unit noise variance (``{(column, channel): (f, psd)}``).

    ``estimate``: the white noise per sample that, with white force noise, best explains the
    residual's top band beyond what is already attributed (the pitch and heave noise reaching the
    spring channels through the simulated spring force, and the pipeline's floor); ``share``: the
    part of the top-band power it explains; ``sigma``: the estimate where the share reaches
    ``MOTION_NOISE_MIN_SHARE``, else 0; ``written``: the rounding noise of the values as printed;
    ``floor``: the level the floor alone would be read as (0 where not measured)."""
    pipe, model = prob.pipe, prob.model
    run, n = pipe.run, pipe.n
    out = {}
    names = [nm for nm in prob.names if nm in MOTION_COLUMN]
    if not names or n < MOTION_NOISE_MIN_SAMPLES:
        return out, {}, {}
    rng = np.random.default_rng(20260)  # the probes: a fixed function of the run, not of a seed
    r0 = pipe.residuals(model, _ZERO).channels
    fs = 1.0 / pipe.h
    wf = {ch: rng.standard_normal(n) for ch in FORCE_CHANNELS}
    rf = {}  # force channel -> residual channels' response to unit white noise on it alone
    for ch in FORCE_CHANNELS:
        one = {c: (wf[c] if c == ch else np.zeros(n)) for c in FORCE_CHANNELS}
        rf[ch] = pipe.residuals(model, None, linear_part_only=True, forces=one).channels
    resp, probes = {}, {}  # (column, channel) -> response to unit white noise on the column
    for nm in names:
        col = MOTION_COLUMN[nm]
        amp = max(1e-4 * float(np.std(run[col])), 1e-12)
        probes[col] = rng.standard_normal(n)
        r2 = ResidualPipeline(_with(run, {col: run[col] + amp * probes[col]})).residuals(model, _ZERO)
        for nm2 in names:
            resp[(col, nm2)] = (r2.channels[nm2] - r0[nm2]) / amp
    floor = {}
    springs = [nm for nm in names if nm.startswith("spring")]
    if springs:
        sim = simulated_travel(pipe, model)
        r3 = ResidualPipeline(_with(run, {MOTION_COLUMN[nm]: sim[MOTION_COLUMN[nm]] for nm in springs}))
        r3 = r3.residuals(model, _ZERO).channels
        floor = {nm: r3[nm] for nm in springs}

    def shape(x_in, y_out, nm, rows, nper):
        # channel rows k are samples k + offset: align the input with them
        off = prob.offset[nm]
        return transfer_psd(x_in[off:off + rows], y_out[:rows], fs, nper)

    # the PSD each channel gets from unit white noise on each column (every column's noise reaches
    # every channel: pitch noise moves the spring points by a sin(beta)), on the channel's Welch grid
    shapes = {}
    for (col, nm), e in resp.items():
        rows = prob.rows[nm]
        nper = welch_segment(rows)
        shapes[(col, nm)] = (np.fft.rfftfreq(nper, 1.0 / fs), shape(probes[col], e, nm, rows, nper))

    # the enforced moment and heave first (each dominated by its own column's noise, growing as
    # f^4); then the spring channels, with the pitch and heave noise found and the floor taken out
    for nm in names:
        col = MOTION_COLUMN[nm]
        rows = prob.rows[nm]
        nper = welch_segment(rows)
        f, P = _welch(r0[nm][:rows], fs, nper)
        band = (f >= TOP_BAND[0] * fs) & (f <= TOP_BAND[1] * fs)
        G = shapes[(col, nm)][1]
        F = sum(shape(wf[ch], rf[ch][nm], nm, rows, nper) for ch in FORCE_CHANNELS)
        known = np.zeros_like(P)
        for col2, v in out.items():
            if (col2, nm) in resp and v["sigma"] > 0:
                known += v["sigma"] ** 2 * shapes[(col2, nm)][1]
        fl = 0.0
        n_seg = welch_segments(rows, nper)
        if nm in floor:
            Pf = _welch(floor[nm][:rows], fs, nper)[1]
            known += Pf
            fl = noise_fit(Pf, G, F, band, n_seg)[0]
        est, _, z = noise_fit(P, G, F, band, n_seg, known=known)
        share = float(est ** 2 * np.sum(G[band]) / max(np.sum(P[band]), 1e-300))
        found = z >= MOTION_NOISE_MIN_Z and (share >= MOTION_NOISE_MIN_SHARE or (fl > 0 and est >= FLOOR_FACTOR * fl))
        out[col] = {"sigma": est if found else 0.0, "estimate": est, "z": z,
                    "share": share, "written": written_noise_sigma(run[col]), "floor": fl}
    return out, resp, shapes


#: the travel's periodogram is smoothed over this share of its bins (at least 17) before it is
#: compared with its noise: a smoothed periodogram of noise alone then scatters by 20 % or less,
#: never up to the threshold
TRAVEL_SMOOTH = 0.01
#: the travel is kept up to the highest frequency where its power stands this many times above
#: the white noise's, and tapered to nothing over the next quarter of that frequency
TRAVEL_SNR = 2.0


def denoised_travel(pipe: ResidualPipeline, motion_noise: dict) -> tuple[dict, dict]:
    """The measured spring travel columns with the white sensor noise found on them
    (``motion_noise``, :func:`measure_motion_noise`) taken out above the travel's own band
    (``{column: samples}``), and ``{column: {"sigma", "cutoff_hz"}}``; empty where none was found.

    The nonlinear terms act on the travel and its rate (``_nonlinear.model_states``): a stop or an
    asymmetric damper read off the noisy travel is a function of a regressor with errors, and the
    rate's noise (white per sample, differentiated: growing with frequency) folds through the
    term's kink into the band it is compared in; its size comes out biased (1e-4 m at 500 Hz: a
    damper ratio 0.759 read 0.716, 1.18 read 1.218). The comparison itself keeps the travel as
    measured: its spring channels are already low-passed where the noise would reach them
    (``_problem.choose_bands``). Each column's padded spectrum (the pipeline's,
    ``_padded_spectrum``) is kept up to the highest frequency where its power, smoothed over
    ``TRAVEL_SMOOTH`` of the bins, stands ``TRAVEL_SNR`` times above the noise's (``n sigma^2`` per
    bin) and tapered (raised cosine) to nothing over the next quarter of that frequency: above it
    the travel is noise. Measured in ``benchmarks/validation/nonlinear_sizes.py``."""
    sigmas = {c: float(motion_noise[c]["sigma"]) for c in ("s1", "s2")
              if motion_noise.get(c, {}).get("sigma", 0.0) > 0}
    if not sigmas:
        return {}, {}
    import scipy.fft
    import scipy.ndimage

    cols, taken = {}, {}
    for c, sig in sigmas.items():
        x = np.asarray(pipe.run[c], dtype=float)
        X, N, m = pipe._padded_spectrum(x)
        f = np.fft.rfftfreq(N, pipe.h)
        P = scipy.ndimage.uniform_filter1d(np.abs(X) ** 2, max(17, int(TRAVEL_SMOOTH * len(X))), mode="nearest")
        above = np.nonzero(P > TRAVEL_SNR * len(x) * sig ** 2)[0]
        fc = float(f[above.max()]) if above.size else float(f[1])
        if fc * 1.25 >= f[-1]:  # the travel stands above its noise everywhere: nothing to take out
            continue
        H = np.where(f <= fc, 1.0, 0.5 * (1.0 + np.cos(np.pi * np.clip((f - fc) / (0.25 * fc), 0.0, 1.0))))
        cols[c] = scipy.fft.irfft(X * H, n=N)[m:m + len(x)]
        taken[c] = {"sigma": sig, "cutoff_hz": fc}
    return cols, taken


def sensor_noise_notes(prob) -> list[str]:
    """The report's notes on the sensor noise of the measured motion: the travel's noise taken
    out for the nonlinear terms (:func:`denoised_travel`), and each channel compared band-limited
    because of it."""
    notes = []
    for col, tk in sorted(prob.travel_noise.items()):
        sig = tk["sigma"]
        notes.append(f"White sensor noise on the measured {col} (about {sig:.2g} m per sample) was taken out of it "
                     f"above {tk['cutoff_hz']:.3g} Hz (above that its spectrum holds that noise alone) for the "
                     f"nonlinear terms: a stop or an asymmetric damper read off the noisy travel and its rate "
                     f"comes out biased.")
    for name, (fc, _) in sorted(prob.pipe.band.items()):
        col = MOTION_COLUMN[name]
        mn = prob.motion_noise[col]
        unit = 'rad' if col == 'beta' else 'm'
        notes.append(f"White sensor noise on the measured {col} (about {mn['sigma']:.2g} {unit} per sample, "
                     f"{100 * mn['share']:.0f} % of the {name} residual above {TOP_BAND[0] * 100:.0f} % of the "
                     f"sampling rate; printing the values with their digits alone adds {mn['written']:.2g} {unit}) "
                     f"swamps its derivatives: the {name} "
                     f"residual is compared below {fc:.3g} Hz only, and what shows only above that "
                     "(wheel hop, fast delays) is not seen.")
    return notes
