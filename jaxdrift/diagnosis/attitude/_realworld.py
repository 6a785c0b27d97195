"""What real runs need beyond the model: the gyro noise as an estimate or an upper bound, causes the
run cannot determine, gaps, and the findings of an inconsistent reference.

- :func:`noise_kind_step`: a gyro noise level is an *estimate* only where the reference says the
  body does not move (the longest still span of :mod:`._consistency`, at least
  :data:`STILL_MIN_S`); anywhere else the high-order differences may hold true motion (a flying
  vehicle's vibration is broadband up to the sampling rate) and the level is reported as an
  *upper bound* (``"estimate_kind": "upper_bound"``, interval ``[0, bound]``). Where the log says
  when the motors are off (a PX4 log's ``actuator_armed``), those rows give the estimate
  (:func:`_motors_off`). Every level is read on the rates as recorded
  (:func:`._noise.recorded_rates`).
- :func:`degenerate`: the parameters of the reference fit that its information matrix does not
  determine (a null direction): reported as not determined, never as a finding with a standard
  error of 0 and an infinite z.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import stats

from ...io._timebase import longest_run, true_runs
from ...models._quaternion import quat_to_euler_np, rotation_matrix_np
from ._causes import GYRO_NOISE, REFERENCE_INCONSISTENT
from ._common import fmt
from .._diffnoise import diff_variance, first_plateau
from ._noise import (BLOCK_MIN_BLOCKS, block_white_noise, estimate_white_noise, recorded_rates, to_grid,
                     white_noise_recorded)

__all__ = ["noise_kind_step", "degenerate", "gap_mask", "restarts", "residual_noise_scale",
           "inconsistent_findings", "residual_noise_bound", "NOISE_BOUND_MIN", "finite_segments", "split_spikes", "heading_only_cells", "vertical_axis",
           "heading_error", "STILL_MIN_S"]

STILL_MIN_S = 1.0  # s: shortest still span whose differences give a noise estimate (and 256 rows)
#: on a still span, a level over this many times the file's rounding (its RMS) is measured (the
#: rounding is then at most 44 % of the variance, and said)
ROUNDING_RATIO = 1.5


def _longest(mask):
    """(i0, i1) of the longest run of True in ``mask`` (or (0, 0))."""
    return (0, 0) if mask is None else longest_run(mask)


def _noise_interval(wn, dt):
    var = float(np.mean(wn["var"]))
    var_se = float(np.sqrt(np.sum(np.square(wn["var_se"]))) / 3.0)
    half = math.hypot(stats.norm.ppf(0.975) * var_se, float(np.mean(wn["var_method"])))
    return math.sqrt(var * dt), math.sqrt(max(var - half, 0.0) * dt), math.sqrt((var + half) * dt)


def noise_kind_step(run, noise, still, vib, by="the reference"):
    """Gyro noise from a span where the reference says the body does not move (rows ``still``),
    else an upper bound: the revised :class:`._records.GyroNoise`. Where the gyro vibrates
    (``vib``, :mod:`._vibration`) the noise was measured on its quiet spans and stays: a body held
    still by the reference may still shake. Where the log says when the motors are off
    (:func:`_motors_off`), those rows give the estimate instead of quiet spans or a bound. Then
    :func:`_below_the_filter`. ``by``: what says where the body does not move, in the evidence."""
    noise = _noise_kind(run, noise, still, vib, by)
    f = noise.finding
    if vib is None and f is not None and f.get("estimate_kind", "estimate") == "estimate":
        return _below_the_filter(run, noise, still, vib)  # measured where the body does not move
    off = _motors_off_rows(run, noise, vib)
    if off is not None:
        noise = _motors_off(run, noise, off, vib)
        if vib is not None:  # the filter's check on rows both still and with the motors off
            still = off if still is None else np.asarray(still, bool) & off
    return _below_the_filter(run, noise, still, vib)


#: motors-off rows needed for a noise estimate (a PX4 log armed soon after it starts has 0.5 s)
MOTORS_OFF_MIN_ROWS = 64
#: shortest contiguous stretch of motors-off rows that counts (its differences stay inside it)
MOTORS_OFF_MIN_RUN = 16
#: the motors-off rows are judged for shaking in pieces of at most this many rows
MOTORS_OFF_PIECE = 64


def _motors_off_rows(run, noise, vib):
    """Row mask where the log says the motors are off (a PX4 log's ``actuator_armed``), inside the
    finite segments, in pieces of :data:`MOTORS_OFF_MIN_RUN` to :data:`MOTORS_OFF_PIECE` rows. A
    disarmed vehicle may still be shaken (a bench test that never sets the flag): pieces whose
    level (order-4 differences) is over :data:`._vibration.VIBRATION_RATIO` times the quietest
    piece's are left out, and all of them where even the quietest is not that much below the
    vibration found (``vib``). None where the log does not say, or holds fewer than
    :data:`MOTORS_OFF_MIN_ROWS` such rows."""
    from ._vibration import VIBRATION_RATIO, _window_levels

    armed = run.get("armed")
    if armed is None or not len(armed["t"]):
        return None
    t = run["t"]
    k = np.clip(np.searchsorted(armed["t"], t, side="right") - 1, 0, None)
    off = ~np.asarray(armed["armed"], bool)[k]
    stretches = [(a + i0, a + i1) for a, b in noise.segments for i0, i1 in true_runs(off[a:b])]
    pieces = [(j, j1, float(np.mean(v)))
              for j, j1, v in _window_levels(run, stretches, 4, MOTORS_OFF_PIECE, MOTORS_OFF_MIN_RUN)]
    if not pieces:
        return None
    quiet = min(p[2] for p in pieces)
    if vib is not None and VIBRATION_RATIO**2 * quiet >= float(np.mean(np.square(vib.level))):
        return None  # the motors-off rows shake as much as the rest: the flag says nothing here
    mask = np.zeros(len(t), bool)
    for j, j1, lev in pieces:
        if lev <= VIBRATION_RATIO**2 * quiet:
            mask[j:j1] = True
    return mask if mask.sum() >= MOTORS_OFF_MIN_ROWS else None


def _motors_off(run, noise, off, vib):
    """The white noise measured where the motors are off (rows ``off``): an estimate that replaces
    a vibrating log's quiet-span level or an upper bound (:func:`noise_kind_step` does not ask
    where a still span gave the estimate). The differences' order is chosen on those
    rows alone (the first two orders that agree, :func:`.._diffnoise.first_plateau`); a level at the
    file's rounding, or never white there, leaves the noise as it was."""
    dt, t = run["dt"], run["t"]
    runs = true_runs(off)
    ests = []
    for k in range(1, 9):
        parts = []
        for a, b in runs:
            x, dtr = recorded_rates(run, a, b)
            if len(x) - k >= 8:
                v_, se_, n_ = diff_variance(x, k)
                parts.append((v_ * (dtr / dt), se_ * (dtr / dt), n_))
        rows = sum(p[2] for p in parts)
        if rows < MOTORS_OFF_MIN_ROWS // 2:
            break
        v = sum(p[0] * p[2] for p in parts) / rows
        se = np.sqrt(sum((p[1] * p[2]) ** 2 for p in parts)) / rows
        ests.append((k, v, se))
    if len(ests) < 2:
        return noise
    (k, v, se), plateau, _ = first_plateau(ests)
    if not plateau or math.sqrt(float(np.mean(v))) <= noise.floor:
        return noise
    wn = {"var": v, "var_se": se, "var_method": 0.0}
    N, lo, hi = _noise_interval(wn, dt)
    where = ", ".join(f"{fmt(t[a])}..{fmt(t[b - 1])} s" for a, b in runs[:4]) + (" ..." if len(runs) > 4 else "")
    sig = np.sqrt(v)
    return replace(noise, found=True, sigma_axis=noise.sigma_axis if vib is not None else sig,
                   var_rate=max(float(np.mean(v)) * dt, noise.floor**2 * dt, 1e-24), finding={
        "cause": GYRO_NOISE.name, "estimate_kind": "estimate", "estimate": N, "unit": GYRO_NOISE.unit,
        "interval": [lo, hi],
        "evidence": (
            f"measured while the motors are off (the log's armed state; {int(off.sum())} rows: t = {where}): "
            f"order-{k} differences white with per-sample std {', '.join(fmt(x) for x in sig)} rad/s "
            f"(wx, wy, wz) at dt={fmt(dt)} s; N = {fmt(N)} rad/sqrt(s) = {fmt(np.degrees(N) * 60)} deg/sqrt(h)"),
    })


#: the block means' level replaces the differences' where it is this many times higher (in std)
FILTERED_RATIO = 1.5


def _below_the_filter(run, noise, still, vib):
    """A gyro whose samples are filtered or averaged inside the sensor (PX4's ``sensor_combined``
    averages a faster gyro over each interval, after a low-pass) has less noise near the sampling
    rate than below its cutoff: high-order differences then see only what the filter lets
    through, and an angle integrates the noise below it. On the longest still span free of
    vibration, whose spectrum does not rise (:func:`_rises`), the block means' level
    (:func:`._noise.block_white_noise`) replaces the estimate where it is more than
    :data:`FILTERED_RATIO` times higher, beyond two standard errors."""
    if still is None:
        return noise
    f = noise.finding
    dt, t = run["dt"], run["t"]
    calm = np.asarray(still, bool).copy()
    for a, b in (vib.spans if vib is not None else []):
        calm &= ~((t >= a) & (t <= b))
    i0, i1 = _longest(calm)
    x, dtr = recorded_rates(run, i0, i1)
    bw = block_white_noise(x, dtr) if len(x) >= 4 * BLOCK_MIN_BLOCKS else None
    if bw is None or not bw["plateau"] or bw["m"] == 1 or _rises(x, dtr):
        return noise
    bw = to_grid(bw, dtr, dt)
    v_blk = float(np.mean(bw["var"]))
    se = float(np.sqrt(np.sum(np.square(bw["var_se"]))) / 3.0)
    # none from the differences: never white there (the filter leaves them coloured to the last order)
    v_now = float(f["estimate"]) ** 2 / dt if f is not None and f.get("estimate") else 0.0
    if v_blk < FILTERED_RATIO**2 * v_now or v_blk - 2.0 * se <= v_now or math.sqrt(v_blk) <= 3.0 * noise.floor:
        return noise
    N, lo, hi = _noise_interval({"var": bw["var"], "var_se": bw["var_se"], "var_method": 0.0}, dt)
    seen = (f"{fmt(N)} rad/sqrt(s), {fmt(N / float(f['estimate']))} times the {fmt(float(f['estimate']))} "
            f"that the differences see near the sampling rate" if v_now > 0 else
            f"{fmt(N)} rad/sqrt(s), where the differences never turn white")
    ladder = ", ".join(f"{m}: {fmt(math.sqrt(v * dtr))}" for m, v, _ in bw["ladder"])
    return replace(noise, sigma_axis=np.sqrt(bw["var"]), found=True, var_rate=max(v_blk * dt, noise.var_rate),
                   finding={
        "cause": GYRO_NOISE.name, "estimate_kind": "estimate", "estimate": N, "unit": GYRO_NOISE.unit,
        "interval": [lo, hi],
        "evidence": (
            f"the gyro's samples are filtered: while the body does not move (t = {fmt(t[i0])}..{fmt(t[i1 - 1])} s), "
            f"the means of blocks of {bw['m']} samples ({fmt(bw['m'] * dtr)} s) give N = {seen} "
            f"({fmt(np.degrees(N) * 60)} deg/sqrt(h); N by block size, samples: {ladder}); an angle "
            f"integrates the noise below the filter's cutoff"),
    })


#: a still span's spectrum (smoothed over 9 bins, above 2 Hz) that rises to this many times its
#: level at 2 Hz holds a disturbance (a phone's vibration motor, an idling rotor), not a filter's
#: shape: filtered white noise is flat below the cutoff and falls above it
RISE_RATIO = 2.5


def _rises(x, dt) -> bool:
    """Whether a still span's spectrum rises above its low end: then the block means' climb is
    that disturbance, not white noise below a filter (a narrow line, smoothed away, does not count)."""
    from scipy import signal
    from scipy.ndimage import median_filter

    f, p = signal.welch(x - x.mean(axis=0), fs=1.0 / dt, nperseg=min(256, max(len(x) // 4, 16)), axis=0)
    p = p.mean(axis=1)[f >= 2.0]
    if p.size <= 8:
        return True  # too short a span to tell: keep the differences' level
    sm = median_filter(p, size=9, mode="nearest")
    return bool(sm.max() > RISE_RATIO * sm[0])


def _noise_kind(run, noise, still, vib, by="the reference"):
    if vib is not None:
        return noise
    dt, t = run["dt"], run["t"]
    i0, i1 = _longest(still)
    why = ("no reference attitude says where the body does not move" if still is None
           else f"{by} says the body does not move for {fmt((i1 - i0) * dt)} s only (at least "
                f"{fmt(STILL_MIN_S)} s needed)")
    if i1 - i0 >= max(256, STILL_MIN_S / dt):
        wn = white_noise_recorded(run, i0, i1)
        level = math.sqrt(float(np.mean(wn["var"])))
        q = float(run.get("quantisation") or 0.0)
        # on a still span the level may be close to the file's rounding (a CAN signal's 0.25 deg/s
        # steps) and still be measured: rounding is white too, and its share is said
        thr = ROUNDING_RATIO * q if 3.0 * q >= noise.floor else noise.floor  # the floor is the rounding's
        if wn["plateau"] and level > thr:
            N, lo, hi = _noise_interval(wn, dt)
            # the per-sample spread the fits regress on: the grid's (the level: as recorded)
            sig = wn["sigma"] if run.get("w_recorded") is None else estimate_white_noise(run["w"][i0:i1], dt)["sigma"]
            share = (f"; the file's rounding ({fmt(q)} rad/s per sample) is {fmt(100 * q**2 / level**2)} % of "
                     f"that variance" if level <= noise.floor and q > 0 else "")
            return replace(noise, sigma_axis=sig, found=True,
                           var_rate=max(float(np.mean(wn["var"])) * dt, noise.floor**2 * dt, 1e-24), finding={
                "cause": GYRO_NOISE.name, "estimate_kind": "estimate", "estimate": N, "unit": GYRO_NOISE.unit,
                "interval": [lo, hi],
                "evidence": (
                    f"while {by} says the body does not move (t = {fmt(t[i0])}..{fmt(t[i1 - 1])} s), "
                    f"order-{wn['order']} differences of the rates are white with per-sample std "
                    f"{', '.join(fmt(v) for v in wn['sigma'])} rad/s (wx, wy, wz) at dt={fmt(dt)} s; "
                    f"N = sigma sqrt(dt) = {fmt(N)} rad/sqrt(s) = {fmt(np.degrees(N) * 60)} deg/sqrt(h){share}"
                ),
            })
        why = (f"while {by} says the body does not move ({fmt((i1 - i0) * dt)} s), the differences "
               + ("never turn white" if not wn["plateau"] else
                  f"are at the file's rounding ({fmt(level)} rad/s per sample, rounding {fmt(q)})"))
    f = noise.finding
    if f is None:
        return noise  # below the file's rounding, or never white (not separable from the motion: a note says so)
    hi = float(f["interval"][1])
    # the estimate stays the differences' level, as for force noise
    return replace(noise, finding={
        **f, "estimate_kind": "upper_bound", "interval": [0.0, hi],
        "evidence": (f"an upper bound, N <= {fmt(hi)} rad/sqrt(s): {why}, so the rates' high-frequency "
                     f"content may be true motion (vibration); " + f["evidence"])})


#: a bound of the gyro noise from the reference's residuals below this [rad/sqrt(s)] (0.0017 deg/sqrt(h),
#: below the best navigation-grade gyros) tells a user nothing: a run without noise reports none
NOISE_BOUND_MIN = 5e-7


def residual_noise_bound(fit, var_rate, n_int, floor=0.0):
    """Where the rates' differences never show a white noise (vibration or motion the samples
    resolve), the reference still bounds it: the intervals' residuals hold the gyro's white noise
    integrated over each interval, and besides it only what adds (the reference's own noise,
    vibration's integration error, what the fit leaves): the 95 % upper limit of the noise density
    they hold, ``var_rate chi2 / chi2_0.05(dof)``. None where the fit has no degrees of freedom, or
    where the bound is at most ``floor`` (the file's rounding, as a density) or
    :data:`NOISE_BOUND_MIN`."""
    dof = float(fit["dof"])
    if not dof >= 1 or not float(fit["chi2"]) > 0:
        return None
    N_hat = math.sqrt(var_rate * float(fit["chi2"]) / dof)
    N_up = math.sqrt(var_rate * float(fit["chi2"]) / float(stats.chi2.ppf(0.05, dof)))
    if not N_up > max(floor, NOISE_BOUND_MIN):
        return None
    return {"cause": GYRO_NOISE.name, "estimate_kind": "upper_bound", "estimate": N_hat, "unit": GYRO_NOISE.unit,
            "interval": [0.0, N_up],
            "evidence": (f"an upper bound, N <= {fmt(N_up)} rad/sqrt(s), from the residuals between the reference "
                         f"and the integrated gyro over {n_int} intervals ({fmt(N_hat)} rad/sqrt(s) if they held gyro "
                         "noise alone): the rates' differences never turn white, so the noise is not separable "
                         "from the motion sample by sample, and the residuals also hold the reference's own noise")}


def residual_noise_scale(fit):
    """chi2/dof of a reference fit: the noise in the fit's band against the weights' noise level."""
    return float(fit["chi2"]) / max(float(fit["dof"]), 1.0)


def degenerate(fit, tol=1e-10, share=0.1):
    """Indices of the fit's parameters that lie on a null direction of its information matrix (an
    eigenvalue of the normalised matrix below ``tol`` of the largest, the parameter's share of the
    direction above ``share``)."""
    H = np.asarray(fit["H"], float)
    dg = np.abs(np.diag(H))
    bad = set(int(i) for i in np.nonzero(~(dg > 1e-300))[0])
    d = np.sqrt(np.where(dg > 1e-300, dg, 1.0))
    Hn = H / np.outer(d, d)
    Hn[list(bad), :] = 0.0
    Hn[:, list(bad)] = 0.0
    ev, V = np.linalg.eigh(0.5 * (Hn + Hn.T))
    null = ev < tol * max(float(ev.max()), 1e-300)
    if null.any():
        bad |= set(int(i) for i in np.nonzero(np.any(np.abs(V[:, null]) > share, axis=1))[0])
    return bad


def finite_segments(run):
    """[i0, i1) row ranges between gaps: the time base's ``segments`` where the reader gives them,
    cut further wherever a rate is not finite (a gap's rows)."""
    fin = np.isfinite(run["w"]).all(1)
    segs = (run.get("time_base") or {}).get("segments") or [(0, len(fin))]
    out = []
    for i0, i1 in segs:
        m = np.r_[False, fin[int(i0):int(i1)], False].astype(np.int8)
        d = np.diff(m)
        out += [(int(i0) + int(a), int(i0) + int(b)) for a, b in zip(np.nonzero(d == 1)[0], np.nonzero(d == -1)[0])]
    return out or [(0, len(fin))]


def gap_mask(run, anchors):
    """Per anchor interval: False where it holds a gap (rows outside the time base's segments, or
    rates that are not finite) or a missing window of rates logged as window means
    (``run["w_unmeasured"]``): nothing was measured there to compare with the reference."""
    n = len(run["t"])
    bad_rows = ~np.isfinite(run["w"]).all(1)
    segs = (run.get("time_base") or {}).get("segments")
    ok = np.ones(len(anchors) - 1, bool)
    if segs and len(segs) > 1:
        seg_id = np.full(n, -1)
        for k, (i0, i1) in enumerate(segs):
            seg_id[int(i0):int(i1)] = k
        bad_rows |= seg_id < 0
        ok &= seg_id[anchors[:-1]] == seg_id[anchors[1:] - 1]
    cum = np.r_[0, np.cumsum(bad_rows)]
    ok &= (cum[anchors[1:]] - cum[anchors[:-1]]) == 0
    holes = run.get("w_unmeasured")
    if holes is not None and len(holes):
        # rates logged as window means with windows missing (bridged on the grid): the integral
        # across a missing window is a guess, under vibration a poor one
        t = run["t"]
        i0 = np.searchsorted(holes[:, 1], t[anchors[:-1]], side="right")  # first hole ending after the start
        ok &= ~((i0 < len(holes)) & (holes[np.minimum(i0, len(holes) - 1), 0] < t[anchors[1:]]))
    return ok


def restarts(run, ref_spans):
    """Where the attitude error restarts on the reference: (rows not compared, rows a piece starts
    at). After each short span where the reference is inconsistent (a reset would otherwise stay in
    the error for the rest of the run; rows inside it are not compared; a span over a quarter of the
    run stays in: nothing would be left to compare), and after each window missing from rates logged
    as window means (``run["w_unmeasured"]``: its rotation is not measured, and under vibration
    its bridge errs by millirad, a random walk that would swamp what a correction changes)."""
    t = run["t"]
    inside = np.zeros(len(t), bool)
    cuts = []
    for sp in ref_spans:
        if sp["t1"] - sp["t0"] > 0.25 * (t[-1] - t[0]):
            continue
        a, b = np.searchsorted(t, sp["t0"]), np.searchsorted(t, sp["t1"], side="right")
        inside[a + 1 : b] = True
        cuts.append(int(b))
    holes = run.get("w_unmeasured")
    if holes is not None and len(holes):
        cuts += [int(b) for b in np.unique(np.searchsorted(t, holes[:, 1], side="left"))]
    return inside, cuts


def inconsistent_findings(spans, use, duration=None):
    """One ``reference_inconsistent`` finding that sums up every span where the reference is
    inconsistent with the gyro (how many stretches, on which axes, how much of the run, left out of
    the gyro fit), ranked after the gyro's causes: it says what was left out, the causes say what
    is wrong with the gyro. ``spans`` holds each stretch (axis, span, kind, rate). Empty where none."""
    if not spans:
        return []
    parts = []
    for sp in spans:
        if sp["kind"] == "jumps":
            parts.append(f"jumps about {sp['axis']} at t = {fmt(sp['t0'])}..{fmt(sp['t1'])} s ({fmt(sp['rate'])} rad/s "
                         "over one interval: a reset)")
        elif sp["kind"] == "converges":
            parts.append(f"converges about the {sp['frame']} {sp['axis']} axis over t = {fmt(sp['t0'])}..{fmt(sp['t1'])} s "
                         f"(an error of {fmt(math.degrees(sp['error_rad']))} deg decaying with a time constant of "
                         f"{fmt(sp['tau_s'])} s: an estimator still converging)")
        else:
            parts.append(f"turns about {sp['axis']} over t = {fmt(sp['t0'])}..{fmt(sp['t1'])} s while the gyro says "
                         f"the body is still (up to {fmt(sp['rate'])} rad/s)")
    covered = sorted((sp["t0"], sp["t1"]) for sp in spans)
    total, (a, b) = 0.0, covered[0]
    for x, y in covered[1:]:  # the union of the stretches, whatever the axes
        if x > b:
            total, a, b = total + (b - a), x, y
        else:
            b = max(b, y)
    total += b - a
    axes = sorted({sp["axis"] for sp in spans})
    share = f" ({fmt(100.0 * total / duration)} % of the run)" if duration else ""
    frame = "global " if all(sp.get("frame", "global") == "global" for sp in spans) else ""
    what = (f"the reference is inconsistent with the gyro on {len(spans)} stretch(es) about the {frame}"
            f"{', '.join(axes)} axis, {fmt(total)} s in all{share}; left out of the gyro fit there "
            f"({int((~use).sum())} interval-axis cells; an estimator still converging, a heading reset): "
            + "; ".join(parts[:5]) + ("; ..." if len(parts) > 5 else ""))
    f = {"cause": REFERENCE_INCONSISTENT.name, "axis": ",".join(axes),
         "span_s": [float(min(sp["t0"] for sp in spans)), float(max(sp["t1"] for sp in spans))],
         "estimate": float(max(sp["rate"] for sp in spans)), "unit": REFERENCE_INCONSISTENT.unit, "interval": None,
         "evidence": what, "spans": [{"axis": sp["axis"], "span_s": [sp["t0"], sp["t1"]], "rate": sp["rate"],
                                      "kind": {"jumps": "reset", "converges": "converging"}.get(
                                          sp["kind"], "turns while the gyro says still")}
                                     for sp in spans],
         "left_out_s": float(total)}
    return [(f, 0.0)]


def split_spikes(spans):
    """(spans that are findings, spikes): the reference's outliers that come back are not findings."""
    return [sp for sp in spans if sp["kind"] != "spike"], [sp for sp in spans if sp["kind"] == "spike"]


def heading_only_cells(use, spans):
    """A heading alone says nothing about the global x and y axes: their cells left out everywhere,
    and no span about them is an inconsistency of the reference."""
    use = use.copy()
    use[:, :2] = False
    return use, [sp for sp in spans if sp["axis"] == "z"]


def vertical_axis(q_ref) -> int:
    """The gyro axis nearest the vertical over the reference rows (body-to-world, scalar first)."""
    rows = np.nonzero(np.isfinite(q_ref[:, 0]))[0]
    return int(np.argmax(np.mean(np.abs(rotation_matrix_np(q_ref[rows])[:, 2, :]), axis=0)))


def heading_error(qa, qb):
    """|heading(qa) - heading(qb)| (the z-y-x yaw of body-to-world quaternions), wrapped to [0, pi]."""
    d = quat_to_euler_np(qa)[:, 2] - quat_to_euler_np(qb)[:, 2]
    return np.abs((d + np.pi) % (2.0 * np.pi) - np.pi)
