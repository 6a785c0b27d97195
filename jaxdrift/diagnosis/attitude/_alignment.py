"""The reference's clock and frame against the gyro's, estimated before the reference is judged.

An optical motion-capture system tracks a body frame defined by its markers, never exactly the IMU's
frame, and stamps its samples on its own clock: a rotation of a degree between the frames and a few
milliseconds between the clocks are normal. Compared as if aligned, every fast turn leaves a large
residual (at 25 rad/s, 4 ms is 0.1 rad), which the consistency check reads as an inconsistent
reference and the bias fit as noise.

:func:`alignment_step` estimates, from the reference's own rates (the rotation between consecutive
reference samples over their step, at the step's midpoint) and the gyro's:

The reference's rate over a span is its rotation over the span, compared with the gyro's mean rate
over the same span (the gyro's integral), so that a reference at 1 Hz is compared with what the gyro
says of the same second, not with its rate at one instant.

1. the **clock offset** tau (the reference's stamps late by tau): the lag that best matches the rate
   magnitudes (the reference's rates over spans of :data:`SPAN_S`), which no frame rotation changes (a grid search over +-:data:`MAX_OFFSET_S`, or half a reference step where that is longer, at a quarter
   of the gyro's step, refined by a parabola);
2. the **frame rotation** R (gyro rate = R x reference body rate + bias): the rotation that fits the
   centred rates best in least squares (Kabsch);

each with a 95 % interval from :data:`N_BLOCKS` time blocks (the spread of the block estimates over
sqrt(blocks)). Both are applied (the reference re-stamped and turned into the gyro's frame) where
they are significant (beyond :data:`Z_APPLY` standard errors), beyond :data:`MIN_OFFSET_STEPS` of the gyro's
step or :data:`MIN_ANGLE_DEG`, and hold out of sample (in every time block, the value the other
blocks found fits better than none: a reference consistent as given is never turned); the report's ``run.reference_alignment`` says what was found and
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
from ...models._quaternion import quat_conjugate_np, quat_log_np, quat_multiply_np
from ._common import fmt
from ._records import Alignment, Said

__all__ = ["alignment_step", "MAX_OFFSET_S", "N_BLOCKS", "MIN_OFFSET_STEPS", "MIN_ANGLE_DEG", "MIN_MOTION_RAD_S"]

MAX_OFFSET_S = 0.1
#: the reference's rates are taken over spans of at least this [s]
SPAN_S = 0.02
#: applied beyond this many standard errors (10 blocks scatter), and only where it holds out of sample
Z_APPLY = 3.0
N_BLOCKS = 10
MIN_OFFSET_STEPS = 0.25
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


def _ref_rates(tq, q, span):
    """Body rates over consecutive reference samples ``span`` apart (a motion-capture attitude
    differenced sample by sample is mostly its own noise): (start, end, w), spans without a gap. The
    rate is the span's mean (its rotation over its length): at a 1 Hz reference it is compared with
    the gyro's mean over the same span, never with the gyro at one instant."""
    med = np.median(np.diff(tq))
    a = np.arange(0, len(tq) - span, span)
    b = a + span
    d = tq[b] - tq[a]
    ok = (d > 0) & (d <= (span + 0.5) * med)
    a, b, d = a[ok], b[ok], d[ok]
    return tq[a], tq[b], quat_log_np(quat_multiply_np(quat_conjugate_np(q[a]), q[b])) / d[:, None]


def _gyro_integral(t_grid, w):
    """(times, cumulative integral) of the gyro rates, each sample the rate at its stamp (as the
    clock offset has always been read: a sample held over a step would lag half a step), by the
    trapezoid rule; linear between the samples, so it interpolates at any instant."""
    fin = np.isfinite(w).all(1)
    tg, wg = t_grid[fin], w[fin]
    steps = np.diff(tg)[:, None] * 0.5 * (wg[:-1] + wg[1:])
    return tg, np.vstack([np.zeros((1, 3)), np.cumsum(steps, 0)])


def _gyro_mean(integral, ta, tb):
    """The gyro's mean rate over [ta, tb] (NaN where the span leaves the gyro's record)."""
    tg, C = integral
    out = np.full((len(ta), 3), np.nan)
    inside = (ta >= tg[0]) & (tb <= tg[-1]) & (tb > ta)
    for c in range(3):
        out[inside, c] = (np.interp(tb[inside], tg, C[:, c]) - np.interp(ta[inside], tg, C[:, c])) / (tb - ta)[inside]
    return out


def _offset_cost(integral, ta, tb, nb, tau):
    """Mean squared mismatch of the rate magnitudes at a clock offset ``tau``."""
    g = np.linalg.norm(_gyro_mean(integral, ta - tau, tb - tau), axis=1)
    m = np.isfinite(g)
    return float(np.mean((g[m] - nb[m]) ** 2)) if m.sum() > 10 else np.inf


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


def _offset_holds_out(integral, ta, tb, wb, taus, blocks) -> bool:
    """A clock offset is applied only where it predicts: in every time block, the offset the other
    blocks found matches the block's rate magnitudes better than no offset (a sign test with 1
    chance in 2^10 for an offset that tells nothing, as at a 1 Hz reference on a slow body)."""
    nb = np.linalg.norm(wb, axis=1)
    for i, b in enumerate(blocks):
        other = float(np.mean(np.delete(taus, i)))
        if not _offset_cost(integral, ta[b], tb[b], nb[b], other) < _offset_cost(integral, ta[b], tb[b], nb[b], 0.0):
            return False
    return True


def _rotation_holds_out(wg, wb, blocks) -> bool:
    """A frame rotation is applied only where it predicts: in every time block, the rotation fitted
    on the other blocks matches the block's rates better than the frames as given. A reference
    consistent as given is never turned (a fitted rotation always beats the identity on the data
    it was fitted to, by the noise it absorbs)."""
    m = np.isfinite(wg).all(1) & np.isfinite(wb).all(1)
    for i, b in enumerate(blocks):
        rest = np.concatenate([x for j, x in enumerate(blocks) if j != i])
        rest, b = rest[m[rest]], b[m[b]]
        if len(b) < 3 or len(rest) < 10:
            return False
        R = _rotation(wg[rest], wb[rest])
        a, c = wg[b] - np.mean(wg[b], 0), wb[b] - np.mean(wb[b], 0)
        if not np.sum((a - c @ R.T) ** 2) < np.sum((a - c) ** 2):
            return False
    return True


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
    ta, tb, wb = _ref_rates(tq, q, span)
    if len(ta) < MIN_SPANS or float(np.sqrt(np.mean(np.sum(wb**2, 1)))) < MIN_MOTION_RAD_S:
        return Alignment(None, run)
    integral = _gyro_integral(run["t"], w)
    # a GNSS heading at 1 Hz lags its gyro by a few tenths of a second: the search spans half a
    # reference step at least
    reach = max(MAX_OFFSET_S, 0.5 * float(np.median(np.diff(tq))))
    tau = _offset(integral, ta, tb, wb, dt, reach)
    blocks = np.array_split(np.arange(len(ta)), N_BLOCKS)
    taus = np.array([_offset(integral, ta[b], tb[b], wb[b], dt, reach) for b in blocks])
    tau_se = float(np.std(taus, ddof=1) / math.sqrt(N_BLOCKS))
    use_tau = abs(tau) > Z_APPLY * tau_se and abs(tau) > MIN_OFFSET_STEPS * dt and \
        _offset_holds_out(integral, ta, tb, wb, taus, blocks)
    wg = _gyro_mean(integral, ta - (tau if use_tau else 0.0), tb - (tau if use_tau else 0.0))
    Rm = _rotation(wg, wb)
    rv = Rotation.from_matrix(Rm).as_rotvec()
    # the blocks' rotations about the whole run's (near 180 deg a rotation vector flips its sign
    # from block to block; their differences from the whole run's do not)
    rvs = np.array([(Rotation.from_matrix(Rm).inv() * Rotation.from_matrix(_rotation(wg[b], wb[b]))).as_rotvec()
                    for b in blocks])
    rv_se = np.std(rvs, axis=0, ddof=1) / math.sqrt(N_BLOCKS)
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
