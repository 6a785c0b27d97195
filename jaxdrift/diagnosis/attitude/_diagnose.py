"""Diagnosis of attitude runs (docs/measured-data.md): gyro noise, bias, scale, bias drift, sensor
positions and rigidity of an accelerometer array, with 95 % intervals.

Methods (all on the run itself, numpy; see docs/attitude.md for the derivations):

- **Gyro noise** (always): the variance of the k-th differences of each rate channel, divided by
  ``C(2k, k)``, is the white-noise variance once the (smooth) motion no longer contributes; the order
  is raised until two consecutive orders agree. ``N = sigma_M sqrt(dt)``. Its standard error follows
  from the MA(k) autocorrelation of differenced white noise (``sum rho^2 = C(4k,2k)/C(2k,k)^2``).
  Allan deviation (allantools) of the best available error series gives N, B, K with fitted lines.
- **Reference attitude** (rows with ``qw..qz``): between consecutive anchor rows the gyro-integrated
  relative rotation is compared with the reference one; the global-frame error vector of each
  interval is linear in the rate errors, ``e = sum_k R_k delta_k dt``, so biases (piecewise constant
  over segments) and scales are fitted by Gauss-Newton weighted least squares with the noise
  covariance ``N^2 dt_i I``. Bias drift (rate random walk) is tested and estimated by REML on the
  segment biases, whose covariance under a random walk of intensity K is known in closed form.
- **Static segment** (no reference): windows whose rate variance equals the white-noise variance and
  whose means agree are taken as standing still (true rate 0): their mean is the bias.
- **Accelerometer array**: per sample, the rigid-body model ``a_i = c + (alpha~ + W) r_i`` with
  ``W = omega~ omega~`` from the gyro (bias-corrected for its noise) is fitted for ``c`` and ``alpha``;
  the residual is the rigidity residual; sensor position corrections (and, without another bias
  source, gyro biases through ``W``) are fitted by Gauss-Newton with block-sandwich covariances.
"""

from __future__ import annotations

import math
import os
import sys

import numpy as np
from scipy import stats

from ...models._quaternion import (
    cumulative_quat_product_np,
    integrate_rates_np,
    quat_conjugate_np,
    quat_exp_np,
    quat_log_np,
    quat_multiply_np,
    rotation_angle_between_np,
    rotation_matrix_np,
    skew_np,
)
from ...models._accel_array import check_positions
from ...io._attitude_files import read_attitude_run, read_sensors as _read_sensors

__all__ = ["run_attitude_diagnosis", "read_attitude_run", "read_sensors", "estimate_white_noise", "diagnose_attitude"]

SCHEMA = "jaxdrift.diagnosis/1"
CHANNELS = ("wx", "wy", "wz")
Z_SIGNIFICANT = 5.0  # |estimate - null| / SE for a systematic finding (false alarms ~ 1e-6 per test)
DRIFT_LR = 16.0  # REML likelihood-ratio threshold for a bias random walk
DRIFT_LR_GIVEN_BIAS = 6.0  # ... when a constant bias is significant on the channel (p ~ 0.7 %)
POSITION_CHI2 = 40.0  # 3-dof chi-square threshold for a displaced sensor
NONRIGID_FLOOR = 2e-3  # m/s^2: below this, a rigidity residual is not reported
# practical floors below which a statistically significant effect is the discretisation of the file
# (noise-free runs at 100 and 50 Hz show apparent scales of 1e-5 and 1.5e-4), not a gyro property
SCALE_FLOOR = 5e-4  # 500 ppm
BIAS_FLOOR = 1e-6  # rad/s (0.2 deg/h)
DRIFT_FLOOR = 1e-7  # rad/s/sqrt(s)
# without any white noise the residuals are the file's discretisation, which is correlated over the
# run and can pass the statistical tests (a noise-free 30 s run at 200 Hz showed an apparent drift of
# 3e-6 rad/s/sqrt(s)); such runs are synthetic, and the floors are raised by this factor
NOISE_FREE_FLOOR_FACTOR = 30.0
MIN_INTERVAL_ROWS = 20
DRIFT_OFF_DEG = 0.5
G = 9.81


def _usage_error(msg):
    from ...errors import UsageError

    return UsageError(msg)


def read_sensors(path, n_expected=None):
    """Read and validate ``{"positions": [[x, y, z], ...]}``: N >= 4 and positions not coplanar."""
    return _read_sensors(path, n_expected, check_geometry=check_positions)


# --------------------------------------------------------------------------- noise


def estimate_white_noise(x, dt, max_order: int = 8):
    """White-noise standard deviation of each column of ``x`` from k-th differences.

    Returns a dict with ``sigma`` (per column, per sample), ``var_se``, ``order`` and ``plateau``
    (False when the motion still dominated the highest order: then ``sigma`` is an upper bound).
    """
    x = np.asarray(x, float)
    n = x.shape[0]
    ests = []
    for k in range(1, max_order + 1):
        if n - k < 8:
            break
        d = np.diff(x, k, axis=0)
        ck = math.comb(2 * k, k)
        v = np.mean(d * d, axis=0) / ck
        rho2 = math.comb(4 * k, 2 * k) / ck**2
        se = v * np.sqrt(2.0 * rho2 / d.shape[0])
        ests.append((k, v, se))
    chosen = None
    for (k, v, se), (k2, v2, se2) in zip(ests[:-1], ests[1:]):
        if np.all(np.abs(v - v2) <= 3.0 * np.maximum(se, se2) + 1e-300):
            chosen = (k2, v2, se2)
            break
    plateau = chosen is not None
    if chosen is None:
        chosen = min(ests, key=lambda e: float(np.sum(e[1])))
    k, v, se = chosen
    return {"sigma": np.sqrt(v), "var": v, "var_se": se, "order": k, "plateau": plateau, "dt": dt}


# --------------------------------------------------------------------------- reference fit


def _interval_sums(X, starts, ends):
    """Sums of rows ``X[starts[i]:ends[i]]`` (contiguous, ends[i] == starts[i+1])."""
    c = np.concatenate([np.zeros((1,) + X.shape[1:]), np.cumsum(X, 0)], 0)
    return c[ends] - c[starts]


def _reference_fit(run, noise_var, seg_of_interval_per_channel, anchors, sample_var=(0.0, 0.0, 0.0), max_iter=6):
    """Gauss-Newton fit of piecewise biases and scales to the reference intervals.

    ``seg_of_interval_per_channel``: list of 3 int arrays (segment index of each interval per channel).
    ``noise_var``: N^2 for the weights; ``sample_var``: per-channel white-noise variance per sample
    (for the errors-in-variables correction of the scale).
    Returns parameters, covariance, residual chi-square and helpers.
    """
    w = run["w"]
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
    p = sc + 4
    theta = np.zeros(p)
    theta[sc : sc + 3] = 1.0
    theta[sc + 3] = 0.5
    rows = np.arange(a0, aN)
    w_pad = np.concatenate([w[:1], w, w[-1:], w[-1:]], 0)  # w_pad[k + 1] = w[k]
    int_of_row = np.searchsorted(anchors, rows, side="right") - 1
    dt_int = (ends - starts) * dt
    wts = 1.0 / (noise_var * dt_int)  # per interval (each of 3 components)
    for it in range(max_iter):
        b_rows = np.stack([theta[offs[c] + seg_of_interval_per_channel[c][int_of_row]] for c in range(3)], 1)
        s = theta[sc : sc + 3]
        lam = theta[sc + 3]
        b_ext = np.concatenate([b_rows[:1], b_rows, b_rows[-1:], b_rows[-1:]], 0)
        wc_all = (w_pad[a0 : aN + 3] - b_ext) / s  # rows a0-1 .. aN+1
        w0, w1, w2, wm = wc_all[1:-2], wc_all[2:-1], wc_all[3:], wc_all[:-3]
        dw = (w1 - w0) - (w2 - w1 - w0 + wm) / 12.0
        wc = w0 + lam * dw  # rate over each step
        d = quat_exp_np(wc * dt)
        # per-interval integration: prefix products restart at every anchor (re-anchored on the reference)
        P = np.empty((len(rows) + 1, 4))
        P[0] = [1, 0, 0, 0]
        P[1:] = cumulative_quat_product_np(d)
        P /= np.linalg.norm(P, axis=1, keepdims=True)
        Pa = P[starts - a0]
        Pb = P[ends - a0]
        rel = quat_multiply_np(quat_conjugate_np(Pa), Pb)  # gyro relative rotation over each interval
        qa = q_ref[starts]
        qb = q_ref[ends]
        err_q = quat_multiply_np(quat_multiply_np(qa, rel), quat_conjugate_np(qb))
        e = quat_log_np(err_q)  # (n_int, 3) global frame
        # attitude of each row, anchored on its interval's reference
        anc = anchors[int_of_row]
        G = quat_multiply_np(quat_multiply_np(q_ref[anc], quat_conjugate_np(P[anc - a0])), P[:-1])
        R = rotation_matrix_np(G) * dt  # (rows, 3, 3)
        J = np.zeros((n_int, 3, p))
        RB = _interval_sums(R, starts - a0, ends - a0)  # (n_int, 3, 3)
        RS = _interval_sums(R * wc[:, None, :], starts - a0, ends - a0)
        for c in range(3):
            cols = offs[c] + seg_of_interval_per_channel[c]
            J[np.arange(n_int), :, cols] = -RB[:, :, c] / s[c]
            J[:, :, sc + c] = -RS[:, :, c] / s[c]
        J[:, :, sc + 3] = _interval_sums(np.einsum("nab,nb->na", R, dw), starts - a0, ends - a0)
        Jf = J.reshape(-1, p)
        ef = e.reshape(-1)
        Wf = np.repeat(wts, 3)
        H = Jf.T @ (Wf[:, None] * Jf)
        g = Jf.T @ (Wf * ef)
        # errors in variables: the scale regressor sum R omega_c dt carries the same white noise as e;
        # remove the expected product, (1/s^2) sum_i w_i n_i sigma_c^2 dt^2, from score and Hessian
        weak = []
        for c in range(3):
            eiv = float(np.sum(wts * (ends - starts))) * sample_var[c] * dt**2 / s[c] ** 2
            if eiv > 0.25 * H[sc + c, sc + c]:
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
        step = -np.linalg.lstsq(H, g, rcond=1e-12)[0]
        theta = theta + step
        se = np.sqrt(np.abs(np.diag(np.linalg.pinv(H, rcond=1e-12))))
        if np.all(np.abs(step) <= 1e-3 * se + 1e-15):
            break
    # residual after the last step (linearised)
    res = ef + Jf @ step
    chi2 = float(np.sum(Wf * res**2))
    dof = max(1, len(ef) - p)
    cov = np.linalg.pinv(H, rcond=1e-12)
    return {
        "theta": theta, "cov": cov, "chi2": chi2, "dof": dof, "offs": offs, "nseg": nseg,
        "e": e, "res": res.reshape(-1, 3), "dt_int": dt_int, "lam": float(theta[sc + 3]), "weak_scale": weak,
    }


def _rw_cov(bounds):
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


def _reml_drift(b, V, S_rw):
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


# --------------------------------------------------------------------------- static segment


def _static_segment(w, dt, sigma):
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


# --------------------------------------------------------------------------- accelerometer array


def _array_residual(acc, r, W):
    """Rigid-model residual per sample: a_i - W r_i - (c + alpha x r_i) projected out. (n, N, 3)."""
    N = r.shape[0]
    D = np.zeros((3 * N, 6))
    for i in range(N):
        D[3 * i : 3 * i + 3, :3] = np.eye(3)
        D[3 * i : 3 * i + 3, 3:] = -skew_np(r[i])
    P = np.eye(3 * N) - D @ np.linalg.pinv(D)
    y = acc - np.swapaxes(W @ r.T, 1, 2)
    return (y.reshape(len(y), -1) @ P.T).reshape(y.shape)


def _array_fit(acc, r, w_gyro, dt, sigma_gyro, fit_bias: bool, n_blocks=20, max_rows=20_000):
    """Fit sensor position corrections (and optionally gyro biases) to the rigid-body array model.

    The residual uses ``W = omega~ omega~`` of each sample's rate, made unbiased for the gyro noise
    (``E[eps~ eps~]`` removed). The Gauss-Newton direction uses instruments: the Jacobian evaluated
    with the neighbours' mean rate ``(omega_{k-1} + omega_{k+1}) / 2``, whose noise is independent
    of sample ``k``'s, so the noisy rates in the regressors do not bias the fit (errors in variables).
    """
    n = acc.shape[0]
    stride = max(1, n // max_rows)
    idx = np.arange(1, n - 1, stride)
    w_s = w_gyro[idx]
    w_i = 0.5 * (w_gyro[idx - 1] + w_gyro[idx + 1])
    A = acc[idx]
    ns = A.shape[0]
    N = r.shape[0]
    s2 = np.asarray(sigma_gyro, float) ** 2

    def corr(v):
        return np.diag([v[1] + v[2], v[0] + v[2], v[0] + v[1]])

    def resid(theta, om_base, cvar):
        dpos = theta[: 3 * N].reshape(N, 3)
        b = theta[3 * N :] if fit_bias else np.zeros(3)
        om = om_base - b
        Wm = skew_np(om) @ skew_np(om) + corr(cvar)
        return _array_residual(A, r + dpos, Wm).reshape(ns, -1)

    def jac(theta, om_base, cvar, r0):
        J = np.empty((r0.size, p))
        for j in range(p):
            h = 1e-6 if j < 3 * N else 1e-7
            tp = theta.copy()
            tp[j] += h
            J[:, j] = (resid(tp, om_base, cvar) - r0).reshape(-1) / h
        return J

    p = 3 * N + (3 if fit_bias else 0)
    theta = np.zeros(p)
    for it in range(8):
        r0 = resid(theta, w_s, s2)
        ri = resid(theta, w_i, s2 / 2)
        Z = jac(theta, w_i, s2 / 2, ri)
        step = -np.linalg.pinv(Z.T @ Z, rcond=1e-10) @ (Z.T @ r0.reshape(-1))
        theta = theta + step
        if it > 0 and np.max(np.abs(step)) < 1e-7:
            break
    r0 = resid(theta, w_s, s2)
    ri = resid(theta, w_i, s2 / 2)
    Z = jac(theta, w_i, s2 / 2, ri)
    Z3 = Z.reshape(ns, -1, p)
    Hi = np.linalg.pinv(Z.T @ Z, rcond=1e-10)
    blocks = np.array_split(np.arange(ns), n_blocks)
    gs = np.stack([np.einsum("nkp,nk->p", Z3[bk], r0[bk]) for bk in blocks])
    cov_s = Hi @ (gs.T @ gs) @ Hi * n_blocks / (n_blocks - 1)
    # model-based covariance: the residual noise that the gyro's white noise makes through W, per
    # sample (G_t = d rho_t / d omega), scaled up if the residual has more power than that. The block
    # sandwich alone is too optimistic when the information comes from a few events (curves).
    G = np.empty((ns, r0.shape[1], 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = 1e-6
        G[:, :, k] = (resid(theta, w_s + e, s2) - r0) / 1e-6
    ZG = np.einsum("nkp,nkj->npj", Z3, G) * np.sqrt(s2)[None, None, :]
    meat_m = np.einsum("npj,nqj->pq", ZG, ZG)
    pred = float(np.sum(G**2 * s2[None, None, :]))
    ratio = max(1.0, float(np.sum(r0**2)) / max(pred, 1e-300))
    cov_m = Hi @ meat_m @ Hi * ratio
    if pred <= 0:
        cov = cov_s
    else:
        dm = np.sqrt(np.maximum(np.diag(cov_m), 1e-300))
        f = np.sqrt(np.maximum(np.diag(cov_s) / dm**2, 1.0))
        cov = cov_m * np.outer(f, f)
    return {"theta": theta, "cov": cov, "resid": r0.reshape(ns, N, 3), "blocks": blocks, "k_s": 1, "stride": stride,
            "idx": idx, "wbar": w_s, "corr": corr(s2), "A": A}


def _rigidity_rms(resid, N, blocks):
    dof = 3 * N - 6
    e = np.sum(resid**2, axis=(1, 2)) / dof
    per_block = np.array([e[b].mean() for b in blocks])
    m = per_block.mean()
    se = per_block.std(ddof=1) / np.sqrt(len(blocks))
    return m, se, len(blocks)


# --------------------------------------------------------------------------- Allan


def _allan(series, dt):
    """Overlapping Allan deviation per axis (allantools) and a fit of N, B, K (IEEE 952)."""
    import allantools

    out = {"taus": None, "adev": [], "fit": None}
    n = series.shape[0]
    taus_all = None
    for c in range(series.shape[1]):
        taus, adev, _, _ = allantools.oadev(series[:, c], rate=1.0 / dt, data_type="freq", taus="octave")[:4]
        keep = taus <= n * dt / 9.0  # enough averages for a stable estimate
        taus_all = taus[keep]
        out["adev"].append(adev[keep])
    out["taus"] = taus_all
    av = np.mean(np.square(out["adev"]), axis=0)  # axis-averaged Allan variance
    # sigma^2(tau) = N^2 / tau + (0.664 B)^2 + K^2 tau / 3, fitted with relative weights (NNLS)
    from scipy.optimize import nnls

    X = np.stack([1.0 / taus_all, np.full_like(taus_all, 0.664**2), taus_all / 3.0], 1)
    wgt = 1.0 / np.maximum(av, 1e-300)
    coef, _ = nnls(X * wgt[:, None], av * wgt)
    N_, B_, K_ = np.sqrt(coef)
    out["fit"] = {"N": float(N_), "B": float(B_), "K": float(K_)}
    return out


# --------------------------------------------------------------------------- main


def _finding(cause, estimate, unit, interval, evidence, z, **extra):
    f = {"cause": cause}
    f.update(extra)
    f.update({"estimate": estimate, "unit": unit, "interval": interval, "evidence": evidence})
    return f, z


def _fmt(x):
    return f"{x:.3g}"


def run_attitude_diagnosis(run_path: str, sensors_path: str | None = None, plots_dir: str | None = None) -> dict:
    """Diagnose an attitude run (docs/measured-data.md); return the report dict (kind "attitude").

    Raises :class:`jaxdrift.cli.UsageError` on bad input before anything is written. With
    ``plots_dir``, writes ``allan.png`` (and ``attitude_error.png``, ``array_residual.png`` where the
    run has what they need) after the analysis succeeded.
    """
    run = read_attitude_run(run_path)
    positions = None
    if run["acc"] is not None:
        if sensors_path is None:
            raise _usage_error(f"{run_path}: the run has accelerometer columns; give their positions with --sensors SENSORS.json")
        positions = read_sensors(sensors_path, run["acc"].shape[1])
    elif sensors_path is not None:
        raise _usage_error(f"{sensors_path}: sensor positions given but {run_path} has no accelerometer columns (a1x, a1y, a1z, ...)")
    report, plots = diagnose_attitude(run, positions)
    if plots_dir is not None:
        os.makedirs(plots_dir, exist_ok=True)
        report["plots"] = _write_plots(plots, plots_dir)
    return report


def diagnose_attitude(run, positions=None):
    """The analysis behind :func:`run_attitude_diagnosis` on an already validated run dict."""
    t, dt, w = run["t"], run["dt"], run["w"]
    n = len(t)
    T = t[-1] - t[0]
    q_ref = run["q_ref"]
    notes = []
    observed = []
    not_observed = []
    findings = []  # (finding, z)
    plots = {}
    if run.get("extra_columns"):
        print(f"jaxdrift diagnose: warning: ignoring column(s) {', '.join(run['extra_columns'])}", file=sys.stderr)

    # ---- gyro noise
    wn = estimate_white_noise(w, dt)
    var_pooled = float(np.mean(wn["var"]))
    var_se = float(np.sqrt(np.sum(np.square(wn["var_se"]))) / 3.0)
    # below this a "noise" is rounding or numerical differentiation, not a gyro: three times the
    # quantisation of the file's digits, or 1e-6 of the RMS rate (navigation-grade gyros at 1 kHz
    # are near 2e-5 rad/s per sample, far above)
    floor = max(3.0 * run["quantisation"], 1e-6 * float(np.sqrt(np.mean(w**2))), 1e-15)
    noise_found = wn["plateau"] and math.sqrt(var_pooled) > floor
    sigma_axis = wn["sigma"] if noise_found else np.zeros(3)
    N_hat = math.sqrt(var_pooled * dt) if noise_found else 0.0
    noise_var_rate = max(var_pooled * dt, (floor**2) * dt, 1e-24)  # N^2 for weights
    if noise_found:
        z95 = stats.norm.ppf(0.975)
        lo = math.sqrt(max(var_pooled - z95 * var_se, 0.0) * dt)
        hi = math.sqrt((var_pooled + z95 * var_se) * dt)
        noise_finding = {
            "cause": "gyro_noise", "estimate": N_hat, "unit": "rad/sqrt(s)", "interval": [lo, hi],
            "evidence": (
                f"order-{wn['order']} differences of the rates are white with per-sample std "
                f"{', '.join(_fmt(s) for s in sigma_axis)} rad/s (wx, wy, wz) at dt={_fmt(dt)} s; "
                f"N = sigma sqrt(dt) = {_fmt(N_hat)} rad/sqrt(s) = {_fmt(np.degrees(N_hat) * 60)} deg/sqrt(h)"
            ),
        }
    else:
        noise_finding = None
        notes.append(
            "no white gyro noise above the rounding of the file"
            if wn["plateau"] else "rate differences never became white: noise not separable from the motion"
        )

    ff = 1.0 if noise_found else NOISE_FREE_FLOOR_FACTOR
    scale_floor, bias_floor = SCALE_FLOOR * ff, BIAS_FLOOR * ff
    # noise-free runs at 100 Hz showed apparent drifts up to 2e-5 (curves): 1e-4 there
    drift_floor = DRIFT_FLOOR if noise_found else 1e-4
    corrections = {c: {"bias": 0.0, "scale": 1.0} for c in CHANNELS}
    bias_path = np.zeros((n, 3))
    scale = np.ones(3)
    bias_source = None
    allan_series, allan_label = None, None
    sim_err = {}
    gain = None

    # ---- reference attitude
    n_ref = 0 if q_ref is None else int(np.sum(np.isfinite(q_ref[:, 0])))
    if n_ref >= 2:
        ref_rows = np.nonzero(np.isfinite(q_ref[:, 0]))[0]
        # anchors: at most 3000 intervals of at least MIN_INTERVAL_ROWS rows. Over a few steps the
        # interpolated step rates share samples, so the interval errors are neither independent nor
        # of variance N^2 dt_i (chi2/dof 0.6 for single steps), and the scale's errors-in-variables
        # correction no longer holds; from about 10 rows on both do (measured).
        step = max(MIN_INTERVAL_ROWS, int(math.ceil((ref_rows[-1] - ref_rows[0]) / 3000.0)))
        grid = np.arange(ref_rows[0], ref_rows[-1], step)
        anchors = np.unique(np.concatenate([ref_rows[np.searchsorted(ref_rows, grid)], ref_rows[-1:]]))
        n_int = len(anchors) - 1
        T_ref = (anchors[-1] - anchors[0]) * dt
        M = int(np.clip(min(n_int // 10, T_ref / 2.0), 1, 16))  # bias segments (drift test)
        int_seg = np.minimum((np.arange(n_int) * M) // n_int, M - 1)
        fit0 = _reference_fit(run, noise_var_rate, [int_seg] * 3, anchors, sigma_axis**2)
        infl = max(1.0, fit0["chi2"] / fit0["dof"])
        bias_source = "reference"
        observed.append(f"reference attitude on {n_ref} rows ({n_int} intervals used)")
        drift = {}
        if M >= 4:
            bounds_rows = np.concatenate([anchors[:-1][np.searchsorted(int_seg, np.arange(M))], [anchors[-1]]])
            bounds = (bounds_rows - 0) * dt  # time since the first row
            S_rw = _rw_cov(bounds)
            for c in range(3):
                sl = slice(fit0["offs"][c], fit0["offs"][c + 1])
                b = fit0["theta"][sl]
                V = fit0["cov"][sl, sl] * infl
                d = _reml_drift(b, V, S_rw)
                # a constant bias that is significant may be the mean of a wandering one: then the
                # choice is between two models of the same size and a lower threshold applies
                Vi = np.linalg.pinv(V)
                one = np.ones(len(b))
                z_const = abs(one @ Vi @ b) / math.sqrt(max(one @ Vi @ one, 1e-300))
                thr = DRIFT_LR_GIVEN_BIAS if z_const > Z_SIGNIFICANT else DRIFT_LR
                d["z_const"] = float(z_const)
                if d["lr"] > thr and d["K"] > drift_floor:
                    drift[c] = d
        else:
            not_observed.append("gyro bias drift (reference spans too few intervals for bias segments)")
        seg_final = [int_seg if c in drift else np.zeros(n_int, int) for c in range(3)]
        fit = _reference_fit(run, noise_var_rate, seg_final, anchors, sigma_axis**2)
        infl = max(1.0, fit["chi2"] / fit["dof"])
        cov = fit["cov"] * infl
        th = fit["theta"]
        offs = fit["offs"]
        z95 = stats.norm.ppf(0.975)
        sc_idx = offs[-1]
        rows_int = np.clip(np.searchsorted(anchors, np.arange(n), side="right") - 1, 0, n_int - 1)
        for c in range(3):
            ch = CHANNELS[c]
            s_hat, s_se = th[sc_idx + c], math.sqrt(max(cov[sc_idx + c, sc_idx + c], 0.0))
            if c in fit["weak_scale"]:
                not_observed.append(f"scale of {ch} (too little rotation about it against the noise)")
            elif s_se > 0.05:
                not_observed.append(f"scale of {ch} (too little rotation about it: SE {_fmt(s_se)})")
            elif abs(s_hat - 1) / max(s_se, 1e-300) > Z_SIGNIFICANT and abs(s_hat - 1) > scale_floor:
                scale[c] = s_hat
                findings.append(_finding(
                    "gyro_scale", float(s_hat), "ratio", [float(s_hat - z95 * s_se), float(s_hat + z95 * s_se)],
                    f"rotation about {ch} between reference rows is {_fmt(s_hat)} times the gyro's "
                    f"(z = {_fmt(abs(s_hat - 1) / s_se)})",
                    abs(s_hat - 1) / s_se, channel=ch))
            corrections[ch]["scale"] = float(scale[c])
            sl = slice(offs[c], offs[c + 1])
            if c in drift:
                d = drift[c]
                b0, b0_se = d["beta"], math.sqrt(d["beta_var"])
                findings.append(_finding(
                    "gyro_bias_drift", d["K"], "rad/s/sqrt(s)", [float(v) for v in d["interval"]],
                    f"the {ch} bias over {M} segments wanders like a random walk (REML likelihood ratio "
                    f"{_fmt(d['lr'])} against a constant bias)",
                    math.sqrt(max(d["lr"], 0.0)), channel=ch))
                bias_path[:, c] = th[sl][seg_final[c][rows_int]]
                corrections[ch]["bias_drift"] = float(d["K"])
            else:
                b0, b0_se = th[sl][0], math.sqrt(max(cov[sl, sl][0, 0], 0.0))
            if abs(b0) / max(b0_se, 1e-300) > Z_SIGNIFICANT and abs(b0) > bias_floor:
                corrections[ch]["bias"] = float(b0)
                if c not in drift:
                    bias_path[:, c] = b0
                findings.append(_finding(
                    "gyro_bias", float(b0), "rad/s", [float(b0 - z95 * b0_se), float(b0 + z95 * b0_se)],
                    f"integrated {ch} departs from the reference like a constant rate error of {_fmt(b0)} rad/s "
                    f"(z = {_fmt(abs(b0) / b0_se)})" + (" at t0, under the random-walk drift" if c in drift else ""),
                    abs(b0) / b0_se, channel=ch))
        if infl > 1.5:
            notes.append(f"reference residuals are {_fmt(math.sqrt(infl))} times the gyro noise: intervals widened by that factor")
        # simulation error and gain: integrate from the first reference row
        a0 = ref_rows[0]
        ok = ref_rows
        q0 = q_ref[a0]

        lam = fit["lam"]

        def err_of(rates):
            r_ = np.concatenate([rates[a0 : a0 + 1], rates[a0:], rates[-1:], rates[-1:]], 0)
            w0, w1, w2, wm = r_[1:-2], r_[2:-1], r_[3:], r_[:-3]
            step = w0 + lam * ((w1 - w0) - (w2 - w1 - w0 + wm) / 12.0)
            qi = integrate_rates_np(q0, step, dt)
            return rotation_angle_between_np(qi[ok - a0], q_ref[ok])

        e_before = err_of(w)
        w_corr = (w - bias_path) / scale
        e_after = err_of(w_corr)
        thr = np.radians(DRIFT_OFF_DEG)
        off = np.nonzero(e_before > thr)[0]
        sim_err["attitude"] = {
            "rms": float(np.sqrt(np.mean(e_before**2))), "max_abs": float(np.max(e_before)),
            "drift_off_time_s": float(t[ok[off[0]]] - t[a0]) if len(off) else None,
            "threshold_rad": float(thr), "unit": "rad",
            "what": "angle of the rotation between the gyro-integrated attitude (from the first reference row) and the reference",
        }
        gain = {"metric": "attitude_error_rms", "before": sim_err["attitude"]["rms"], "after": float(np.sqrt(np.mean(e_after**2))), "unit": "rad"}
        plots["attitude"] = (t[ok], e_before, e_after)
        # error series for Allan: per-sample rate error against the reference (dense reference only)
        if n_ref >= 0.9 * n and n > 1000:
            dq = quat_multiply_np(quat_conjugate_np(q_ref[:-1]), q_ref[1:])
            w_ref = quat_log_np(dq) / dt
            good = np.isfinite(w_ref).all(1)
            allan_series = (w[:-1] - scale * w_ref)[good]
            allan_label = "gyro minus reference-derived rate"
    else:
        if n_ref == 1:
            notes.append("one reference row only: used as the initial attitude, no bias information")
        not_observed.append("attitude departure (no reference attitude over more than one row)")
        st = _static_segment(w, dt, wn["sigma"] if noise_found else np.zeros(3))
        if st is not None:
            bias_source = "static"
            i0, i1 = st["rows"]
            observed.append(f"static segment t = {_fmt(t[i0])}..{_fmt(t[i1 - 1])} s (assumed at rest, true rate 0)")
            z95 = stats.norm.ppf(0.975)
            for c in range(3):
                ch = CHANNELS[c]
                b = float(st["mean"][c])
                se = math.sqrt(max(wn["var"][c], floor**2) / st["n"])
                corrections[ch]["bias"] = b
                bias_path[:, c] = b
                if abs(b) / se > Z_SIGNIFICANT and abs(b) > bias_floor:
                    findings.append(_finding(
                        "gyro_bias", b, "rad/s", [float(b - z95 * se), float(b + z95 * se)],
                        f"{ch} reads {_fmt(b)} rad/s on average while standing still ({_fmt((i1 - i0) * dt)} s, z = {_fmt(abs(b) / se)})",
                        abs(b) / se, channel=ch))
            allan_series, allan_label = st["data"], "rates in the static segment"
            not_observed.append("gyro scale (needs a reference attitude)")
            not_observed.append("gyro bias drift (needs a reference attitude)")
            sim_err["static_rate"] = {"rms": float(np.sqrt(np.mean(st["mean"] ** 2))), "unit": "rad/s"}
            gain = {"metric": "static_mean_rate_rms", "before": float(np.sqrt(np.mean(st["mean"] ** 2))), "after": 0.0, "unit": "rad/s"}

    # ---- accelerometer array
    if positions is not None:
        acc = run["acc"]
        N = positions.shape[0]
        fit_bias = bias_source is None
        w_use = (w - bias_path) / scale
        af = _array_fit(acc, positions, w_use, dt, sigma_axis, fit_bias=fit_bias)
        observed.append(f"accelerometer array of {N} sensors (rigid-body residual, sensor positions)")
        th, cov = af["theta"], af["cov"]
        nb = len(af["blocks"])
        tq = stats.t.ppf(0.975, nb - 1)
        dpos = th[: 3 * N].reshape(N, 3)
        excluded = []
        pos_found = []
        for _ in range(N - 3):
            best = None
            for j in range(N):
                if j in excluded:
                    continue
                others = [i for i in range(N) if i != j and i not in excluded]
                L = np.zeros((3, len(th)))
                L[:, 3 * j : 3 * j + 3] = np.eye(3)
                for i in others:
                    L[:, 3 * i : 3 * i + 3] -= np.eye(3) / len(others)
                dj = L @ th
                Cj = L @ cov @ L.T
                chi2 = float(dj @ np.linalg.solve(Cj + 1e-300 * np.eye(3), dj))
                if best is None or chi2 > best[0]:
                    best = (chi2, j, dj, np.sqrt(np.diag(Cj)))
            if best is None or best[0] < POSITION_CHI2:
                break
            chi2, j, dj, se = best
            excluded.append(j)
            pos_found.append(_finding(
                "sensor_position", [float(v) for v in dj], "m", [[float(v) for v in dj - tq * se], [float(v) for v in dj + tq * se]],
                f"the accelerations of sensor {j + 1} fit the rigid-body motion seen by the gyro best with its position "
                f"moved by [{', '.join(_fmt(v) for v in dj)}] m relative to the others (chi-square {_fmt(chi2)}, 3 dof)",
                math.sqrt(chi2), sensor=j + 1))
        # rigidity residual with the given positions, and the share a full position fit explains
        W_of = lambda om: skew_np(om) @ skew_np(om) + af["corr"]  # noqa: E731
        b_arr = th[3 * N :] if fit_bias else np.zeros(3)
        resid_before = _array_residual(af["A"], positions, W_of(af["wbar"] - b_arr))
        m2b, _, _ = _rigidity_rms(resid_before, N, af["blocks"])
        m2all, _, _ = _rigidity_rms(af["resid"], N, af["blocks"])
        explained = 1.0 - m2all / max(m2b, 1e-300)
        pos_corr = np.zeros((N, 3))
        if pos_found and explained >= 0.5:
            findings.extend(pos_found)
            for j in excluded:
                others = [i for i in range(N) if i not in excluded]
                pos_corr[j] = dpos[j] - dpos[others].mean(0)
        elif pos_found:
            notes.append(
                f"position fits for sensor(s) {', '.join(str(j + 1) for j in excluded)} explain only "
                f"{100 * explained:.0f} % of the rigidity residual: not reported as sensor_position (the body is not rigid)"
            )
        for j in range(N):
            corrections[f"sensor{j + 1}"] = {"position": [float(v) for v in pos_corr[j]]}
        if fit_bias:
            z95 = stats.norm.ppf(0.975)
            for c in range(3):
                ch = CHANNELS[c]
                b = float(th[3 * N + c])
                se = math.sqrt(max(cov[3 * N + c, 3 * N + c], 0.0))
                if se > 0 and abs(b) / se > Z_SIGNIFICANT and abs(b) > bias_floor:
                    findings.append(_finding(
                        "gyro_bias", b, "rad/s", [float(b - tq * se), float(b + tq * se)],
                        f"the array's centripetal accelerations (M+ = omega~ omega~) match the gyro's {ch} only after "
                        f"removing {_fmt(b)} rad/s (z = {_fmt(abs(b) / se)})",
                        abs(b) / se, channel=ch))
                    corrections[ch]["bias"] = b
                    bias_path[:, c] = b
            bias_source = "array"
            observed.append("gyro biases through the array's centripetal terms")
        # rigidity residual after the reported corrections
        b_rep = np.array([corrections[c]["bias"] if bias_source == "array" else 0.0 for c in CHANNELS])
        resid_after = _array_residual(af["A"], positions + pos_corr, W_of(af["wbar"] - b_rep))
        m2, se2, nb2 = _rigidity_rms(resid_after, N, af["blocks"])
        resid_raw = _array_residual(af["A"], positions, W_of(af["wbar"])) if fit_bias else resid_before
        m2raw, _, _ = _rigidity_rms(resid_raw, N, af["blocks"])
        # the part of the residual that the gyro noise alone explains (W from noisy rates)
        rng = np.random.default_rng(0)
        eps = rng.normal(size=af["wbar"].shape) * sigma_axis
        om = af["wbar"]
        dW = skew_np(om + eps) @ skew_np(om + eps) - skew_np(om) @ skew_np(om)
        r_fit = positions + pos_corr
        gn = _array_residual(np.einsum("nab,kb->nka", dW, r_fit), r_fit, np.zeros_like(dW))
        m_gn, _, _ = _rigidity_rms(gn, N, af["blocks"])
        nr2 = max(m2 - m_gn, 0.0)
        nr = math.sqrt(nr2)
        sim_err["rigidity_residual"] = {"rms": float(math.sqrt(m2raw)), "unit": "m/s^2",
                                        "what": "RMS per residual degree of freedom of the rigid-body fit of the array with the given positions"}
        if nr > NONRIGID_FLOOR and nr2 > 5.0 * se2:
            tq2 = stats.t.ppf(0.975, nb2 - 1)
            # statistical interval of the residual power, then the unidentifiable share: the part of a
            # deformation that looks like rigid motion is absorbed by the fit. The estimate assumes an
            # isotropic deformation ((3N - 6) of 3N degrees of freedom seen); the interval spans from
            # "nothing hidden" (factor sqrt((3N-6)/3N)) to twice the isotropic hidden share.
            frac = (3 * N - 6) / (3 * N)
            lo = math.sqrt(max(nr2 - tq2 * se2, 0.0) * frac)
            hi = math.sqrt((nr2 + tq2 * se2) * (1.0 + 2.0 * (1.0 - frac)) / 1.0)
            findings.append(_finding(
                "nonrigid", nr, "m/s^2", [lo, hi],
                f"the array's accelerations depart from the best rigid-body motion by {_fmt(nr)} m/s^2 RMS per "
                f"degree of freedom (gyro noise accounts for {_fmt(math.sqrt(m_gn))})",
                nr2 / max(se2, 1e-300), ))
        if gain is None:
            gain = {"metric": "rigidity_residual_rms", "before": float(math.sqrt(m2raw)), "after": float(math.sqrt(m2)), "unit": "m/s^2"}
        plots["array"] = (t[af["idx"]], np.sqrt(np.sum(resid_raw**2, axis=(1, 2)) / (3 * N - 6)),
                          np.sqrt(np.sum(resid_after**2, axis=(1, 2)) / (3 * N - 6)))
    else:
        not_observed.append("sensor positions and rigidity (no accelerometer array)")

    if bias_source is None:
        not_observed.append("gyro bias (no reference attitude, no static segment, no accelerometer array)")
        not_observed.append("gyro scale and bias drift (need a reference attitude)")

    # ---- Allan deviation
    if allan_series is None:
        allan_series, allan_label = w - bias_path, "measured rates (the motion dominates at long tau)"
    allan = None
    if allan_series.shape[0] >= 64:
        allan = _allan(allan_series, dt)
        allan["series"] = allan_label
        plots["allan"] = allan
        if noise_finding is not None:
            noise_finding["evidence"] += f"; Allan deviation of the {allan_label} gives N = {_fmt(allan['fit']['N'])}"

    # ---- ranking
    findings.sort(key=lambda fz: -fz[1])
    ranked = [f for f, _ in findings]
    if noise_finding is not None:
        ranked.append(noise_finding)
    if not ranked:
        ranked = [{"cause": "none", "estimate": None, "unit": None, "interval": None,
                   "evidence": "no systematic effect and no white noise above the file's rounding"}]
    report = {
        "schema": SCHEMA,
        "kind": "attitude",
        "simulation_error": sim_err,
        "findings": ranked,
        "extended_model": {"corrections": corrections},
        "gain": gain if gain is not None else {"metric": None, "before": None, "after": None},
        "observability": {"used": observed, "not_observed": not_observed, "notes": notes},
        "allan": None if allan is None else {
            "series": allan["series"], "N": allan["fit"]["N"], "B": allan["fit"]["B"], "K": allan["fit"]["K"],
            "units": {"N": "rad/sqrt(s)", "B": "rad/s", "K": "rad/s/sqrt(s)"},
        },
        "run": {"rows": int(n), "dt": float(dt), "duration_s": float(T), "reference_rows": n_ref,
                "sensors": 0 if positions is None else int(positions.shape[0])},
    }
    return report, plots


def _write_plots(plots, out):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    written = []
    if "allan" in plots:
        a = plots["allan"]
        fig, ax = plt.subplots(figsize=(6, 4.5))
        for c, ad in enumerate(a["adev"]):
            ax.loglog(a["taus"], ad, "o-", ms=3, label=CHANNELS[c])
        f = a["fit"]
        tt = a["taus"]
        if f["N"] > 0:
            ax.loglog(tt, f["N"] / np.sqrt(tt), "k--", lw=1, label=f"N = {f['N']:.3g} rad/sqrt(s) (slope -1/2)")
        if f["B"] > 0:
            ax.loglog(tt, np.full_like(tt, 0.664 * f["B"]), "k:", lw=1, label=f"B = {f['B']:.3g} rad/s (flat)")
        if f["K"] > 0:
            ax.loglog(tt, f["K"] * np.sqrt(tt / 3.0), "k-.", lw=1, label=f"K = {f['K']:.3g} rad/s/sqrt(s) (slope +1/2)")
        ax.set_xlabel("tau [s]")
        ax.set_ylabel("Allan deviation [rad/s]")
        ax.set_title(f"Allan deviation: {a['series']}", fontsize=9)
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
        p = os.path.join(out, "allan.png")
        fig.tight_layout()
        fig.savefig(p, dpi=110)
        plt.close(fig)
        written.append(p)
    def before_after(tt, before, after, labels, ylabel, name, lw=None):
        fig, ax = plt.subplots(figsize=(6, 3.5))
        ax.plot(tt - tt[0], before, lw=lw, label=labels[0])
        ax.plot(tt - tt[0], after, lw=lw, label=labels[1])
        ax.set_xlabel("t [s]")
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
        p = os.path.join(out, name)
        fig.tight_layout()
        fig.savefig(p, dpi=110)
        plt.close(fig)
        written.append(p)

    if "attitude" in plots:
        tt, eb, ea = plots["attitude"]
        before_after(tt, np.degrees(eb), np.degrees(ea), ("gyro as measured", "after corrections"),
                     "attitude error [deg]", "attitude_error.png")
    if "array" in plots:
        tt, rb, ra = plots["array"]
        before_after(tt, rb, ra, ("given positions", "corrected positions"), "rigidity residual [m/s^2]",
                     "array_residual.png", lw=0.5)
    return written
