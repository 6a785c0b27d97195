"""Report pieces: intervals, evidence sentences, the channel where a correction shows most."""

from __future__ import annotations

import math

import numpy as np
import scipy.stats

from ...io._corrections import NO_CORRECTION, Corrections
from ...io._csvio import MODEL_KEYS
from ...io._timebase import run_block
from ._causes import FORCE_CHANNELS, FORCE_NOISE, FORCE_OFFSET, PARAMETER_ERROR, Cause, _apply, _finding_for, _practical
from ._confirm import OOS_STRETCHES
from ._detectors import (MOTION_COLUMN, NOISE_MIN_N, _force_hf_noise, force_top_band_shared,
                         force_top_band_white,
                         lowband_cutoff, written_digits)
from ._mode import mode_shift_var, settled_half
from ._motion_noise import sensor_noise_notes
from ._problem import _Problem
from ._residuals import Residuals
from ._residuals import kept as _kept
from ._residuals import rms as _rms
from ._residuals import telling_channel as _telling_channel

SCHEMA = "jaxdrift.diagnosis/1"



def _chi2_sigma_interval(sigma: float, dof: float) -> tuple[float, float]:
    lo = sigma * math.sqrt(dof / scipy.stats.chi2.ppf(0.975, dof))
    hi = sigma * math.sqrt(dof / scipy.stats.chi2.ppf(0.025, dof))
    return lo, hi



def evidence_sentence(c: Cause, est: float, ch: str, rms_without: float, rms_with: float, z: float,
                      sigma: float, cutoff_hz: float | None = None) -> str:
    """The evidence sentence, written from the numbers it cites (the finding carries the same
    numbers in ``residual``, ``z`` and the ``force_noise`` finding): the verb follows the numbers."""
    verb = "falls" if rms_with < rms_without else "rises"
    band = f" (compared below {cutoff_hz:.3g} Hz)" if cutoff_hz is not None else ""
    return (f"{_describe(c, est)} explains the {_CHANNEL_WORDS[ch]}{band}: its RMS {verb} from "
            f"{rms_without:.4g} to {rms_with:.4g} {_CHANNEL_UNITS[ch]} when it is corrected "
            f"(z = {z:.1f}, noise level {sigma:.3g} N)")


def _alternatives_json(alts) -> list[dict]:
    """``indistinguishable_from`` entries in the report's terms (an equal offset on both forces
    is one entry per channel, as the contract names channels f1/f2)."""
    out = []
    for a, est, iv in alts:
        for tgt in (FORCE_CHANNELS if a.target == "both" else (a.target,)):
            d = a.target_json(tgt)
            d["cause"] = a.kind.name
            if est is not None:
                d["estimate"] = est
            if iv is not None:
                d["interval"] = [float(iv[0]), float(iv[1])]
            out.append(d)
    return out


def _describe(c: Cause, est: float) -> str:
    return c.kind.describe(c.target, est)


_CHANNEL_WORDS = {"moment": "enforced moment", "heave": "vertical enforced force",
                  "spring1": "front spring force residual", "spring2": "rear spring force residual",
                  "tyre1": "front tyre force residual", "tyre2": "rear tyre force residual",
                  "static": "static load at the first sample"}
_CHANNEL_UNITS = {"moment": "N m", "heave": "N", "spring1": "N", "spring2": "N", "tyre1": "N", "tyre2": "N",
                  "static": "N"}


#: the forces' 4th-difference level over the residual's low-band level above which the force
#: samples are taken to carry content up to the Nyquist frequency (for white noise both estimate
#: the same level, within a few % at the record lengths of a run)
ALIAS_RATIO = 3.0
#: below NOISE_MIN_N a low-band level is reported when the forces' 4th differences confirm it
#: (within ALIAS_RATIO) and it exceeds this [N]
NOISE_CONFIRMED_MIN_N = 0.1
#: and also when only content above this frequency [Hz] folds into the low band (fs - cutoff)
#: and no motion noise is in the band: measured on independent runs without noise
FOLD_MIN_HZ = 460.0
#: ... and when the measured motion is written with at least this many significant digits: the
#: rounding of slower motion written with fewer is a staircase whose low band is not white
#: (a van on road E at 500 Hz without force noise: 0.13 N at 9 m/s and 0.97 N at 20 m/s with
#: 6 digits, 0.34 N at 20 m/s with 7, 0.019-0.037 N with 8, 0.005-0.013 N with 9)
FINE_DIGITS = 8


def _motion_digits(run) -> int:
    """The fewest significant digits any measured motion column is written with."""
    cols = [c for c in (*MOTION_COLUMN.values(), "beta_rate") if run.has(c)]
    return min((written_digits(run[c]) for c in cols), default=16)


def _sensor_noise(prob: "_Problem") -> bool:
    """True when a measured motion column carries sensor noise beyond the rounding of its written
    digits (ALIAS_RATIO x the rounding's level): its share of the residual's low band is then only
    estimated, not known."""
    return any(v.get("sigma", 0.0) > ALIAS_RATIO * v.get("written", 0.0)
               for v in prob.motion_noise.values())


#: residual channels whose low-band levels differ by more than this ratio, and by more than
#: LEVELS_APART_Z standard errors, hold more than white force noise (measured on the 22 runs of the
#: last vehicle card whose noise estimate held: their channels agree within 1.25x)
LEVELS_APART_RATIO = 1.5
LEVELS_APART_Z = 4.0


def _levels_apart(levels: dict):
    """The lowest and highest channel of ``lowband_channel_levels`` as ``(name, level, dof)``
    where they differ beyond ``LEVELS_APART_RATIO`` and ``LEVELS_APART_Z``; else None."""
    got = sorted((v[0], nm, v[1]) for nm, v in levels.items() if v[0] > 0)
    if len(got) < 2:
        return None
    (s_lo, n_lo, d_lo), (s_hi, n_hi, d_hi) = got[0], got[-1]
    se = math.sqrt(1.0 / (2.0 * d_lo) + 1.0 / (2.0 * d_hi))
    if s_hi <= LEVELS_APART_RATIO * s_lo or math.log(s_hi / s_lo) <= LEVELS_APART_Z * se:
        return None
    return (n_lo, s_lo, d_lo), (n_hi, s_hi, d_hi)


def _channel_bound(levels: dict, sigma: float, hi: float):
    """Where the channels' low-band levels disagree (``_levels_apart``): the level to report, the
    upper end of its interval and the evidence clause; else None. White force noise gives every
    residual channel one level: where they differ, the band holds an error of the model's too (an
    independent whole car whose centre of mass sat 3.7 cm beside the centreline where heave was
    measured: its roll gave the heave channel 197 N, the moment and spring travels 2.8-4.2 N, for
    2.75 N of noise), and the lowest channel's level bounds the noise."""
    apart = _levels_apart(levels)
    if apart is None:
        return None
    (n_lo, s_lo, d_lo), (n_hi, s_hi, _) = apart
    level = sigma
    if s_lo < sigma:
        level, hi = s_lo, _chi2_sigma_interval(s_lo, d_lo)[1]
    return level, hi, (f"; but its channels do not agree ({n_hi} alone gives {s_hi:.3g} N, {n_lo} {s_lo:.3g} N), "
                       f"where white force noise gives every channel one level: the band holds an error of the "
                       f"model's besides the noise, so the smallest level, {level:.3g} N, is an upper bound")


def _shared_text(shared: tuple, hf: float) -> str:
    """The evidence clause for road content both forces share at the top of the band."""
    return (f"; the forces' 4th differences give {hf:.3g} N, and the two forces share that content "
            f"{abs(shared[0]) * 1e3:.4g} ms apart (correlation {shared[1]:.2f}, at most {shared[2]:.2f} "
            "by chance): road content both wheels meet, which sampling without an anti-aliasing filter "
            "folds into every band, so the level is an upper bound and its interval starts at 0")


def noise_level(prob: "_Problem", sel, corr_ext: dict, p_ext: dict, r: np.ndarray | None = None,
                restored=()) -> dict:
    """The force-noise level with its 95 % interval and the sentence saying where it comes from.

    Runs with a residual to compare: the low band of the residual left after the fit (see
    ``_Problem.lowband_noise``), or the forces' 4th differences where they give less (sensor noise
    on the measured motion left in the band reads as force noise in the residual). Forces only:
    the 4th differences, an upper bound. ``r``: the weighted residual of the extended model where
    it differs from the fit's (a nonlinear force refitted after the linear causes were chosen);
    default the fit's. ``restored``: the force channels whose lost samples a detection restored
    (what the restoration missed is a force error the residual keeps: the level is an upper
    bound, the smaller of the residual's and the forces' 4th differences')."""
    run = prob.pipe.run
    dynamic = len(sel.fit.r) > 2
    full = sel.sigma if r is None else math.sqrt(float(r @ r) / max(len(r) - len(sel.fit.causes), 1))
    r = sel.fit.r if r is None else r
    notes = []
    kind = "estimate"  # or "upper_bound": a level the noise cannot exceed, interval from 0
    hf, hf_lo, hf_hi = _force_hf_noise(run)
    if dynamic:
        parts = prob.lowband_parts(r, {ch: corr_ext[ch].gain for ch in FORCE_CHANNELS},
                                   prob.impulse_responses(p_ext)[0])
        sigma, with_motion, dof = prob.lowband_levels(r, parts=parts)
        lo, hi = _chi2_sigma_interval(sigma, dof)
        found = sigma > NOISE_MIN_N  # decided on the low band, before a smaller bound replaces it
        fc = lowband_cutoff(1.0 / run.dt)
        src = (f"below {fc:.3g} Hz, inside the model's bandwidth, the residual left after the "
               f"fit has the power that white force noise of {sigma:.3g} N would give it "
               f"(worth {dof:.0f} independent samples; the full-band residual corresponds "
               f"to {full:.3g} N including the comparison's own discretisation error)")
        from_lowband = not (prob.pipe.band and hf < sigma)  # else the 4th differences give less
        shared = force_top_band_shared(run)
        if not from_lowband:
            # Sensor noise on the measured motion left in the band adds to the residual's low band
            # and reads as force noise; the forces' own 4th differences do not see it. Both are
            # upper bounds: the smaller one is reported.
            lo, hi = hf_lo, hf_hi
            src = (f"the 4th differences of the forces give {hf:.3g} N; the residual's low band, "
                   f"which here also holds the sensor noise of the measured motion, gives "
                   f"{sigma:.3g} N; the smaller of these two upper bounds is reported")
            if 1.0 / run.dt - fc < FOLD_MIN_HZ:
                # content from below FOLD_MIN_HZ folds into both: no lower limit can be read
                kind = "upper_bound"
                src += (f" (at {1.0 / run.dt:.4g} Hz the forces' content near and above the "
                        f"Nyquist frequency reaches both, so its interval starts at 0)")
            elif shared is None and force_top_band_white(run):
                kind = "estimate"
                src += ("; the forces' 4th, 6th and 8th differences agree and the two forces share "
                        "nothing there, so the top of the band holds noise alone and the "
                        "4th-difference level is an estimate")
            elif shared is not None:
                kind = "upper_bound"
                src += _shared_text(shared, hf)
            else:
                # a level read from the forces' differences holds their own content there too
                kind = "upper_bound"
                src += ("; the forces' 4th, 6th and 8th differences give decreasing levels (the "
                        "forces' own content near the Nyquist frequency), so it is an upper bound "
                        "and its interval starts at 0")
            sigma = hf
        elif shared is not None and hf >= sigma / ALIAS_RATIO:
            # road content at the top of the band, in both forces: what lies above the Nyquist
            # frequency folds into the low band too (an independent run on a road of straight
            # lines read 8.6 N there for 3.4 N of noise, its 4th differences 15.9 N)
            kind, lo = "upper_bound", 0.0
            src += _shared_text(shared, hf)
        elif not found and sigma > NOISE_CONFIRMED_MIN_N and sigma / ALIAS_RATIO <= hf <= ALIAS_RATIO * sigma:
            # below the reporting floor, but the forces' own 4th differences, an estimate from the
            # other end of the band that shares nothing with the residual, give the same level:
            # white noise on the samples, not the comparison's floor
            found = True
            src += (f"; the forces' 4th differences give {hf:.3g} N, the same level from the top of "
                    f"the band")
        elif (not found and sigma > NOISE_CONFIRMED_MIN_N and not _sensor_noise(prob)
              and 1.0 / run.dt - fc >= FOLD_MIN_HZ and _motion_digits(run) >= FINE_DIGITS):
            # below the reporting floor, but sampled fast enough that what folds into the low
            # band comes from above FOLD_MIN_HZ, where the force content of the independent
            # tuning runs without noise left <= 0.058 N in the low band (docs/diagnosis.md,
            # "Noise level"), and the measured motion carries no noise beyond its written digits
            found = True
            src += (f"; sampled at {1.0 / run.dt:.4g} Hz, only content above {1.0 / run.dt - fc:.4g} "
                    f"Hz folds into this band, which leaves no measurable level on runs without noise")
        elif hf > ALIAS_RATIO * sigma:
            kind = "upper_bound"
            # The force samples carry content up to the Nyquist frequency: without an
            # anti-aliasing filter, content above it folds into the low band as an error on the
            # samples that no model tells from noise (measured on an independent noise-free 250 Hz
            # run: 1.04 N here, 0.001 N for the same run sampled at 1000 Hz and anti-aliased down
            # to 250 Hz; benchmarks/validation/aliasing_floor.py). The level is then an upper
            # bound, and its interval reaches down to zero.
            lo = 0.0
            src += (f"; the forces' 4th differences give {hf:.3g} N, "
                    + (f"{hf / sigma:.3g}x this" if sigma > 0 else "far more")
                    + ": they carry content up to the Nyquist frequency, which sampling without "
                    "an anti-aliasing filter folds into the low band, so this level is an upper bound")
    else:
        from_lowband = False
        sigma, hi = hf, hf_hi
        kind = "upper_bound"  # see src
        found = sigma > NOISE_MIN_N
        src = (f"no pitch, heave or spring travel to compare with: the 4th differences of the "
               f"forces give {sigma:.3g} N, an upper bound (the forces' own content near the "
               f"Nyquist frequency counts as noise here)")
        notes.append("The run has neither beta, z3 nor s1/s2: only the static load and the force "
                     "noise can be checked.")
    if dynamic and from_lowband and _sensor_noise(prob):
        # the sensor noise's share of the low band is estimated from the top band, and the
        # estimate can be off by 2x where slow motion is written with few digits (see
        # _Problem._lowband_channels): taking out too much leaves too little force noise. The
        # level with the sensor noise left in bounds it from above, also where the estimate took
        # out all of the band's power (then the band cannot see the force noise, and only this
        # level says how much it could hide: a detection limit, not the comparison's floor)
        raw_hi = _chi2_sigma_interval(with_motion, dof)[1]
        if raw_hi > hi:
            hi = raw_hi
            src += (f"; with the sensor noise of the measured motion left in, the low band gives "
                    f"{with_motion:.3g} N, the upper end of the interval")
    level = sigma  # the level the finding reports
    if dynamic and from_lowband and kind == "estimate" and found:  # (a level too small to report is a bound already)
        bound = _channel_bound(prob.lowband_channel_levels(parts), sigma, hi)
        if bound is not None:
            kind = "upper_bound"
            level, hi, text = bound
            src += text
    # the method component (the fitted noise response is only as right as the fitted model),
    # added in quadrature to each side; an upper bound keeps its interval from zero
    m = FORCE_NOISE.method_half(level)
    hi = level + math.hypot(hi - level, m)
    if kind == "upper_bound":
        lo = 0.0
    elif lo > 0.0:
        lo = max(sigma - math.hypot(sigma - lo, m), 0.0)
    if restored:  # what a restoration of lost samples missed is a force error the residual keeps
        src += (f"; what the restoration of {' and '.join(restored)}'s lost samples missed counts in it, "
                f"so the level is an upper bound")
        hf_bound = hf + math.hypot(hf_hi - hf, FORCE_NOISE.method_half(hf))  # with its method part
        if found and hf_bound < hi:
            # the forces' 4th differences (a robust level over the whole record, which the few
            # restored samples hardly move) are an upper bound too: the smaller one is reported
            src += (f"; the forces' 4th differences give {hf:.3g} N, which the restored samples hardly "
                    f"move: the smaller upper bound is reported")
            sigma, hi = hf, hf_bound
            level = sigma
        kind, lo = "upper_bound", 0.0
    # a level too small to report still bounds the noise: the upper end of its interval (the band
    # holds the noise and whatever else the comparison leaves there)
    bound = max(hi, level)
    return {"sigma": sigma, "level": level, "lo": lo, "hi": hi, "found": found, "source": src,
            "notes": notes, "kind": kind, "bound": bound}


def cause_findings(prob: "_Problem", sel, model: dict, res1: "Residuals", sigma: float,
                   only=None, mode=None) -> list[dict]:
    """One finding per chosen cause (an equal offset on both forces: one per channel), with the
    evidence sentence: the RMS of the channel where the cause shows most, without the cause and
    with it (the other causes kept). ``only``: the causes to write findings for (default all).
    ``mode``: the ``Mode`` the model carries, if any: each interval carries its frequency error too
    (``_mode.mode_shift_var``)."""
    pipe = prob.pipe
    fit = sel.fit
    dynamic = len(fit.r) > 2
    names = prob.names
    main = "moment" if "moment" in names else next((nm for nm in names if nm != "static"), "static")
    var = np.maximum(np.diag(sel.cov), 0.0) if len(fit.causes) else np.zeros(0)
    extra = np.zeros(len(var))
    if mode is not None and len(var):
        extra = mode_shift_var(prob, fit, mode, settled_half(prob, fit, mode))
    se = np.sqrt(var + extra)
    findings = []
    for i, c in enumerate(fit.causes):
        if only is not None and c not in only:
            continue
        est = c.to_estimate(fit.theta[i])
        others = [j for j in range(len(fit.causes)) if j != i]
        p_o, corr_o = _apply(model, [fit.causes[j] for j in others], fit.theta[others])
        r_without = pipe.residuals(p_o, corr_o)
        ch_i = _telling_channel(prob, r_without, res1, main) if dynamic else main
        a_rms = _rms(_kept(prob, r_without, ch_i))
        b_rms = _rms(_kept(prob, res1, ch_i))
        ev = evidence_sentence(c, est, ch_i, a_rms, b_rms, abs(sel.z[i]), sigma, pipe.band.get(ch_i, (None,))[0])
        alts = sel.alternatives.get(c, [])
        if alts:
            ev += "; the data cannot tell it from " + ", ".join(
                _describe(a, e) if e is not None else a.label for a, e, _ in alts)
        targets = [c.target] if not (c.kind is FORCE_OFFSET and c.target == "both") else list(FORCE_CHANNELS)
        for tgt in targets:
            f = _finding_for(Cause(c.kind, tgt) if c.target == "both" else c, fit.theta[i], se[i],
                             _practical(c, pipe))
            f["evidence"] = ev + (f"; its interval carries the unmodelled mode's frequency error ("
                                  f"{extra[i] / max(var[i] + extra[i], 1e-300):.0%} of its variance)"
                                  if extra[i] > var[i] else "") + "."
            f["z"] = float(abs(sel.z[i]))
            f["residual"] = {"channel": ch_i, "rms_without": float(a_rms), "rms_with": float(b_rms),
                             "unit": _CHANNEL_UNITS[ch_i],
                             "band_hz": [0.0, float(pipe.band[ch_i][0]) if ch_i in pipe.band else 0.5 / pipe.h]}
            if alts:
                f["indistinguishable_from"] = _alternatives_json(alts)
            findings.append(f)
    return findings


def static_findings(res0: "Residuals", sigma: float,
                    corrections: Corrections) -> tuple[list[dict], Corrections]:
    """Forces only: the static load at the first sample is all there is to check. The findings,
    and ``corrections`` with their offsets."""
    findings = []
    st = res0.channels["static"]
    for i, ch in enumerate(FORCE_CHANNELS):
        z = float(st[i] / sigma)
        if abs(z) > 3.5:  # two tests, well beyond the 95 % level: a static load error
            findings.append({
                "cause": FORCE_OFFSET.name, "channel": ch, "estimate": float(st[i]), "unit": FORCE_OFFSET.unit,
                "interval": [float(st[i] - 1.96 * sigma), float(st[i] + 1.96 * sigma)],
                "evidence": (f"at the first sample (vehicle at rest) {ch} differs from the "
                             f"model's static load by {st[i]:+.4g} N ({abs(z):.1f} noise "
                             f"levels); with forces alone this cannot be told from a mass or "
                             f"lever-arm error of the model."),
                "z": abs(z),
                "indistinguishable_from": [{"cause": PARAMETER_ERROR.name, "parameter": k}
                                           for k in ("m3", "m1" if ch == "f1" else "m2", "a", "b", "g")]})
            corrections = corrections.with_channel(ch, offset=float(st[i]))
    return findings, corrections


def identifiability_notes(prob: "_Problem", sel) -> list[str]:
    """Notes on parameters the run cannot see, sees weakly, and on band-limited channels."""
    run = prob.pipe.run
    notes = []
    ni = sorted({c.target for c in sel.not_identifiable if c.kind is PARAMETER_ERROR})
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
    if len(sel.fit.r) > 2 and not run.has("z3"):
        notes.append("Without z3 a chassis-mass error and equal offsets on both forces differ only "
                     "in their small dynamic signature.")
    notes += sensor_noise_notes(prob)
    return notes


def residual_gain(prob: "_Problem", res0: "Residuals", res1: "Residuals", fitted: bool,
                  corrections: Corrections, dynamic: bool) -> dict:
    """RMS of the channel where the corrections show most (the enforced moment by default), before
    and after; forces only: the static load error."""
    names = prob.names
    main = "moment" if "moment" in names else next((nm for nm in names if nm != "static"), "static")
    if dynamic and fitted:
        main = _telling_channel(prob, res0, res1, main)
    metric = {"moment": "enforced_moment_rms", "heave": "vertical_enforced_force_rms",
              "spring1": "spring_force_residual_rms", "spring2": "spring_force_residual_rms",
              "tyre1": "tyre_force_residual_rms", "tyre2": "tyre_force_residual_rms",
              "static": "static_load_error_rms"}[main]
    gain = {"metric": metric, "before": _rms(_kept(prob, res0, main)), "after": _rms(_kept(prob, res1, main)),
            "unit": _CHANNEL_UNITS[main]}
    if main in prob.pipe.band:
        gain["band_hz"] = [0.0, float(prob.pipe.band[main][0])]
    if not dynamic:
        st = res0.channels["static"]
        gain["after"] = _rms([st[i] - corrections[ch].offset for i, ch in enumerate(FORCE_CHANNELS)])
    return gain


def enforced_terms(prob: "_Problem", model: dict, res0: "Residuals") -> dict:
    """The enforced moment (and vertical force) of the model over the full band, with the inertia
    term's size; where the channel is compared band-limited (sensor noise on the motion), the
    band-limited one too, labelled with its band."""
    pipe = prob.pipe
    full = pipe.with_band({}).residuals(model, NO_CORRECTION) if pipe.band else res0
    fs2 = 0.5 / pipe.h
    out = {}
    for nm, key, inertia in (("moment", "enforced_moment", lambda: model["I"] * pipe.d2beta[:prob.rows["moment"]]),
                             ("heave", "vertical_enforced_force", lambda: model["m3"] * pipe.d2z3)):
        if nm not in prob.names:
            continue
        lam = _kept(prob, full, nm)
        out[key] = {"rms": _rms(lam), "max_abs": float(np.max(np.abs(lam))),
                    "inertia_term_rms": _rms(inertia()), "band_hz": [0.0, fs2]}
        if nm in pipe.band:
            lam_b = _kept(prob, res0, nm)
            out[key + "_band_limited"] = {"rms": _rms(lam_b), "max_abs": float(np.max(np.abs(lam_b))),
                                          "band_hz": [0.0, float(pipe.band[nm][0])]}
    return out



def unconfirmed_findings(prob: "_Problem", sel0, model: dict, sigma: float,
                         held_out: list, resim_out: list, mode=None) -> list[dict]:
    """The findings of the causes a check did not confirm (the halves check of
    ``_confirm.confirm_corrections``, the re-simulation of ``_confirm.confirm_by_resimulation``). Each keeps
    its estimate and interval from the fit that selected it (all selected causes present), is
    marked ``"confirmed": false`` and says why in its evidence; the extended model leaves it out.
    No finding is ever moved to a note: the check can be wrong where the cause is right."""
    reasons = {}
    for c, est, imp in held_out:
        (a1, b1), (a2, b2) = imp["halves"]
        t1, t2 = imp["halves_t"]
        why = imp.get("failed", "halves")
        if why == "share":
            reasons[c] = (f"not confirmed, left out of the extended model: a small unexplained residual, not a "
                          f"cause: corrected, the {imp['channel']} residual's RMS goes {imp['without']:.4g} -> "
                          f"{imp['with']:.4g}, so it explains {imp['explained'] * imp['with']:.3g} "
                          f"({100 * imp['explained']:.0f} % of what is left, the comparison's noise and error "
                          f"among it); a confirmed cause explains at least {100 * imp['share_min']:.0f} % of what it "
                          "leaves")
        elif why == "out_of_sample":
            reasons[c] = (f"not confirmed, left out of the extended model: sized on every other stretch of the run "
                          f"({OOS_STRETCHES} in all), it does not improve the {imp['channel']} residual on the stretches it was "
                          f"not sized on (their drop is {imp['out_of_sample_t']:.2g} standard errors): it fits "
                          "what the stretches it was sized on hold, not a cause the whole run shows")
        elif why == "stand_in" and imp["stand_in"]["axle"] == "body":
            reasons[c] = (f"not confirmed, left out of the extended model: the run shows the body does not move as one "
                          f"rigid body (z = {imp['stand_in']['z']:.3g}, the model-form finding above), and compared below "
                          f"its resonance in two bands, the rigid model's fit does not size this cause alike in "
                          f"both, as a cause standing in for what the rigid body lacks would not")
        elif why == "stand_in":
            s = imp["stand_in"]
            reasons[c] = (f"not confirmed, left out of the extended model: the run shows the {s['axle']} suspension's "
                          f"law is not linear (the adequacy test of the fit that selected it: the residual depends on "
                          f"{s['state']}, z = {s['z']:.1f}, which no cause in its range takes) but cannot size it; "
                          f"a linear change of {c.target} is what such a law looks like on a linear model, so it "
                          f"may stand in for it")
        elif why == "margin":
            reasons[c] = (f"not confirmed, left out of the extended model: its size is within {imp['margin']:.3g} "
                          f"({c.kind.unit}) of no effect, a difference no engineer would act on")
        else:
            reasons[c] = (f"not confirmed, left out of the extended model: corrected, the {imp['channel']} "
                          f"residual's RMS goes {imp['without']:.4g} -> {imp['with']:.4g} on the whole run, "
                          f"{a1:.4g} -> {b1:.4g} on the first half and {a2:.4g} -> {b2:.4g} on the second "
                          f"(drops of {imp['whole_t']:.2g}, {t1:.2g} and {t2:.2g} standard errors): clearly higher "
                          f"on the whole run or on a half")
    for c, est, ch, before, after, without in resim_out:
        what = {"beta": "pitch", "z3": "heave", "s1": "front spring travel", "s2": "rear spring travel"}[ch]
        unit = "rad" if ch == "beta" else "m"
        reasons[c] = (f"not confirmed, left out of the extended model: re-simulated force-driven in windows "
                      f"restarted from the measured motion, the {what} error is {after:.4g} {unit} with it and "
                      f"{without:.4g} {unit} without it ({before:.4g} {unit} for the model as given)")
    if not reasons:
        return []
    fit0 = sel0.fit
    p0, corr0 = _apply(model, fit0.causes, fit0.theta)
    res_all = prob.pipe.residuals(p0, corr0)
    out = cause_findings(prob, sel0, model, res_all, sigma, only=set(reasons), mode=mode)
    for f in out:
        c = next(c for c in reasons if c.kind.name == f["cause"]
                 and c.target in (f.get("channel"), f.get("parameter"), "both"))
        f["confirmed"] = False
        f["evidence"] = f["evidence"].rstrip(".") + "; " + reasons[c] + "."
    return out


def vehicle_report(run, model: dict, prob: "_Problem", prob_lin: "_Problem", sel, sel0, held_out: list,
                   resim_out: list, form: dict, detected, p_ext: dict, corr_ext: Corrections, res0: "Residuals",
                   res1: "Residuals", dynamic: bool, with_simulation: bool, plots_dir=None) -> dict:
    """The report of a diagnosed run (``docs/measured-data.md``), from the steps' results: the
    causes read off the forces (``detected``), the selection before (``sel0``) and after (``sel``)
    the checks with the causes they left out, the adequacy test (``form``), the extended model
    (``p_ext``, ``corr_ext``) and the residuals of the model as given and of the extended one. The
    force noise, every finding, the notes, the extended model, the gain, its re-simulation and the
    figures (with ``plots_dir``)."""
    from .._intervals import joint_intervals
    from ._detectors import with_detections
    from ._extend import resimulate
    from ._plots import write_vehicle_plots

    pipe, lin, fit = prob.pipe, prob_lin.pipe, sel.fit
    # the force noise from what the extended model leaves: where it carries a nonlinear force, that
    # force as the adequacy test refitted it last, not as it stood when the linear causes were
    # chosen (a stop's force of 7 x the spring, refitted by 0.04 %, left a residual that read as
    # 10 x the true noise)
    noise = noise_level(prob, sel, corr_ext, p_ext, None if form["extra"] is None else prob.weighted(res1),
                        restored=[d.channel for d, _ in detected if d.restores])
    sigma = noise["sigma"]
    notes = list(noise["notes"])

    # findings: the confirmed causes (in the extended model), then those a check did not confirm
    corrections = corr_ext
    mode = form.get("mode")  # (Mode, its finding) or None
    carried = None if mode is None else mode[0]
    findings = cause_findings(prob, sel, model, res1, sigma, mode=carried)
    for f in findings:
        f["confirmed"] = True
    if form.get("held_body"):  # kept by the checks, sized as they left them, on a body that is not rigid
        findings += unconfirmed_findings(prob, form["held_body"][0], model, sigma, form["held_body"][1], [], carried)
    findings += unconfirmed_findings(prob, sel0, model, sigma, held_out, resim_out, carried)
    if not dynamic and sigma > 0:
        static, corrections = static_findings(res0, sigma, corrections)
        findings += static
    src = noise["source"]
    if noise["found"]:
        findings.append(FORCE_NOISE.finding(noise["level"], noise["lo"], noise["hi"], noise["kind"],
                                            src[0].upper() + src[1:] + "."))
    elif sigma >= NOISE_CONFIRMED_MIN_N:
        # too small to report as a level, above the comparison's own floor: never silence, a bound
        b = noise["bound"]
        findings.append(FORCE_NOISE.finding(noise["level"], 0.0, b, "upper_bound", (
            f"Too small to measure, at most {b:.3g} N: {src} (below the {NOISE_MIN_N:g} N a level is "
            f"reported at); the bound is the upper end of that level's 95 % interval.")))
    # below the comparison's own floor: still a statement, the floor as the bound (after the joint
    # widening, which it does not take part in: the floor is no statistical interval)
    b = max(noise["bound"], NOISE_CONFIRMED_MIN_N)
    floor_text = (f"At most {b:.3g} N, the comparison's own floor: {src}; a force noise below "
                  f"{NOISE_CONFIRMED_MIN_N:g} N cannot be told from the comparison's own error.")
    if noise["bound"] > NOISE_CONFIRMED_MIN_N:  # the band's own detection limit, above the floor
        floor_text = (f"At most {b:.3g} N, the largest force noise the comparison could have missed: "
                      f"{src}; below {NOISE_CONFIRMED_MIN_N:g} N a level cannot be told from the "
                      f"comparison's own error.")
    floor_bound = None if (noise["found"] or sigma >= NOISE_CONFIRMED_MIN_N) else FORCE_NOISE.finding(
        noise["level"], 0.0, b, "upper_bound", floor_text)
    findings = ([] if mode is None else [mode[1]]) + [{**d.finding(det), "confirmed": True} for d, det in detected] \
        + form["findings"] + findings
    findings = _stand_ins(findings, form.get("unseen") or [])
    # logger faults (found by the reader before anything was fitted; the run is their sound part)
    # lead the list: every other finding holds for the sound part only
    faults = (getattr(run, "time_base", None) or {}).get("logger_faults") or []
    findings = [{"cause": "channel_fault", "channel": f["channel"], "kind": f["kind"], "span_s": f["span_s"],
                 "estimate": float(f["span_s"][1] - f["span_s"][0]), "unit": "s", "interval": None,
                 "evidence": f["evidence"] + "; the run is analysed without it"} for f in faults] + findings
    findings = joint_intervals(findings)
    if not findings:
        findings.append({"cause": "none", "evidence": (
            "no systematic cause passes the test and " + noise["source"] +
            ", indistinguishable from the numerical floor of the comparison.")})
    if floor_bound is not None:
        findings.append(floor_bound)
    notes += identifiability_notes(prob, sel) + form["notes"]

    # extended model and gain
    params_ext = {k: float(p_ext[k]) for k in MODEL_KEYS}
    gain = residual_gain(prob, res0, res1, bool(fit.causes) or form["extra"] is not None or mode is not None,
                         corrections, dynamic)
    sim_err = enforced_terms(prob_lin, model, res0)
    nonlinear = {k: v for d, det in detected for k, v in d.model_terms(det).items()} | form["correction"]
    mount = None if mode is None else mode[0].extended(p_ext)
    sims = {}
    if with_simulation and (run.has("beta") or run.has("z3")):
        sims, sim_err, gain = resimulate(lin, model, p_ext, corr_ext, sigma, sim_err, gain, nonlinear, mount)

    report = {
        "schema": SCHEMA,
        "kind": "vehicle",
        "simulation_error": sim_err,
        "findings": findings,
        "extended_model": {"parameters": params_ext, "corrections": with_detections(corrections, detected).to_json(),
                           **({"nonlinear": nonlinear} if nonlinear else {}),
                           **({} if mount is None else {"unmodelled_mode": mount})},
        "gain": gain,
        "run": {"file": str(run.path), "samples": run.n, "dt_s": run.dt,
                "duration_s": float(run.t[-1] - run.t[0]),
                "channels": sorted(run.channels), "residual_channels": prob.names,
                "time_base": run_block(getattr(run, "time_base", None))},
        "notes": notes,
    }
    if plots_dir is not None:
        write_vehicle_plots(plots_dir, run, model, p_ext, pipe, prob, res0, res1, sims,
                            sigma, report)
    return report


#: the linear parameter a nonlinear suspension cause of each axle looks like (front: the k3/d3
#: spring and damper over s1; rear: k4/d4): a stop or a progressive spring a stiffer spring, an
#: asymmetric damper a damper rate
_STANDS_IN = {("bump_stop", 0): "k3", ("progressive_spring", 0): "k3", ("damper_asymmetry", 0): "d3",
              ("bump_stop", 1): "k4", ("progressive_spring", 1): "k4", ("damper_asymmetry", 1): "d4"}


def _stand_ins(findings, unseen):
    """A linear parameter of an axle whose nonlinear suspension causes the run could not show may
    stand in for one of them (a stop or a progressive spring reads as a stiffer spring, an
    asymmetric damper as a damper rate): the finding says so (``may_stand_in_for``), not only the
    notes. Returns the findings with the key set (new dicts where it is)."""
    out = list(findings)
    for i, f in enumerate(findings):
        if f.get("cause") != "parameter_error":
            continue
        names = sorted({n for n, axle in unseen if _STANDS_IN.get((n, axle)) == f.get("parameter")})
        if names:
            out[i] = {**f, "may_stand_in_for": names, "evidence": f["evidence"] + (
                f" It may stand in for a {' or '.join(names)} on this axle, which the run could not show "
                f"(no spring travel measured, or too noisy): a linear change of the parameter is what such a "
                f"cause looks like without one.")}
    return out
