"""Accelerometer-array checks: sensor positions, gyro biases through the centripetal terms, rigidity.

Per sample, the rigid-body model ``a_i = c + (alpha~ + W) r_i`` with ``W = omega~ omega~`` from the
gyro (bias-corrected for its noise) is fitted for ``c`` and ``alpha``; what is left is the rigidity
residual (:func:`array_residual`). Sensor position corrections (and, without another bias source,
gyro biases through ``W``) are fitted by Gauss-Newton with block-sandwich covariances
(:func:`array_fit`). The rigidity residual is split by its character in time: its white part
(:func:`white_rigidity_power`) is the gyro noise through ``W`` (:func:`gyro_noise_power`) plus
``accel_noise``; the rest is ``nonrigid`` (docs/attitude.md, "Accelerometer noise and
non-rigidity"). :func:`array_step` is the pipeline step that turns them into findings.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import stats

from ...models._quaternion import skew_np
from .._diffnoise import first_plateau, white_factor
from ._causes import ACCEL_NOISE, GYRO_BIAS, NONRIGID, SENSOR_POSITION, gyro_inverse
from ._records import Comparison, Said
from ._common import BIAS_FLOOR, CHANNELS, NONRIGID_FLOOR, POSITION_AGREE_CHI2, POSITION_CHI2, RIGID_BAND_HZ, Z_SIGNIFICANT, fmt

__all__ = ["array_residual", "array_fit", "rigidity_rms", "gyro_noise_power", "white_rigidity_power", "array_step"]


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
    # the parameters' response to an error of the upstream gyro corrections: a rate offset on axis k
    # (a bias error) and a relative rate error omega_k (a scale error), through the same normal equations
    sens_bias = Hi @ np.einsum("nkp,nkj->pj", Z3, G)
    sens_scale = Hi @ np.einsum("nkp,nkj,nj->pj", Z3, G, w_s)
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
    def linearised(th):
        return resid(th, w_s, s2), jac(th, w_i, s2 / 2, resid(th, w_i, s2 / 2)).reshape(ns, -1, p)

    low = _low_band_fit(theta, linearised, blocks, dt * stride, first=(r0, Z3))
    # RMS over the samples of the residual's change per unit of each parameter (all 3N components):
    # the resolution of the written accelerations in parameter units (:func:`position_floor`)
    gain = np.sqrt(np.mean(np.sum(Z3**2, axis=1), axis=0))
    return {"theta": theta, "cov": cov, "resid": r0.reshape(ns, N, 3), "blocks": blocks, "k_s": 1, "stride": stride,
            "idx": idx, "wbar": w_s, "corr": corr(s2), "A": A, "low": low, "gain": gain,
            "sens_bias": sens_bias, "sens_scale": sens_scale}


#: Gauss-Newton stopping steps of the full-band and rigid-band position fits [m]: no position is
#: resolved more finely than the step at which its fit stops
SOLVER_STEP = {"full": 1e-7, "low": 1e-6}


def upstream_cov(af, N, scale_se, bias_se):
    """Covariance (3N x 3N) of the position corrections that the uncertainty of the gyro corrections
    applied before the array fit (scales and biases from the reference or a static segment, standard
    errors ``scale_se``, ``bias_se`` per axis) propagates into them (:func:`array_fit`'s sensitivities)."""
    a = np.concatenate([af["sens_scale"][: 3 * N] * np.asarray(scale_se)[None, :],
                        af["sens_bias"][: 3 * N] * np.asarray(bias_se)[None, :]], 1)
    return a @ a.T


def position_floor(af, acc_rounding_rms):
    """Per sensor and axis (N, 3) [m]: the displacement whose rigid-field signature on the sensor's
    three axes has, per axis, the RMS of half a written step of the accelerometer cells (``sqrt(3)``
    times their RMS rounding error ``q``): ``3 q / gain`` (the signature's norm over the 3N residual
    components is ``gain`` per metre, :func:`array_fit`).

    Rounding is not white noise once the signal is smooth on the scale of a step, and the rates in
    ``omega~ omega~`` carry their own rounding; neither averages down with the number of samples, so
    no estimate of a position is better than this resolution. It is the method part of a position's
    interval (added in quadrature to the statistical part) and the least displacement reported.
    """
    N = af["resid"].shape[1]
    g = np.maximum(af["gain"][: 3 * N], 1e-300)
    return (3.0 * acc_rounding_rms / g).reshape(N, 3)


def _low_band_fit(theta, linearised, blocks, dt_s, f_cut=RIGID_BAND_HZ, max_iter=4, first=None):
    """The same fit restricted to frequencies below ``f_cut`` (the rigid band): Gauss-Newton from
    ``theta`` on the low-passed residual and Jacobian (``linearised(theta)`` gives both, per sample).

    The projection onto the rigid-body complement acts per sample and the parameters do not depend
    on time, so low-passing the residual and the Jacobian columns in time gives the model of the
    low-passed data. A position error acts on the rigid field ``(alpha~ + omega~ omega~) dr`` at
    every frequency; a deformation mode above ``f_cut`` does not reach the band, so its chance
    correlation with the rigid field (which a block sandwich cannot see when it persists over the
    run) does not enter here. Returns ``theta``, ``cov`` (block sandwich) and ``f_cut``, or None
    where the sampling is too coarse or the run too short to filter.
    """
    from scipy.signal import butter, sosfiltfilt

    r0, Z3 = first if first is not None else linearised(theta)
    r0 = r0.reshape(Z3.shape[0], -1)
    ns, _, p = Z3.shape
    fs = 1.0 / dt_s
    if f_cut >= 0.25 * fs or ns < 200:
        return None
    # order 8, run forwards and backwards: a mode at 2 f_cut keeps 1.5e-5 of its amplitude
    sos = butter(8, f_cut, fs=fs, output="sos")
    th = theta.copy()
    for it in range(max_iter):
        if it > 0:
            r0, Z3 = linearised(th)
        Zl = sosfiltfilt(sos, Z3, axis=0)
        rl = sosfiltfilt(sos, r0, axis=0)
        Zf = Zl.reshape(-1, p)
        Hi = np.linalg.pinv(Zf.T @ Zf, rcond=1e-10)
        step = -Hi @ (Zf.T @ rl.reshape(-1))
        th = th + step
        if np.max(np.abs(step)) < 1e-6:  # 1 um (positions) or 1e-6 rad/s (biases)
            break
    res = rl + np.einsum("nkp,p->nk", Zl, step)
    gs = np.stack([np.einsum("nkp,nk->p", Zl[bk], res[bk]) for bk in blocks])
    nb = len(blocks)
    return {"theta": th, "cov": Hi @ (gs.T @ gs) @ Hi * nb / (nb - 1), "f_cut": f_cut}


def rigidity_rms(resid, N, blocks):
    dof = 3 * N - 6
    e = np.sum(resid**2, axis=(1, 2)) / dof
    per_block = np.array([e[b].mean() for b in blocks])
    m = per_block.mean()
    se = per_block.std(ddof=1) / np.sqrt(len(blocks))
    return m, se, len(blocks)


def _block_power(resid, N, blocks):
    """Mean residual power per degree of freedom (3N - 6) in each block of samples."""
    e = np.sum(resid**2, axis=(1, 2)) / (3 * N - 6)
    n = len(e)
    return np.array([e[b[b < n]].mean() for b in blocks])


def _mean_se(per_block):
    return float(per_block.mean()), float(per_block.std(ddof=1) / np.sqrt(len(per_block)))


def gyro_noise_power(w_prev, w_next, sigma, r, n_draws: int = 4000):
    """Expected power per degree of freedom, per sample, of the rigidity residual that white gyro
    noise of per-sample std ``sigma`` (per axis) makes through ``W = omega~ omega~``.

    To first order the noise ``eps`` adds ``(omega~ eps~ + eps~ omega~) r_i``, a quadratic form in the
    true rate. The measured rate carries the noise itself (its square would overstate the power by
    ``sigma^2`` terms), so the form is evaluated with the rates of the two neighbouring samples,
    ``L omega_{k-1} . L omega_{k+1}``, whose noises are independent (unbiased up to the rate's
    curvature over two steps). The second-order term ``eps~ eps~ - E[eps~ eps~]`` does not depend on
    the rate; its power is averaged over ``n_draws`` seeded draws.
    """
    N = r.shape[0]
    dof = 3 * N - 6
    sigma = np.asarray(sigma, float)
    zero = np.zeros((len(w_prev), 3, 3))
    e = np.zeros(len(w_prev))
    if not np.any(sigma > 0):
        return e
    for k in range(3):
        if sigma[k] == 0:
            continue
        ek = skew_np(np.eye(3)[k])

        def first_order(om):
            M = skew_np(om) @ ek + ek @ skew_np(om)
            return array_residual(np.einsum("nab,kb->nka", M, r), r, zero)

        e += sigma[k] ** 2 * np.sum(first_order(w_prev) * first_order(w_next), axis=(1, 2)) / dof
    eps = np.random.default_rng(0).normal(size=(n_draws, 3)) * sigma
    D = skew_np(eps) @ skew_np(eps) + np.diag([sigma[1] ** 2 + sigma[2] ** 2, sigma[0] ** 2 + sigma[2] ** 2,
                                                 sigma[0] ** 2 + sigma[1] ** 2])
    second = array_residual(np.einsum("nab,kb->nka", D, r), r, np.zeros((n_draws, 3, 3)))
    return e + float(np.mean(np.sum(second**2, axis=(1, 2)))) / dof


def white_rigidity_power(resid, N, blocks, max_order: int = 8):
    """White (temporally uncorrelated) part of the rigidity residual's power per degree of freedom.

    The k-th difference in time of a white series has ``C(2k, k)`` times its variance, while a
    deformation (or any motion) that is smooth at the sampling rate is damped by
    ``(2 sin(pi f dt))^(2k)``. As for the gyro (:func:`jaxdrift.diagnosis.attitude._noise.estimate_white_noise`)
    the order is raised until two consecutive orders agree within 3 standard errors (standard errors
    from the blocks of samples). Returns ``power`` (its mean), ``se``, ``per_block``, ``order`` and
    ``plateau`` (False: no two orders agreed, ``power`` is the smallest, an upper bound).
    """
    dof = 3 * N - 6
    ests = []
    for k in range(1, max_order + 1):
        if resid.shape[0] - k < 4 * len(blocks):
            break
        d = np.diff(resid, k, axis=0)
        e = np.sum(d**2, axis=(1, 2)) / (white_factor(k) * dof)
        pb = np.array([e[b[b < len(e)]].mean() for b in blocks])
        m, se = _mean_se(pb)
        ests.append((k, m, se, pb))
    chosen, plateau, _ = first_plateau(ests)
    k, m, se, pb = chosen
    return {"power": m, "se": se, "per_block": pb, "order": k, "plateau": plateau}


def _accel_noise_finding(run, acc_var, acc_se, tq, wp, m_gn):
    """``accel_noise``: the white part of the rigidity residual beyond what the gyro noise explains,
    reported where it is 3 standard errors above zero and above the rounding of the file's digits.
    Returns ``(finding or None, note or None)``."""
    floor = max(3.0 * run.get("acc_quantisation", 0.0), 1e-12)
    if not (wp["plateau"] and acc_var > 3.0 * acc_se and math.sqrt(max(acc_var, 0.0)) > floor):
        if not wp["plateau"]:
            return None, "the rigidity residual never became white under differencing: accelerometer noise not separable"
        return None, (
            f"no accelerometer noise found: the white part of the rigidity residual, {fmt(math.sqrt(wp['power']))} "
            f"m/s^2 RMS per degree of freedom, is what the gyro noise explains ({fmt(math.sqrt(m_gn))}) or below "
            "the rounding of the file")
    est = math.sqrt(acc_var)
    lo = math.sqrt(max(acc_var - tq * acc_se, 0.0))
    hi = math.sqrt(acc_var + tq * acc_se)
    return {
        "cause": ACCEL_NOISE.name, "estimate": est, "unit": ACCEL_NOISE.unit, "interval": [lo, hi],
        "evidence": (
            f"order-{wp['order']} differences of the array's rigidity residual are white with "
            f"{fmt(math.sqrt(wp['power']))} m/s^2 RMS per degree of freedom; gyro noise through omega~ omega~ "
            f"accounts for {fmt(math.sqrt(m_gn))}, the rest in quadrature is accelerometer noise of {fmt(est)} "
            "m/s^2 per axis"
        ),
    }, None


# --------------------------------------------------------------------------- pipeline step


def array_step(run, positions, noise, comp: Comparison) -> Comparison:
    """Findings of the accelerometer array: displaced sensors, gyro biases (where no reference or
    static segment gave them), and the rigidity residual beyond what the gyro noise explains. Returns
    the comparison ``comp`` with the array's findings, corrections and measures added (its ``said``
    the array's alone)."""
    model = comp.model
    N = positions.shape[0]
    fit_bias = model.bias_source is None
    w_use = gyro_inverse(run["w"], model.scale, model.bias_path)
    af = array_fit(run["acc"], positions, w_use, run["dt"], noise.sigma_axis, fit_bias=fit_bias)
    observed = [f"accelerometer array of {N} sensors (rigid-body residual, sensor positions)"]
    nb = len(af["blocks"])
    tq = stats.t.ppf(0.975, nb - 1)
    # a position correction is a 3-vector: its interval is the box whose three components hold the
    # truth together with 95 % probability (Sidak: each at 0.95^(1/3); per-component 95 % intervals
    # would hold all three in about 86 %)
    tq_box = stats.t.ppf(1.0 - (1.0 - 0.95 ** (1.0 / 3.0)) / 2.0, nb - 1)
    floor = position_floor(af, run.get("acc_quantisation", 0.0))
    c_up = upstream_cov(af, N, model.scale_se, model.bias_se)
    excluded, pos_found = _displaced_sensors(af, N, tq_box, floor, c_up)
    pos_corr, resid_before = _position_corrections(af, positions, excluded, pos_found, fit_bias)
    corrections = {**model.corrections, **{f"sensor{j + 1}": {"position": [float(v) for v in pos_corr[j]]}
                                           for j in range(N)}}
    findings = list(pos_found)
    if fit_bias:
        biases, found = _array_gyro_biases(af, N, tq)
        findings += found
        bias_path = model.bias_path.copy()
        for c, b in biases.items():
            corrections[CHANNELS[c]] = replace(corrections[CHANNELS[c]], bias=b)
            bias_path[:, c] = b
        model = replace(model, bias_path=bias_path, bias_source="array")
        observed.append("gyro biases through the array's centripetal terms")
    model = replace(model, corrections=corrections)
    rig = _rigidity(run, af, positions, pos_corr, fit_bias, w_use, model, noise.sigma_axis, resid_before)
    findings += rig["findings"]
    return replace(
        comp, model=model, findings=comp.findings + tuple(findings),
        noise_findings=comp.noise_findings + rig["noise_findings"],
        sim_err={**comp.sim_err, "rigidity_residual": rig["sim_err"]},
        gain=comp.gain if comp.gain is not None else rig["gain"], plots={**comp.plots, "array": rig["plot"]},
        said=Said(notes=rig["notes"], observed=tuple(observed)))


def _W_of(af):
    return lambda om: skew_np(om) @ skew_np(om) + af["corr"]


def _rel_matrix(p, j, others):
    """The linear map from the parameters to sensor j's position correction relative to the mean of ``others``."""
    L = np.zeros((3, p))
    L[:, 3 * j : 3 * j + 3] = np.eye(3)
    for i in others:
        L[:, 3 * i : 3 * i + 3] -= np.eye(3) / len(others)
    return L


def _relative(th, cov, j, others):
    """Sensor j's position correction relative to the mean of ``others``, its covariance and chi-square."""
    L = _rel_matrix(len(th), j, others)
    d, C = L @ th, L @ cov @ L.T
    return d, C, float(d @ np.linalg.solve(C + 1e-300 * np.eye(3), d))


def _spread_chi2(th, cov, others):
    """Chi-square of the spread of the ``others``' position corrections about their mean
    (3 (len(others) - 1) dof): small where they moved together (not at all, or a common shift)."""
    L = np.vstack([_rel_matrix(len(th), i, others) for i in others[:-1]])
    d = L @ th
    return float(d @ np.linalg.pinv(L @ cov @ L.T, rcond=1e-12) @ d)


def _sensor_test(af, j, others):
    """(chi2, d, C, band, spread) of sensor j's displacement as reported, or None (spread: of the
    others, :func:`_spread_chi2`).

    Reported from the full band where its chi-square exceeds POSITION_CHI2 and the rigid-band
    estimate agrees with it (Hausman: the difference against Cov(low) - Cov(full)); from the rigid
    band alone where that one exceeds POSITION_CHI2 (a deformation above the band biased the full one).
    """
    d, C, chi2 = _relative(af["theta"], af["cov"], j, others)
    low = af.get("low")

    def shown(x, Cx, c2):
        # a 3 x 3 covariance from a few blocks is unreliable in its smallest direction: the
        # displacement must also stand out in a coordinate the report shows (its interval)
        return c2 >= POSITION_CHI2 and np.max(np.abs(x) / np.sqrt(np.maximum(np.diag(Cx), 1e-300))) > Z_SIGNIFICANT

    if low is None:
        return (chi2, d, C, "full", _spread_chi2(af["theta"], af["cov"], others)) if shown(d, C, chi2) else None
    dl, Cl, chi2l = _relative(low["theta"], low["cov"], j, others)
    V = Cl - C
    if np.any(np.linalg.eigvalsh(V) <= 0):
        V = Cl
    diff = d - dl
    agree = float(diff @ np.linalg.solve(V + 1e-300 * np.eye(3), diff))
    if shown(d, C, chi2) and agree < POSITION_AGREE_CHI2:
        return chi2, d, C, "full", _spread_chi2(af["theta"], af["cov"], others)
    if shown(dl, Cl, chi2l):
        return chi2l, dl, Cl, "low", _spread_chi2(low["theta"], low["cov"], others)
    return None


def _method_half(af, N, j, others, floor, c_up, band):
    """Method half-width (3,) of sensor j's relative position: the written resolution (``floor``, of
    sensor j and the mean of the others), the upstream gyro corrections (``c_up``, at 95 %) and the
    fit's stopping step, in quadrature."""
    L = _rel_matrix(3 * N, j, others)
    fl2 = floor[j] ** 2 + np.sum(floor[others] ** 2, 0) / len(others) ** 2
    return np.sqrt(fl2 + 1.96**2 * np.maximum(np.diag(L @ c_up @ L.T), 0.0) + SOLVER_STEP[band] ** 2)


def _displaced_sensors(af, N, tq, floor, c_up):
    """Greedy search for displaced sensors: each round, among the sensors whose position (relative to
    the mean of the others) departs significantly (:func:`_sensor_test`), the one that leaves the
    others most consistent with one another is taken (the model "only this sensor moved" that fits
    best: with four sensors, one displaced by d also makes each other one look displaced by -d/3).
    A displacement must exceed its method half-width (:func:`_method_half`: the written resolution,
    the upstream gyro corrections, the fit's stopping step) in some axis; its interval is the
    statistical half-width and the method half-width in quadrature."""
    excluded = []
    pos_found = []
    for _ in range(N - 3):
        best = None
        for j in range(N):
            if j in excluded:
                continue
            others = [i for i in range(N) if i != j and i not in excluded]
            tst = _sensor_test(af, j, others)
            if tst is not None:
                m = _method_half(af, N, j, others, floor, c_up, tst[3])
                tst = tst + (m,) if np.any(np.abs(tst[1]) > m) else None  # else below what the method resolves
            if tst is not None and (best is None or tst[4] < best[0][4]):
                best = (tst, j)
        if best is None:
            break
        (chi2, dj, Cj, band, _, m), j = best
        half = np.sqrt((tq * np.sqrt(np.diag(Cj))) ** 2 + m**2)
        excluded.append(j)
        where = (f"below {fmt(af['low']['f_cut'])} Hz, where the body moves as a rigid one" if band == "low"
                 else "over the full band")
        pos_found.append(SENSOR_POSITION.finding(
            [float(v) for v in dj], [[float(v) for v in dj - half], [float(v) for v in dj + half]],
            f"the accelerations of sensor {j + 1} fit the rigid-body motion seen by the gyro best with its position "
            f"moved by [{', '.join(fmt(v) for v in dj)}] m relative to the others {where} (chi-square {fmt(chi2)}, 3 dof)",
            math.sqrt(chi2), sensor=j + 1))
    return excluded, pos_found


def _position_corrections(af, positions, excluded, pos_found, fit_bias):
    """The position corrections (N, 3) of the displaced sensors reported (the estimates reported,
    relative to the mean of the sensors not displaced), and the rigidity residual before them."""
    N = positions.shape[0]
    W_of = _W_of(af)
    b_arr = af["theta"][3 * N :] if fit_bias else np.zeros(3)
    resid_before = array_residual(af["A"], positions, W_of(af["wbar"] - b_arr))
    pos_corr = np.zeros((N, 3))
    for j, (f, _) in zip(excluded, pos_found):
        pos_corr[j] = f["estimate"]
    return pos_corr, resid_before


def _array_gyro_biases(af, N, tq):
    """Gyro biases through the centripetal terms (only when no reference or static segment gave
    them): ``({axis: bias} of the significant ones, their findings)``."""
    th, cov = af["theta"], af["cov"]
    biases, findings = {}, []
    for c in range(3):
        ch = CHANNELS[c]
        b = float(th[3 * N + c])
        se = math.sqrt(max(cov[3 * N + c, 3 * N + c], 0.0))
        if se > 0 and abs(b) / se > Z_SIGNIFICANT and abs(b) > BIAS_FLOOR:
            findings.append(GYRO_BIAS.finding(
                b, [float(b - tq * se), float(b + tq * se)],
                f"the array's centripetal accelerations (M+ = omega~ omega~) match the gyro's {ch} only after "
                f"removing {fmt(b)} rad/s (z = {fmt(abs(b) / se)})",
                abs(b) / se, channel=ch))
            biases[c] = b
    return biases, findings


def _rigidity(run, af, positions, pos_corr, fit_bias, w_use, model, sigma_axis, resid_before):
    """Rigidity residual after the reported corrections, split into its white part (gyro noise
    through ``W`` plus accelerometer noise: ``accel_noise``) and the rest (``nonrigid``): a dict of
    the findings, noise findings, notes, the simulation error, gain and figure."""
    N = positions.shape[0]
    blocks = af["blocks"]
    W_of = _W_of(af)
    b_rep = np.array([model.corrections[c].bias if model.bias_source == "array" else 0.0 for c in CHANNELS])
    resid_after = array_residual(af["A"], positions + pos_corr, W_of(af["wbar"] - b_rep))
    m2, _, nb2 = rigidity_rms(resid_after, N, blocks)
    resid_raw = array_residual(af["A"], positions, W_of(af["wbar"])) if fit_bias else resid_before
    m2raw, _, _ = rigidity_rms(resid_raw, N, blocks)
    # the part of the residual that the gyro noise alone explains (W from noisy rates), per sample
    r_fit = positions + pos_corr
    idx = af["idx"]
    e_gn = gyro_noise_power(w_use[idx - 1] - b_rep, w_use[idx + 1] - b_rep, sigma_axis, r_fit)
    wp = white_rigidity_power(resid_after, N, blocks)
    tq2 = stats.t.ppf(0.975, nb2 - 1)
    # per block: total power, white power, gyro-noise power; differences taken block by block
    pb_total = _block_power(resid_after, N, blocks)
    pb_gn = np.array([e_gn[b].mean() for b in blocks])
    m_gn = float(pb_gn.mean())
    acc_var, acc_se = _mean_se(wp["per_block"] - pb_gn)
    nr2_raw, nr_se = _mean_se(pb_total - wp["per_block"])
    nr2 = max(nr2_raw, 0.0)
    nr = math.sqrt(nr2)
    sim_err = {
        "rms": float(math.sqrt(m2raw)), "unit": "m/s^2",
        "what": "RMS per residual degree of freedom of the rigid-body fit of the array with the given positions",
        "rms_after_corrections": float(math.sqrt(m2)),
        "white_rms": float(math.sqrt(wp["power"])), "white_order": int(wp["order"]), "white_plateau": bool(wp["plateau"]),
        "gyro_noise_rms": float(math.sqrt(m_gn)),
    }
    acc_f, note = _accel_noise_finding(run, acc_var, acc_se, tq2, wp, m_gn)
    findings = []
    if nr > NONRIGID_FLOOR and nr2 > 5.0 * nr_se:
        # statistical interval of the residual power, then the unidentifiable share: the part of a
        # deformation that looks like rigid motion is absorbed by the fit. The estimate assumes an
        # isotropic deformation ((3N - 6) of 3N degrees of freedom seen); the interval spans from
        # "nothing hidden" (factor sqrt((3N-6)/3N)) to twice the isotropic hidden share.
        frac = (3 * N - 6) / (3 * N)
        lo = math.sqrt(max(nr2 - tq2 * nr_se, 0.0) * frac)
        hi = math.sqrt((nr2 + tq2 * nr_se) * (1.0 + 2.0 * (1.0 - frac)) / 1.0)
        findings.append(NONRIGID.finding(
            nr, [lo, hi],
            f"after the reported corrections the array's accelerations depart from the best rigid-body motion "
            f"by {fmt(math.sqrt(m2))} m/s^2 RMS per degree of freedom, of which {fmt(math.sqrt(wp['power']))} is white "
            f"(noise); the rest, {fmt(nr)} m/s^2, is correlated in time (a deformation)",
            nr2 / max(nr_se, 1e-300), ))
    return {"findings": findings, "noise_findings": () if acc_f is None else (acc_f,),
            "notes": () if note is None else (note,), "sim_err": sim_err,
            "gain": {"metric": "rigidity_residual_rms", "before": float(math.sqrt(m2raw)), "after": float(math.sqrt(m2)),
                     "unit": "m/s^2"},
            "plot": (run["t"][af["idx"]], np.sqrt(np.sum(resid_raw**2, axis=(1, 2)) / (3 * N - 6)),
                     np.sqrt(np.sum(resid_after**2, axis=(1, 2)) / (3 * N - 6)))}
