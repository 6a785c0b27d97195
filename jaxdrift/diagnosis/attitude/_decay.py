"""An onboard estimator still converging, as nuisance parameters of the reference fit
(:func:`._gyro.reference_fit`, its ``decay``): the error ``v exp(-(t - t0) / tau)`` of the reference,
in the global or the body frame, with a constant turn of its frame beside it where one shows.

- :func:`decay_profile`: the decay that gains most beside the gyro's effects, where it beats a
  constant turn and prefers the run's start;
- :func:`decay_tail`: the tail of a convergence whose start the consistency check left out;
- :func:`without_decay`: the reference with the fitted decay (and turn) taken out.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize

from ...models._quaternion import quat_exp_np, quat_multiply_np, rotation_matrix_np

__all__ = ["decay_regressor", "decay_terms", "n_decay", "corrected_anchors", "decay_profile", "decay_tail", "size_where_compared", "without_decay", "DECAY_CHI2", "DECAY_VS_FRAME"]


def decay_regressor(run, anchors, tau, frame, after=0.0, d_log_tau=False):
    """(n_int, 3, 3): how a reference error ``v exp(-(t - t0) / tau)`` (``t0`` the first anchor, or
    ``after`` seconds later with no error before; in the ``"global"`` frame or the ``"body"``'s)
    enters each interval's discrepancy, per component of ``v`` (``d_log_tau``: its derivative with
    respect to ``log tau``)."""
    t, q_ref = run["t"], run["q_ref"]
    starts, ends = anchors[:-1], anchors[1:]
    t0 = t[anchors[0]] + after

    def e(x):
        u = np.maximum(x - t0, 0.0) / tau
        return np.where(x >= t0, np.exp(-u) * (u if d_log_tau else 1.0), 0.0)

    ea, eb = e(t[starts]), e(t[ends])
    if frame == "body":
        return rotation_matrix_np(q_ref[starts]) * ea[:, None, None] - rotation_matrix_np(q_ref[ends]) * eb[:, None, None]
    return (ea - eb)[:, None, None] * np.eye(3)


def n_decay(decay) -> int:
    """The reference fit's parameters of ``decay`` (None, ``(tau, frame)`` or ``(tau, frame, True)``):
    three amplitudes, three of the turn where it is fitted, and ``log tau``."""
    return 0 if decay is None else 7 if len(decay) > 2 and decay[2] else 4


def decay_terms(run, anchors, decay, theta):
    """The Jacobian (n_int, 3, :func:`n_decay`) of the intervals' discrepancy in the decay's parameters
    ``theta`` (amplitudes, the turn's where ``decay`` is ``(tau, frame, True)``, ``log tau`` last):
    the amplitudes' regressor, the constant turn's (a body-frame error that never decays: a marker
    frame the alignment left, under an estimator's error converging) and the time constant's."""
    tau, frame = math.exp(theta[-1]), decay[1]
    X = [decay_regressor(run, anchors, tau, frame)]
    if len(decay) > 2 and decay[2]:
        X.append(decay_regressor(run, anchors, math.inf, "body"))
    X.append(np.einsum("nab,b->na", decay_regressor(run, anchors, tau, frame, d_log_tau=True), theta[:3])[:, :, None])
    return np.concatenate(X, axis=2)


def _decay_record(decay, theta, i):
    """A fitted converging error: its time constant, frame, first parameter index, amplitudes [rad] and
    the constant turn beside it [rad] (None where it is not fitted)."""
    if decay is None:
        return None
    k = n_decay(decay)
    return {"tau_s": float(math.exp(theta[i + k - 1])), "frame": decay[1], "index": int(i),
            "amplitude_rad": [float(x) for x in theta[i:i + 3]],
            "turn_rad": [float(x) for x in theta[i + 3:i + 6]] if k == 7 else None}


#: a converging estimator is fitted beside the gyro's effects where its decay, profiled over
#: ``DECAY_TAUS`` time constants (from three intervals to half the run) in both frames, gains this
#: chi-square (in units of the fit's own residual level: 28 tries of 3 amplitudes each) and starts at
#: least this far off [rad] (estimators start degrees off; a gyro's drift does not decay from the start);
#: and it must fit better than a constant turn of the reference's frame (a body-frame error that never
#: decays, which a slow decay can stand in for) by ``DECAY_VS_FRAME`` in the same units
DECAY_CHI2 = 30.0
DECAY_MIN_RAD = math.radians(1.0)
#: ... and at most this far (an estimator seen converging from tens of degrees is no estimator
#: settling but a reference gone wrong, which the consistency check judges: on a PX4 bench log the
#: profile read 61 deg)
DECAY_MAX_RAD = math.radians(15.0)
DECAY_VS_FRAME = 10.0
#: the same decay started at these shares of the run must gain at most 1 / DECAY_START_RATIO of it
DECAY_LATER = (0.1, 0.2, 0.3, 0.4)
DECAY_START_RATIO = 2.0
DECAY_TAUS = 14


def _decay_gain(without, with_decay) -> float:
    """The chi-square a decay gains, in units of the residual level left with it (the weights'
    noise level may be off either way)."""
    return (without["chi2"] - with_decay["chi2"]) / max(with_decay["chi2"] / max(with_decay["dof"] - 3, 1), 1e-300)


def _sized_tau(fit0, sw, r, decay_cols, tau, taus):
    """The time constant of a decay found on the grid ``taus`` (near ``tau``), sized beside constant
    biases: segment biases take a body-frame decay for a fading bias, and where they take part of it
    its time constant comes out off by the grid's step, which leaves a residual that reads as a bias
    drift. Linearised at ``fit0`` (weighted Jacobian ``fit0["Jf"] * sw``, weighted residual ``r``):
    the segment biases' columns summed per channel, the signal they held put back."""
    A = fit0["Jf"] * sw[:, None]
    offs = fit0["offs"]
    y = r + A[:, :offs[-1]] @ fit0["theta"][:offs[-1]]
    Ac = np.column_stack([A[:, offs[c]:offs[c + 1]].sum(1) for c in range(3)] + [A[:, offs[-1]:]])

    def rss(log_tau):
        B = np.hstack([Ac, decay_cols(math.exp(log_tau))])
        return float(np.sum((y - B @ np.linalg.lstsq(B, y, rcond=1e-12)[0]) ** 2))

    step = math.log(taus[1] / taus[0]) if len(taus) > 1 else 0.5
    lo, hi = max(math.log(tau) - 2 * step, math.log(taus[0])), min(math.log(tau) + 2 * step, math.log(taus[-1]))
    if hi <= lo:
        return tau
    return float(math.exp(optimize.minimize_scalar(rss, bounds=(lo, hi), method="bounded",
                                                   options={"xatol": 0.01}).x))


def decay_profile(fit_ref, fit0, run, anchors, *args, **kw):
    """The reference as an estimator still converging: ``(tau, frame)`` of the decay
    ``v exp(-(t - t0) / tau)`` of its error that :func:`reference_fit` (``decay=``) fits best beside
    the gyro's effects, where it gains :data:`DECAY_CHI2` over ``fit0`` (the same fit without it),
    ``|v|`` is between :data:`DECAY_MIN_RAD` and :data:`DECAY_MAX_RAD`, it fits better than a constant turn of the reference's
    frame (:data:`DECAY_VS_FRAME`) and it prefers the run's start (:data:`DECAY_START_RATIO`); else
    None. ``fit_ref(run, *args, **kw)`` is the fit. Returns (decay or None, the fit with it or None).

    An onboard estimator starts degrees off and its error decays over seconds to a minute; read as
    the gyro's, that decay is a bias that fades: a wandering bias (a drift named where there is
    none) and the constant bias lost under it. The converging check of :mod:`._consistency` leaves
    out its first stretch where it decays fast; a slow one (a time constant of a third of the run
    and more) outlasts any stretch that can be left out, so it is modelled instead."""
    t = run["t"]
    T = float(t[anchors[-1]] - t[anchors[0]])
    n_int = len(anchors) - 1
    if n_int < 20 or T <= 0:
        return None, None
    # the profile, linearised at ``fit0`` (its Jacobian beside the decay's regressor), picks the decay;
    # the full fit with it then decides
    sw = np.sqrt(fit0["Wf"])
    A0 = fit0["Jf"] * sw[:, None]
    r = fit0["res"].reshape(-1) * sw

    def cols(tau, frame, after=0.0):
        Jd = decay_regressor(run, anchors, tau, frame, after)
        return fit0["whiten"](Jd).reshape(-1, 3) * sw[:, None]  # (the fit's whitening of its rows)

    turn_cols = cols(math.inf, "body")

    def rss(tau, frame, after=0.0, turn=False):
        A = np.hstack([A0, cols(tau, frame, after)] + [turn_cols] * turn)
        return float(np.sum((r - A @ np.linalg.lstsq(A, r, rcond=1e-12)[0]) ** 2))

    taus = np.geomspace(max(1.0, 3.0 * T / n_int), T / 2.0, DECAY_TAUS)
    # a reference turned by a constant rotation (a frame the alignment left) is a body-frame error that
    # never decays: a slow decay would stand in for it. The decay must beat that as well; where the
    # reference is both turned and converging, the turn is fitted beside the decay (each must gain
    # DECAY_VS_FRAME over the other alone)
    frame_rss = rss(math.inf, "body")
    level = max(frame_rss / max(len(r) - A0.shape[1] - 6, 1), 1e-300)
    best = min((rss(float(tau), frame), (float(tau), frame)) for frame in ("global", "body") for tau in taus)
    both = min((rss(float(tau), frame, turn=True), (float(tau), frame, True)) for frame in ("global", "body")
               for tau in taus)
    if (frame_rss - both[0]) / level >= DECAY_VS_FRAME and (best[0] - both[0]) / level >= DECAY_VS_FRAME:
        best = both
    turn = len(best[1]) > 2
    vs_frame = (frame_rss - best[0]) / max(best[0] / max(len(r) - A0.shape[1] - 3 - 3 * turn, 1), 1e-300)
    decay = best[1]
    # only an estimator prefers the start: a bias that wanders shows decays as large anywhere in the
    # run, so the same decay started later must gain at most half as much (beside the turn where one is
    # fitted: the gains are then over the turn alone)
    rss0 = frame_rss if turn else float(r @ r)
    later = min(rss(*decay[:2], after=f * T, turn=turn) for f in DECAY_LATER)
    prefers_start = rss0 - best[0] >= DECAY_START_RATIO * (rss0 - later)
    if vs_frame < DECAY_VS_FRAME or not prefers_start:
        return None, None
    decay = (_sized_tau(fit0, sw, r, lambda tau: np.hstack([cols(tau, decay[1])] + [turn_cols] * turn),
                        decay[0], taus), *decay[1:])
    f = fit_ref(run, *args, decay=decay, fit_tau=False, **kw)
    # in units of the residual level left with the decay (the weights' noise level may be off either way)
    if _decay_gain(fit0, f) < DECAY_CHI2 or not DECAY_MIN_RAD <= np.linalg.norm(f["decay"]["amplitude_rad"]) <= DECAY_MAX_RAD:
        return None, None
    return decay, fit_ref(run, *args, decay=decay, **kw)


def decay_tail(fit_ref, decay, run, noise_var, segs, anchors, *args, held=(), **kw):
    """The tail of an estimator's convergence whose start the consistency check left out
    (:func:`._consistency.converging`, its time constant and frame ``decay``): fitted beside the
    gyro's effects where, with constant biases (segment biases would take the decay for a bias that
    moves), it gains :data:`DECAY_CHI2` and stays below :data:`DECAY_MAX_RAD`. Left unfitted, the
    decay still under way after the stretch left out reads as a bias that fades: a drift named on a
    clean gyro. ``held``: the channels whose biases ``kw``'s ``hold_bias`` holds at 0 in the fit with
    ``segs``. Returns ``(decay, the fit with ``segs`` and the decay)`` or ``(None, None)``."""
    const = [np.zeros(len(anchors) - 1, int)] * 3
    kc = {**kw, "hold_bias": tuple(sorted(held))}  # with one bias per channel, channel c's is parameter c
    f0 = fit_ref(run, noise_var, const, anchors, *args, **kc)
    f1 = fit_ref(run, noise_var, const, anchors, *args, decay=decay, fit_tau=False, **kc)
    # the frame's turn the alignment estimated over the convergence (or left) is off by what the decay
    # lent it: a constant turn beside the tail where it gains DECAY_VS_FRAME over the tail alone
    f2 = fit_ref(run, noise_var, const, anchors, *args, decay=(*decay[:2], True), fit_tau=False, **kc)
    if _decay_gain(f1, f2) >= DECAY_VS_FRAME:
        decay, f1 = (*decay[:2], True), f2
    if _decay_gain(f0, f1) < DECAY_CHI2 or size_where_compared(f1["decay"], run["t"], anchors, kw.get("use"))[0] > DECAY_MAX_RAD:
        return None, None
    return decay, fit_ref(run, noise_var, segs, anchors, *args, decay=decay, **kw)


def size_where_compared(rec, t, anchors, use):
    """A fitted decay's size [rad] where the compared stretch starts (at the first interval ``use``
    keeps; the fit's amplitudes are extrapolated to the first anchor, far larger where the consistency
    check left the start out), and that interval's index."""
    i0 = int(np.argmax(use.any(1))) if use is not None and use.any() else 0
    return float(np.linalg.norm(rec["amplitude_rad"]) * math.exp(-(t[anchors[i0]] - t[anchors[0]]) / rec["tau_s"])), i0


def corrected_anchors(run, anchors, decay, theta):
    """The reference at the anchor rows with the converging error ``decay`` (``(tau, frame)``, or
    ``(tau, frame, True)`` with a constant turn) of the fit's parameters ``theta`` (:func:`decay_terms`;
    the amplitudes are minus the error's) taken out. The reference fit takes it out exactly at each
    step, the regressors its Jacobian: the linear model alone (a 4 deg error's second order) and a
    time constant 2 % off on the profile's grid read as biases of 6e-6 to 9e-6 rad/s."""
    sub = {"t": run["t"][anchors], "q_ref": run["q_ref"][anchors]}
    return without_decay(sub, _decay_record(decay, theta, 0), 0)


def without_decay(run, decay: dict, a0: int):
    """The reference quaternions (n, 4) with a fitted converging error (``reference_fit``'s
    ``decay`` record, ``a0`` its first anchor row) taken out: the fit's amplitudes ``v`` are minus the
    error's, so the true attitude is ``q exp(v e(t))`` (body frame) or ``exp(v e(t)) q`` (global)."""
    q = run["q_ref"]
    e = np.exp(-np.maximum(run["t"] - run["t"][a0], 0.0) / decay["tau_s"])
    d = quat_exp_np(np.outer(e, decay["amplitude_rad"]))
    q = quat_multiply_np(q, d) if decay["frame"] == "body" else quat_multiply_np(d, q)
    if decay.get("turn_rad") is None:
        return q
    return quat_multiply_np(q, np.broadcast_to(quat_exp_np(np.asarray(decay["turn_rad"])[None]), q.shape))
