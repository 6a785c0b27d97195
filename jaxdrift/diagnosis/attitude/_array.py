"""Accelerometer-array checks: sensor positions, gyro biases through the centripetal terms, rigidity.

Per sample, the rigid-body model ``a_i = c + (alpha~ + W) r_i`` with ``W = omega~ omega~`` from the
gyro (bias-corrected for its noise) is fitted for ``c`` and ``alpha``; what is left is the rigidity
residual (:func:`array_residual`). Sensor position corrections (and, without another bias source,
gyro biases through ``W``) are fitted by Gauss-Newton with block-sandwich covariances
(:func:`array_fit`). :func:`array_step` is the pipeline step that turns them into findings.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

from ...models._quaternion import skew_np
from ._common import CHANNELS, NONRIGID_FLOOR, POSITION_CHI2, Z_SIGNIFICANT, finding, fmt

__all__ = ["array_residual", "array_fit", "rigidity_rms", "array_step"]


def array_residual(acc, r, W):
    """Rigid-model residual per sample: a_i - W r_i - (c + alpha x r_i) projected out. (n, N, 3)."""
    N = r.shape[0]
    D = np.zeros((3 * N, 6))
    for i in range(N):
        D[3 * i : 3 * i + 3, :3] = np.eye(3)
        D[3 * i : 3 * i + 3, 3:] = -skew_np(r[i])
    P = np.eye(3 * N) - D @ np.linalg.pinv(D)
    y = acc - np.swapaxes(W @ r.T, 1, 2)
    return (y.reshape(len(y), -1) @ P.T).reshape(y.shape)


def array_fit(acc, r, w_gyro, dt, sigma_gyro, fit_bias: bool, n_blocks=20, max_rows=20_000):
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
        return array_residual(A, r + dpos, Wm).reshape(ns, -1)

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


def rigidity_rms(resid, N, blocks):
    dof = 3 * N - 6
    e = np.sum(resid**2, axis=(1, 2)) / dof
    per_block = np.array([e[b].mean() for b in blocks])
    m = per_block.mean()
    se = per_block.std(ddof=1) / np.sqrt(len(blocks))
    return m, se, len(blocks)


# --------------------------------------------------------------------------- pipeline step


def array_step(s):
    """Findings of the accelerometer array: displaced sensors, gyro biases (without another bias
    source), and the rigidity residual beyond what the gyro noise explains."""
    positions = s.positions
    N = positions.shape[0]
    fit_bias = s.bias_source is None
    w_use = (s.w - s.bias_path) / s.scale
    af = array_fit(s.run["acc"], positions, w_use, s.dt, s.sigma_axis, fit_bias=fit_bias)
    s.observed.append(f"accelerometer array of {N} sensors (rigid-body residual, sensor positions)")
    nb = len(af["blocks"])
    tq = stats.t.ppf(0.975, nb - 1)
    excluded, pos_found = _displaced_sensors(af, N, tq)
    pos_corr = _position_corrections(s, af, positions, excluded, pos_found, fit_bias)
    if fit_bias:
        _array_gyro_biases(s, af, N, tq)
    _rigidity(s, af, positions, pos_corr, fit_bias)


def _W_of(af):
    return lambda om: skew_np(om) @ skew_np(om) + af["corr"]


def _displaced_sensors(af, N, tq):
    """Greedy search for displaced sensors: each round, the sensor whose position (relative to the
    mean of the others) departs most (3-dof chi-square) is taken if above POSITION_CHI2."""
    th, cov = af["theta"], af["cov"]
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
        pos_found.append(finding(
            "sensor_position", [float(v) for v in dj], "m", [[float(v) for v in dj - tq * se], [float(v) for v in dj + tq * se]],
            f"the accelerations of sensor {j + 1} fit the rigid-body motion seen by the gyro best with its position "
            f"moved by [{', '.join(fmt(v) for v in dj)}] m relative to the others (chi-square {fmt(chi2)}, 3 dof)",
            math.sqrt(chi2), sensor=j + 1))
    return excluded, pos_found


def _position_corrections(s, af, positions, excluded, pos_found, fit_bias):
    """Report the displaced sensors only where their fits explain at least half of the rigidity
    residual (else the body is not rigid); returns the position corrections (N, 3)."""
    N = positions.shape[0]
    th = af["theta"]
    dpos = th[: 3 * N].reshape(N, 3)
    W_of = _W_of(af)
    b_arr = th[3 * N :] if fit_bias else np.zeros(3)
    resid_before = array_residual(af["A"], positions, W_of(af["wbar"] - b_arr))
    m2b, _, _ = rigidity_rms(resid_before, N, af["blocks"])
    m2all, _, _ = rigidity_rms(af["resid"], N, af["blocks"])
    explained = 1.0 - m2all / max(m2b, 1e-300)
    af["resid_before"] = resid_before
    pos_corr = np.zeros((N, 3))
    if pos_found and explained >= 0.5:
        s.findings.extend(pos_found)
        for j in excluded:
            others = [i for i in range(N) if i not in excluded]
            pos_corr[j] = dpos[j] - dpos[others].mean(0)
    elif pos_found:
        s.notes.append(
            f"position fits for sensor(s) {', '.join(str(j + 1) for j in excluded)} explain only "
            f"{100 * explained:.0f} % of the rigidity residual: not reported as sensor_position (the body is not rigid)"
        )
    for j in range(N):
        s.corrections[f"sensor{j + 1}"] = {"position": [float(v) for v in pos_corr[j]]}
    return pos_corr


def _array_gyro_biases(s, af, N, tq):
    """Gyro biases through the centripetal terms (only when no reference or static segment gave them)."""
    th, cov = af["theta"], af["cov"]
    for c in range(3):
        ch = CHANNELS[c]
        b = float(th[3 * N + c])
        se = math.sqrt(max(cov[3 * N + c, 3 * N + c], 0.0))
        if se > 0 and abs(b) / se > Z_SIGNIFICANT and abs(b) > s.bias_floor:
            s.findings.append(finding(
                "gyro_bias", b, "rad/s", [float(b - tq * se), float(b + tq * se)],
                f"the array's centripetal accelerations (M+ = omega~ omega~) match the gyro's {ch} only after "
                f"removing {fmt(b)} rad/s (z = {fmt(abs(b) / se)})",
                abs(b) / se, channel=ch))
            s.corrections[ch]["bias"] = b
            s.bias_path[:, c] = b
    s.bias_source = "array"
    s.observed.append("gyro biases through the array's centripetal terms")


def _rigidity(s, af, positions, pos_corr, fit_bias):
    """Rigidity residual after the reported corrections, less the share the gyro noise explains."""
    N = positions.shape[0]
    W_of = _W_of(af)
    b_rep = np.array([s.corrections[c]["bias"] if s.bias_source == "array" else 0.0 for c in CHANNELS])
    resid_after = array_residual(af["A"], positions + pos_corr, W_of(af["wbar"] - b_rep))
    m2, se2, nb2 = rigidity_rms(resid_after, N, af["blocks"])
    resid_raw = array_residual(af["A"], positions, W_of(af["wbar"])) if fit_bias else af["resid_before"]
    m2raw, _, _ = rigidity_rms(resid_raw, N, af["blocks"])
    # the part of the residual that the gyro noise alone explains (W from noisy rates)
    rng = np.random.default_rng(0)
    eps = rng.normal(size=af["wbar"].shape) * s.sigma_axis
    om = af["wbar"]
    dW = skew_np(om + eps) @ skew_np(om + eps) - skew_np(om) @ skew_np(om)
    r_fit = positions + pos_corr
    gn = array_residual(np.einsum("nab,kb->nka", dW, r_fit), r_fit, np.zeros_like(dW))
    m_gn, _, _ = rigidity_rms(gn, N, af["blocks"])
    nr2 = max(m2 - m_gn, 0.0)
    nr = math.sqrt(nr2)
    s.sim_err["rigidity_residual"] = {"rms": float(math.sqrt(m2raw)), "unit": "m/s^2",
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
        s.findings.append(finding(
            "nonrigid", nr, "m/s^2", [lo, hi],
            f"the array's accelerations depart from the best rigid-body motion by {fmt(nr)} m/s^2 RMS per "
            f"degree of freedom (gyro noise accounts for {fmt(math.sqrt(m_gn))})",
            nr2 / max(se2, 1e-300), ))
    if s.gain is None:
        s.gain = {"metric": "rigidity_residual_rms", "before": float(math.sqrt(m2raw)), "after": float(math.sqrt(m2)), "unit": "m/s^2"}
    s.plots["array"] = (s.t[af["idx"]], np.sqrt(np.sum(resid_raw**2, axis=(1, 2)) / (3 * N - 6)),
                        np.sqrt(np.sum(resid_after**2, axis=(1, 2)) / (3 * N - 6)))
