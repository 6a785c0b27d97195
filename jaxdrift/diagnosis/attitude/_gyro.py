"""Gyro bias, scale and bias drift estimators: the reference-attitude fit, REML for a bias random
walk, and the static segment.

- :func:`reference_fit`: between consecutive anchor rows the gyro-integrated relative rotation is
  compared with the reference one; the global-frame error vector of each interval is linear in the
  rate errors, ``e = sum_k R_k delta_k dt``, so biases (piecewise constant over segments) and scales
  are fitted by Gauss-Newton weighted least squares with the noise covariance ``N^2 dt_i I``.
- :func:`reml_drift`: bias drift (rate random walk) tested and estimated by REML on the segment
  biases, whose covariance under a random walk of intensity K is :func:`rw_cov` (closed form).
- :func:`static_segment`: windows whose rate variance equals the white-noise variance and whose
  means agree are taken as standing still (true rate 0): their mean is the bias.
"""

from __future__ import annotations

import math
from functools import partial

import numpy as np
from scipy import stats

from ...models._quaternion import (
    cumulative_quat_product_np,
    quat_conjugate_np,
    quat_exp_np,
    quat_log_np,
    quat_multiply_np,
    rotation_matrix_np,
)
from ._decay import _decay_record, corrected_anchors, decay_profile, decay_terms, n_decay

__all__ = ["reference_fit", "reference_noise_var", "gyro_halves", "gls_agrees", "gls_holds", "test_se", "half_rate_fit", "cluster_cov", "rw_cov", "reml_drift", "static_segment", "convention_terms"]


def _interval_sums(X, starts, ends):
    """Sums of rows ``X[starts[i]:ends[i]]`` (contiguous, ends[i] == starts[i+1])."""
    c = np.concatenate([np.zeros((1,) + X.shape[1:]), np.cumsum(X, 0)], 0)
    return c[ends] - c[starts]


def convention_terms(wc):
    """``(omega_k, D1_k - D3_k / 12)`` of each step: the rate over step k in the sampling
    convention ``lam`` of :func:`reference_fit` is ``omega_k + lam (D1_k - D3_k / 12)``. ``wc``
    holds the rows around the n steps: one before them, the n rows that start them, two after."""
    w0, w1, w2, wm = wc[1:-2], wc[2:-1], wc[3:], wc[:-3]
    return w0, (w1 - w0) - (w2 - w1 - w0 + wm) / 12.0


def _tridiag_inv_diag(d, o):
    """Diagonal of the inverse of the symmetric tridiagonal matrix with diagonal ``d`` and
    off-diagonal ``o`` (len(d) - 1), by the two ratio recurrences (no overflow at any size)."""
    n = len(d)
    r = np.empty(n)
    s_ = np.empty(n)
    r[0] = d[0]
    for i in range(1, n):
        r[i] = d[i] - o[i - 1] ** 2 / r[i - 1]
    s_[-1] = d[-1]
    for i in range(n - 2, -1, -1):
        s_[i] = d[i] - o[i] ** 2 / s_[i + 1]
    return 1.0 / (r + s_ - d)


def _whiteners(noise_var, ref_var, dt_int, use):
    """Per global axis: (used interval indices, the lower banded Cholesky factor of their residuals'
    covariance, the diagonal of its inverse). An interval's residual holds the gyro's white noise
    integrated over it (``noise_var dt_i``) and the reference's own attitude noise at both of its
    rows (``2 ref_var``); neighbours share a row, so they covary by ``-ref_var`` (white attitude noise
    read interval by interval: it telescopes over a run, and the weighting by this covariance is the
    generalised least squares that lets it)."""
    from scipy.linalg import cholesky_banded

    out = []
    for a in range(3):
        u = np.nonzero(use[:, a])[0]
        d = noise_var * dt_int[u] + 2.0 * ref_var
        o = np.where(np.diff(u) == 1, -ref_var, 0.0)
        ab = np.zeros((2, len(u)))
        ab[0] = d
        ab[1, :-1] = o
        out.append((u, cholesky_banded(ab, lower=True) if len(u) else ab, _tridiag_inv_diag(d, o) if len(u) else d))
    return out


def _whiten(white, X):
    """``X`` (n_int, 3, ...) with each axis's used rows replaced by L^-1 of them (unused rows 0)."""
    from scipy.linalg import solve_banded

    out = np.zeros_like(X)
    for a, (u, L, _) in enumerate(white):
        if len(u):
            out[u, a] = solve_banded((1, 0), L, X[u, a].reshape(len(u), -1)).reshape(X[u, a].shape)
    return out


def _prefix_rotations(d):
    """Prefix products (rows + 1, 4) of the step rotations ``d`` from the identity, normalised."""
    P = np.empty((len(d) + 1, 4))
    P[0] = [1, 0, 0, 0]
    P[1:] = cumulative_quat_product_np(d)
    return P / np.linalg.norm(P, axis=1, keepdims=True)


def _interval_errors(P, q, starts, ends, a0):
    """The rotation vectors (n_int, 3; global frame) by which the gyro's rotation over each interval
    (from the prefix products ``P``, whose row 0 is row ``a0``) misses the reference ``q``'s."""
    rel = quat_multiply_np(quat_conjugate_np(P[starts - a0]), P[ends - a0])
    return quat_log_np(quat_multiply_np(quat_multiply_np(q[starts], rel), quat_conjugate_np(q[ends])))


def reference_fit(run, noise_var, seg_of_interval_per_channel, anchors, sample_var=(0.0, 0.0, 0.0), max_iter=6,
                  use=None, hold_scale=(), hold_bias=(), ref_var=0.0, decay=None, fit_tau=True):
    """Gauss-Newton fit of piecewise biases and scales to the reference intervals.

    ``ref_var``: the reference's own attitude noise variance per row and axis [rad^2]; where it is
    positive the fit is generalised least squares with the intervals' covariance of
    :func:`_whiteners` (else weighted, each interval ``noise_var dt_i``).

    ``hold_scale``: channels whose scale is held at 1, ``hold_bias``: parameter indices of biases held
    at 0 (what the run does not determine, so that the rest is judged on its own).

    ``decay``: ``(tau, frame)``, an estimator's converging error (:func:`._decay.decay_regressor`), its
    three amplitudes the last parameters; ``(tau, frame, True)``: with a constant turn of the
    reference's frame beside it, three parameters more; and ``log tau``, fitted from ``tau`` unless
    ``fit_tau`` is False (a decay's test holds it at the profile's: fitted, it gains a degree of freedom
    the test's threshold does not count).

    ``use``: optional (n_int, 3) bool, the (interval, global axis) cells that enter the fit (the others
    get weight 0: a reference inconsistent there, :mod:`._consistency`, or an interval across a gap).

    ``seg_of_interval_per_channel``: list of 3 int arrays (segment index of each interval per channel).
    ``noise_var``: N^2 for the weights; ``sample_var``: per-channel white-noise variance per sample
    (for the errors-in-variables correction of the scale).
    Returns parameters, covariance, residual chi-square and helpers.
    """
    w = run["w"]
    w = np.where(np.isfinite(w), w, 0.0)  # rows of a gap: their intervals are left out by ``use``
    dt = run["dt"]
    q_ref = run["q_ref"]
    a0, aN = anchors[0], anchors[-1]
    starts, ends = anchors[:-1], anchors[1:]
    n_int = len(starts)
    nseg = [int(s.max()) + 1 for s in seg_of_interval_per_channel]
    offs = np.concatenate([[0], np.cumsum(nseg)])
    sc = int(offs[-1])
    # parameters: biases, 3 scales, and a sampling-convention nuisance lam: the rate held over step k
    # is omega_k + lam (D1_k - D3_k / 12), D1_k = omega_{k+1} - omega_k,
    # D3_k = omega_{k+2} - omega_{k+1} - omega_k + omega_{k-1}. Samples of a continuous rate at t_k give
    # the cubic step average, lam = 1/2; rates held over each step (the reference made by the
    # exponential map of omega_k) give lam = 0; a small gyro delay shifts lam. It is fitted: its
    # regressor telescopes over an interval, so it costs the other parameters almost nothing, while a
    # wrong fixed convention leaves O(dt) errors per interval that look like scale errors.
    # with the reference's noise weighed (GLS), a clock offset tau left between it and the gyro is a
    # nuisance parameter too: its error over an interval, R_b w_b tau - R_a w_a tau, telescopes like
    # the noise but follows the motion, and unfitted it would be read as a scale
    has_tau, i_dec = ref_var > 0, sc + 4 + (ref_var > 0)
    p = i_dec + n_decay(decay)
    theta = np.zeros(p)
    theta[sc : sc + 3] = 1.0
    theta[sc + 3] = 0.5
    if decay is not None:  # its time constant is fitted too, from ``decay``'s, within a factor of e of it
        log_tau0 = theta[p - 1] = math.log(decay[0])
    rows = np.arange(a0, aN)
    w_pad = np.concatenate([w[:1], w, w[-1:], w[-1:]], 0)  # w_pad[k + 1] = w[k]
    int_of_row = np.searchsorted(anchors, rows, side="right") - 1
    dt_int = (ends - starts) * dt
    wts = 1.0 / (noise_var * dt_int)  # per interval (each of 3 components)
    use = np.ones((n_int, 3), bool) if use is None else np.asarray(use, bool)
    white = _whiteners(noise_var, ref_var, dt_int, use) if ref_var > 0 else None
    if white is None:
        Wf = (wts[:, None] * use).reshape(-1)
        w_int = wts * use.mean(1)  # the errors-in-variables weight of each interval
    else:  # whitened rows: unit weights; the errors-in-variables weight is the precision's diagonal
        Wf = use.astype(float).reshape(-1)
        prec = np.zeros((n_int, 3))
        for a, (u, _, dinv) in enumerate(white):
            prec[u, a] = dinv
        w_int = prec.mean(1)
    nuisance = []  # (first index, regressor (n_int, 3, k)) of the parameters linear in e
    if has_tau:  # the offset's regressor: the reference's attitudes and the gyro at the anchors only
        Rw = np.einsum("nab,nb->na", rotation_matrix_np(q_ref[anchors]), w[anchors])
        nuisance.append((sc + 4, (Rw[1:] - Rw[:-1])[:, :, None]))
    q_anc = q_ref.copy() if decay is not None else q_ref
    for it in range(max_iter):
        if decay is not None:
            # the fitted decay (and turn) taken out exactly, the regressors its Jacobian (:mod:`._decay`)
            q_anc[anchors] = corrected_anchors(run, anchors, decay, theta[i_dec:p])
            X_dec = decay_terms(run, anchors, decay, theta[i_dec:p])
        b_rows = np.stack([theta[offs[c] + seg_of_interval_per_channel[c][int_of_row]] for c in range(3)], 1)
        s = theta[sc : sc + 3]
        lam = theta[sc + 3]
        b_ext = np.concatenate([b_rows[:1], b_rows, b_rows[-1:], b_rows[-1:]], 0)
        wc_all = (w_pad[a0 : aN + 3] - b_ext) / s  # rows a0-1 .. aN+1
        w0, dw = convention_terms(wc_all)
        wc = w0 + lam * dw  # rate over each step
        d = quat_exp_np(wc * dt)
        P = _prefix_rotations(d)  # re-anchored on the reference at every anchor (below)
        e = _interval_errors(P, q_anc, starts, ends, a0)  # (n_int, 3) global frame
        for i, X in nuisance:
            e = e + np.einsum("nab,b->na", X, theta[i:i + X.shape[2]])
        # attitude of each row, anchored on its interval's reference
        anc = anchors[int_of_row]
        G = quat_multiply_np(quat_multiply_np(q_anc[anc], quat_conjugate_np(P[anc - a0])), P[:-1])
        R = rotation_matrix_np(G) * dt  # (rows, 3, 3)
        J = np.zeros((n_int, 3, p))
        RB = _interval_sums(R, starts - a0, ends - a0)  # (n_int, 3, 3)
        RS = _interval_sums(R * wc[:, None, :], starts - a0, ends - a0)
        for c in range(3):
            cols = offs[c] + seg_of_interval_per_channel[c]
            J[np.arange(n_int), :, cols] = -RB[:, :, c] / s[c]
            J[:, :, sc + c] = -RS[:, :, c] / s[c]
        J[:, :, sc + 3] = _interval_sums(np.einsum("nab,nb->na", R, dw), starts - a0, ends - a0)
        for i, X in nuisance + ([(i_dec, X_dec)] if decay is not None else []):
            J[:, :, i:i + X.shape[2]] = X
        Jf = (J if white is None else _whiten(white, J)).reshape(-1, p)
        ef = (e if white is None else _whiten(white, e)).reshape(-1)
        H = Jf.T @ (Wf[:, None] * Jf)
        g = Jf.T @ (Wf * ef)
        # errors in variables: the scale regressor sum R omega_c dt carries the same white noise as e;
        # remove the expected product, (1/s^2) sum_i w_i n_i sigma_c^2 dt^2, from score and Hessian
        weak = []
        for c in range(3):
            eiv = float(np.sum(w_int * (ends - starts))) * sample_var[c] * dt**2 / s[c] ** 2
            if eiv > 0.25 * H[sc + c, sc + c] or c in hold_scale:
                # the rotation about this axis is too small against the noise: the corrected Hessian
                # would be near zero. The scale is not observable here; keep it at 1.
                weak.append(c)
                H[sc + c, :] = 0.0
                H[:, sc + c] = 0.0
                H[sc + c, sc + c] = 1.0
                g[sc + c] = theta[sc + c] - 1.0
                continue
            g[sc + c] += eiv
            H[sc + c, sc + c] -= eiv
        for i in tuple(hold_bias) + (() if decay is None or fit_tau else (p - 1,)):
            H[i, :] = 0.0
            H[:, i] = 0.0
            H[i, i] = 1.0
            g[i] = theta[i] - (log_tau0 if i == p - 1 and decay is not None else 0.0)
        step = -np.linalg.lstsq(H, g, rcond=1e-12)[0]
        theta = theta + step
        if decay is not None:
            theta[p - 1] = np.clip(theta[p - 1], log_tau0 - 1.0, log_tau0 + 1.0)
        se = np.sqrt(np.abs(np.diag(np.linalg.pinv(H, rcond=1e-12))))
        if np.all(np.abs(step) <= 1e-3 * se + 1e-15):
            break
    # residual after the last step (linearised)
    res = ef + Jf @ step
    chi2 = float(np.sum(Wf * res**2))
    dof = max(1, int(use.sum()) - p)
    cov = np.linalg.pinv(H, rcond=1e-12)
    # per-interval scores (the gradient's share of each interval at the solution), for the
    # cluster-robust covariance of :func:`cluster_cov`
    scores = np.einsum("nkp,nk->np", Jf.reshape(n_int, 3, p), (Wf * res).reshape(n_int, 3))
    return {
        "theta": theta, "cov": cov, "chi2": chi2, "dof": dof, "offs": offs, "nseg": nseg, "Jf": Jf, "Wf": Wf,
        "e": e, "res": res.reshape(-1, 3), "res_rad": e + np.einsum("nkp,p->nk", J, step), "dt_int": dt_int,
        "lam": float(theta[sc + 3]), "weak_scale": weak, "scores": scores, "H": H, "use": use, "ref_var": ref_var,
        "white": white, "whiten": (lambda X: X) if white is None else (lambda X: _whiten(white, X)),
        "decay": _decay_record(decay, theta, i_dec)}


def reference_noise_var(fit) -> float:
    """The reference's own attitude noise variance per row and axis [rad^2] from a fit's residuals
    (0 where it does not show): white attitude noise makes neighbouring intervals' residuals covary
    by ``-ref_var`` while the gyro's noise leaves them independent, so one interval's spread is
    ``2 ref_var + N^2 dt`` and two neighbours' sum's ``2 ref_var + 2 N^2 dt``: ``ref_var`` is the first
    less half the second (robust spreads: an optical marker's few jumps are outliers, not noise).
    Counted only where it is beyond three of its own standard errors (from the spreads' sampling
    error), so that a reference without noise is not given any."""
    from .._diffnoise import mad_sigma

    r, use = np.asarray(fit["res_rad"]), np.asarray(fit["use"], bool)
    v1, v2, n, lag1 = [], [], 0, 0.0
    for a in range(3):
        pair = use[:-1, a] & use[1:, a]
        if pair.sum() < 10:
            continue
        x, y = r[:-1, a][pair], r[1:, a][pair]
        v1.append(mad_sigma(x) ** 2)
        v2.append(mad_sigma(x + y) ** 2)
        n += int(pair.sum())
        # by ranks: an optical marker's few jumps (one row off and back) are opposite neighbours too
        lag1 += float(stats.spearmanr(x, y)[0]) * int(pair.sum()) if np.ptp(x) > 0 and np.ptp(y) > 0 else 0.0
    if not v1:
        return 0.0
    v1m, v2m = float(np.mean(v1)), float(np.mean(v2))
    est = v1m - 0.5 * v2m
    # a MAD spread's square has a sampling variance of about 5.4 v^2 / n (normal data, 37 %
    # efficiency); doubled for the two spreads' dependence
    se = math.sqrt(10.8 / n) * math.sqrt(v1m**2 + 0.25 * v2m**2)
    # or where neighbouring residuals are opposite beyond three standard errors of a rank correlation
    # (1/sqrt(n) without the reference's noise; a wandering bias makes them alike): the spreads'
    # own test is weak over a few dozen intervals (a 1 Hz reference over a minute)
    sparse = n < LAG1_BELOW
    return est if est > 3.0 * se or (sparse and est > 0 and lag1 / math.sqrt(n) < -3.0) else 0.0


#: below this many neighbouring pairs of intervals (over the three axes) the reference's noise may be
#: shown by their rank correlation as well: a 1 Hz reference over 80 s gives 234, where the spreads'
#: test read 2.3 standard errors; over hundreds of intervals the spreads suffice (on the mocap log
#: broad_05, 2500 pairs, the correlation weighed a noise they did not show and the refit flagged 6 spans)
LAG1_BELOW = 600


def half_rate_fit(run, noise_var, seg_of_interval_per_channel, anchors, sample_var=(0.0, 0.0, 0.0), use=None,
                  hold_scale=(), hold_bias=(), ref_var=0.0, decay=None):
    """:func:`reference_fit` on every other row (step 2 dt) between the anchors of the same parity as
    the first one (each interval keeps its segment), or None where fewer than two intervals remain.

    The integration's error (the step rates' interpolation, the coning of a rate that turns within a
    step) grows at least as dt^2, so the change of the estimates from dt to 2 dt is at least three times
    the error left at dt (Richardson): ``|theta(2 dt) - theta(dt)| / 3`` is the method part of their
    intervals. Rates that are step means (``run["w_unmeasured"]`` set: windows integrated onto the
    grid) are averaged in pairs instead.
    """
    a0 = int(anchors[0])
    anc = anchors[(anchors - a0) % 2 == 0]
    if len(anc) < 3:
        return None
    first_int = np.searchsorted(anchors, anc[:-1], side="right") - 1
    segs = [np.unique(sg[first_int], return_inverse=True)[1] for sg in seg_of_interval_per_channel]
    par = a0 % 2
    w2 = run["w"][par::2]
    if run.get("w_unmeasured") is not None:
        # rates that are means over their steps (windows integrated onto the grid): the same method at
        # 2 dt is the mean over two steps, not every other step's (which would read a vibration's
        # aliasing as the integration's error)
        w2 = w2.copy()
        m = len(run["w"][par + 1 :: 2])
        w2[:m] = 0.5 * (w2[:m] + run["w"][par + 1 :: 2])
    run2 = {"w": w2, "dt": 2.0 * run["dt"], "q_ref": run["q_ref"][par::2], "t": run["t"][par::2]}
    use2 = None
    if use is not None:  # a half-rate interval spans whole intervals of the full fit: all of them must be used
        last_int = np.searchsorted(anchors, anc[1:], side="right") - 2
        use2 = np.stack([use[a : b + 1].all(0) for a, b in zip(first_int, last_int)])
    return reference_fit(run2, noise_var, segs, (anc - par) // 2, sample_var, use=use2, hold_scale=hold_scale,
                         hold_bias=hold_bias, ref_var=ref_var, decay=decay)


def cluster_cov(fit, cluster_of_interval):
    """Cluster-robust (sandwich) covariance of the reference fit: ``H^-1 (sum_g s_g s_g^T) H^-1 G/(G-1)``
    with ``s_g`` the summed scores of the consecutive intervals of cluster ``g``.

    The model covariance assumes independent interval errors of variance ``N^2 dt_i``; a bias that
    wanders within its segments, or the discretisation's error that follows the motion, makes the
    errors of neighbouring intervals correlated, which the sandwich over clusters of them sees.
    """
    G = int(cluster_of_interval.max()) + 1
    if G < 3:
        return fit["cov"]
    sg = np.zeros((G, fit["scores"].shape[1]))
    np.add.at(sg, cluster_of_interval, fit["scores"])
    return fit["cov"] @ (sg.T @ sg) @ fit["cov"] * G / (G - 1)


def rw_cov(bounds):
    """Covariance of segment means of a standard Brownian motion W(0) = 0 over [bounds[m], bounds[m+1])."""
    mid = 0.5 * (bounds[:-1] + bounds[1:])
    L = np.diff(bounds)
    M = len(L)
    S = np.empty((M, M))
    for i in range(M):
        for j in range(M):
            if i == j:
                S[i, j] = bounds[i] + L[i] / 3.0
            else:
                S[i, j] = mid[min(i, j)]
    return S


def reml_drift(b, V, S_rw):
    """REML for ``b ~ N(beta 1, V + K^2 S_rw)``: MLE of K, 95 % profile interval, LR vs K = 0, beta."""
    M = len(b)
    X = np.ones((M, 1))

    def ll(K2):
        Sig = V + K2 * S_rw
        try:
            L = np.linalg.cholesky(Sig)
        except np.linalg.LinAlgError:
            return -np.inf, 0.0, np.inf
        Li = np.linalg.inv(L)
        Si = Li.T @ Li
        xsx = float((X.T @ Si @ X)[0, 0])
        beta = float((X.T @ Si @ b)[0]) / xsx
        r = b - beta
        val = -0.5 * (2 * np.sum(np.log(np.diag(L))) + np.log(xsx) + float(r @ Si @ r))
        return val, beta, 1.0 / xsx

    scale = max(float(np.max(np.abs(np.diff(b)))), 1e-30) ** 2 / max(float(np.max(np.diag(S_rw))), 1e-30)
    grid = np.concatenate([[0.0], scale * np.logspace(-8, 3, 400)])
    vals = np.array([ll(k2)[0] for k2 in grid])
    i = int(np.argmax(vals))
    # refine around the max
    lo_k, hi_k = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    fine = np.linspace(lo_k, hi_k, 200)
    fv = np.array([ll(k2)[0] for k2 in fine])
    j = int(np.argmax(fv))
    K2hat, lmax = fine[j], fv[j]
    allg = np.concatenate([grid, fine])
    allv = np.concatenate([vals, fv])
    order = np.argsort(allg)
    allg, allv = allg[order], allv[order]
    inside = allv >= lmax - 0.5 * stats.chi2.ppf(0.95, 1)
    k2lo, k2hi = allg[inside].min(), allg[inside].max()
    lr = 2.0 * (lmax - vals[0])
    _, beta, beta_var = ll(K2hat)
    return {"K": math.sqrt(K2hat), "interval": [math.sqrt(k2lo), math.sqrt(k2hi)], "lr": lr, "beta": beta, "beta_var": beta_var}


def static_segment(w, dt, sigma):
    n = w.shape[0]
    W = int(max(50, round(0.5 / dt)))
    nw = n // W
    if nw < 4:
        return None
    x = w[: nw * W].reshape(nw, W, 3)
    m = x.mean(1)
    v = x.var(1, ddof=1)
    s2 = np.maximum(sigma**2, 1e-30)
    ok_var = np.all(v / s2 < 1.0 + 5.0 * np.sqrt(2.0 / W), axis=1)
    ok_mean = np.ones(nw, bool)
    dm = np.abs(np.diff(m, axis=0))
    cons = np.all(dm < 5.0 * np.sqrt(2.0 * s2 / W) + 1e-12, axis=1)
    static = ok_var.copy()
    # a static window must agree in mean with a static neighbour
    ok_mean[:] = False
    ok_mean[:-1] |= cons & ok_var[1:]
    ok_mean[1:] |= cons & ok_var[:-1]
    static &= ok_mean
    best, cur, start = (0, 0), 0, 0
    for i, s in enumerate(static):
        if s:
            if cur == 0:
                start = i
            cur += 1
            if cur > best[1] - best[0]:
                best = (start, start + cur)
        else:
            cur = 0
    i0, i1 = best
    if i1 - i0 < 4 or (i1 - i0) * W * dt < 2.0:
        return None
    seg = w[i0 * W : i1 * W]
    return {"rows": (i0 * W, i1 * W), "mean": seg.mean(0), "n": seg.shape[0], "data": seg}


#: a scale is named only where the run's two halves, fitted apart, agree within this many standard
#: errors of their difference
HALVES_Z = 3.0
#: ... or within this share of the effect (a bias, or a scale's distance from 1)
HALVES_REL = 0.05


def gyro_halves(fit_fn, use, *args, **kw):
    """The scales, and the constant biases, fitted on the first and on the second half of the
    intervals apart (each half with the same model): ``{("scale" | "bias", channel): (agree, first,
    second)}``, agreeing where within :data:`HALVES_Z` standard errors of their difference. A scale
    or a bias is a constant of the gyro, while a bias wandering within its segments, or a reference
    whose error follows one stretch (an estimator converging), leaks into each half differently."""
    n_int = len(use)
    out = {}
    fits = []
    for half in (slice(0, n_int // 2), slice(n_int // 2, n_int)):
        u = np.zeros_like(use)
        u[half] = use[half]
        fits.append(fit_fn(*args, use=u, **kw))
    offs = fits[0]["offs"]
    for kind, c, i in [("scale", c, offs[-1] + c) for c in range(3)] + \
            [("bias", c, offs[c]) for c in range(3) if offs[c + 1] - offs[c] == 1]:
        a, b = (float(f["theta"][i]) for f in fits)
        v = sum(max(float(f["cov"][i, i]), 0.0) * max(1.0, f["chi2"] / f["dof"]) for f in fits)
        # or within HALVES_REL of the effect: a noise-free gyro under a reference weighed row by row
        # has errors of 1e-10 rad/s, and halves of -2.0e-5 and -2.0e-5 rad/s then read as "no constant bias"
        size = max(abs(a), abs(b)) if kind == "bias" else max(abs(a - 1.0), abs(b - 1.0))
        out[(kind, c)] = (abs(a - b) <= max(HALVES_Z * math.sqrt(v), HALVES_REL * size), a, b)
    return out


def test_se(se_model, se_interval, infl, coloured=False):
    """The standard error a finding is tested with: the model's (residual-inflated) one; where the
    residuals between reference rows are more than twice the white-noise level in variance (a real
    reference, with its own errors and a gyro filtered before logging: the white model is evidently
    wrong), the interval's one (cluster-robust, integration) when larger; where they are coloured
    (``coloured``: vibration, or correlated between neighbouring intervals), the interval's one."""
    if coloured:
        return se_interval
    return max(se_model, se_interval) if infl > 2.0 else se_model


#: the weighted (GLS) fit is kept where its biases and scales are within this many of the
#: unweighted fit's cluster-robust standard errors of the unweighted fit's
GLS_AGREE_Z = 4.0


def gls_agrees(fit_w, fit_g, z=GLS_AGREE_Z) -> bool:
    """A specification test in Hausman's manner for weighing the reference's noise: both fits are
    consistent where the reference's error is white per row, the weighted one then the more precise,
    so they differ by about the unweighted one's (cluster-robust) error. Where the reference's error
    is smooth instead (an estimator converging, a slow wobble of its frame), the weighted fit leans
    on it row by row and moves far: the weights are wrong, and not used."""
    n = len(fit_w["dt_int"])
    G = int(np.clip(n // 10, 1, 16))
    V = cluster_cov(fit_w, (np.arange(n) * G) // n)
    idx = np.arange(fit_w["offs"][-1] + 3)  # the biases and the scales
    d = np.abs(fit_w["theta"][idx] - fit_g["theta"][idx])
    se = np.sqrt(np.maximum(np.diag(V)[idx], 0.0)) * math.sqrt(max(1.0, fit_w["chi2"] / fit_w["dof"]) if G < 3 else 1.0)
    ok = se > 0
    return bool(np.all(d[ok] <= z * se[ok]))


def gls_holds(run, var_rate, one, use, ref_var, fit_w) -> bool:
    """Whether the fit weighed by the reference's noise (GLS) agrees with the unweighted one ``fit_w``
    (:func:`gls_agrees`; ``one``: constant biases' layout, the anchors, the sample variances),
    also where it does with an estimator's decay fitted in both (:func:`._decay.decay_profile`,
    profiled on the weighted fit): a converging reference's error is not white per row, but its decay
    is a nuisance the fit carries."""
    segs, anchors, sample_var = one
    fg = reference_fit(run, var_rate, segs, anchors, sample_var, use=use, ref_var=ref_var)
    if gls_agrees(fit_w, fg):
        return True
    dec = decay_profile(partial(reference_fit, ref_var=ref_var), fg, run, anchors, var_rate, *one, use=use)[0]
    return bool(dec) and gls_agrees(reference_fit(run, var_rate, *one, use=use, decay=dec),
                                    reference_fit(run, var_rate, *one, use=use, ref_var=ref_var, decay=dec))
