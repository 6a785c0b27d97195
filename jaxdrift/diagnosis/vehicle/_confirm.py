"""Every correction in the extended model must improve the model where the report shows it.

A later finding can undo an earlier right one (``FIELD-NOTES``: a spurious inertia and delay after a
right stiffness made the force-driven pitch error 12x worse while the report showed a gain). So
each chosen cause is checked the way the report presents it: on the residual channel where it shows
most (the evidence sentence's channel), the RMS with the cause must be below the RMS without it
(the other causes kept) on the whole run *and* on each half of it separately (the second half is
data the cause's size was not tuned to alone; a cause that only trades one half against the other
is fitting noise or the comparison's own error). A cause that fails is dropped and the rest refit.
"""

from __future__ import annotations

import math

import numpy as np

from ._causes import _apply
from ._problem import Fit, _gauss_newton, _Problem
from ._report import _rms, _telling_channel
from ._select import Selection, _covariance


def improvement(prob: _Problem, fit: Fit, i: int, res1=None) -> dict:
    """RMS of the telling channel without cause ``i`` and with it, whole run and halves."""
    pipe, model = prob.pipe, prob.model
    if res1 is None:
        p_ext, corr_ext = _apply(model, fit.causes, fit.theta)
        res1 = pipe.residuals(p_ext, corr_ext)
    others = [j for j in range(len(fit.causes)) if j != i]
    p_o, corr_o = _apply(model, [fit.causes[j] for j in others], fit.theta[others])
    r_without = pipe.residuals(p_o, corr_o)
    main = "moment" if "moment" in prob.names else next(nm for nm in prob.names if nm != "static")
    ch = _telling_channel(prob, r_without, res1, main)
    a = r_without.channels[ch][:prob.rows[ch]]
    b = res1.channels[ch][:prob.rows[ch]]
    h = len(a) // 2
    return {"channel": ch, "without": _rms(a), "with": _rms(b),
            "halves": [(_rms(a[:h]), _rms(b[:h])), (_rms(a[h:]), _rms(b[h:]))]}


def confirm_corrections(prob: _Problem, sel: Selection, log=None) -> tuple[Selection, list]:
    """Drop the causes that do not improve the model on the whole run and on each half (weakest
    first, refitting the rest each time). Returns the new selection and the dropped causes with
    their numbers."""
    fit = sel.fit
    if len(fit.r) <= 2 or not fit.causes:
        return sel, []
    dropped = []
    while fit.causes:
        bad = None
        for i in range(len(fit.causes) - 1, -1, -1):  # the weakest (last ranked) first
            imp = improvement(prob, fit, i)
            ok = imp["with"] < imp["without"] and all(w < wo for wo, w in imp["halves"])
            if not ok:
                bad = (i, imp)
                break
        if bad is None:
            break
        i, imp = bad
        c = fit.causes[i]
        dropped.append((c, float(c.to_estimate(fit.theta[i])), imp))
        if log is not None:
            log.append(f"held out {c.label}: {imp}")
        keep = [j for j in range(len(fit.causes)) if j != i]
        fit = _gauss_newton(prob, [fit.causes[j] for j in keep], fit.theta[keep])
    if not dropped:
        return sel, []
    p = len(fit.causes)
    sigma2 = fit.rss / max(len(fit.r) - p, 1)
    if p:
        cov = _covariance(prob, fit.X, sigma2)
        z = fit.theta / np.sqrt(np.maximum(np.diag(cov), 1e-300))
        order = np.argsort(-np.abs(z))
        fit = Fit([fit.causes[k] for k in order], fit.theta[order], fit.r, fit.res, fit.rss, fit.X[:, order])
        cov, z = cov[np.ix_(order, order)], z[order]
    else:
        cov, z = np.zeros((0, 0)), np.zeros(0)
    alts = {c: a for c, a in sel.alternatives.items() if c in fit.causes}
    return Selection(fit, cov, math.sqrt(sigma2), z, alts, sel.not_identifiable, sel.weakly_identifiable,
                     sel.rss0, sel.rss_path + [fit.rss]), dropped
