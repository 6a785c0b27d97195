"""Which causes: forward selection with a joint refit, an exchange step, backward elimination,
exact confounding and the ranking (step 3 of ``docs/diagnosis.md``)."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import scipy.stats

from ._causes import (_BOTH, ALPHA, FORCE_CHANNELS, FORCE_OFFSET, PARAMETER_ERROR, Cause, _apply, _at_bound, _candidates,
                      _finding_for, _practical, _redundant)
from ._detectors import _force_hf_noise
from ._problem import Fit, _gauss_newton, _Problem, _proj

def _lin_rss(X: np.ndarray, r: np.ndarray) -> float:
    if X.shape[1] == 0:
        return float(r @ r)
    beta, *_ = np.linalg.lstsq(X, r, rcond=None)
    e = r - X @ beta
    return float(e @ e)


@dataclass
class Selection:
    fit: Fit
    cov: np.ndarray
    sigma: float
    z: np.ndarray
    alternatives: dict
    not_identifiable: list
    weakly_identifiable: dict
    rss0: float
    rss_path: list


def _covariance(prob: _Problem, X: np.ndarray, sigma2: float) -> np.ndarray:
    XtX = X.T @ X
    inv = np.linalg.pinv(XtX)
    meat = prob.sandwich_meat(X)
    return sigma2 * inv @ meat @ inv


def _systematic_rss(prob: _Problem, fit: "Fit", sigma2: float) -> float:
    """RSS plus the noise RSS that the fit's causes hide by passing less noise than the base model
    does (in the base weighting): a parameter that damps the noise response, or a force scale
    whose correction shrinks the measured samples, and with them their noise. Only a penalty:
    passing more noise already costs RSS."""
    if sigma2 <= 0:
        return fit.rss
    p, corr = _apply(prob.model, fit.causes, fit.theta)
    ir = prob.impulse_responses(p)[0]
    noise = 0.0
    for nm in prob.names:
        if nm == "static":
            noise += prob.rows[nm]
            continue
        v = sum(corr[ch].gain ** 2 * float(np.sum(ir[(nm, ch)][0] ** 2)) for ch in FORCE_CHANNELS)
        noise += prob.rows[nm] * v / prob.noise_std[nm] ** 2
    base = sum(prob.rows[nm] for nm in prob.names)
    return fit.rss + sigma2 * max(base - noise, 0.0)


def _normalise(prob: _Problem, fit: "Fit") -> "Fit":
    """An equal offset on both forces next to a single-channel offset is two channel offsets:
    report it so (the same span, the same residual)."""
    causes = list(fit.causes)
    if _BOTH not in causes:
        return fit
    singles = [c for c in causes if c.kind is FORCE_OFFSET and c != _BOTH]
    if not singles:
        return fit
    ib = causes.index(_BOTH)
    other = next(ch for ch in FORCE_CHANNELS if ch != singles[0].target)
    theta = np.array(fit.theta, dtype=float)
    i1 = causes.index(singles[0])
    theta[i1] += theta[ib]
    causes[ib] = Cause(FORCE_OFFSET, other)
    return _gauss_newton(prob, causes, theta)


def _swap_pass(prob: _Problem, fit: "Fit", active, sig2: float, log=None) -> "Fit":
    """Exchange step of the stepwise selection: forward selection can lock in a cause that only
    stood in for two others (a scale for an offset while a delay was not yet in). For each chosen
    cause, refit without it, screen the others linearly in its place, refine the best two, and
    take an exchange that lowers the systematic residual by more than the 95 % level of one
    parameter's worth of noise."""
    improved = True
    rounds = 0
    while improved and rounds < 2 and len(fit.causes) > 1:
        improved = False
        rounds += 1
        cur = _systematic_rss(prob, fit, sig2)
        for i in range(len(fit.causes)):
            keep = [j for j in range(len(fit.causes)) if j != i]
            others = [fit.causes[j] for j in keep]
            f_o = _gauss_newton(prob, others, fit.theta[keep], iters=3)
            Xo = f_o.X if others else np.zeros((len(f_o.r), 0))
            scores = []
            for c in active:
                if c == fit.causes[i] or _redundant(c, others):
                    continue
                col = prob.jacobian(others + [c], np.append(f_o.theta, 0.0), which=[len(others)])[:, 0]
                scores.append((_proj(np.column_stack([Xo, col]), f_o.r), c))
            scores.sort(key=lambda s_: -s_[0])
            best = None
            for _, c in scores[:2]:
                f_c = _gauss_newton(prob, others + [c], np.append(f_o.theta, 0.0))
                if any(_at_bound(cc, th, prob.pipe) for cc, th in zip(f_c.causes, f_c.theta)):
                    continue
                v = _systematic_rss(prob, f_c, sig2)
                if best is None or v < best[0]:
                    best = (v, c, f_c)
            q = scipy.stats.chi2.ppf(0.95, 1) * max(sig2, 1e-300)
            if log is not None and best is not None:
                log.append(f"swap? {fit.causes[i].label}: screened {[c.label for _, c in scores[:3]]}, "
                           f"best {best[1].label} {best[0]:.6g} vs {cur:.6g}")
            if best is not None and best[0] < cur - q:
                if log is not None:
                    log.append(f"swap {fit.causes[i].label} -> {best[1].label}: rss {cur:.6g} -> {best[0]:.6g}")
                fit = _normalise(prob, best[2])
                improved = True
                break
    return fit


def _identifiable(prob: _Problem, cands):
    """(active, not identifiable, their columns): candidates the available signals see at all,
    judged by the norm of their sensitivity at the base point."""
    J = prob.jacobian(cands, np.zeros(len(cands)))
    norms = np.sqrt(np.sum(J * J, axis=0))
    scale_ref = np.max(norms) if norms.size else 1.0
    not_ident = [c for c, nv in zip(cands, norms) if nv <= 1e-12 * max(scale_ref, 1e-300)]
    active = [c for c, nv in zip(cands, norms) if nv > 1e-12 * max(scale_ref, 1e-300)]
    Jc = {c: J[:, i] for i, c in enumerate(cands)}
    return active, not_ident, Jc


def _screen(prob: _Problem, fit: Fit, chosen, active, Jc) -> list:
    """Linear screen of each candidate: the RSS a linear fit of (chosen + c) removes from the
    current residual beyond what the chosen causes remove; best first."""
    n_rows = len(fit.r)
    Xc = fit.X if chosen else np.zeros((n_rows, 0))
    scores = []
    for c in active:
        if _redundant(c, chosen):
            continue
        if chosen:
            col = prob.jacobian(chosen + [c], np.append(fit.theta, 0.0), which=[len(chosen)])[:, 0]
        else:
            col = Jc[c]
        Jc[c] = col
        gain_lin = _proj(np.column_stack([Xc, col]), fit.r) - _proj(Xc, fit.r)
        scores.append((gain_lin, c))
    scores.sort(key=lambda s: -s[0])
    return scores


def _refine(prob: _Problem, fit: Fit, chosen, scores, sig2_now: float, log=None) -> list:
    """Refine the best three screened candidates nonlinearly; rank them by the residual beyond the
    noise they are expected to carry (a heavier wheel or a softer damper passes less noise: that
    must not count as a better explanation). Fits at the edge of the plausible range are left out.

    The noise level of that penalty is an upper bound (``sig2_now``); the best candidate's own
    residual variance is another, and the smaller one is used: a residual that still holds the
    effect being looked for overstates the noise, and then a cause that shrinks the samples (a
    scale) paid for noise the run does not have, and lost to two causes that do not (a share of
    the other channel and a mass error standing in for a scale)."""
    fits = []
    for gain_lin, c in scores[:3]:
        f_c = _gauss_newton(prob, chosen + [c], np.append(fit.theta, 0.0))
        if _at_bound(c, f_c.theta[-1], prob.pipe):
            if log is not None:
                log.append(f"step {len(chosen) + 1}: {c.label} left out: its fit sits at the edge of "
                           f"its plausible range ({c.to_estimate(f_c.theta[-1]):.6g})")
            continue
        fits.append((c, f_c))
    if not fits:
        return []
    sig2_now = min(sig2_now, min(f_c.rss / max(len(f_c.r) - len(f_c.causes), 1) for _, f_c in fits))
    base = _systematic_rss(prob, fit, sig2_now)
    refined = [(base - _systematic_rss(prob, f_c, sig2_now), c, f_c) for c, f_c in fits]
    refined.sort(key=lambda s: -s[0])
    return refined


def _step_alternatives(prob: _Problem, f_best: Fit, gain: float, refined, scores, sigma2: float) -> list:
    """Candidates whose fit is not significantly worse than the chosen one's."""
    pipe = prob.pipe
    infl = float(prob.sandwich_meat(f_best.X[:, -1:])[0, 0] / (f_best.X[:, -1] @ f_best.X[:, -1]))
    q = scipy.stats.chi2.ppf(0.95, 1) * sigma2 * max(infl, 1.0)
    alts = []
    for g_c, c, f_c in refined[1:]:
        if g_c >= gain - q:
            se_c = math.sqrt(max(_covariance(prob, f_c.X, sigma2)[-1, -1], 0.0))
            iv = _finding_for(c, f_c.theta[-1], se_c, _practical(c, pipe))["interval"]
            alts.append((c, float(c.to_estimate(f_c.theta[-1])), iv))
    for g_lin, c in scores[3:]:
        if g_lin >= gain - q:
            alts.append((c, None, None))
    return alts


def _forward(prob: _Problem, base: Fit, active, Jc, crit: float, max_causes: int, log=None):
    """Forward selection with a joint refit: add the best candidate while it passes the test.
    Returns (fit, chosen, alternatives, rss path)."""
    pipe = prob.pipe
    n_rows = len(base.r)
    fit = base
    path = [base.rss]
    hf_sigma = _force_hf_noise(pipe.run)[0]
    alternatives = {}
    chosen: list[Cause] = []
    dynamic = n_rows > 2
    while len(chosen) < max_causes and dynamic:
        scores = _screen(prob, fit, chosen, active, Jc)
        if not scores:
            break
        # the noise level: the smaller of two upper bounds, the low band of the current residual
        # still holding what is not yet explained, and the forces' 4th differences
        sig2_now = min(prob.lowband_noise(fit.r)[0], hf_sigma) ** 2 if dynamic else 0.0
        refined = _refine(prob, fit, chosen, scores, sig2_now, log)
        if not refined:
            break
        gain, c_best, f_best = refined[0]
        p = len(f_best.causes)
        sigma2 = f_best.rss / max(n_rows - p, 1)
        cov = _covariance(prob, f_best.X, sigma2)
        var = cov[-1, -1]
        z2 = f_best.theta[-1] ** 2 / var if var > 0 else 0.0
        est = c_best.to_estimate(f_best.theta[-1])
        size = abs(f_best.theta[-1])
        thr = _practical(c_best, pipe)
        if log is not None:
            log.append(f"step {len(chosen) + 1}: best {c_best.label} est {est:.6g} z2 {z2:.3g} "
                       f"(crit {crit:.3g}) rss {fit.rss:.6g} -> {f_best.rss:.6g}; next: " +
                       ", ".join(f"{c.label}:{g:.4g}" for g, c, _ in refined[1:]))
        if z2 < crit or size < thr:
            break
        alternatives[c_best] = _step_alternatives(prob, f_best, gain, refined, scores, sigma2)
        chosen.append(c_best)
        fit = f_best
        if _BOTH in chosen and len([c for c in chosen if c.kind is FORCE_OFFSET]) > 1:
            # {equal offsets, offset on f1} is {offsets on f1 and f2}: report it so
            alts_b = alternatives.pop(_BOTH, [])
            fit = _normalise(prob, fit)
            new = next(c for c in fit.causes if c not in chosen)
            alternatives[new] = [alt for alt in alts_b if alt[0] not in fit.causes]
            chosen = list(fit.causes)
        path.append(fit.rss)
    if dynamic and len(fit.causes) > 1:
        sig2_now = min(prob.lowband_noise(fit.r)[0], hf_sigma) ** 2
        before = list(fit.causes)
        fit = _swap_pass(prob, fit, active, sig2_now, log)
        if fit.causes != before:
            alternatives = {c: a for c, a in alternatives.items() if c in fit.causes}
            chosen = list(fit.causes)
            path.append(fit.rss)
    return fit, chosen, alternatives, path


def _backward(prob: _Problem, fit: Fit, alternatives: dict, crit: float, log=None):
    """Backward elimination: a cause chosen early can lose its significance once later causes
    explain the same residual; drop the weakest (or one too small or at the edge of its range)
    until all pass, refitting each time. Returns (fit, cov, z, sigma2)."""
    pipe = prob.pipe
    n_rows = len(fit.r)
    while True:
        p = len(fit.causes)
        sigma2 = fit.rss / max(n_rows - p, 1)
        if not p:
            return fit, np.zeros((0, 0)), np.zeros(0), sigma2
        cov = _covariance(prob, fit.X, sigma2)
        z = fit.theta / np.sqrt(np.maximum(np.diag(cov), 1e-300))
        small = [i for i, c in enumerate(fit.causes)
                 if abs(fit.theta[i]) < _practical(c, pipe) or _at_bound(c, fit.theta[i], pipe)]
        weakest = small[0] if small else int(np.argmin(np.abs(z)))
        if not small and z[weakest] ** 2 >= crit:
            return fit, cov, z, sigma2
        if log is not None:
            log.append(f"drop {fit.causes[weakest].label} (z2 {z[weakest] ** 2:.3g})")
        keep = [i for i in range(p) if i != weakest]
        dropped = fit.causes[weakest]
        alternatives.pop(dropped, None)
        fit = _gauss_newton(prob, [fit.causes[i] for i in keep], fit.theta[keep])


def _exact_confounding(prob: _Problem, fit: Fit, cov, active, alternatives: dict, log=None) -> None:
    """Exact confounding, whatever the noise: a candidate whose signature lies in the span of the
    chosen causes can take the place of each chosen cause it loads on (without z3, an offset on f2
    next to m3 does what an offset on f1 does). Noise-free runs make the tie exact, so the
    significance test cannot see it. Adds to ``alternatives`` in place."""
    pipe = prob.pipe
    X = fit.X
    for c in active:
        if c in fit.causes or _redundant(c, fit.causes):
            continue
        col = prob.jacobian(fit.causes + [c], np.append(fit.theta, 0.0), which=[len(fit.causes)])[:, 0]
        nc = float(np.sqrt(col @ col))
        if nc <= 0:
            continue
        b, *_ = np.linalg.lstsq(X, col, rcond=None)
        if np.sqrt(np.sum((col - X @ b) ** 2)) > 1e-3 * nc:
            continue
        for j, cj in enumerate(fit.causes):
            if abs(b[j]) * np.sqrt(X[:, j] @ X[:, j]) < 0.05 * nc:
                continue
            alts = alternatives.setdefault(cj, [])
            if any(alt[0] == c for alt in alts):
                continue
            # the same span with c in place of cj: its estimate and standard error from the
            # linear relation
            se_c = math.sqrt(max(cov[j, j], 0.0)) / abs(b[j])
            iv = _finding_for(c, fit.theta[j] / b[j], se_c, _practical(c, pipe))["interval"]
            alts.append((c, float(c.to_estimate(fit.theta[j] / b[j])), iv))
            if log is not None:
                log.append(f"confounded: {c.label} can replace {cj.label}")


def _weak_identifiability(prob: _Problem, active, chosen, Jc, sigma2: float) -> dict:
    """Per parameter not chosen: the 95 % half-width a single-cause fit would have at this noise
    level."""
    weak = {}
    for c in active:
        if c.kind is not PARAMETER_ERROR or c in chosen:
            continue
        col = Jc.get(c)
        if col is None:
            continue
        nn = float(col @ col)
        if nn <= 0:
            continue
        var = sigma2 * float(prob.sandwich_meat(col[:, None])[0, 0]) / nn**2
        weak[c.target] = 1.96 * math.sqrt(var)
    return weak


def _subset_screen(base_r: np.ndarray, active, Jc, size: int, top: int = 3) -> list:
    """The ``top`` subsets of ``size`` candidates whose linear fit (sensitivities at the model,
    ``Jc``) leaves the smallest residual of the base run, from the Gram matrix (every subset is
    screened, not only the ones forward selection walks through)."""
    cands = [c for c in active if c in Jc]
    if len(cands) < size:
        return []
    J = np.column_stack([Jc[c] for c in cands])
    norms = np.sqrt(np.sum(J * J, axis=0))
    norms[norms == 0] = 1.0
    Jn = J / norms
    G = Jn.T @ Jn
    b = Jn.T @ base_r
    out = []
    for S in itertools.combinations(range(len(cands)), size):
        if size > 1 and any(cands[i] == _BOTH for i in S) and \
                sum(cands[i].kind is FORCE_OFFSET for i in S) > 1:
            continue  # equal offsets next to a single offset: two channel offsets, screened as such
        GS = G[np.ix_(S, S)]
        if np.linalg.cond(GS) > 1e10:
            continue
        gain = float(b[list(S)] @ np.linalg.solve(GS, b[list(S)]))
        out.append((gain, [cands[i] for i in S]))
    out.sort(key=lambda s: -s[0])
    return out[:top]


def _wald(prob: _Problem, fit: Fit, idx: list[int]) -> float:
    """Joint Wald statistic of the causes ``idx`` of a fit (sandwich covariance: the rows are
    correlated through the model)."""
    if not idx:
        return 0.0
    sigma2 = fit.rss / max(len(fit.r) - len(fit.causes), 1)
    cov = _covariance(prob, fit.X, sigma2)[np.ix_(idx, idx)]
    th = fit.theta[idx]
    return float(th @ np.linalg.pinv(cov) @ th)


def _union(fit: Fit, extra: list) -> tuple[list, np.ndarray]:
    """The selection's causes and ``extra`` in one fit, with its start. Equal offsets on both
    forces next to a single-channel offset span what the two channel offsets span: they enter as
    the channel offsets (the span, and so the test, is the same)."""
    causes = list(fit.causes) + list(extra)
    theta = np.append(fit.theta, np.zeros(len(extra)))
    if _BOTH in causes and any(c.kind is FORCE_OFFSET and c != _BOTH for c in causes):
        ib = causes.index(_BOTH)
        tb = theta[ib]
        causes.pop(ib)
        theta = np.delete(theta, ib)
        for ch in FORCE_CHANNELS:
            c = Cause(FORCE_OFFSET, ch)
            if c in causes:
                theta[causes.index(c)] += tb
            else:
                causes.append(c)
                theta = np.append(theta, tb)
    return causes, theta


def _parsimony(prob: _Problem, base: Fit, fit: Fit, active, Jc, crit: float, log=None) -> tuple[Fit, list]:
    """Best-subset check of the selected causes. Forward selection adds one cause at a time and
    can lock in a cause that only stands in for two others (an offset on f2 for an offset on f1
    next to a scale on f2, then a mass error to mend the rest). Every subset of the same size and
    of one cause fewer is screened linearly and the best three refined; each is fitted together
    with the selection, and the joint Wald test (sandwich covariance, the selection's own
    familywise level) decides: a smaller set replaces the selection when the selection's causes
    outside it add nothing significant to it, a set of the same size when its own causes are
    significant next to the selection's and the selection's are not next to its."""
    pipe = prob.pipe
    level = scipy.stats.chi2.sf(crit, 1)
    seen = {frozenset(fit.causes)}
    ties: list = []
    for _ in range(3):
        k = len(fit.causes)
        if k < 2:
            return fit, ties
        cur = set(fit.causes)
        new = None
        for size in (k - 1, k):
            for _, S in _subset_screen(base.r, active, Jc, size):
                if frozenset(S) in seen:
                    continue
                seen.add(frozenset(S))
                extra = [c for c in S if c not in cur]
                union, th0 = _union(fit, extra)
                f_u = _gauss_newton(prob, union, th0)
                if any(_at_bound(c, th, pipe) for c, th in zip(f_u.causes, f_u.theta)):
                    continue
                out_idx = [i for i, c in enumerate(f_u.causes) if c not in S]
                in_idx = [i for i, c in enumerate(f_u.causes) if c in extra]
                w_out = _wald(prob, f_u, out_idx)
                w_in = _wald(prob, f_u, in_idx)
                ok_out = w_out < scipy.stats.chi2.isf(level, len(out_idx))
                ok_in = size < k or w_in >= scipy.stats.chi2.isf(level, len(in_idx))
                if log is not None:
                    log.append(f"subset? {[c.label for c in S]}: Wald of {[f_u.causes[i].label for i in out_idx]} "
                               f"{w_out:.3g}, of {[f_u.causes[i].label for i in in_idx]} {w_in:.3g}")
                if size == k and ok_out and not ok_in and len(in_idx) == 1 and len(out_idx) == 1:
                    # one cause for another and neither adds anything next to the other: the run
                    # cannot tell them apart
                    ties.append((f_u.causes[out_idx[0]], f_u.causes[in_idx[0]], list(S)))
                if not (ok_out and ok_in):
                    continue
                f_s = _gauss_newton(prob, S, np.array([f_u.theta[f_u.causes.index(c)] for c in S]))
                if any(_at_bound(c, th, pipe) or abs(th) < _practical(c, pipe)
                       for c, th in zip(f_s.causes, f_s.theta)):
                    continue
                new = f_s
                break
            if new is not None:
                break
        if new is None:
            return fit, ties
        if log is not None:
            log.append(f"subset {[c.label for c in fit.causes]} -> {[c.label for c in new.causes]}")
        fit = _normalise(prob, new)
        ties = []
    return fit, ties


def _tie_alternatives(prob: _Problem, fit: Fit, ties: list, alternatives: dict, log=None) -> None:
    """Record the one-for-one ties of the best-subset check as ``indistinguishable_from`` (with
    the estimate and 95 % interval the other cause takes in place of the chosen one)."""
    pipe = prob.pipe
    for c_out, c_in, S in ties:
        if c_out not in fit.causes or c_in in fit.causes:
            continue
        alts = alternatives.setdefault(c_out, [])
        if any(a[0] == c_in for a in alts):
            continue
        f_s = _gauss_newton(prob, S, np.zeros(len(S)))
        j = f_s.causes.index(c_in)
        sigma2 = f_s.rss / max(len(f_s.r) - len(S), 1)
        se = math.sqrt(max(_covariance(prob, f_s.X, sigma2)[j, j], 0.0))
        iv = _finding_for(c_in, f_s.theta[j], se, _practical(c_in, pipe))["interval"]
        alts.append((c_in, float(c_in.to_estimate(f_s.theta[j])), iv))
        if log is not None:
            log.append(f"indistinguishable: {c_in.label} for {c_out.label}")


def _select(prob: _Problem, max_causes: int = 3, log=None, candidates=None) -> Selection:
    """Which causes: forward selection, exchange, backward elimination, exact confounding, then
    ranked by |z| (most significant first). ``candidates``: the causes to choose from (default:
    every candidate of the run; a campaign passes the sensor effects only, its vehicle parameters
    being fitted jointly over the runs)."""
    base = _gauss_newton(prob, [], [])
    dynamic = len(base.r) > 2
    active, not_ident, Jc = _identifiable(prob, _candidates(prob.pipe) if candidates is None else list(candidates))
    crit = scipy.stats.chi2.ppf(1 - ALPHA / max(len(active), 1), 1)
    fit, chosen, alternatives, path = _forward(prob, base, active, Jc, crit, max_causes, log)
    fit, cov, z, sigma2 = _backward(prob, fit, alternatives, crit, log)
    if dynamic and len(fit.causes) > 1:
        before = list(fit.causes)
        fit, ties = _parsimony(prob, base, fit, active, Jc, crit, log)
        if fit.causes != before:
            alternatives = {c: a for c, a in alternatives.items() if c in fit.causes}
            fit, cov, z, sigma2 = _backward(prob, fit, alternatives, crit, log)
        _tie_alternatives(prob, fit, ties, alternatives, log)
    if dynamic and fit.causes:
        _exact_confounding(prob, fit, cov, active, alternatives, log)
    if len(fit.causes) > 1:
        order = np.argsort(-np.abs(z))
        fit = Fit([fit.causes[i] for i in order], fit.theta[order], fit.r, fit.res, fit.rss,
                  fit.X[:, order])
        cov = cov[np.ix_(order, order)]
        z = z[order]
    weak = _weak_identifiability(prob, active, chosen, Jc, sigma2) if dynamic else {}
    return Selection(fit, cov, math.sqrt(sigma2), z, alternatives, not_ident, weak,
                     base.rss, path)
