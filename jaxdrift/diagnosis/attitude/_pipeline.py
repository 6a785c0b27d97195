"""The attitude diagnosis as a pipeline of named steps, each returning a frozen record
(:mod:`._records`).

:func:`diagnose_records` runs, in this order:

1. :func:`gyro_noise_step`: white gyro noise from high-order differences, and the floors below which
   an effect is the file's discretisation; :func:`._vibration.vibration_step`: vibration told apart
   from that noise (the noise then from the quiet spans, or an upper bound);
2. :func:`._alignment.alignment_step` then :func:`reference_step` (two or more reference rows): the
   reference's clock offset and frame rotation against the gyro, applied where significant; where the reference is consistent with the
   gyro (:mod:`._consistency`: ``reference_inconsistent`` spans are left out) and where it says the
   body does not move (the gyro noise is an estimate there, an upper bound otherwise:
   :func:`._realworld.noise_kind_step`), then biases, scales and bias drift from the reference
   attitude (what the fit cannot determine goes into ``not_determined``), the attitude error before
   and after the corrections; or :func:`static_segment_step` (otherwise): biases from a segment
   standing still;
3. :func:`jaxdrift.diagnosis.attitude._array.array_step` (with sensor positions): positions, gyro
   biases through the centripetal terms, accelerometer noise and rigidity;
4. :func:`allan_step`: Allan deviation of the best error series;
5. :func:`jaxdrift.diagnosis.attitude._report.assemble_report`: ranking and the report dict.

Each step is a function of the records before it and returns a new one; no step changes what it
was given. The report is assembled from the :class:`._records.Diagnosis` alone.
"""

from __future__ import annotations

import math
from dataclasses import replace
from functools import partial

import numpy as np
from scipy import stats

from ...models._quaternion import (
    integrate_rates_np,
    quat_conjugate_np,
    quat_log_np,
    quat_multiply_np,
    rotation_angle_between_np,
)
from ._causes import GYRO_BIAS, GYRO_BIAS_DRIFT, GYRO_NOISE, GYRO_SCALE, gyro_inverse
from ._array import array_step
from ._consistency import anchor_rows, consistency, rejudge, still_rows, thinned
from ._realworld import (
    degenerate,
    finite_segments,
    gap_mask,
    restarts,
    heading_error,
    heading_only_cells,
    inconsistent_findings,
    split_spikes,
    vertical_axis,
    noise_kind_step,
    residual_noise_bound,
    residual_noise_scale,
)
from ._common import (
    BIAS_FLOOR,
    CHANNELS,
    DRIFT_OFF_DEG,
    SCALE_FLOOR,
    Z_COLOURED,
    Z_SIGNIFICANT,
    fmt,
)
from ._decay import decay_profile, decay_tail, size_where_compared, without_decay
from ._gyro import (cluster_cov, convention_terms, half_rate_fit, reference_fit, reference_noise_var, gls_holds,
                    gyro_halves, test_se, static_segment)
from ._drift import drift_tests
from ._noise import allan, estimate_white_noise, white_noise_recorded
from ._alignment import alignment_step, clock_offset_left, clock_settled
from ._vibration import vibration_step
from ._records import Comparison, Diagnosis, GyroModel, GyroNoise, Said, Vibration
from ._report import assemble_report

__all__ = ["diagnose_attitude", "diagnose_records"]


#: a fitted sampling convention further than this from "held" (0) has the reference checked again in it
LAM_RECHECK = 0.2

#: the diagnosis takes a run split by gaps whole and analyses its segments jointly (integration
#: restarts at each segment; the reference intervals across a gap are left out)
SEGMENTS_JOINT = True


def diagnose_attitude(run, positions=None):
    """The analysis behind :func:`run_attitude_diagnosis` on an already validated run dict.

    A log whose primary gyro switches (:func:`._context.sensor_parts`) is diagnosed part by part,
    each part its own sensor (:func:`._context.merge_parts`); the flight controller's own bias
    estimate, where the log has one, is set beside every bias (:func:`._context.onboard_block`).

    Returns ``(report, plots)``: the report dict (docs/measured-data.md) and the series behind the
    figures (:func:`jaxdrift.diagnosis.attitude._report.write_plots`).
    """
    from ._context import merge_parts, onboard_block, sensor_parts, slice_run

    parts, dropped = sensor_parts(run)
    done = []
    for sub, label in ([(run, None)] if parts is None else [(slice_run(run, i0, i1), lb) for i0, i1, lb in parts]):
        d = diagnose_records(sub, positions)
        span = (float(sub["t"][0]), float(sub["t"][-1]))
        rep = onboard_block(assemble_report(d), sub, d.comparison.model.bias_fit, span)
        done.append((rep, d.plots, label, span))
    if parts is None:
        return {**done[0][0], "run": {**done[0][0]["run"], "events": run.get("events") or []}}, done[0][1]
    return merge_parts(done, run, dropped)


def diagnose_records(run, positions=None) -> Diagnosis:
    """The steps on one sensor's run, in order; each returns a record (:mod:`._records`)."""
    noise, said = gyro_noise_step(run)
    noise, vib, said_vib = vibration_step(run, noise)
    said = said + said_vib
    q_ref = run["q_ref"]
    n_ref = 0 if q_ref is None else int(np.sum(np.isfinite(q_ref[:, 0])))
    alignment = None
    if n_ref >= 2:
        al = alignment_step(run)
        run, alignment, said = al.run, al.alignment, said + al.said
        comp, noise = reference_step(run, n_ref, noise, vib, clock_offset_left(alignment))
    else:
        comp = static_segment_step(run, n_ref, noise)
        still = None
        if comp.still_rows is not None:  # the gyro says the body does not move there
            still = np.zeros(len(run["t"]), bool)
            still[comp.still_rows[0] : comp.still_rows[1]] = True
        noise = noise_kind_step(run, noise, still, vib, by="the gyro (the static segment)")
    said = said + comp.said
    if positions is not None:
        comp = array_step(run, positions, noise, comp)
        said = said + comp.said
    else:
        said = said + Said(not_observed=("sensor positions and rigidity (no accelerometer array)",))
    if comp.model.bias_source is None:
        said = said + Said(not_observed=(
            "gyro bias (no reference attitude, no static segment, no accelerometer array)",
            "gyro scale and bias drift (need a reference attitude)"))
    allan_, noise = allan_step(run, noise, comp)
    return Diagnosis(run=run, positions=positions, n_ref=n_ref, noise=noise, vibration=vib, alignment=alignment,
                     comparison=comp, allan=allan_, said=said)


def gyro_noise_step(run) -> tuple[GyroNoise, Said]:
    """White gyro noise N from the rates' high-order differences; the floor below which a level is
    the file's rounding."""
    dt, w = run["dt"], run["w"]
    segments = tuple(finite_segments(run))
    i0, i1 = max(segments, key=lambda r: r[1] - r[0])
    # on the longest segment (differences never span a gap), the rates as recorded for the level
    # (:func:`._noise.recorded_rates`); the per-sample spread of the grid's rates, which the fits
    # regress on, from the grid
    wn = white_noise_recorded(run, i0, i1)
    wn_grid = estimate_white_noise(w[i0:i1], dt) if run.get("w_recorded") is not None else wn
    var_pooled = float(np.mean(wn["var"]))
    var_se = float(np.sqrt(np.sum(np.square(wn["var_se"]))) / 3.0)
    # below this a "noise" is rounding or numerical differentiation, not a gyro: three times the
    # quantisation of the file's digits, or 1e-6 of the RMS rate (navigation-grade gyros at 1 kHz
    # are near 2e-5 rad/s per sample, far above)
    floor = max(3.0 * run["quantisation"], 1e-6 * float(np.sqrt(np.nanmean(w**2))), 1e-15)
    noise_found = wn["plateau"] and math.sqrt(var_pooled) > floor
    grid_found = wn_grid["plateau"] and math.sqrt(float(np.mean(wn_grid["var"]))) > floor
    sigma_axis = wn_grid["sigma"] if noise_found and grid_found else np.zeros(3)
    N_hat = math.sqrt(var_pooled * dt) if noise_found else 0.0
    var_rate = max(var_pooled * dt, (floor**2) * dt, 1e-24)  # N^2 for weights
    notes = ()
    if noise_found:
        z95 = stats.norm.ppf(0.975)
        # the statistical half-width and the motion's possible share at the chosen order
        # (:func:`._noise.estimate_white_noise`'s ``var_method``, pooled like the variances) in quadrature
        half = math.hypot(z95 * var_se, float(np.mean(wn["var_method"])))
        lo = math.sqrt(max(var_pooled - half, 0.0) * dt)
        hi = math.sqrt((var_pooled + half) * dt)
        finding = {
            "cause": GYRO_NOISE.name, "estimate": N_hat, "unit": GYRO_NOISE.unit, "interval": [lo, hi],
            "evidence": (
                f"order-{wn['order']} differences of the rates are white with per-sample std "
                f"{', '.join(fmt(v) for v in wn['sigma'])} rad/s (wx, wy, wz) at dt={fmt(dt)} s; "
                f"N = sigma sqrt(dt) = {fmt(N_hat)} rad/sqrt(s) = {fmt(np.degrees(N_hat) * 60)} deg/sqrt(h)"
            ),
        }
    else:
        finding = None
        notes = ("no white gyro noise above the rounding of the file"
                 if wn["plateau"] else "rate differences never became white: noise not separable from the motion",)
    return GyroNoise(segments, wn_grid, floor, bool(noise_found), sigma_axis, var_rate, finding), Said(notes=notes)


# --------------------------------------------------------------------------- reference attitude


def reference_step(run, n_ref, noise: GyroNoise, vib: Vibration | None, offset_left=0.0) -> tuple[Comparison, GyroNoise]:
    """Biases, scales and bias drift from two or more reference rows; attitude error and gain. Also
    the gyro noise as the reference tells it (:func:`._realworld.noise_kind_step`)."""
    t, dt, w, n = run["t"], run["dt"], run["w"], len(run["t"])
    q_ref = run["q_ref"]
    notes, observed, not_observed = [], [], []
    findings = []
    ref_rows = np.nonzero(np.isfinite(q_ref[:, 0]))[0]
    anchors = anchor_rows(ref_rows, windowed=run.get("w_unmeasured") is not None)
    # where the reference cannot be compared with the gyro: gaps, and an inconsistent reference
    valid = gap_mask(run, anchors)
    use, ref_spans, still_int = consistency(w, dt, q_ref, anchors, t, valid)
    ref_spans, spikes = split_spikes(ref_spans)
    use &= valid[:, None]
    if run.get("heading_only"):
        use, ref_spans = heading_only_cells(use, ref_spans)
        notes.append("the reference is a heading only: compared with the gyro about the vertical alone")
    still = still_rows(n, anchors, still_int)
    var_rate0, noise = noise.var_rate, noise_kind_step(run, noise, still, vib)
    var_rate, sample_var, fit_ref = noise.var_rate, noise.sigma_axis**2, reference_fit
    # the reference's noise: weighed (GLS) on a settled clock where it shows, else telescoped (``thinned``)
    one = ([np.zeros(len(anchors) - 1, int)] * 3, anchors, sample_var)
    settled = clock_settled(offset_left, float(np.median(np.diff(anchors))) * dt)
    fit_w = fit_ref(run, var_rate, *one, use=use) if settled else None
    ref_var = reference_noise_var(fit_w) if settled else 0.0
    if ref_var > 0 and not gls_holds(run, var_rate, one, use, ref_var, fit_w):
        ref_var = 0.0
        notes.append("the reference's own noise is not weighed: its fit disagrees with the unweighted one (Hausman)")
    if ref_var > 0:
        fit_ref = partial(reference_fit, ref_var=ref_var)
        notes.append(f"the reference's own noise ({fmt(math.sqrt(ref_var))} rad per row, from neighbouring residuals) weighs the fit (GLS)")
    else:
        anchors, use, valid, said_thin = thinned(run, anchors, use, valid, var_rate0)
        notes += said_thin
    n_int = len(anchors) - 1
    M = int(np.clip(min(n_int // 10, (anchors[-1] - anchors[0]) * dt / 2.0), 1, 16))  # bias segments (drift test)
    int_seg = np.minimum((np.arange(n_int) * M) // n_int, M - 1)
    fit0 = fit_ref(run, var_rate, [int_seg] * 3, anchors, sample_var, use=use)
    if abs(fit0["lam"]) > LAM_RECHECK:
        # the gyro's samples follow another convention than a rate held over the step after each
        # (a motion-capture IMU's samples are the rate at their stamps): at a fast turn's angular
        # acceleration the held one lags by half a step and reads as jumps of the reference. The
        # check again, in the fitted convention
        use2, spans2, _ = consistency(w, dt, q_ref, anchors, t, valid, lam=fit0["lam"])
        use2 &= valid[:, None]
        if not np.array_equal(use2, use):
            notes.append(f"the reference was checked again in the gyro's fitted sampling convention (lam = "
                         f"{fmt(fit0['lam'])}): {len(ref_spans)} inconsistent span(s) before, {len(spans2)} after")
            use, (ref_spans, spikes) = use2, split_spikes(spans2)
            if run.get("heading_only"):
                use, ref_spans = heading_only_cells(use, ref_spans)
            fit0 = fit_ref(run, var_rate, [int_seg] * 3, anchors, sample_var, use=use)
    # the reference is judged again against the gyro as the fit corrects it (:func:`._consistency.rejudge`)
    use, ref_spans, spikes, fit0, said_again = rejudge(run, fit0, use, ref_spans, spikes, valid, int_seg, anchors,
                                                      var_rate, sample_var, LAM_RECHECK)
    notes += said_again
    if noise.finding is not None and noise.finding["estimate_kind"] == "upper_bound" or not noise.found:
        # the weights came from a noise level that may hold true motion (vibration): the residuals
        # between reference rows say how large the noise is in the band the fit uses
        r = residual_noise_scale(fit0)
        if r < 1.0:
            var_rate *= r
            sample_var = sample_var * r
            fit0 = fit_ref(run, var_rate, [int_seg] * 3, anchors, sample_var, use=use)
    r = residual_noise_scale(fit0)
    if vib is not None:
        # vibration averages out between reference rows: the intervals carry what their residuals
        # show, not the white noise of the quiet spans (the per-sample level stays that noise)
        var_rate *= r
        fit0 = fit_ref(run, var_rate, [int_seg] * 3, anchors, sample_var, use=use)
        r = residual_noise_scale(fit0)
    if r > 1.5 and np.any(sample_var > 0):
        # the interval errors are r times (in variance) what white noise of the differences' level
        # gives (a low-pass filtered gyro: its differences see less noise than its integral carries):
        # the scales' errors-in-variables correction takes the level the intervals show
        sample_var = sample_var * r
        fit0 = fit_ref(run, var_rate, [int_seg] * 3, anchors, sample_var, use=use)
    # a scale on a null direction of the fit (a body that does not turn about that axis: the scale
    # and the bias say the same) is held at 1, so that the bias is judged on its own
    sc0 = fit0["offs"][-1]
    hold = tuple(c for c in range(3) if sc0 + c in degenerate(fit0))
    if hold:
        fit0 = fit_ref(run, var_rate, [int_seg] * 3, anchors, sample_var, use=use, hold_scale=hold)
    # with axes of the reference left out, a bias about an axis that is nearly the left-out one keeps a
    # sliver of information (the tilt's share): held at 0, and said so, instead of spreading its
    # uncertainty into the other channels
    held = {}
    if run.get("heading_only"):  # the gyro axes off the vertical: seen only through the tilt
        held = {c: True for c in range(3) if c != vertical_axis(q_ref)}
        fit0 = fit_ref(run, var_rate, [int_seg] * 3, anchors, sample_var, use=use, hold_scale=hold,
                             hold_bias=_bias_idx(fit0, held))
    elif not use.all():  # judged on constant biases: a segment inside a left-out span is no axis's blindness
        fit_c = fit_ref(run, var_rate, [np.zeros(n_int, int)] * 3, anchors, sample_var, use=use, hold_scale=hold)
        for i in sorted(degenerate(fit_c, tol=1e-3, share=0.5)):
            c = int(np.searchsorted(fit_c["offs"], i, side="right") - 1)
            if c < 3:
                held[c] = True
        if held:
            fit0 = fit_ref(run, var_rate, [int_seg] * 3, anchors, sample_var, use=use,
                                 hold_scale=hold, hold_bias=_bias_idx(fit0, held))
    decay, fit_ref, fit0, fit_drift, fit_const, said_decay = _converging(run, fit_ref, fit0, ref_spans, anchors, var_rate,
                                                                         int_seg, sample_var, use, hold, held, ref_var)
    notes += said_decay
    observed.append(f"reference attitude on {n_ref} rows ({int(use.any(1).sum())} of {n_int} intervals used)")
    if M >= 4:
        drift, drift_notes = drift_tests(dt, fit_drift, anchors, int_seg, M)
        notes += drift_notes
    else:
        drift = {}
        not_observed.append("gyro bias drift (reference spans too few intervals for bias segments)")
    seg_final = [int_seg if c in drift else np.zeros(n_int, int) for c in range(3)]
    if decay and not drift:  # constant biases beside the decay: the fit its drift test was sized on
        fit = fit_const
    else:
        fit = fit_ref(run, var_rate, seg_final, anchors, sample_var, use=use, hold_scale=hold)
        if held:
            fit = fit_ref(run, var_rate, seg_final, anchors, sample_var, use=use, hold_scale=hold,
                          hold_bias=_bias_idx(fit, held))
    fit["half_rate"] = half_rate_fit(run, var_rate, seg_final, anchors, sample_var, use=use,
                                     hold_scale=hold, ref_var=ref_var, decay=decay)
    infl = max(1.0, fit["chi2"] / fit["dof"])
    fit["halves"] = gyro_halves(fit_ref, use, run, var_rate, seg_final, anchors, sample_var, hold_scale=hold) \
        if ref_var > 0 and n_int >= 40 else {}
    findings.extend(inconsistent_findings(ref_spans, use, float(t[-1] - t[0])))
    if spikes:
        notes.append(f"{len(spikes)} outlier(s) of the reference (up to {fmt(max(sp['rate'] for sp in spikes))} rad/s "
                       "off the gyro over one interval and back within a few: the reference's own noise, not a "
                       "reset) left out of the gyro fit on their axis")
    model, found, said = _reference_findings(run, fit, infl, drift, seg_final, anchors, M, vib is not None, ref_spans, held)
    findings.extend(found)
    if infl > 1.5:
        said = said + Said(notes=(f"reference residuals are {fmt(math.sqrt(infl))} times the gyro noise: intervals "
                                  "widened by that factor",))
    run_e = run if not decay else {**run, "q_ref": without_decay(run, fit["decay"], anchors[0])}
    comp = _reference_attitude_error(run_e, noise.segments, ref_spans, model, n_ref, ref_rows, fit["lam"])
    said = Said(tuple(notes), tuple(observed), tuple(not_observed)) + said + comp.said
    noise = replace(noise, var_rate=var_rate)
    if noise.finding is None and not (noise.wn or {}).get("plateau", True):  # never white: the reference bounds it
        noise = replace(noise, finding=residual_noise_bound(fit, var_rate, n_int, noise.floor * math.sqrt(dt)))
    return replace(comp, findings=tuple(findings), said=said), noise


def _converging(run, fit_ref, fit0, ref_spans, anchors, var_rate, int_seg, sample_var, use, hold, held, ref_var):
    """An estimator converging (:func:`._decay.decay_profile`, or the tail of one the consistency check
    cut the start of, :func:`._decay.decay_tail`): ``(decay or None, the fit function with it, fit0 with
    it, the fit the drift test reads, the fit with it over constant biases (None without it), notes)``. A body-frame decay is a fading bias to segment biases
    beside it: they take part of it, and what they take reads as a bias that wanders. So the drift
    test reads the segment biases of the reference with the decay, sized over constant biases, taken out."""
    t, n_int = run["t"], len(anchors) - 1
    hb = {"hold_bias": _bias_idx(fit0, held)} if held else {}
    decay, fit_d = decay_profile(fit_ref, fit0, run, anchors, var_rate, [int_seg] * 3, anchors, sample_var, use=use,
                                 hold_scale=hold, **hb)
    conv = next((sp for sp in ref_spans if sp.get("kind") == "converges"), None)
    if not decay and conv:  # the tail of the convergence the consistency check left out the start of
        decay, fit_d = decay_tail(fit_ref, (conv["tau_s"], conv["frame"]), run, var_rate, [int_seg] * 3, anchors,
                                  sample_var, use=use, hold_scale=hold, held=tuple(held), **hb)
    if not decay:
        return None, fit_ref, fit0, fit0, None, []
    rec = fit_d["decay"]
    size, i0 = size_where_compared(rec, t, anchors, use)
    where = "at its start" if i0 == 0 else f"where it is compared from ({fmt(t[anchors[i0]] - t[0])} s)"
    turn = "" if rec["turn_rad"] is None else \
        f", its frame turned by a constant {fmt(math.degrees(np.linalg.norm(rec['turn_rad'])))} deg beside it"
    note = (f"the reference converges like an estimator {fmt(math.degrees(size))} deg off {where} (its error decays "
            f"with a time constant of {fmt(rec['tau_s'])} s, in the {decay[1]} frame{turn}): the decay is fitted beside "
            "the gyro's effects")
    fit_ref = partial(fit_ref, decay=decay)
    fc = fit_ref(run, var_rate, [np.zeros(n_int, int)] * 3, anchors, sample_var, use=use, hold_scale=hold,
                 hold_bias=tuple(sorted(held)))  # one bias per channel: channel c's is parameter c
    run_c = {**run, "q_ref": without_decay(run, fc["decay"], anchors[0])}
    fit_drift = reference_fit(run_c, var_rate, [int_seg] * 3, anchors, sample_var, use=use, hold_scale=hold,
                              ref_var=ref_var, **hb)
    return decay, fit_ref, fit_d, fit_drift, fc, [note]


def _bias_idx(fit, channels):
    return tuple(i for c in channels for i in range(fit["offs"][c], fit["offs"][c + 1]))


def _reference_findings(run, fit, infl, drift, seg_final, anchors, M, vibrates, ref_spans, held):
    """Scale, drift and bias findings per channel from the final reference fit: the gyro model they
    make, the findings ``(finding, z)`` and what is said beside them."""
    n = len(run["t"])
    model = GyroModel.uncorrected(n)
    corrections, bias_path, scale = dict(model.corrections), model.bias_path.copy(), model.scale.copy()
    scale_se, bias_se, bias_fit = np.zeros(3), np.zeros(3), {}
    findings, notes, undetermined = [], [], Said()
    n_int = len(anchors) - 1
    cov = fit["cov"] * infl
    # intervals: the model covariance (inflated by the residual chi-square) or, where larger, the
    # sandwich over up to 16 consecutive blocks of intervals (errors correlated in time: a bias that
    # wanders within its segments, the discretisation); the tests keep the model covariance
    G = int(np.clip(n_int // 10, 1, 16))
    cov_rob = cluster_cov(fit, (np.arange(n_int) * G) // n_int)
    # residuals coloured by vibration, or correlated from one interval to the next (a noisy
    # reference: its error enters two neighbouring intervals with opposite signs, and a constant
    # bias sees only their telescoping sum): the block sandwich is the standard error, with the
    # t quantile of its G - 1 degrees of freedom, for the intervals and the tests alike
    coloured = G >= 8 and (vibrates or _correlated_scores(fit))
    if coloured:
        var_int = np.diag(cov_rob) * (stats.t.ppf(0.975, G - 1) / stats.norm.ppf(0.975)) ** 2
        notes.append(f"the reference residuals are correlated from interval to interval: bias and scale "
                     f"intervals from {G} blocks of intervals (cluster-robust, t with {G - 1} degrees of freedom)")
    else:
        var_int = np.maximum(np.diag(cov), np.diag(cov_rob))
    # the integration's share (:func:`half_rate_fit`): a third of the change at twice the step, as a
    # standard error in quadrature (parameters: the first bias segment and the scale of each channel)
    fh = fit["half_rate"]
    if fh is not None:
        for c in range(3):
            pairs = [(fit["offs"][c], fh["offs"][c])]
            if c not in fh["weak_scale"]:  # else the scale is held at 1 there: no comparison
                pairs.append((fit["offs"][-1] + c, fh["offs"][-1] + c))
            for i, i2 in pairs:
                var_int[i] += ((fh["theta"][i2] - fit["theta"][i]) / 3.0 / stats.norm.ppf(0.975)) ** 2
    th = fit["theta"]
    offs = fit["offs"]
    z95 = stats.norm.ppf(0.975)
    sc_idx = offs[-1]
    rows_int = np.clip(np.searchsorted(anchors, np.arange(n), side="right") - 1, 0, n_int - 1)
    bad = degenerate(fit)
    lost = {sp["axis"] for sp in ref_spans}
    for c in range(3):
        ch = CHANNELS[c]
        why_lost = (f"; the reference is inconsistent about the global {', '.join(sorted(lost))} axis and was left out there"
                    if lost else "")
        s_hat, s_se = th[sc_idx + c], math.sqrt(max(cov[sc_idx + c, sc_idx + c], 0.0))
        s_half = z95 * math.sqrt(max(var_int[sc_idx + c], 0.0))
        if c in fit["weak_scale"]:
            undetermined += Said.undetermined(GYRO_SCALE.name, ch, "too little rotation about it against the noise")
        elif sc_idx + c in bad or not s_se > 0 or not math.isfinite(s_hat):
            undetermined += Said.undetermined(GYRO_SCALE.name, ch, _degenerate_reason(fit, sc_idx + c) + why_lost)
        elif max(s_se, s_half / z95) > 0.05:
            undetermined += Said.undetermined(GYRO_SCALE.name, ch, f"too little rotation about it: standard error {fmt(max(s_se, s_half / z95))}")
        elif not 0.5 < s_hat < 2.0:
            undetermined += Said.undetermined(GYRO_SCALE.name, ch, f"the fitted ratio {fmt(s_hat)} is no gyro's scale: the reference and "
                           "the gyro disagree in a way no scale explains" + why_lost)
        elif abs(s_hat - 1) > SCALE_FLOOR and not fit["halves"].get(("scale", c), (True,))[0] and \
                abs(s_hat - 1) / test_se(s_se, s_half / z95, infl, coloured) > Z_SIGNIFICANT:
            undetermined += Said.undetermined(GYRO_SCALE.name, ch, "the run's halves, fitted apart, read {} and {}: no "
                                              "constant scale".format(*(fmt(x) for x in fit["halves"][("scale", c)][1:])))
        elif abs(s_hat - 1) / test_se(s_se, s_half / z95, infl, coloured) > Z_SIGNIFICANT and abs(s_hat - 1) > SCALE_FLOOR:
            scale[c] = s_hat
            findings.append(GYRO_SCALE.finding(
                float(s_hat), [float(s_hat - s_half), float(s_hat + s_half)],
                f"rotation about {ch} between reference rows is {fmt(s_hat)} times the gyro's "
                f"(z = {fmt(abs(s_hat - 1) / s_se)})",
                abs(s_hat - 1) / s_se, channel=ch))
        if c not in fit["weak_scale"]:
            scale_se[c] = math.sqrt(max(var_int[sc_idx + c], 0.0))
        corrections[ch] = replace(corrections[ch], scale=float(scale[c]))
        sl = slice(offs[c], offs[c + 1])
        if c in drift:
            d = drift[c]
            b0, b0_se = d["beta"], math.sqrt(max(d["beta_var"], 0.0))
            b0_half = z95 * b0_se
        else:
            b0, b0_se = th[sl][0], math.sqrt(max(cov[sl, sl][0, 0], 0.0))
            b0_half = z95 * math.sqrt(max(var_int[offs[c]], 0.0))
        if c in held:
            undetermined += Said.undetermined(GYRO_BIAS.name, ch, "the reference is a heading only, which does not see rotation "
                           "about this axis (held at 0 while fitting the others)" if run.get("heading_only") else
                           "its axis is nearly the global axis on which the reference is "
                           "inconsistent: the rest of the reference hardly sees it (held at 0 while fitting the others)")
            continue
        if (offs[c] in bad and c not in drift) or not b0_se > 0 or not math.isfinite(b0):
            undetermined += Said.undetermined(GYRO_BIAS.name, ch, _degenerate_reason(fit, offs[c]) + why_lost)
            continue
        if c in drift:
            findings.append(GYRO_BIAS_DRIFT.finding(
                d["K"], [float(v) for v in d["interval"]],
                f"the {ch} bias over {M} segments wanders like a random walk of intensity {fmt(d['K'])} "
                f"rad/s/sqrt(s) (REML likelihood ratio {fmt(d['lr'])} against a constant bias)",
                math.sqrt(max(d["lr"], 0.0)), channel=ch))
            k = np.nonzero(d["segments"])[0]  # a segment the reference did not see: its neighbours' level
            bias_path[:, c] = np.interp(np.arange(M), k, th[sl][k])[seg_final[c][rows_int]]
            corrections[ch] = replace(corrections[ch], bias_drift=float(d["K"]))
        bias_se[c] = b0_half / z95
        bias_fit[ch] = (float(b0), float(b0_half))
        bias_z = abs(b0) / test_se(b0_se, b0_half / z95, infl, coloured)
        if bias_z > (Z_COLOURED if coloured else Z_SIGNIFICANT) and abs(b0) > BIAS_FLOOR and \
                not fit["halves"].get(("bias", c), (True,))[0]:
            undetermined += Said.undetermined(GYRO_BIAS.name, ch, "the run's halves, fitted apart, read {} and {} rad/s: no "
                                              "constant bias".format(*(fmt(x) for x in fit["halves"][("bias", c)][1:])))
        elif bias_z > (Z_COLOURED if coloured else Z_SIGNIFICANT) and abs(b0) > BIAS_FLOOR:
            corrections[ch] = replace(corrections[ch], bias=float(b0))
            if c not in drift:
                bias_path[:, c] = b0
            findings.append(GYRO_BIAS.finding(
                float(b0), [float(b0 - b0_half), float(b0 + b0_half)],
                f"integrated {ch} departs from the reference like a constant rate error of {fmt(b0)} rad/s "
                f"(z = {fmt(abs(b0) / b0_se)})" + (" at t0, under the random-walk drift" if c in drift else ""),
                abs(b0) / b0_se, channel=ch))
    model = GyroModel(corrections, bias_path, scale, "reference", scale_se, bias_se, bias_fit)
    return model, findings, Said(notes=tuple(notes)) + undetermined


def _correlated_scores(fit, z=4.0):
    """True where the scores of a bias parameter are autocorrelated at lag one beyond ``z``
    standard errors (1/sqrt(n) under independence) over the intervals the fit used."""
    S = np.asarray(fit["scores"])
    for c in range(3):
        x = S[:, fit["offs"][c]]
        x = x[x != 0.0]
        if len(x) < 30:
            continue
        x = x - x.mean()
        den = float(np.dot(x, x))
        if den > 0 and abs(float(np.dot(x[1:], x[:-1])) / den) > z / np.sqrt(len(x)):
            return True
    return False


def _degenerate_reason(fit, i):
    if fit["dof"] <= 1 and not np.any(fit["scores"]):
        return "no reference interval free of gaps and inconsistencies is left to compare the gyro with"
    if not abs(fit["H"][i, i]) > 1e-300:
        return "degenerate fit: the reference intervals carry no information on it (a standard error of 0, an infinite z)"
    return ("degenerate fit: the reference intervals do not tell it apart from the other parameters (a direction "
            "without information; its standard error would be 0 and its z infinite)")


def _reference_attitude_error(run, segments, ref_spans, model, n_ref, ref_rows, lam) -> Comparison:
    """Attitude error integrated from the first reference row of each segment (a gap restarts it on
    the reference), before and after the corrections of ``model``: its comparison."""
    t, dt, w, q_ref = run["t"], run["dt"], run["w"], run["q_ref"]
    w_corr = gyro_inverse(w, model.scale, model.bias_path)
    e_before, e_after, rows = [], [], []
    inside, cuts = restarts(run, ref_spans)
    pieces = []
    for i0, i1 in segments:
        edges = sorted({i0, i1, *[c for c in cuts if i0 < c < i1]})
        pieces += list(zip(edges[:-1], edges[1:]))
    ref_rows = ref_rows[~inside[ref_rows]]
    for i0, i1 in pieces:
        ok = ref_rows[(ref_rows >= i0) & (ref_rows < i1)]
        if len(ok) < 2:
            continue
        a0 = ok[0]

        def err_of(rates):
            r_ = np.concatenate([rates[a0 : a0 + 1], rates[a0:i1], rates[i1 - 1 : i1], rates[i1 - 1 : i1]], 0)
            w0, dw = convention_terms(r_)
            step = w0 + lam * dw
            qi = integrate_rates_np(q_ref[a0], step, dt)
            if run.get("heading_only"):  # the heading's error: the reference says nothing else
                return heading_error(qi[ok - a0], q_ref[ok])
            return rotation_angle_between_np(qi[ok - a0], q_ref[ok])

        e_before.append(err_of(w))
        e_after.append(err_of(w_corr))
        rows.append(ok)
    if not rows:  # every piece too short: no comparison left (at most single reference rows)
        return Comparison(model, said=Said(not_observed=(
            "attitude error (no two reference rows in one piece between gaps and inconsistent spans)",)))
    e_before, e_after, ok = np.concatenate(e_before), np.concatenate(e_after), np.concatenate(rows)
    a0 = ok[0]
    thr = np.radians(DRIFT_OFF_DEG)
    off = np.nonzero(e_before > thr)[0]
    sim_err = {"attitude": {
        "rms": float(np.sqrt(np.mean(e_before**2))), "max_abs": float(np.max(e_before)),
        "drift_off_time_s": float(t[ok[off[0]]] - t[a0]) if len(off) else None,
        "threshold_rad": float(thr), "unit": "rad",
        "what": "angle of the rotation between the gyro-integrated attitude (from the first reference row of each "
                "segment between gaps, after each span where the reference is inconsistent and after each window "
                "missing from rates logged as window means) and the reference",
    }}
    gain = {"metric": "attitude_error_rms", "before": sim_err["attitude"]["rms"], "after": float(np.sqrt(np.mean(e_after**2))), "unit": "rad"}
    plots = {"attitude": (t[ok], e_before, e_after)}
    n = len(t)
    series, label = None, None
    # error series for Allan: per-sample rate error against the reference (dense reference only)
    if n_ref >= 0.9 * n and n > 1000:
        dq = quat_multiply_np(quat_conjugate_np(q_ref[:-1]), q_ref[1:])
        w_ref = quat_log_np(dq) / dt
        good = np.isfinite(w_ref).all(1) & np.isfinite(w[:-1]).all(1)
        series = (w[:-1] - GYRO_SCALE.forward(w_ref, model.scale))[good]  # the additive errors
        label = "gyro minus reference-derived rate"
    return Comparison(model, sim_err=sim_err, gain=gain, plots=plots, allan_series=series, allan_label=label)


# --------------------------------------------------------------------------- no reference


def static_segment_step(run, n_ref, noise: GyroNoise) -> Comparison:
    """Without a reference (at most one row): biases from the longest segment standing still."""
    t, dt, w, wn = run["t"], run["dt"], run["w"], noise.wn
    notes = ("one reference row only: used as the initial attitude, no bias information",) if n_ref == 1 else ()
    not_observed = ("attitude departure (no reference attitude over more than one row)",)
    model = GyroModel.uncorrected(len(t))
    # a gyro recorded in coarse steps toggles between them while standing still: its rounding
    # (a third of a step squared, the variance of a toggle) is the least spread a still window has
    sigma = np.maximum(wn["sigma"] if noise.found else np.zeros(3), math.sqrt(3.0) * run["quantisation"])
    st = static_segment(w, dt, sigma)
    if st is None:
        return Comparison(model, said=Said(notes=notes, not_observed=not_observed))
    i0, i1 = st["rows"]
    observed = (f"static segment t = {fmt(t[i0])}..{fmt(t[i1 - 1])} s (assumed at rest, true rate 0)",)
    z95 = stats.norm.ppf(0.975)
    corrections, bias_path, bias_se, bias_fit = dict(model.corrections), model.bias_path.copy(), np.zeros(3), {}
    findings = []
    for c in range(3):
        ch = CHANNELS[c]
        b = float(st["mean"][c])
        se = math.sqrt(max(wn["var"][c], noise.floor**2) / st["n"])
        bias_se[c] = se
        bias_fit[ch] = (b, float(z95 * se))
        corrections[ch] = replace(corrections[ch], bias=b)
        bias_path[:, c] = b
        if abs(b) / se > Z_SIGNIFICANT and abs(b) > BIAS_FLOOR:
            findings.append(GYRO_BIAS.finding(
                b, [float(b - z95 * se), float(b + z95 * se)],
                f"{ch} reads {fmt(b)} rad/s on average while standing still ({fmt((i1 - i0) * dt)} s, z = {fmt(abs(b) / se)})",
                abs(b) / se, channel=ch))
    not_observed += ("gyro scale (needs a reference attitude)", "gyro bias drift (needs a reference attitude)")
    rms = float(np.sqrt(np.mean(st["mean"] ** 2)))
    return Comparison(
        replace(model, corrections=corrections, bias_path=bias_path, bias_source="static", bias_se=bias_se,
                bias_fit=bias_fit),
        findings=tuple(findings), sim_err={"static_rate": {"rms": rms, "unit": "rad/s"}},
        gain={"metric": "static_mean_rate_rms", "before": rms, "after": 0.0, "unit": "rad/s"},
        allan_series=st["data"], allan_label="rates in the static segment",
        said=Said(notes=notes, observed=observed, not_observed=not_observed), still_rows=(int(i0), int(i1)))


# --------------------------------------------------------------------------- Allan


def allan_step(run, noise: GyroNoise, comp: Comparison) -> tuple[dict | None, GyroNoise]:
    """Allan deviation of the best available error series (the rates themselves as the last
    resort); the gyro noise finding with what it says."""
    series, label = comp.allan_series, comp.allan_label
    if series is None:
        i0, i1 = max(noise.segments, key=lambda r: r[1] - r[0])
        series = (run["w"] - comp.model.bias_path)[i0:i1]
        label = "measured rates (the motion dominates at long tau)"
    if series.shape[0] < 64:
        return None, noise
    a = {**allan(series, run["dt"]), "series": label}
    if noise.finding is not None:
        noise = replace(noise, finding={**noise.finding, "evidence": noise.finding["evidence"]
                                        + f"; Allan deviation of the {label} gives N = {fmt(a['fit']['N'])}"})
    return a, noise
