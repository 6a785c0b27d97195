"""Is the reference attitude consistent with the gyro? Still spans, and spans where it is not.

Real reference attitudes come from an estimator (a flight controller's EKF, a GNSS/INS), not from
the truth: an estimator still converging turns its heading while the vehicle stands, and a heading
reset jumps. A gyro bias cannot do either (it is nearly constant), a scale error cannot act while
the body does not rotate; fitted as gyro errors they give absurd scales and biases. Per reference
interval (between anchor rows) the gyro is integrated as it was measured and compared with the
reference, both as rates in the global frame:

- ``gamma``: the gyro's rotation over the interval, ``rho``: the reference's, ``d = rho - gamma``
  (a constant gyro bias ``b`` gives ``d = -S b``);
- windows of at least :data:`WINDOW_S` (and 3 intervals) hold their means and standard errors;
- the **gyro says still** in a window whose mean gyro rate is below :data:`STILL_GYRO` and the
  **reference says still** where its rate is below :data:`STILL_REF`;
- on a stretch of consecutive gyro-still windows the reference is **inconsistent** on a global axis
  where both its rate and the discrepancy leave the stretch's median by more than
  :data:`REF_DEV` and 5 standard errors (the reference turns, the gyro does not follow: a bias
  drift moves the discrepancy but not the reference, a true slow rotation moves the reference but
  not the discrepancy); when more than a third of the stretch's windows do, the whole stretch;
- anywhere, an interval whose discrepancy jumps from its neighbours' median by more than
  :data:`REF_JUMP` and 10 robust standard deviations is a jump of the reference: a reset where the
  attitude stays stepped, an outlier (kind ``"spike"``) where the discrepancy comes back within
  :data:`SPIKE_SPAN` intervals (an optical marker's jitter: the reference's own heavy-tailed noise,
  not an inconsistency);
- an estimator still converging at the start of the run (:func:`converging`: the discrepancy
  decays like ``exp(-t / tau)`` from a degree or more, and prefers the start) is left out there.

The flagged (interval, axis) cells are left out of the reference fit; the spans other than spikes
are reported as ``reference_inconsistent`` findings, the spikes in a note.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import median_filter

from ...models._quaternion import (
    cumulative_quat_product_np,
    quat_conjugate_np,
    quat_exp_np,
    quat_log_np,
    quat_multiply_np,
    rotation_matrix_np,
)
from .._diffnoise import mad_sigma
from ._common import MIN_INTERVAL_ROWS
from ._gyro import convention_terms, reference_fit

__all__ = ["interval_rates", "consistency", "rejudge", "anchor_rows", "thinned_anchors", "thinned", "MIN_THINNED_INTERVALS", "still_rows", "RECHECK_SCALE_SE", "RECHECK_CHI2", "AXES",
           "STILL_GYRO", "STILL_REF", "REF_DEV", "REF_JUMP", "SPIKE_SPAN", "WINDOW_S"]

AXES = ("x", "y", "z")
WINDOW_S = 0.5  # s: shortest window of reference intervals
STILL_GYRO = 0.05  # rad/s: a mean gyro rate below this (bias included) is "the gyro says still"
STILL_REF = 0.02  # rad/s: a reference rate below this is "the reference says the body does not move"
REF_DEV = 0.005  # rad/s: a reference that turns this much faster than the gyro while still is inconsistent
REF_JUMP = 0.05  # rad/s over one interval, and 10 robust standard deviations: a jump (reset)
SPIKE_SPAN = 5  # intervals each side over which a jump that comes back is an outlier, not a reset
#: the reference is judged again against the gyro corrected by the fit where the fit's scale is known
#: this well (standard error), and cells are given back only where the fit's chi-square per degree
#: of freedom grows by less than this factor with them
RECHECK_SCALE_SE = 0.01
RECHECK_CHI2 = 1.5


def interval_rates(w, dt, q_ref, anchors, lam=0.0):
    """Per anchor interval: global-frame gyro rate ``gamma``, reference rate ``rho`` (rad/s), the
    interval lengths and the interval start times' row indices. Rates held over each step, or in
    the sampling convention ``lam`` of the reference fit (:func:`._gyro.convention_terms`; 0 holds
    each sample, 1/2 takes the samples as the rate at their stamps)."""
    w = np.where(np.isfinite(w), w, 0.0)
    a0, aN = int(anchors[0]), int(anchors[-1])
    P = np.empty((aN - a0 + 1, 4))
    P[0] = [1.0, 0.0, 0.0, 0.0]
    step = w[a0:aN]
    if lam:
        w_pad = np.concatenate([w[:1], w, w[-1:], w[-1:]], 0)  # w_pad[k + 1] = w[k]
        w0, dw = convention_terms(w_pad[a0 : aN + 3])
        step = w0 + lam * dw
    P[1:] = cumulative_quat_product_np(quat_exp_np(step * dt))
    P /= np.linalg.norm(P, axis=1, keepdims=True)
    starts, ends = anchors[:-1], anchors[1:]
    rel = quat_multiply_np(quat_conjugate_np(P[starts - a0]), P[ends - a0])
    qa, qb = q_ref[starts], q_ref[ends]
    Ra = rotation_matrix_np(qa)
    dti = (ends - starts) * dt
    gamma = np.einsum("nab,nb->na", Ra, quat_log_np(rel)) / dti[:, None]
    rho = np.einsum("nab,nb->na", Ra, quat_log_np(quat_multiply_np(quat_conjugate_np(qa), qb))) / dti[:, None]
    return gamma, rho, dti


def _windows(t_start, dti):
    """Window index of each interval: at least WINDOW_S long and 3 intervals (the last one absorbs a rest)."""
    width = max(WINDOW_S, 3.0 * float(np.median(dti)))
    win = np.floor((t_start - t_start[0]) / width).astype(int)
    n_win = int(win.max()) + 1
    counts = np.bincount(win, minlength=n_win)
    # merge windows with fewer than 3 intervals into the one before
    remap = np.arange(n_win)
    for j in range(1, n_win):
        if counts[j] < 3:
            remap[j] = remap[j - 1]
    return np.unique(remap[win], return_inverse=True)[1]


def _window_stats(x, dti, win):
    nw = int(win.max()) + 1
    wsum = np.bincount(win, weights=dti, minlength=nw)
    mean = np.stack([np.bincount(win, weights=x[:, c] * dti, minlength=nw) / wsum for c in range(3)], 1)
    n = np.bincount(win, minlength=nw)
    dev = x - mean[win]
    var = np.stack([np.bincount(win, weights=dev[:, c] ** 2, minlength=nw) for c in range(3)], 1)
    se = np.sqrt(var / np.maximum(n - 1, 1)[:, None] / np.maximum(n, 1)[:, None])
    return mean, se


def consistency(w, dt, q_ref, anchors, t, valid=None, lam=0.0):
    """Flag the (interval, global axis) cells where the reference is inconsistent with the gyro.

    Returns ``use`` (n_int, 3) bool (False: leave out), ``spans``: a list of dicts ``{axis, t0, t1,
    rate, kind}`` (``kind`` "turns while the gyro says still" or "jumps"), and ``still``: the
    per-interval flag "gyro and reference both say still".
    """
    gamma, rho, dti = interval_rates(w, dt, q_ref, anchors, lam)
    n_all = len(dti)
    idx = np.arange(n_all) if valid is None else np.nonzero(valid)[0]
    use_all, still_all = np.ones((n_all, 3), bool), np.zeros(n_all, bool)
    if len(idx) < 3:
        return use_all, [], still_all
    use, spans, still = _flag(gamma[idx], rho[idx], dti[idx], t[anchors[:-1]][idx], t[anchors[1:]][idx])
    conv = converging(rho[idx] - gamma[idx], rotation_matrix_np(q_ref[anchors[:-1][idx]]), t[anchors[:-1]][idx],
                      t[anchors[1:]][idx])
    if conv is not None:  # a decay about a global axis leaves that axis's cells out, about a body axis all
        cols = [AXES.index(conv[1]["axis"])] if conv[1]["frame"] == "global" else [0, 1, 2]
        use[np.ix_(conv[0], cols)] = False
        spans = sorted(spans + [conv[1]], key=lambda s: (s["t0"], s["axis"]))
    use_all[idx], still_all[idx] = use, still
    return use_all, spans, still_all


#: an estimator converging: the reference's error decays like exp(-t / tau) from at least this
#: [rad] (estimators start degrees off), and the decay improves the fit of the discrepancy over
#: a bias and a linear drift by at least this chi-square (the maximum over the tau grid, the axes
#: and both frames of a chi-square with one degree of freedom under the null: 144 tries exceed 20
#: with probability about 1e-3; an independent converging estimator 2.9 deg off with a 5.6 s
#: time constant, seen through 5 Hz reference rows, gained 20.7)
CONVERGE_MIN_RAD = math.radians(1.0)
CONVERGE_CHI2 = 20.0
#: the converging stretch ends where the decaying rate falls below this [rad/s]
CONVERGE_TAIL = 1e-4


#: the same decay started at these shares of the run must gain at most 1 / CONVERGE_START_RATIO
#: of what it gains at the start
CONVERGE_LATER = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
CONVERGE_START_RATIO = 2.0


def _decay_gain(base, y, rss0, sig, tm, tau, t0):
    """Chi-square gain of ``exp(-(t - t0) / tau)`` from ``t0`` on beside ``base``, and its amplitude."""
    X = np.column_stack([base, np.where(tm >= t0, np.exp(-(tm - t0) / tau), 0.0)])
    coef = np.linalg.lstsq(X, y, rcond=None)[0]
    r = y - X @ coef
    return (rss0 - float(r @ r)) / sig**2, float(coef[-1])


def converging(d, Ra, t_start, t_end):
    """``(intervals to leave out, span)`` where the reference is an estimator still converging at
    the start of the run, else None.

    The reference's error ``e(t) = e0 exp(-t / tau)`` adds its rate ``-(e0 / tau) exp(-t / tau)`` to
    the discrepancy ``d`` (reference rate minus gyro rate per interval), where a gyro bias adds a
    constant and its drift a slow change. Per axis, in the global frame and in the body's (an
    error on either side of the attitude), ``d`` is fitted with a constant and a slope, and with
    ``exp(-t / tau)`` beside them on a grid of ``tau`` up to a third of the run; the decay counts
    where it gains ``CONVERGE_CHI2`` (scale from the discrepancy's first differences) and the
    error it implies, ``|A| tau``, is ``CONVERGE_MIN_RAD`` or more. The stretch left out runs from
    the start until the decaying rate is ``CONVERGE_TAIL`` (at least one tau, at most half the run).
    A gyro's own bias drift wanders both ways and implies far less than a degree."""
    n = len(d)
    T = float(t_end[-1] - t_start[0])
    if n < 20 or T <= 0:
        return None
    tm = 0.5 * (t_start + t_end) - t_start[0]
    taus = np.geomspace(max(0.5, 3.0 * float(np.median(t_end - t_start))), T / 3.0, 24)
    if taus[0] >= taus[-1]:
        return None
    base = np.column_stack([np.ones(n), tm / T])
    best = None
    for frame, y3 in (("global", d), ("body", np.einsum("nba,nb->na", Ra, d))):
        for c in range(3):
            y = y3[:, c]
            sig = mad_sigma(np.diff(y)) / math.sqrt(2.0)
            if not sig > 0:
                continue
            r0 = y - base @ np.linalg.lstsq(base, y, rcond=None)[0]
            rss0 = float(r0 @ r0)
            for tau in taus:
                gain, A = _decay_gain(base, y, rss0, sig, tm, tau, 0.0)
                if gain >= CONVERGE_CHI2 and abs(A) * tau >= CONVERGE_MIN_RAD and (best is None or gain > best[0]):
                    best = (gain, A, float(tau), frame, AXES[c], y, sig, rss0)
    if best is None:
        return None
    # only an estimator prefers the start: a bias that wanders (a random walk) shows decays as large
    # anywhere in the run, so the same decay started later must gain far less
    gain, A, tau, frame, axis, y, sig, rss0 = best
    later = max(_decay_gain(base, y, rss0, sig, tm, tau, f * T)[0] for f in CONVERGE_LATER)
    if gain < CONVERGE_START_RATIO * later:
        return None
    t_cut = float(np.clip(tau * math.log(max(abs(A) / CONVERGE_TAIL, 1.0)), tau, T / 2.0))
    cut = tm < t_cut
    return cut, {"axis": axis, "t0": float(t_start[0]), "t1": float(t_start[0] + t_cut), "rate": abs(A),
                 "kind": "converges", "tau_s": tau, "error_rad": abs(A) * tau, "frame": frame}


def _flag(gamma, rho, dti, t_start, t_end):
    d = rho - gamma
    n_int = len(dti)
    use = np.ones((n_int, 3), bool)
    spans = []
    win = _windows(t_start, dti) if n_int >= 3 else np.zeros(n_int, int)
    G, _ = _window_stats(gamma, dti, win)
    Rm, Rse = _window_stats(rho, dti, win)
    D, Dse = _window_stats(d, dti, win)
    g_still = np.linalg.norm(G, axis=1) < STILL_GYRO
    still_int = (g_still & (np.linalg.norm(Rm, axis=1) < STILL_REF))[win]
    # stretches of consecutive gyro-still windows (two or more)
    j = 0
    nw = len(g_still)
    while j < nw:
        if not g_still[j]:
            j += 1
            continue
        k = j
        while k < nw and g_still[k]:
            k += 1
        if k - j >= 2:
            for c in range(3):
                sl = slice(j, k)
                dev_r = np.abs(Rm[sl, c] - np.median(Rm[sl, c]))
                dev_d = np.abs(D[sl, c] - np.median(D[sl, c]))
                bad = (dev_r > np.maximum(REF_DEV, 5 * Rse[sl, c])) & (dev_d > np.maximum(REF_DEV, 5 * Dse[sl, c]))
                if not bad.any():
                    continue
                if bad.sum() > (k - j) / 3.0:
                    bad[:] = True
                cells = np.isin(win, np.arange(j, k)[bad])
                use[cells, c] = False
                spans += _spans_of(cells, t_start, t_end, AXES[c], float(np.max(np.abs(D[sl, c][bad] - np.median(D[sl, c])))),
                           "turns while the gyro says still")
        j = k
    # jumps (resets), moving or not
    if n_int >= 7:
        for c in range(3):
            loc = median_filter(d[:, c], size=7, mode="nearest")
            res = d[:, c] - loc
            sig = mad_sigma(res)
            jump = (np.abs(res) > max(REF_JUMP, 10.0 * sig)) & (np.abs(res) * dti > 5e-3)
            if jump.any():
                cells = jump | np.r_[jump[1:], False] | np.r_[False, jump[:-1]]
                use[cells, c] = False
                # a reset steps the attitude and stays; an outlier of the reference (an optical
                # marker's jitter, a sample late on a fast turn) comes back within a few intervals:
                # the attitude discrepancy's median over SPIKE_SPAN intervals after the jump is less
                # than half the jump away from its median over SPIKE_SPAN intervals before. Both are
                # left out of the fit; only a step is a finding
                step = res * dti
                level = np.concatenate([[0.0], np.cumsum(step)])  # level[i] before interval i
                back = np.zeros(n_int, bool)
                for i in np.nonzero(jump)[0]:
                    before = np.median(level[max(i - SPIKE_SPAN + 1, 0) : i + 1])
                    after = np.median(level[i + 1 : i + 1 + SPIKE_SPAN])
                    back[i] = abs(after - before) < 0.5 * abs(step[i])
                rate = np.abs(res)
                for kind, sel in (("jumps", jump & ~back), ("spike", jump & back)):
                    if sel.any():
                        near = sel | np.r_[sel[1:], False] | np.r_[False, sel[:-1]]
                        spans += _spans_of(near, t_start, t_end, AXES[c], np.where(sel, rate, 0.0), kind)
    spans.sort(key=lambda s: (s["t0"], s["axis"]))
    return use, spans, still_int


def _spans_of(cells, t_start, t_end, axis, rate, kind):
    """The spans ``{axis, t0, t1, rate, kind}`` of the runs of flagged ``cells``."""
    idx = np.nonzero(cells)[0]
    if not len(idx):
        return []
    breaks = np.nonzero(np.diff(idx) > 1)[0]
    out = []
    for a, b in zip(np.r_[0, breaks + 1], np.r_[breaks, len(idx) - 1]):
        r = float(np.max(rate[idx[a] : idx[b] + 1])) if np.ndim(rate) else float(rate)
        out.append({"axis": axis, "t0": float(t_start[idx[a]]), "t1": float(t_end[idx[b]]), "rate": r, "kind": kind})
    return out


def still_rows(n, anchors, still_int):
    """Row mask of the intervals where the gyro and the reference both say the body does not move."""
    m = np.zeros(n, bool)
    for i in np.nonzero(still_int)[0]:
        m[anchors[i] : anchors[i + 1]] = True
    return m


def corrected_rates(run, fit, int_seg, anchors):
    """The rates with a reference fit's piecewise biases taken off and its scales divided out,
    where the fit determines them (a bias whose standard error is under a fifth of
    :data:`REF_DEV`, a scale under :data:`RECHECK_SCALE_SE`; the rest left as measured, so that a
    bias the flagged cells alone would tell cannot absorb the reference's own turn). Rows outside
    the anchors take the nearest segment's bias."""
    theta, offs, cov = fit["theta"], fit["offs"], fit["cov"]
    sc = int(offs[-1])
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    th = np.where(se[: sc + 3] < np.r_[np.full(sc, 0.2 * REF_DEV), np.full(3, RECHECK_SCALE_SE)], theta[: sc + 3],
                  np.r_[np.zeros(sc), np.ones(3)])
    w = np.array(run["w"], float)
    rows = np.arange(len(w))
    int_of_row = np.clip(np.searchsorted(anchors, rows, side="right") - 1, 0, len(int_seg) - 1)
    b = np.stack([th[offs[c] + int_seg[int_of_row]] for c in range(3)], 1)
    return (w - b) / th[sc : sc + 3]


def rejudge(run, fit0, use, spans, spikes, valid, int_seg, anchors, var_rate, sample_var, lam_recheck):
    """The reference judged again against the gyro as the first fit corrects it (its
    well-determined bias and scale, :func:`corrected_rates`): a gyro bias rotated into the global
    frame by a slow turn, or a scale on a turn the gyro calls still, moves the discrepancy as an
    inconsistent reference would. Cells may only be given back, and only where the refit with them
    keeps its chi-square per degree of freedom within :data:`RECHECK_CHI2` of the first fit's;
    twice at most. Returns (use, spans, spikes, fit, notes)."""
    from ._realworld import heading_only_cells, split_spikes

    notes = []
    lam = fit0["lam"] if abs(fit0["lam"]) > lam_recheck else 0.0
    for _ in range(2):
        if use.all():
            break
        use2, spans2, _ = consistency(corrected_rates(run, fit0, int_seg, anchors), run["dt"], run["q_ref"], anchors,
                                      run["t"], valid, lam=lam)
        use2 &= valid[:, None] & (use | ~use2)  # the correction may only give cells back
        spans2, spikes2 = split_spikes(spans2)
        if run.get("heading_only"):
            use2, spans2 = heading_only_cells(use2, spans2)
        if np.array_equal(use2, use):
            break
        fit2 = reference_fit(run, var_rate, [int_seg] * 3, anchors, sample_var, use=use2, ref_var=fit0.get("ref_var", 0.0))
        if fit2["chi2"] / max(fit2["dof"], 1) > RECHECK_CHI2 * fit0["chi2"] / max(fit0["dof"], 1):
            break  # the cells given back do not fit the gyro's effects: the reference is inconsistent there
        notes.append(f"the reference judged again against the gyro corrected for its fitted bias and scale: "
                     f"{len(spans)} inconsistent span(s) before, {len(spans2)} after "
                     f"({int(np.sum(use2 & ~use))} interval-axis cells given back to the fit)")
        use, spans, spikes, fit0 = use2, spans2, spikes2, fit2
    return use, spans, spikes, fit0, notes


#: thinning keeps at least this many intervals (the drift test splits them into 16 segments of 10)
MIN_THINNED_INTERVALS = 160


def thinned_anchors(run, anchors, var_rate):
    """Anchors far enough apart that the gyro's random walk over an interval is at least the
    reference's own attitude noise, where that noise dominates (a GNSS/INS or tracker attitude
    with milliradians of noise at 10-100 Hz against a gyro of 1e-4 rad/sqrt(s)). The noise of
    each reference row is white in attitude, so interval by interval it reads as a rate noise of
    sqrt(2) sigma_ref / dt_i and swamps the bias, while over longer intervals it telescopes away.
    sigma_ref^2 is read off the discrepancies of single intervals against those of pairs (white
    attitude noise cancels in a pair's sum, the gyro's random walk adds), by robust spreads. Returns (anchors,
    sigma_ref), or (the anchors unchanged, None) where the reference noise does not dominate."""
    if len(anchors) < 4 * MIN_THINNED_INTERVALS:
        return anchors, None
    gamma, rho, dti = interval_rates(run["w"], run["dt"], run["q_ref"], anchors)
    d = (rho - gamma) * dti[:, None]  # angle discrepancies per interval
    ok = np.isfinite(d).all(1)
    d = d[ok] - np.median(d[ok], 0)
    if len(d) < 4 * MIN_THINNED_INTERVALS:
        return anchors, None
    # robustly (an optical marker's few jumps are outliers, not noise): the spread of one interval's
    # discrepancy is 2 s_ref^2 + N^2 dt, of two neighbours' sum 2 s_ref^2 + 2 N^2 dt
    v1 = float(np.mean([mad_sigma(d[:, c]) ** 2 for c in range(3)]))
    v2 = float(np.mean([mad_sigma(d[1:, c] + d[:-1, c]) ** 2 for c in range(3)]))
    var_ref = max(v1 - 0.5 * v2, 0.0)
    step = float(np.median(dti))
    k = int(math.ceil(2.0 * var_ref / max(var_rate * step, 1e-300)))
    k = min(k, (len(anchors) - 1) // MIN_THINNED_INTERVALS)
    if k < 2:
        return anchors, None
    return np.unique(np.concatenate([anchors[::k], anchors[-1:]])), math.sqrt(var_ref)


def thinned(run, anchors, use, valid, var_rate):
    """The reference judged interval by interval (``use``, ``valid`` per interval of ``anchors``)
    and compared over the longer intervals of :func:`thinned_anchors`: a longer interval is used on
    an axis only where every interval in it is, and valid only where every one is. Returns
    (anchors, use, valid, notes)."""
    thin, sigma_ref = thinned_anchors(run, anchors, var_rate)
    if len(thin) == len(anchors):
        return anchors, use, valid, []
    grp = np.searchsorted(thin, anchors[:-1], side="right") - 1
    m = len(thin) - 1
    use_t = np.stack([np.bincount(grp, weights=~use[:, c], minlength=m) == 0 for c in range(3)], 1)
    valid_t = np.bincount(grp, weights=~np.asarray(valid, bool), minlength=m) == 0
    note = (f"the reference's own attitude noise ({sigma_ref:.3g} rad per row) dominates the gyro's over one "
            f"interval: judged over {len(anchors) - 1} intervals, compared with the gyro over {m} longer ones, "
            "where it telescopes away")
    return thin, use_t & valid_t[:, None], valid_t, [note]


def anchor_rows(ref_rows, windowed=False):
    """Anchor rows: at most 3000 intervals of at least :data:`MIN_INTERVAL_ROWS` rows.

    Over a few steps the interpolated step rates share samples, so the interval errors are neither
    independent nor of variance N^2 dt_i (chi2/dof 0.6 for single steps), and the scale's
    errors-in-variables correction no longer holds; from about 10 rows on both do (measured).
    Rates integrated from their own windows (``windowed``) have no interpolation to share: the
    integral between two reference rows is exact there, and every reference row is an anchor
    (within the 3000).
    """
    step = max(MIN_INTERVAL_ROWS if not windowed else 1, int(math.ceil((ref_rows[-1] - ref_rows[0]) / 3000.0)))
    grid = np.arange(ref_rows[0], ref_rows[-1], step)
    return np.unique(np.concatenate([ref_rows[np.searchsorted(ref_rows, grid)], ref_rows[-1:]]))
