"""The attitude diagnosis as a pipeline of named steps over one state (:class:`AttitudeState`).

:func:`diagnose_attitude` runs, in this order:

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

Each step reads and writes named fields of the state; the report is assembled from them only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import stats

from ...io._corrections import GyroCorrection
from ...models._quaternion import (
    integrate_rates_np,
    quat_conjugate_np,
    quat_log_np,
    quat_multiply_np,
    rotation_angle_between_np,
)
from ._causes import GYRO_BIAS, GYRO_BIAS_DRIFT, GYRO_NOISE, GYRO_SCALE
from ._array import array_step
from ._consistency import consistency, still_rows
from ._realworld import (
    degenerate,
    finite_segments,
    gap_mask,
    heading_error,
    heading_only_cells,
    inconsistent_findings,
    split_spikes,
    vertical_axis,
    not_determined,
    noise_kind_step,
    residual_noise_scale,
)
from ._common import (
    BIAS_FLOOR,
    CHANNELS,
    DRIFT_FLOOR,
    DRIFT_LR,
    DRIFT_LR_GIVEN_BIAS,
    DRIFT_OFF_DEG,
    MIN_INTERVAL_ROWS,
    SCALE_FLOOR,
    Z_COLOURED,
    Z_SIGNIFICANT,
    fmt,
)
from ._gyro import (cluster_cov, convention_terms, half_rate_fit, reference_fit, reml_drift, rw_cov,
                    static_segment)
from ._noise import allan, estimate_white_noise
from ._alignment import alignment_step
from ._vibration import vibration_step
from ._report import assemble_report

__all__ = ["AttitudeState", "diagnose_attitude"]


#: a fitted sampling convention further than this from "held" (0) has the reference checked again in it
LAM_RECHECK = 0.2

#: the diagnosis takes a run split by gaps whole and analyses its segments jointly (integration
#: restarts at each segment; the reference intervals across a gap are left out)
SEGMENTS_JOINT = True


@dataclass
class AttitudeState:
    """What the steps know about one run; filled in step by step."""

    run: dict
    positions: object = None
    notes: list = field(default_factory=list)
    observed: list = field(default_factory=list)
    not_observed: list = field(default_factory=list)
    not_determined: list = field(default_factory=list)  # [{cause, channel, reason}]
    ref_spans: list = field(default_factory=list)  # reference inconsistent: [{axis, t0, t1, rate, kind}]
    still: np.ndarray | None = None  # rows where the reference says the body does not move
    held_bias: dict = field(default_factory=dict)  # channels whose bias the reference cannot see
    segments: list = field(default_factory=list)  # [i0, i1) row ranges with finite rates (between gaps)
    findings: list = field(default_factory=list)  # (finding, z)
    plots: dict = field(default_factory=dict)
    # gyro noise (gyro_noise_step)
    wn: dict | None = None
    floor: float = 0.0
    noise_found: bool = False
    sigma_axis: np.ndarray | None = None
    noise_var_rate: float = 0.0
    noise_finding: dict | None = None
    noise_findings: list = field(default_factory=list)  # further noise findings (vibration, accel_noise), after gyro_noise
    vibration: dict | None = None  # vibration_step: spans, level per axis, peaks
    alignment: dict | None = None  # alignment_step: the reference's clock offset and frame rotation
    scale_se: np.ndarray = field(default_factory=lambda: np.zeros(3))  # of the applied corrections
    bias_se: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale_floor: float = 0.0
    bias_floor: float = 0.0
    drift_floor: float = 0.0
    # the corrected gyro model, shared by the later steps
    corrections: dict = field(default_factory=dict)
    bias_path: np.ndarray | None = None
    scale: np.ndarray | None = None
    bias_source: str | None = None
    allan_series: np.ndarray | None = None
    allan_label: str | None = None
    allan: dict | None = None
    sim_err: dict = field(default_factory=dict)
    gain: dict | None = None
    n_ref: int = 0
    bias_fit: dict = field(default_factory=dict)  # channel -> (estimate, 95 % half-width), named or not

    @property
    def t(self):
        return self.run["t"]

    @property
    def dt(self):
        return self.run["dt"]

    @property
    def w(self):
        return self.run["w"]

    @property
    def n(self):
        return len(self.run["t"])


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
        s = _diagnose_state(sub, positions)
        rep = assemble_report(s)
        span = (float(sub["t"][0]), float(sub["t"][-1]))
        onboard_block(rep, sub, s.bias_fit, span)
        done.append((rep, s.plots, label, span))
    if parts is None:
        done[0][0]["run"]["events"] = run.get("events") or []
        return done[0][:2]
    return merge_parts(done, run, dropped)


def _diagnose_state(run, positions=None):
    """The pipeline on one sensor's run: the filled state."""
    s = AttitudeState(run=run, positions=positions)
    gyro_noise_step(s)
    vibration_step(s)
    q_ref = run["q_ref"]
    s.n_ref = 0 if q_ref is None else int(np.sum(np.isfinite(q_ref[:, 0])))
    if s.n_ref >= 2:
        alignment_step(s)
        reference_step(s)
    else:
        noise_kind_step(s)
        static_segment_step(s)
    if positions is not None:
        array_step(s)
    else:
        s.not_observed.append("sensor positions and rigidity (no accelerometer array)")
    if s.bias_source is None:
        s.not_observed.append("gyro bias (no reference attitude, no static segment, no accelerometer array)")
        s.not_observed.append("gyro scale and bias drift (need a reference attitude)")
    allan_step(s)
    return s


def gyro_noise_step(s):
    """White gyro noise N from the rates' high-order differences; floors for the systematic effects."""
    run, dt, w = s.run, s.dt, s.w
    s.segments = finite_segments(run)
    i0, i1 = max(s.segments, key=lambda r: r[1] - r[0])
    wn = estimate_white_noise(w[i0:i1], dt)  # on the longest segment: differences never span a gap
    var_pooled = float(np.mean(wn["var"]))
    var_se = float(np.sqrt(np.sum(np.square(wn["var_se"]))) / 3.0)
    # below this a "noise" is rounding or numerical differentiation, not a gyro: three times the
    # quantisation of the file's digits, or 1e-6 of the RMS rate (navigation-grade gyros at 1 kHz
    # are near 2e-5 rad/s per sample, far above)
    floor = max(3.0 * run["quantisation"], 1e-6 * float(np.sqrt(np.nanmean(w**2))), 1e-15)
    noise_found = wn["plateau"] and math.sqrt(var_pooled) > floor
    sigma_axis = wn["sigma"] if noise_found else np.zeros(3)
    N_hat = math.sqrt(var_pooled * dt) if noise_found else 0.0
    s.noise_var_rate = max(var_pooled * dt, (floor**2) * dt, 1e-24)  # N^2 for weights
    if noise_found:
        z95 = stats.norm.ppf(0.975)
        # the statistical half-width and the motion's possible share at the chosen order
        # (:func:`estimate_white_noise`'s ``var_method``, pooled like the variances) in quadrature
        half = math.hypot(z95 * var_se, float(np.mean(wn["var_method"])))
        lo = math.sqrt(max(var_pooled - half, 0.0) * dt)
        hi = math.sqrt((var_pooled + half) * dt)
        s.noise_finding = {
            "cause": GYRO_NOISE.name, "estimate": N_hat, "unit": GYRO_NOISE.unit, "interval": [lo, hi],
            "evidence": (
                f"order-{wn['order']} differences of the rates are white with per-sample std "
                f"{', '.join(fmt(v) for v in sigma_axis)} rad/s (wx, wy, wz) at dt={fmt(dt)} s; "
                f"N = sigma sqrt(dt) = {fmt(N_hat)} rad/sqrt(s) = {fmt(np.degrees(N_hat) * 60)} deg/sqrt(h)"
            ),
        }
    else:
        s.noise_finding = None
        s.notes.append(
            "no white gyro noise above the rounding of the file"
            if wn["plateau"] else "rate differences never became white: noise not separable from the motion"
        )
    s.wn, s.floor, s.noise_found, s.sigma_axis = wn, floor, noise_found, sigma_axis
    s.scale_floor, s.bias_floor, s.drift_floor = SCALE_FLOOR, BIAS_FLOOR, DRIFT_FLOOR
    s.corrections = {c: GyroCorrection() for c in CHANNELS}
    s.bias_path = np.zeros((s.n, 3))
    s.scale = np.ones(3)


# --------------------------------------------------------------------------- reference attitude


def reference_step(s):
    """Biases, scales and bias drift from two or more reference rows; attitude error and gain."""
    q_ref = s.run["q_ref"]
    ref_rows = np.nonzero(np.isfinite(q_ref[:, 0]))[0]
    anchors = _anchors(ref_rows)
    n_int = len(anchors) - 1
    T_ref = (anchors[-1] - anchors[0]) * s.dt
    M = int(np.clip(min(n_int // 10, T_ref / 2.0), 1, 16))  # bias segments (drift test)
    int_seg = np.minimum((np.arange(n_int) * M) // n_int, M - 1)
    # where the reference cannot be compared with the gyro: gaps, and an inconsistent reference
    valid = gap_mask(s.run, anchors)
    use, s.ref_spans, still_int = consistency(s.w, s.dt, q_ref, anchors, s.t, valid)
    s.ref_spans, spikes = split_spikes(s.ref_spans)
    use &= valid[:, None]
    if s.run.get("heading_only"):
        use, s.ref_spans = heading_only_cells(use, s.ref_spans)
        s.notes.append("the reference is a heading only: compared with the gyro about the vertical alone")
    s.still = still_rows(s.n, anchors, still_int)
    noise_kind_step(s)
    sample_var = s.sigma_axis**2
    fit0 = reference_fit(s.run, s.noise_var_rate, [int_seg] * 3, anchors, sample_var, use=use)
    if abs(fit0["lam"]) > LAM_RECHECK:
        # the gyro's samples follow another convention than a rate held over the step after each
        # (a motion-capture IMU's samples are the rate at their stamps): at a fast turn's angular
        # acceleration the held one lags by half a step and reads as jumps of the reference. The
        # check again, in the fitted convention
        use2, spans2, _ = consistency(s.w, s.dt, q_ref, anchors, s.t, valid, lam=fit0["lam"])
        use2 &= valid[:, None]
        if not np.array_equal(use2, use):
            s.notes.append(f"the reference was checked again in the gyro's fitted sampling convention (lam = "
                           f"{fmt(fit0['lam'])}): {len(s.ref_spans)} inconsistent span(s) before, {len(spans2)} after")
            use, (s.ref_spans, spikes) = use2, split_spikes(spans2)
            if s.run.get("heading_only"):
                use, s.ref_spans = heading_only_cells(use, s.ref_spans)
            fit0 = reference_fit(s.run, s.noise_var_rate, [int_seg] * 3, anchors, sample_var, use=use)
    if s.noise_finding is not None and s.noise_finding["estimate_kind"] == "upper_bound" or not s.noise_found:
        # the weights came from a noise level that may hold true motion (vibration): the residuals
        # between reference rows say how large the noise is in the band the fit uses
        r = residual_noise_scale(fit0)
        if r < 1.0:
            s.noise_var_rate *= r
            sample_var = sample_var * r
            fit0 = reference_fit(s.run, s.noise_var_rate, [int_seg] * 3, anchors, sample_var, use=use)
    r = residual_noise_scale(fit0)
    if s.vibration is not None:
        # vibration averages out between reference rows: the intervals carry what their residuals
        # show, not the white noise of the quiet spans (the per-sample level stays that noise)
        s.noise_var_rate *= r
        fit0 = reference_fit(s.run, s.noise_var_rate, [int_seg] * 3, anchors, sample_var, use=use)
        r = residual_noise_scale(fit0)
    if r > 1.5 and np.any(sample_var > 0):
        # the interval errors are r times (in variance) what white noise of the differences' level
        # gives (a low-pass filtered gyro: its differences see less noise than its integral carries):
        # the scales' errors-in-variables correction takes the level the intervals show
        sample_var = sample_var * r
        fit0 = reference_fit(s.run, s.noise_var_rate, [int_seg] * 3, anchors, sample_var, use=use)
    # a scale on a null direction of the fit (a body that does not turn about that axis: the scale
    # and the bias say the same) is held at 1, so that the bias is judged on its own
    sc0 = fit0["offs"][-1]
    hold = tuple(c for c in range(3) if sc0 + c in degenerate(fit0))
    if hold:
        fit0 = reference_fit(s.run, s.noise_var_rate, [int_seg] * 3, anchors, sample_var, use=use, hold_scale=hold)
    # with axes of the reference left out, a bias about an axis that is nearly the left-out one keeps a
    # sliver of information (the tilt's share): held at 0, and said so, instead of spreading its
    # uncertainty into the other channels
    held = {}
    if s.run.get("heading_only"):  # the gyro axes off the vertical: seen only through the tilt
        held = {c: True for c in range(3) if c != vertical_axis(q_ref)}
        fit0 = reference_fit(s.run, s.noise_var_rate, [int_seg] * 3, anchors, sample_var, use=use, hold_scale=hold,
                             hold_bias=_bias_idx(fit0, held))
    elif not use.all():
        for i in sorted(degenerate(fit0, tol=1e-3, share=0.5)):
            c = int(np.searchsorted(fit0["offs"], i, side="right") - 1)
            if c < 3:
                held[c] = True
        if held:
            fit0 = reference_fit(s.run, s.noise_var_rate, [int_seg] * 3, anchors, sample_var, use=use,
                                 hold_scale=hold, hold_bias=_bias_idx(fit0, held))
    s.held_bias = held
    s.bias_source = "reference"
    s.observed.append(f"reference attitude on {s.n_ref} rows ({n_int} intervals used)")
    if M >= 4:
        drift = _drift_tests(s, fit0, anchors, int_seg, M, use)
    else:
        drift = {}
        s.not_observed.append("gyro bias drift (reference spans too few intervals for bias segments)")
    seg_final = [int_seg if c in drift else np.zeros(n_int, int) for c in range(3)]
    fit = reference_fit(s.run, s.noise_var_rate, seg_final, anchors, sample_var, use=use, hold_scale=hold)
    if held:
        fit = reference_fit(s.run, s.noise_var_rate, seg_final, anchors, sample_var, use=use, hold_scale=hold,
                            hold_bias=_bias_idx(fit, held))
    fit["half_rate"] = half_rate_fit(s.run, s.noise_var_rate, seg_final, anchors, sample_var, use=use,
                                     hold_scale=hold)
    infl = max(1.0, fit["chi2"] / fit["dof"])
    s.findings.extend(inconsistent_findings(s.ref_spans, use))
    if spikes:
        s.notes.append(f"{len(spikes)} outlier(s) of the reference (up to {fmt(max(sp['rate'] for sp in spikes))} rad/s "
                       "off the gyro over one interval and back within a few: the reference's own noise, not a "
                       "reset) left out of the gyro fit on their axis")
    _reference_findings(s, fit, infl, drift, seg_final, anchors, M)
    if infl > 1.5:
        s.notes.append(f"reference residuals are {fmt(math.sqrt(infl))} times the gyro noise: intervals widened by that factor")
    _reference_attitude_error(s, ref_rows, fit["lam"])


def _bias_idx(fit, channels):
    return tuple(i for c in channels for i in range(fit["offs"][c], fit["offs"][c + 1]))


def _anchors(ref_rows):
    """Anchor rows: at most 3000 intervals of at least MIN_INTERVAL_ROWS rows.

    Over a few steps the interpolated step rates share samples, so the interval errors are neither
    independent nor of variance N^2 dt_i (chi2/dof 0.6 for single steps), and the scale's
    errors-in-variables correction no longer holds; from about 10 rows on both do (measured).
    """
    step = max(MIN_INTERVAL_ROWS, int(math.ceil((ref_rows[-1] - ref_rows[0]) / 3000.0)))
    grid = np.arange(ref_rows[0], ref_rows[-1], step)
    return np.unique(np.concatenate([ref_rows[np.searchsorted(ref_rows, grid)], ref_rows[-1:]]))


def _drift_tests(s, fit0, anchors, int_seg, M, use):
    """REML test of a bias random walk on the M segment biases of each channel: {channel: result}."""
    infl = max(1.0, fit0["chi2"] / fit0["dof"])
    drift = {}
    bounds_rows = np.concatenate([anchors[:-1][np.searchsorted(int_seg, np.arange(M))], [anchors[-1]]])
    bounds = (bounds_rows - 0) * s.dt  # time since the first row
    S_rw = rw_cov(bounds)
    bad = degenerate(fit0)
    for c in range(3):
        sl = slice(fit0["offs"][c], fit0["offs"][c + 1])
        if any(i in bad for i in range(sl.start, sl.stop)):
            continue  # a segment bias the reference cannot determine: no drift test
        b = fit0["theta"][sl]
        V = fit0["cov"][sl, sl] * infl
        d = reml_drift(b, V, S_rw)
        # a constant bias that is significant may be the mean of a wandering one: then the
        # choice is between two models of the same size and a lower threshold applies
        Vi = np.linalg.pinv(V)
        one = np.ones(len(b))
        z_const = abs(one @ Vi @ b) / math.sqrt(max(one @ Vi @ one, 1e-300))
        thr = DRIFT_LR_GIVEN_BIAS if z_const > Z_SIGNIFICANT else DRIFT_LR
        d["z_const"] = float(z_const)
        if d["lr"] > thr and d["K"] > s.drift_floor:
            drift[c] = d
    return drift


def _reference_findings(s, fit, infl, drift, seg_final, anchors, M):
    """Scale, drift and bias findings per channel from the final reference fit; the corrections."""
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
    coloured = G >= 8 and (s.vibration is not None or _correlated_scores(fit))
    if coloured:
        var_int = np.diag(cov_rob) * (stats.t.ppf(0.975, G - 1) / stats.norm.ppf(0.975)) ** 2
        s.notes.append(f"the reference residuals are correlated from interval to interval: bias and scale "
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
    rows_int = np.clip(np.searchsorted(anchors, np.arange(s.n), side="right") - 1, 0, n_int - 1)
    bad = degenerate(fit)
    lost = {sp["axis"] for sp in s.ref_spans}
    for c in range(3):
        ch = CHANNELS[c]
        why_lost = (f"; the reference is inconsistent about the global {', '.join(sorted(lost))} axis and was left out there"
                    if lost else "")
        s_hat, s_se = th[sc_idx + c], math.sqrt(max(cov[sc_idx + c, sc_idx + c], 0.0))
        s_half = z95 * math.sqrt(max(var_int[sc_idx + c], 0.0))
        if c in fit["weak_scale"]:
            not_determined(s, GYRO_SCALE.name, ch, "too little rotation about it against the noise")
        elif sc_idx + c in bad or not s_se > 0 or not math.isfinite(s_hat):
            not_determined(s, GYRO_SCALE.name, ch, _degenerate_reason(fit, sc_idx + c) + why_lost)
        elif max(s_se, s_half / z95) > 0.05:
            not_determined(s, GYRO_SCALE.name, ch, f"too little rotation about it: standard error {fmt(max(s_se, s_half / z95))}")
        elif not 0.5 < s_hat < 2.0:
            not_determined(s, GYRO_SCALE.name, ch, f"the fitted ratio {fmt(s_hat)} is no gyro's scale: the reference and "
                           "the gyro disagree in a way no scale explains" + why_lost)
        elif abs(s_hat - 1) / _test_se(s_se, s_half / z95, infl, coloured) > Z_SIGNIFICANT and abs(s_hat - 1) > s.scale_floor:
            s.scale[c] = s_hat
            s.findings.append(GYRO_SCALE.finding(
                float(s_hat), [float(s_hat - s_half), float(s_hat + s_half)],
                f"rotation about {ch} between reference rows is {fmt(s_hat)} times the gyro's "
                f"(z = {fmt(abs(s_hat - 1) / s_se)})",
                abs(s_hat - 1) / s_se, channel=ch))
        if c not in fit["weak_scale"]:
            s.scale_se[c] = math.sqrt(max(var_int[sc_idx + c], 0.0))
        s.corrections[ch] = replace(s.corrections[ch], scale=float(s.scale[c]))
        sl = slice(offs[c], offs[c + 1])
        if c in drift:
            d = drift[c]
            b0, b0_se = d["beta"], math.sqrt(max(d["beta_var"], 0.0))
            b0_half = z95 * b0_se
        else:
            b0, b0_se = th[sl][0], math.sqrt(max(cov[sl, sl][0, 0], 0.0))
            b0_half = z95 * math.sqrt(max(var_int[offs[c]], 0.0))
        if c in s.held_bias:
            not_determined(s, GYRO_BIAS.name, ch, "the reference is a heading only, which does not see rotation "
                           "about this axis (held at 0 while fitting the others)" if s.run.get("heading_only") else
                           "its axis is nearly the global axis on which the reference is "
                           "inconsistent: the rest of the reference hardly sees it (held at 0 while fitting the others)")
            continue
        if offs[c] in bad or not b0_se > 0 or not math.isfinite(b0):
            not_determined(s, GYRO_BIAS.name, ch, _degenerate_reason(fit, offs[c]) + why_lost)
            continue
        if c in drift:
            s.findings.append(GYRO_BIAS_DRIFT.finding(
                d["K"], [float(v) for v in d["interval"]],
                f"the {ch} bias over {M} segments wanders like a random walk of intensity {fmt(d['K'])} "
                f"rad/s/sqrt(s) (REML likelihood ratio {fmt(d['lr'])} against a constant bias)",
                math.sqrt(max(d["lr"], 0.0)), channel=ch))
            s.bias_path[:, c] = th[sl][seg_final[c][rows_int]]
            s.corrections[ch] = replace(s.corrections[ch], bias_drift=float(d["K"]))
        s.bias_se[c] = b0_half / z95
        s.bias_fit[ch] = (float(b0), float(b0_half))
        if abs(b0) / _test_se(b0_se, b0_half / z95, infl, coloured) > (Z_COLOURED if coloured else Z_SIGNIFICANT) \
                and abs(b0) > s.bias_floor:
            s.corrections[ch] = replace(s.corrections[ch], bias=float(b0))
            if c not in drift:
                s.bias_path[:, c] = b0
            s.findings.append(GYRO_BIAS.finding(
                float(b0), [float(b0 - b0_half), float(b0 + b0_half)],
                f"integrated {ch} departs from the reference like a constant rate error of {fmt(b0)} rad/s "
                f"(z = {fmt(abs(b0) / b0_se)})" + (" at t0, under the random-walk drift" if c in drift else ""),
                abs(b0) / b0_se, channel=ch))


def _test_se(se_model, se_interval, infl, coloured=False):
    """The standard error a finding is tested with: the model's (residual-inflated) one; where the
    residuals between reference rows are more than twice the white-noise level in variance (a real
    reference, with its own errors and a gyro filtered before logging: the white model is evidently
    wrong), the interval's one (cluster-robust, integration) when larger; where they are coloured
    (``coloured``: vibration, or correlated between neighbouring intervals), the interval's one."""
    if coloured:
        return se_interval
    return max(se_model, se_interval) if infl > 2.0 else se_model


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


def _reference_attitude_error(s, ref_rows, lam):
    """Attitude error integrated from the first reference row of each segment (a gap restarts it on
    the reference), before and after the corrections."""
    t, dt, w, q_ref = s.t, s.dt, s.w, s.run["q_ref"]
    w_corr = (w - s.bias_path) / s.scale
    e_before, e_after, rows = [], [], []
    # restart at each gap and after each short span where the reference is inconsistent (a reset
    # would otherwise stay in the error for the rest of the run); rows inside such a span are not
    # compared. A span over a quarter of the run stays in (nothing would be left to compare).
    inside = np.zeros(len(t), bool)
    cuts = []
    for sp in s.ref_spans:
        if sp["t1"] - sp["t0"] > 0.25 * (t[-1] - t[0]):
            continue
        a, b = np.searchsorted(t, sp["t0"]), np.searchsorted(t, sp["t1"], side="right")
        inside[a + 1 : b] = True
        cuts.append(b)
    pieces = []
    for i0, i1 in s.segments:
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
            if s.run.get("heading_only"):  # the heading's error: the reference says nothing else
                return heading_error(qi[ok - a0], q_ref[ok])
            return rotation_angle_between_np(qi[ok - a0], q_ref[ok])

        e_before.append(err_of(w))
        e_after.append(err_of(w_corr))
        rows.append(ok)
    if not rows:  # every piece too short: no comparison left (at most single reference rows)
        s.not_observed.append("attitude error (no two reference rows in one piece between gaps and inconsistent spans)")
        return
    e_before, e_after, ok = np.concatenate(e_before), np.concatenate(e_after), np.concatenate(rows)
    a0 = ok[0]
    thr = np.radians(DRIFT_OFF_DEG)
    off = np.nonzero(e_before > thr)[0]
    s.sim_err["attitude"] = {
        "rms": float(np.sqrt(np.mean(e_before**2))), "max_abs": float(np.max(e_before)),
        "drift_off_time_s": float(t[ok[off[0]]] - t[a0]) if len(off) else None,
        "threshold_rad": float(thr), "unit": "rad",
        "what": "angle of the rotation between the gyro-integrated attitude (from the first reference row of each "
                "segment between gaps and after each span where the reference is inconsistent) and the reference",
    }
    s.gain = {"metric": "attitude_error_rms", "before": s.sim_err["attitude"]["rms"], "after": float(np.sqrt(np.mean(e_after**2))), "unit": "rad"}
    s.plots["attitude"] = (t[ok], e_before, e_after)
    n = s.n
    # error series for Allan: per-sample rate error against the reference (dense reference only)
    if s.n_ref >= 0.9 * n and n > 1000:
        dq = quat_multiply_np(quat_conjugate_np(q_ref[:-1]), q_ref[1:])
        w_ref = quat_log_np(dq) / dt
        good = np.isfinite(w_ref).all(1) & np.isfinite(w[:-1]).all(1)
        s.allan_series = (w[:-1] - s.scale * w_ref)[good]
        s.allan_label = "gyro minus reference-derived rate"


# --------------------------------------------------------------------------- no reference


def static_segment_step(s):
    """Without a reference (at most one row): biases from the longest segment standing still."""
    t, dt, w, wn = s.t, s.dt, s.w, s.wn
    if s.n_ref == 1:
        s.notes.append("one reference row only: used as the initial attitude, no bias information")
    s.not_observed.append("attitude departure (no reference attitude over more than one row)")
    # a gyro recorded in coarse steps toggles between them while standing still: its rounding
    # (a third of a step squared, the variance of a toggle) is the least spread a still window has
    sigma = np.maximum(wn["sigma"] if s.noise_found else np.zeros(3), math.sqrt(3.0) * s.run["quantisation"])
    st = static_segment(w, dt, sigma)
    if st is None:
        return
    s.bias_source = "static"
    i0, i1 = st["rows"]
    s.observed.append(f"static segment t = {fmt(t[i0])}..{fmt(t[i1 - 1])} s (assumed at rest, true rate 0)")
    z95 = stats.norm.ppf(0.975)
    for c in range(3):
        ch = CHANNELS[c]
        b = float(st["mean"][c])
        se = math.sqrt(max(wn["var"][c], s.floor**2) / st["n"])
        s.bias_se[c] = se
        s.bias_fit[ch] = (b, float(z95 * se))
        s.corrections[ch] = replace(s.corrections[ch], bias=b)
        s.bias_path[:, c] = b
        if abs(b) / se > Z_SIGNIFICANT and abs(b) > s.bias_floor:
            s.findings.append(GYRO_BIAS.finding(
                b, [float(b - z95 * se), float(b + z95 * se)],
                f"{ch} reads {fmt(b)} rad/s on average while standing still ({fmt((i1 - i0) * dt)} s, z = {fmt(abs(b) / se)})",
                abs(b) / se, channel=ch))
    s.allan_series, s.allan_label = st["data"], "rates in the static segment"
    s.not_observed.append("gyro scale (needs a reference attitude)")
    s.not_observed.append("gyro bias drift (needs a reference attitude)")
    s.sim_err["static_rate"] = {"rms": float(np.sqrt(np.mean(st["mean"] ** 2))), "unit": "rad/s"}
    s.gain = {"metric": "static_mean_rate_rms", "before": float(np.sqrt(np.mean(st["mean"] ** 2))), "after": 0.0, "unit": "rad/s"}


# --------------------------------------------------------------------------- Allan


def allan_step(s):
    """Allan deviation of the best available error series (the rates themselves as the last resort)."""
    if s.allan_series is None:
        i0, i1 = max(s.segments, key=lambda r: r[1] - r[0])
        s.allan_series = (s.w - s.bias_path)[i0:i1]
        s.allan_label = "measured rates (the motion dominates at long tau)"
    if s.allan_series.shape[0] >= 64:
        a = allan(s.allan_series, s.dt)
        a["series"] = s.allan_label
        s.allan = a
        s.plots["allan"] = a
        if s.noise_finding is not None:
            s.noise_finding["evidence"] += f"; Allan deviation of the {s.allan_label} gives N = {fmt(a['fit']['N'])}"
