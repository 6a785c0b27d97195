"""The reference's clock and frame against the gyro's, estimated before the reference is judged.

An optical motion-capture system tracks a body frame defined by its markers, never exactly the IMU's
frame, and stamps its samples on its own clock: a rotation of a degree between the frames and a few
milliseconds between the clocks are normal. Compared as if aligned, every fast turn leaves a large
residual (at 25 rad/s, 4 ms is 0.1 rad), which the consistency check reads as an inconsistent
reference and the bias fit as noise.

:func:`alignment_step` estimates, from the reference's own rates (the rotation between consecutive
reference samples over their step, at the step's midpoint) and the gyro's:

The reference's rate over a span is its rotation over the span, compared with the gyro's rotation
over the same span (integrated as a quaternion, exact however far the body turns), so that a
reference at 1 Hz is compared with what the gyro says of the same second, not with its rate at one
instant. Spans are :data:`SPAN_S` long (or one reference step) and overlap (one starts every
1/:data:`SPAN_STRIDE` of a span): a tracker's noise of a milliradian per row is 0.07 rad/s over one
50 Hz step but 0.007 rad/s over 0.2 s, while an offset shows in each span alike.

1. the **clock offset** tau (the reference's stamps late by tau): the lag that best matches the rate
   magnitudes (the reference's rates over spans of :data:`SPAN_S`), which no frame rotation changes (a grid search over +-:data:`MAX_OFFSET_S`, or half a reference step where that is longer, at a quarter
   of the gyro's step, refined by a parabola);
2. the **frame rotation** R (gyro rate = R x reference body rate + bias): the rotation that fits the
   centred rates best in least squares (Kabsch);

each with a 95 % interval from :data:`N_BLOCKS` time blocks (or where a block holds fewer than
:data:`JACKKNIFE_BELOW` spans, the delete-one-block jackknife; the spread of the block estimates over
sqrt(blocks)). Both are applied (the reference re-stamped and turned into the gyro's frame) where
they are significant (beyond :data:`Z_APPLY` standard errors), beyond :data:`MIN_OFFSET_STEPS` of the gyro's
step or :data:`MIN_ANGLE_DEG`, and hold out of sample (:func:`_predicts`: in 8 of 10 time blocks
where the body moves, the value the other blocks found fits better than none: a reference consistent
as given is not turned); the report's ``run.reference_alignment`` says what was found and
whether it was applied. A reference that hardly turns tells neither: nothing is applied then. Where
the rotation is not determined (a body turned about one axis) but a signed permutation of the
axes fits the rates with less than half the identity's misfit (an IMU mounted with its x pointing
back), that axis convention is applied and reported (``axis_convention``).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from ...io._timebase import place_nearest
from ...models._quaternion import cumulative_quat_product_np, quat_conjugate_np, quat_exp_np, quat_log_np, quat_multiply_np
from ._common import fmt
from ._records import Alignment, Said

__all__ = ["alignment_step", "clock_settled", "clock_offset_left", "CLOCK_SETTLED_S", "OFFSET_SHARE", "MAX_OFFSET_S", "N_BLOCKS", "MIN_OFFSET_STEPS", "MIN_ANGLE_DEG", "MIN_MOTION_RAD_S"]

MAX_OFFSET_S = 0.1
#: the reference's rates are taken over spans of at least this [s]
SPAN_S = 0.2
#: ... overlapping: one starts every SPAN_STRIDE-th of a span (a span's rate noise is the reference's
#: noise over its length, while an offset shows in each span alike: long spans, many of them)
SPAN_STRIDE = 8
#: applied beyond this many standard errors (10 blocks scatter), and only where it holds out of sample
Z_APPLY = 3.0
N_BLOCKS = 10
#: an offset within half a gyro step is the gyro's sampling convention (a rate at its stamp, or held
#: over the step after it), which the reference fit takes as its own parameter: never applied
MIN_OFFSET_STEPS = 0.5
MIN_ANGLE_DEG = 0.1
#: a fitted frame rotation this close to an axis convention [deg] is reported and applied as it
CONVENTION_SNAP_DEG = 2.0
#: reference spans needed to estimate anything (three per time block: a 1 Hz reference over 80 s,
#: whose frame may be an axis convention, is aligned; the held-out check guards the rest)
MIN_SPANS = 3 * N_BLOCKS
#: a reference turning slower than this (RMS) [rad/s] tells neither clock nor frame
MIN_MOTION_RAD_S = 0.05


def _xyzw(q):
    return np.column_stack([q[:, 1:], q[:, :1]])


def _wxyz(q):
    return np.column_stack([q[:, 3:], q[:, :3]])


def _ref_rates(tq, q, span, stride=None):
    """Body rates over consecutive reference samples ``span`` apart (a motion-capture attitude
    differenced sample by sample is mostly its own noise): (start, end, w), spans without a gap. The
    rate is the span's mean (its rotation over its length): at a 1 Hz reference it is compared with
    the gyro's mean over the same span, never with the gyro at one instant."""
    med = np.median(np.diff(tq))
    a = np.arange(0, len(tq) - span, stride or span)
    b = a + span
    d = tq[b] - tq[a]
    ok = (d > 0) & (d <= (span + 0.5) * med)
    a, b, d = a[ok], b[ok], d[ok]
    return tq[a], tq[b], quat_log_np(quat_multiply_np(quat_conjugate_np(q[a]), q[b])) / d[:, None]


def _gyro_integral(t_grid, w):
    """The gyro's attitude at its samples, integrated from the rates (each step at the mean of its
    two samples' rates, as the clock offset has always been read: a sample held over a step would
    lag half a step): (times, quaternions, step rates). The rotation between any two instants is
    then exact for that model of the rates, however far the body turns between them (a reference at
    0.5 Hz is compared with the gyro's rotation over the same two seconds, not with its mean rate:
    the two differ where the axis of the turn moves)."""
    fin = np.isfinite(w).all(1)
    tg, wg = t_grid[fin], w[fin]
    ws = 0.5 * (wg[:-1] + wg[1:])
    Q = cumulative_quat_product_np(np.concatenate([[[1.0, 0.0, 0.0, 0.0]], quat_exp_np(ws * np.diff(tg)[:, None])], 0))
    return tg, Q / np.linalg.norm(Q, axis=1, keepdims=True), ws


def _gyro_at(integral, t):
    """The gyro's attitude at instants ``t`` inside its record (the step's rate carried on)."""
    tg, Q, ws = integral
    k = np.clip(np.searchsorted(tg, t, side="right") - 1, 0, len(ws) - 1)
    return quat_multiply_np(Q[k], quat_exp_np(ws[k] * (t - tg[k])[:, None]))


def _gyro_mean(integral, ta, tb):
    """The gyro's rotation over [ta, tb] as a rotation vector over the span's length (the "mean
    rate" whose frame-invariant relation to the reference's is exact), NaN where the span leaves
    the gyro's record."""
    tg = integral[0]
    out = np.full((len(ta), 3), np.nan)
    inside = (ta >= tg[0]) & (tb <= tg[-1]) & (tb > ta)
    if inside.any():
        qa, qb = _gyro_at(integral, ta[inside]), _gyro_at(integral, tb[inside])
        out[inside] = quat_log_np(quat_multiply_np(quat_conjugate_np(qa), qb)) / (tb - ta)[inside][:, None]
    return out


def _offset_cost(integral, ta, tb, nb, tau, min_spans=10):
    """Mean squared mismatch of the rate magnitudes at a clock offset ``tau``."""
    g = np.linalg.norm(_gyro_mean(integral, ta - tau, tb - tau), axis=1)
    m = np.isfinite(g)
    return float(np.mean((g[m] - nb[m]) ** 2)) if m.sum() >= min_spans else np.inf


def _offset(integral, ta, tb, wb, dt, reach=MAX_OFFSET_S):
    """Clock offset minimising the rate magnitudes' mismatch, searched over +-``reach``."""
    nb = np.linalg.norm(wb, axis=1)
    taus = np.arange(-reach, reach + 1e-12, max(dt / 4.0, reach / 400.0))
    c = np.array([_offset_cost(integral, ta, tb, nb, x) for x in taus])
    k = int(np.argmin(c))
    if 0 < k < len(taus) - 1 and np.all(np.isfinite(c[k - 1 : k + 2])):
        a, b, cc = c[k - 1], c[k], c[k + 1]
        den = a - 2 * b + cc
        shift = 0.5 * (a - cc) / den if den > 0 else 0.0
        return float(taus[k] + np.clip(shift, -1, 1) * (taus[1] - taus[0]))
    return float(taus[k])


#: an axis convention is applied where it fits the rates better than the identity in every one of
#: the ``N_BLOCKS`` time blocks (a sign test: 1 chance in 2^10 for a convention that fits no better)
#: and leaves at most this share of the identity's misfit over the run
CONVENTION_SHARE = 0.9


def _signed_permutations():
    """The 24 rotations that map axes onto axes (signed permutation matrices of determinant 1)."""
    out = []
    for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
        for signs in np.ndindex(2, 2, 2):
            P = np.zeros((3, 3))
            P[np.arange(3), perm] = [1 - 2 * x for x in signs]
            if np.linalg.det(P) > 0:
                out.append(P)
    return out


def _axis_convention(wg, wb):
    """The signed permutation P (not the identity) with gyro rate = P x reference body rate that
    fits the rates better than the identity in every time block and over the run leaves at most
    ``CONVENTION_SHARE`` of its mean squared misfit; None where there is none. (A body turned about
    one axis fixes the other two axes' signs only through their small rates: the misfit falls by a
    third, not by half, but it falls everywhere.)"""
    m = np.isfinite(wg).all(1) & np.isfinite(wb).all(1)
    if m.sum() < MIN_SPANS:
        return None
    a, b = wg[m] - np.mean(wg[m], 0), wb[m] - np.mean(wb[m], 0)
    cost = lambda P, i=slice(None): float(np.mean(np.sum((a[i] - b[i] @ P.T) ** 2, 1)))  # noqa: E731
    best = min(_signed_permutations(), key=cost)
    eye = np.eye(3)
    if np.allclose(best, eye) or not cost(best) <= CONVENTION_SHARE * cost(eye):
        return None
    blocks = np.array_split(np.arange(len(a)), N_BLOCKS)
    return best if all(cost(best, i) < cost(eye, i) for i in blocks) else None


def _rotation(wg, wb):
    """R (3x3) with wg = R wb + b: the rotation that fits the rates best in least squares, the bias
    taken out by centring both (Kabsch, ``scipy Rotation.align_vectors``). Not the rotation nearest
    to the general least-squares map: that map divides by the rates' covariance, so where a body
    turns mostly about one axis the noise of the other two is magnified into a rotation (on a PX4
    flight yawing at up to 3.6 rad/s against its 20 Hz attitude: 16 degrees between two frames
    that are one, where this fit gives 0.2)."""
    m = np.isfinite(wg).all(1) & np.isfinite(wb).all(1)
    a, b = wg[m] - np.mean(wg[m], 0), wb[m] - np.mean(wb[m], 0)
    with warnings.catch_warnings():
        # a body turned about one axis does not fix the rotation (scipy warns): the time blocks'
        # spread then says it is not determined, and it is not applied
        warnings.simplefilter("ignore", UserWarning)
        rot, _ = Rotation.align_vectors(a, b)
    return rot.as_matrix()


#: an alignment holds out of sample where, in at least this share of the time blocks that tell
#: anything (a block of a body standing still fits as well with it as without), the value the other
#: blocks found fits better than none, and the blocks' misfits summed fall with it
HOLD_SHARE = 0.8
#: ... and at least this many blocks tell
MIN_TELLING_BLOCKS = 5


def _predicts(with_it, without) -> bool:
    """The held-out rule over the blocks' misfits with the alignment and without it: a sign test
    (8 of 10 blocks better: 5 % for an alignment that tells nothing, on top of its significance)."""
    a, b = np.asarray(with_it, float), np.asarray(without, float)
    tell = np.abs(a - b) > 1e-9 * np.maximum(np.abs(b), 1e-300)
    if tell.sum() < MIN_TELLING_BLOCKS:
        return False
    return bool(np.mean(a[tell] < b[tell]) >= HOLD_SHARE and a.sum() < b.sum())


def _offset_holds_out(integral, ta, tb, wb, taus, blocks) -> bool:
    """A clock offset is applied only where it predicts (:func:`_predicts`): in a block, the offset
    the other blocks found against no offset (as at a 1 Hz reference on a slow body, it tells
    nothing)."""
    nb = np.linalg.norm(wb, axis=1)
    with_it, without = [], []
    for i, b in enumerate(blocks):
        other = float(np.mean(np.delete(taus, i)))
        with_it.append(_offset_cost(integral, ta[b], tb[b], nb[b], other, 1))
        without.append(_offset_cost(integral, ta[b], tb[b], nb[b], 0.0, 1))
    return _predicts(with_it, without)


def _rotation_holds_out(wg, wb, blocks) -> bool:
    """A frame rotation is applied only where it predicts (:func:`_predicts`): in a block, the
    rotation fitted on the other blocks against the frames as given. A reference consistent as
    given is not turned (a fitted rotation always beats the identity on the data it was fitted
    to, by the noise it absorbs, but not on data it was not)."""
    m = np.isfinite(wg).all(1) & np.isfinite(wb).all(1)
    with_it, without = [], []
    for i, b in enumerate(blocks):
        rest = np.concatenate([x for j, x in enumerate(blocks) if j != i])
        rest, b = rest[m[rest]], b[m[b]]
        if len(b) < 3 or len(rest) < 10:
            return False
        R = _rotation(wg[rest], wb[rest])
        a, c = wg[b] - np.mean(wg[b], 0), wb[b] - np.mean(wb[b], 0)
        with_it.append(float(np.sum((a - c @ R.T) ** 2)))
        without.append(float(np.sum((a - c) ** 2)))
    return _predicts(with_it, without)


#: below this many reference spans per time block the intervals come from the jackknife (each
#: estimate without one block) rather than from each block's own estimate
JACKKNIFE_BELOW = 30


def _jackknife_se(loo) -> float:
    """The delete-one-block jackknife's standard error from the estimates without each block."""
    loo = np.asarray(loo, float)
    B = len(loo)
    return float(math.sqrt((B - 1) / B * np.sum((loo - loo.mean()) ** 2)))


def _rms_rate(wb) -> float:
    """RMS magnitude [rad/s] of the reference's rates over spans (rows of ``wb``)."""
    return float(np.sqrt(np.mean(np.sum(wb**2, 1))))


def alignment_step(run) -> Alignment:
    """Estimate (and where significant, apply) the reference's clock offset and frame rotation: the
    :class:`._records.Alignment` (``alignment`` the report's ``run.reference_alignment``; ``run`` a
    copy with the aligned reference where it was applied, else the run given)."""
    tq, q = run.get("q_ref_t"), run.get("q_ref_q")
    if tq is None:
        rows = np.nonzero(np.isfinite(run["q_ref"][:, 0]))[0]
        tq, q = run["t"][rows], run["q_ref"][rows]
    if len(tq) < MIN_SPANS + 1:
        return Alignment(None, run)
    dt, w = run["dt"], run["w"]
    # rates over at least SPAN_S (or one reference step): the reference's noise divided by the span
    span = max(1, int(round(SPAN_S / float(np.median(np.diff(tq))))))
    ta, tb, wb = _ref_rates(tq, q, span, max(1, span // SPAN_STRIDE))
    if len(ta) < MIN_SPANS or _rms_rate(wb) < MIN_MOTION_RAD_S:
        return Alignment(None, run)
    integral = _gyro_integral(run["t"], w)
    # a GNSS heading at 1 Hz lags its gyro by a few tenths of a second: the search spans half a
    # reference step at least
    reach = max(MAX_OFFSET_S, 0.5 * float(np.median(np.diff(tq))))
    tau = _offset(integral, ta, tb, wb, dt, reach)
    blocks = np.array_split(np.arange(len(ta)), N_BLOCKS)
    # the blocks' own estimates, or where a block holds too few spans for one (a reference at 1 Hz or
    # less) the jackknife's: each estimate from the other blocks (then ``_offset_holds_out`` judges
    # each block by the value found without it either way)
    sparse = len(ta) < JACKKNIFE_BELOW * N_BLOCKS
    rest = [np.concatenate([x for j, x in enumerate(blocks) if j != i]) for i in range(N_BLOCKS)]
    if sparse:
        loo = np.array([_offset(integral, ta[r], tb[r], wb[r], dt, reach) for r in rest])
        taus = np.sum(loo) - (N_BLOCKS - 1) * loo  # pseudo-values: mean of the others = loo
        tau_se = _jackknife_se(loo)
    else:
        taus = np.array([_offset(integral, ta[b], tb[b], wb[b], dt, reach) for b in blocks])
        # a block that tells no offset (its reference turns slower than MIN_MOTION_RAD_S, or its best
        # offset lies on the search's edge) is left out of the scatter; the held-out rule judges it by
        # the others' mean
        tells = np.array([abs(x) < reach * (1 - 1e-6) and _rms_rate(wb[b]) >= MIN_MOTION_RAD_S for x, b in zip(taus, blocks)])
        if MIN_TELLING_BLOCKS <= tells.sum() < N_BLOCKS:
            taus = np.where(tells, taus, np.mean(taus[tells]))
        k = int(tells.sum()) if tells.sum() >= MIN_TELLING_BLOCKS else N_BLOCKS
        tau_se = float(np.std(taus[tells] if k < N_BLOCKS else taus, ddof=1) / math.sqrt(k))
    use_tau = abs(tau) > Z_APPLY * tau_se and abs(tau) > MIN_OFFSET_STEPS * dt and \
        _offset_holds_out(integral, ta, tb, wb, taus, blocks)
    # the frame is fitted at the best clock, whether or not the offset is applied (a lag within the
    # gyro's sampling convention, half a step, would otherwise be turned into a rotation)
    wg = _gyro_mean(integral, ta - tau, tb - tau)
    Rm = _rotation(wg, wb)
    rv = Rotation.from_matrix(Rm).as_rotvec()
    # the blocks' rotations about the whole run's (near 180 deg a rotation vector flips its sign
    # from block to block; their differences from the whole run's do not)
    rvs = np.array([(Rotation.from_matrix(Rm).inv() * Rotation.from_matrix(_rotation(wg[b], wb[b]))).as_rotvec()
                    for b in (rest if sparse else blocks)])
    rv_se = np.array([_jackknife_se(rvs[:, i]) for i in range(3)]) if sparse else \
        np.std(rvs, axis=0, ddof=1) / math.sqrt(N_BLOCKS)
    angle = float(np.linalg.norm(rv))
    angle_se = float(np.sqrt(np.sum((rv / max(angle, 1e-300)) ** 2 * rv_se**2))) if angle > 0 else float(np.linalg.norm(rv_se))
    z = 1.96
    use_rot = angle > Z_APPLY * angle_se and math.degrees(angle) > MIN_ANGLE_DEG and \
        _rotation_holds_out(wg, wb, blocks)
    convention = None
    if run.get("heading_only"):
        # a heading tells no frame but the vertical's sense (a compass heading turns clockwise
        # seen from above, a gyro's z may point up): the axis convention only
        use_rot = False
    if use_rot:
        # a turn within CONVENTION_SNAP_DEG of an axis convention (other than none) is that convention
        P = min(_signed_permutations(), key=lambda X: Rotation.from_matrix(X.T @ Rm).magnitude())
        if not np.allclose(P, np.eye(3)) and math.degrees(Rotation.from_matrix(P.T @ Rm).magnitude()) < CONVENTION_SNAP_DEG:
            Rm, convention = P, True
            rv = Rotation.from_matrix(Rm).as_rotvec()
    else:
        # a body turned about one axis (a pendulum) does not fix the whole rotation, but it does
        # tell an axis convention (the IMU's x pointing back): the signed permutation that fits
        P = _axis_convention(wg, wb)
        if P is not None:
            Rm, convention, use_rot = P, True, True
            rv = Rotation.from_matrix(Rm).as_rotvec()
            angle, angle_se = float(np.linalg.norm(rv)), 0.0
    alignment = {
        "clock_offset_s": tau, "clock_offset_interval_s": [tau - z * tau_se, tau + z * tau_se],
        "rotation_deg": math.degrees(angle),
        "rotation_interval_deg": [math.degrees(max(angle - z * angle_se, 0.0)), math.degrees(angle + z * angle_se)],
        "rotation_vector_rad": [float(v) for v in rv], "applied": {"clock_offset": bool(use_tau), "rotation": bool(use_rot)},
        **({"axis_convention": [[int(round(x)) for x in row] for row in Rm]} if convention else {}),
        "what": "the reference's stamps late by clock_offset_s against the gyro's; gyro rate = R x reference body rate "
                "(R a rotation of rotation_deg about rotation_vector_rad); intervals from "
                f"{N_BLOCKS} time blocks",
    }
    if not (use_tau or use_rot):
        return Alignment(alignment, run)
    tq2 = tq - tau if use_tau else tq
    q2 = q
    if use_rot:
        q2 = _wxyz((Rotation.from_quat(_xyzw(q)) * Rotation.from_matrix(Rm.T)).as_quat())
        q2 *= np.sign(q2[:, :1] + 1e-300)
    valid = np.isfinite(w).all(1)
    aligned = {**run, "q_ref_t": tq2, "q_ref_q": q2, "q_ref": place_nearest(run["t"], valid, tq2, q2, dt)}
    note = (
        "reference aligned with the gyro before it was judged: "
        + "; ".join(x for x in (
            f"its clock offset {fmt(tau * 1e3)} ms [{fmt((tau - z * tau_se) * 1e3)}, {fmt((tau + z * tau_se) * 1e3)}]" if use_tau else "",
            f"its frame turned by {fmt(math.degrees(angle))} deg [{fmt(math.degrees(max(angle - z * angle_se, 0)))}, "
            f"{fmt(math.degrees(angle + z * angle_se))}] into the gyro's" if use_rot else "") if x))
    return Alignment(alignment, aligned, Said(notes=(note,)))


#: the reference's clock is settled where the offset left in it is at most this [s] (95 %)
CLOCK_SETTLED_S = 0.002


#: ... or at most this share of the intervals the reference is compared over: on a 90 s rocking
#: body read by a noisy reference with a 30 ms offset left unapplied, 0.25 s intervals (a share of
#: 0.12) named scales of 1.027 and 1.012 when its noise was weighed, 1 s intervals (0.03) nothing
OFFSET_SHARE = 0.04


def clock_offset_left(alignment) -> float:
    """The clock offset that may be left between the reference and the gyro [s] (95 %): the applied
    offset's interval half-width, or, where none was applied, the farthest end of the estimate's
    interval from zero; 0 where the alignment found too few spans or too little motion to say (the
    motion then hardly shows an offset)."""
    if not alignment:
        return 0.0
    lo, hi = alignment["clock_offset_interval_s"]
    return 0.5 * (hi - lo) if alignment["applied"]["clock_offset"] else max(abs(lo), abs(hi))


def clock_settled(offset_left: float, interval_s: float) -> bool:
    """Whether the clock offset left (:func:`clock_offset_left`) is within :data:`CLOCK_SETTLED_S`,
    or within :data:`OFFSET_SHARE` of the intervals compared (``interval_s``, their median). An
    offset delta left in a reference of a body oscillating at f reads as a scale of about 2 pi^2 f^2
    delta^2 (at 3 Hz and 30 ms, 1.15: seen) where the reference's noise is weighed row by row, the
    more so the shorter the intervals, and to first order as noise that telescopes."""
    return offset_left <= CLOCK_SETTLED_S or interval_s * OFFSET_SHARE >= offset_left
