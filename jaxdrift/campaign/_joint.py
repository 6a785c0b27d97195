"""The joint diagnosis of a campaign: the vehicle's parameter errors fitted over all runs at once,
each logger's sensor effects as nuisance parameters (``docs/campaign.md``).

The residual problem of each run is the single-run one (:class:`~jaxdrift.diagnosis.vehicle.
_problem._Problem`: the same weighted residual rows, instruments, sandwich covariance); the runs'
rows are stacked. Per logger group the nuisance directions are projected out (``Z = S - N N^+ S``,
computed on the workers, :func:`._tasks.blocks_task`), so the shared step and covariance need only
the small sums ``A = sum Z^T Z``, ``b = sum Z^T r`` and ``M = sum sigma_i^2 meat_i(Z_i)``:
``delta = -A^-1 b``, ``cov = A^-1 M A^-1``. Runs are independent, so their meats add. Each run's
rows are weighted by ``1 / sigma_i`` (its own force-noise level): the runs' noise differs by
orders of magnitude, and an unweighted stack lets the noisiest runs decide the variance.

Selection is the single-run one lifted to the stack: forward steps by the linear score of each
candidate, a joint Gauss-Newton refit, the Wald test at the single-run level (Bonferroni over the
candidates), backward elimination. Then each run's sensor effects are chosen again by the
single-run selection against the joint vehicle (``_tasks.reselect_task``), and the shared fit is
repeated with them.

The reported estimate and interval of each chosen parameter are a fixed-effect meta-analysis over
the runs' own estimates (:func:`meta_analysis`): each run weighted by its whole single-run error
budget, the sandwich variance plus the resolution floor's, which the stacked fit's one weight per
run cannot express (:func:`joint_findings`).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.stats

from ..diagnosis.vehicle import (ALPHA, FORCE_CHANNELS, FORCE_OFFSET, PARAMETER_ERROR, SENSOR_KINDS, Cause,
                                 apply_causes as _apply, finding_for as _finding_for, practical_size as _practical,
                                 theta_bounds as _theta_bounds, kind_named)
from ._executor import map_tasks
from ._tasks import blocks_task, reselect_task

__all__ = ["JointFit", "sensor_causes_of", "effective_runs", "meta_analysis", "CONSISTENCY_LEVEL"]

#: the family-wise false-alarm rate of "X differs between runs" over one campaign: every shared
#: parameter's scatter test and every run's own test together (Bonferroni over 2 x parameters
#: tests, the run tests of a parameter also over its runs); a campaign of consistent runs raises an
#: alarm in at most this share (tests/test_campaign.py, 400 simulated campaigns)
CONSISTENCY_LEVEL = 0.05


def sensor_causes_of(report: dict) -> tuple[list[Cause], list[float]]:
    """The sensor effects a single-run report names, as causes and starting theta."""
    causes, theta = [], []
    for f in report.get("findings", []):
        if f.get("cause") not in {k.name for k in SENSOR_KINDS} or "channel" not in f:
            continue
        c = Cause(kind_named(f["cause"]), f["channel"])
        if c in causes:
            continue
        causes.append(c)
        theta.append(c.kind.to_theta(float(f["estimate"])))
    return causes, theta


def _merge(cause_lists) -> tuple[list[Cause], list[float]]:
    """One logger's sensor effects from its runs' (causes, theta): the union; the theta averaged.
    An equal offset on both forces next to a channel offset becomes the two channel offsets."""
    acc: dict = {}
    for causes, theta in cause_lists:
        for c, t in zip(causes, theta):
            acc.setdefault(c, []).append(float(t))
    both = Cause(FORCE_OFFSET, "both")
    if both in acc and any(c.kind is FORCE_OFFSET and c != both for c in acc):
        tb = float(np.mean(acc.pop(both)))
        for ch in FORCE_CHANNELS:
            c = Cause(FORCE_OFFSET, ch)
            acc[c] = [t + tb for t in acc.get(c, [0.0])]
    causes = sorted(acc, key=lambda c: (c.kind.name, c.target))
    return causes, [float(np.mean(acc[c])) for c in causes]


class JointFit:
    """The campaign's joint fit over ``groups`` (lists of run specs sharing a logger) on a Dask
    ``client``. ``start``: per group the (causes, theta) of its sensor effects to start from."""

    def __init__(self, client, groups, model: dict, model_given: bool, candidates, start, *,
                 progress: bool = True, max_shared: int = 6, log: list | None = None):
        self.client, self.groups, self.model = client, groups, model
        self.model_given = model_given
        self.candidates = list(candidates)
        self.nuis = [list(s[0]) for s in start]
        self.theta_n = [np.asarray(s[1], float) for s in start]
        self.progress, self.max_shared = progress, max_shared
        self.log = log if log is not None else []
        self.crit = scipy.stats.chi2.ppf(1 - ALPHA / max(len(self.candidates), 1), 1)
        self.rounds = 0
        #: per group, per run: the extra spring forces of the joint nonlinear causes (None: none)
        self.extra = [None] * len(groups)
        self.not_carried = [[] for g in groups for _ in g]

    # -- one round over all groups
    def _blocks(self, shared, theta, final=False, screen=True):
        """One round: every group's blocks at ``theta``; ``screen``: with the columns of the
        candidates not chosen (for the next forward step)."""
        extras = [c for c in self.candidates if c not in shared] if screen else []
        outs = []
        for g, out in enumerate(map_tasks(
                self.client, _blocks_call, list(zip(range(len(self.groups)), self.extra)),
                desc=f"joint fit, round {self.rounds + 1}",
                progress=self.progress, groups=self.groups, model=self.model, model_given=self.model_given,
                shared=list(shared), theta_shared=np.asarray(theta, float).tolist(), extras=extras,
                nuis=self.nuis, theta_nuis=[t.tolist() for t in self.theta_n], final=final)):
            self.theta_n[g] = np.asarray(out["theta_nuis"], float)
            outs.append(out)
        self.rounds += 1
        order = list(shared) + extras
        A = sum(r["A"] for o in outs for r in o["runs"])
        b = sum(r["b"] for o in outs for r in o["runs"])
        M = np.zeros_like(A)
        p = len(shared)
        for o, nuis in zip(outs, self.nuis):
            for r in o["runs"]:
                M = M + self.sigma2(r, p + len(nuis)) * r["M"]
        if screen:
            # candidates no run sees (tyre parameters without contact-point data): not screened again
            d = np.diag(A)
            seen = d > 1e-12 * max(float(np.max(d)) if d.size else 0.0, 1e-300)
            self.candidates = [c for c in self.candidates if c in shared or seen[order.index(c)]]
        return order, A, b, M, outs

    @staticmethod
    def sigma2(r: dict, p: int) -> float:
        return r["rss"] / max(r["rows"] - p, 1)

    def refit(self, shared, theta, iters: int = 6):
        """Gauss-Newton over the shared parameters (the nuisance refitted inside each round),
        until a step is below 5 % of every standard error; then one round at the result with the
        screening columns."""
        theta = np.asarray(theta, float)
        for _ in range(iters if shared else 0):
            order, A, b, M, outs = self._blocks(shared, theta, screen=False)
            idx = list(range(len(shared)))
            step = -np.linalg.lstsq(A[np.ix_(idx, idx)], b[idx], rcond=None)[0]
            se = np.sqrt(np.maximum(np.diag(self.covariance((order, A, b, M, outs, theta), len(shared))), 0.0))
            new = theta + step
            for i, c in enumerate(shared):
                lo, hi = _theta_bounds(c, None)
                new[i] = min(max(new[i], lo), hi)
            done = np.all(np.abs(new - theta) <= 0.05 * se)
            theta = new
            if done:
                break
        order, A, b, M, outs = self._blocks(shared, theta)
        self.log.append(f"joint refit {[c.label for c in shared]}: round {self.rounds}")
        return theta, (order, A, b, M, outs, theta.copy())
    def covariance(self, state, k: int) -> np.ndarray:
        _, A, _, M, _, _ = state
        idx = list(range(k))
        Ai = np.linalg.pinv(A[np.ix_(idx, idx)])
        return Ai @ M[np.ix_(idx, idx)] @ Ai

    def _passes(self, c, theta_c, var) -> bool:
        lo, hi = _theta_bounds(c, None)
        at_bound = theta_c <= lo + 1e-9 or theta_c >= hi - 1e-9
        return (var > 0 and theta_c ** 2 / var >= self.crit and abs(theta_c) >= _practical(c, None)
                and not at_bound)

    def select(self, shared=(), theta=()):
        """Forward selection of the shared parameters with joint refits, then backward elimination."""
        shared, theta = list(shared), np.asarray(theta, float)
        theta, state = self.refit(shared, theta)
        while len(shared) < self.max_shared:
            order, A, b, _, _, _ = state
            k = len(shared)
            idx0 = list(range(k))
            base = float(b[idx0] @ np.linalg.lstsq(A[np.ix_(idx0, idx0)], b[idx0], rcond=None)[0]) if k else 0.0
            scores = []
            for j in range(k, len(order)):
                S = idx0 + [j]
                g = float(b[S] @ np.linalg.lstsq(A[np.ix_(S, S)], b[S], rcond=None)[0]) - base
                scores.append((g, j))
            if not scores:
                break
            scores.sort(reverse=True)
            j = scores[0][1]
            c = order[j]
            # the linear Wald statistic first: a candidate far below the test is not refined
            S = idx0 + [j]
            Ai = np.linalg.pinv(A[np.ix_(S, S)])
            t_lin = (-(Ai @ b[S]))[-1]
            v_lin = (Ai @ state[3][np.ix_(S, S)] @ Ai)[-1, -1]
            if not (v_lin > 0 and t_lin ** 2 / v_lin >= 0.25 * self.crit):
                self.log.append(f"joint step {k + 1}: best candidate {c.label}, linear z2 "
                                f"{t_lin ** 2 / v_lin if v_lin > 0 else 0:.3g}: none passes")
                break
            th_c, st_c = self.refit(shared + [c], np.append(theta, t_lin))
            var = self.covariance(st_c, k + 1)[-1, -1]
            self.log.append(f"joint step {k + 1}: {c.label} theta {th_c[-1]:.5g} z2 "
                            f"{th_c[-1] ** 2 / var if var > 0 else 0:.3g} (crit {self.crit:.3g})")
            if not self._passes(c, th_c[-1], var):
                break
            shared, theta, state = shared + [c], th_c, st_c
        while shared:
            cov = self.covariance(state, len(shared))
            ok = [self._passes(c, theta[i], cov[i, i]) for i, c in enumerate(shared)]
            if all(ok):
                break
            z2 = [theta[i] ** 2 / cov[i, i] if cov[i, i] > 0 else 0.0 for i in range(len(shared))]
            drop = next((i for i, o in enumerate(ok) if not o and abs(theta[i]) < _practical(shared[i], None)),
                        int(np.argmin(z2)))
            self.log.append(f"joint: drop {shared[drop].label} (z2 {z2[drop]:.3g})")
            keep = [i for i in range(len(shared)) if i != drop]
            shared = [shared[i] for i in keep]
            theta, state = self.refit(shared, theta[keep])
        return shared, theta, state

    def carry(self, sized) -> None:
        """The extra spring forces of the joint nonlinear laws, per run (``_nonlinear.size_task``'s
        ``extra``, groups flattened; None: none), into every later round; ``not_carried``: per run the
        laws that could not be carried into it."""
        self.not_carried = [list((sized[i] if sized else {}).get("unsettled", [])) for i in range(sum(map(len, self.groups)))]
        pos, extra = 0, []
        for grp in self.groups:
            extra.append(None if sized is None else [tuple(sized[pos + k]["extra"]) for k in range(len(grp))])
            pos += len(grp)
        self.extra = extra

    def reselect(self, specs_by_group, shared, theta):
        """Each run's sensor effects chosen again against the joint vehicle; per logger the union."""
        p_joint, _ = _apply(self.model, shared, theta)
        flat = [(s, None if self.extra[g] is None else self.extra[g][k])
                for g, grp in enumerate(specs_by_group) for k, s in enumerate(grp)]
        res = map_tasks(self.client, _reselect_call, flat, desc="sensor effects against the joint vehicle",
                        progress=self.progress, model=self.model, model_given=self.model_given,
                        joint_model={k: float(v) for k, v in p_joint.items()})
        pos = 0
        for g, grp in enumerate(specs_by_group):
            part = res[pos:pos + len(grp)]
            pos += len(grp)
            self.nuis[g], th = _merge([(r["causes"], r["theta"]) for r in part])
            self.theta_n[g] = np.asarray(th, float)


def _blocks_call(item, *, groups, theta_nuis, nuis, **kw):
    g, extra = item
    return blocks_task(groups[g], nuis=nuis[g], theta_nuis=theta_nuis[g], extra_forces=extra, **kw)


def _reselect_call(item, **kw):
    spec, extra = item
    return reselect_task(spec, extra_forces=extra, **kw)


def consistency(shared, theta, state, sigma2_fn, run_names, p_of_run) -> list[dict]:
    """Per shared parameter: each run's own estimate (the other shared parameters held at the joint
    values, the run's sensor effects projected out: one Gauss-Newton step from the joint value),
    its sandwich standard error and its ``weight`` in the joint estimate (its weighted ``Z^T Z``:
    the joint value is, to first order, the weight-averaged runs' own estimates); these feed the
    meta-analysis (:func:`meta_analysis`). Beside them ``own_estimate``/``own_se``: the run's
    marginal estimate, every shared parameter the run resolves free at once (:func:`_own_block`);
    :func:`check_consistency` tests their scatter. Held at the joint values, a run whose mass
    differs reads its spring as differing too; free, each difference stays where it is."""
    _, _, _, _, outs, _ = state
    rows = [(r, p_of_run[g]) for g, o in enumerate(outs) for r in o["runs"]]
    ns = len(shared)
    own = [_own_block(r, ns, sigma2_fn(r, p)) for r, p in rows]
    out = []
    for j, c in enumerate(shared):
        per_run = []
        for (r, p), name, (d_own, v_own) in zip(rows, run_names, own):
            a = r["A"][j, j]
            if a <= 0:
                continue
            var = sigma2_fn(r, p) * r["M"][j, j] / a ** 2
            if not (var > 0 and math.isfinite(var)):
                continue
            row = {"run": name, "estimate": c.to_estimate(theta[j] - r["b"][j] / a), "se": math.sqrt(var),
                   "weight": float(a), "own_estimate": None, "own_se": None}
            if d_own is not None and math.isfinite(d_own[j]) and v_own[j] > 0 and math.isfinite(v_own[j]):
                row["own_estimate"], row["own_se"] = c.to_estimate(theta[j] - d_own[j]), math.sqrt(v_own[j])
            per_run.append(row)
        out.append({"parameter": c.target, "joint_estimate": c.to_estimate(theta[j]), "per_run": per_run})
    return out


#: the smallest difference between runs that "X differs" claims: two runs whose parameter differs
#: by less than 0.5 % are one vehicle (the campaign's false-alarm table, docs/explanation/campaign.md,
#: was measured at it; the single-run confirmation margin, PARAMETER_ERROR.confirm_margin, is wider:
#: what one run's model lacks is read as changes near it, while a difference between runs of one
#: vehicle shares that lack); the tests ask whether the difference exceeds it
DIFFERENCE_MARGIN = 0.005

#: the smallest eigenvalue of a run's scaled information matrix of the shared parameters (a
#: correlation matrix, so this is 1 - |rho| for two parameters) below which the run cannot tell
#: them apart: the parameter weighing most in that direction is left out of the run's block
_RESOLVED_EIG = 1e-9


def _own_block(r: dict, ns: int, sigma2: float) -> tuple:
    """A run's marginal Gauss-Newton step over the shared parameters (``delta = A_s^-1 b_s`` on
    the run's own block, the sandwich variances ``sigma2 diag(A_s^-1 M_s A_s^-1)``); parameters the
    run cannot separate from the others (:data:`_RESOLVED_EIG`) or does not see at all get NaN.
    ``(None, None)`` when the run resolves none."""
    A, b, M = (np.asarray(r["A"], float)[:ns, :ns], np.asarray(r["b"], float)[:ns],
               np.asarray(r["M"], float)[:ns, :ns])
    keep = [j for j in range(ns) if A[j, j] > 0 and math.isfinite(A[j, j])]
    while keep:
        Ak = A[np.ix_(keep, keep)]
        d = np.sqrt(np.diag(Ak))
        w, V = np.linalg.eigh(Ak / np.outer(d, d))
        if w[0] > _RESOLVED_EIG:
            break
        keep.pop(int(np.argmax(np.abs(V[:, 0]))))
    if not keep:
        return None, None
    Ainv = np.linalg.inv(A[np.ix_(keep, keep)])
    delta, var = np.full(ns, np.nan), np.full(ns, np.nan)
    delta[keep] = Ainv @ b[keep]
    var[keep] = sigma2 * np.diag(Ainv @ M[np.ix_(keep, keep)] @ Ainv)
    return delta, var


def meta_analysis(entry: dict) -> dict | None:
    """The fixed-effect meta-analysis of a shared parameter over the runs' own estimates
    (:func:`consistency`): each run's variance ``v_i`` is its single-run error budget, the sandwich
    variance plus the single-run resolution floor's, ``se_i^2 + (floor / 1.96)^2`` (the variance
    its single-run interval stands for); the combined estimate is their inverse-variance mean
    ``sum w_i e_i / sum w_i`` with ``w_i = 1 / v_i``, its variance ``1 / sum w_i``; ``chi2`` is the
    scatter ``sum w_i (e_i - mean)^2`` on ``runs - 1`` degrees of freedom. ``None`` without runs."""
    c = Cause(PARAMETER_ERROR, entry["parameter"])
    floor_se = _practical(c, None) / 1.96
    rows = [(float(r["estimate"]), float(r["se"]) ** 2 + floor_se ** 2) for r in entry.get("per_run", [])]
    if not rows:
        return None
    e = np.array([x for x, _ in rows])
    w = 1.0 / np.array([v for _, v in rows])
    W = float(w.sum())
    mean = float(w @ e / W)
    return {"estimate": mean, "se": math.sqrt(1.0 / W), "chi2": float(w @ (e - mean) ** 2),
            "dof": max(len(rows) - 1, 1), "runs": len(rows), "effective_runs": effective_runs(w),
            "largest_weight_share": float(w.max() / W), "floor_se": floor_se}


def check_consistency(entry: dict, family: int = 1) -> dict:
    """The scatter of the runs' own estimates of a shared parameter about their inverse-variance
    mean (the stacked fit's value where no run has its own estimate): each run's marginal estimate
    (:func:`_tested`: every shared parameter the run resolves free, so that a difference in one
    parameter is not read as one in another), its variance the sandwich variance plus the
    single-run resolution floor in quadrature (its single-run interval), the chi-square on runs - 1
    degrees of freedom, and the runs whose own estimate lies outside it; runs that cannot separate
    the parameter from the others are listed in ``not_separable``, and runs whose own estimate lies
    outside the parameter's plausible range (``ParameterError.theta_range``: a body mass x 5.3, on a
    pitch-only run of a rough road that its model could not fit, with 1300 N of residual for 2.5 N of
    force noise) in ``implausible``: neither is tested. Both tests ask whether a
    difference exceeds :data:`DIFFERENCE_MARGIN` (each deviation shrunk by it towards 0): the claim
    is a vehicle that differs by more than the single-run diagnosis would call no error.
    ``family``: how many parameters the campaign tests; the scatter test
    runs at ``CONSISTENCY_LEVEL / (2 family)`` and each run's at that level over the runs, so the
    campaign's alarms stay within ``CONSISTENCY_LEVEL`` family-wise. The combined estimate is
    kept as ``meta``."""
    c = Cause(PARAMETER_ERROR, entry["parameter"])
    floor_se = _practical(c, None) / 1.96
    lo, hi = _theta_bounds(c, None)
    meta = meta_analysis(entry)
    ests, untested, implausible = [], [], []
    for r in entry["per_run"]:
        e, se = _tested(r)
        if e is None:
            untested.append(r["run"])
        elif not lo < e - 1.0 < hi:  # no vehicle has it: the run's model broke down, not its vehicle
            implausible.append(r["run"])
        else:
            ests.append((r["run"], e - 1.0, se ** 2 + floor_se ** 2))
    if ests:  # the centre: the inverse-variance mean of the estimates tested
        w = np.array([1.0 / v for _, _, v in ests])
        th = float(w @ np.array([e for _, e, _ in ests]) / w.sum())
    else:
        th = (meta["estimate"] if meta else entry["joint_estimate"]) - 1.0
    n = len(ests)
    level = CONSISTENCY_LEVEL / (2 * max(family, 1))
    z_bonf = float(scipy.stats.norm.isf(0.5 * level / max(n, 1)))
    q = float(sum(_beyond_margin(e - th) ** 2 / v for _, e, v in ests))
    dof = max(n - 1, 1)
    pval = float(scipy.stats.chi2.sf(q, dof))
    bad = [{"run": nm, "estimate": 1.0 + e, "interval": [1.0 + e - 1.96 * math.sqrt(v), 1.0 + e + 1.96 * math.sqrt(v)],
            "z": z} for nm, e, v, z in _outlying_runs(ests, z_bonf, DIFFERENCE_MARGIN)]
    return {**entry, "meta": meta, "runs": len(entry["per_run"]), "runs_tested": n, "chi2": q, "dof": dof,
            "p_value": pval, "level": level, "consistent": pval >= level and not bad, "disagreeing_runs": bad,
            **({"not_separable": untested} if untested else {}), **({"implausible": implausible} if implausible else {})}


def _beyond_margin(d, margin: float = DIFFERENCE_MARGIN):
    """A deviation (or an array of them) shrunk towards 0 by ``margin``, its sign kept: how far it
    lies beyond the difference that "differs" does not claim."""
    return np.sign(d) * np.maximum(np.abs(d) - margin, 0.0)


def _tested(r: dict) -> tuple:
    """The estimate and standard error of a run that the scatter test compares: the run's marginal
    one (``own_estimate``, every shared parameter it resolves free) where :func:`consistency` made
    it, ``(None, None)`` where the run cannot separate this parameter from the others; the
    conditional one for entries that carry only ``estimate`` and ``se`` (made by hand from
    per-run estimates)."""
    if "own_estimate" not in r:
        return r["estimate"], r["se"]
    return r["own_estimate"], r["own_se"]


def _outlying_runs(ests: list, z_crit: float, margin: float = 0.0) -> list:
    """The runs whose estimate differs from the others', one at a time: each run against the
    inverse-variance mean of the others (``z = (e - mean_others) / sqrt(v + 1 / W_others)``; a
    run against a mean that includes itself is pulled towards it, most where it weighs most); the
    most distant one beyond ``z_crit`` is listed and left out, and the rest tested again. Names a
    run only among three or more (of two, the data cannot tell which one differs).
    ``ests``: ``(run, estimate, variance)``; returns ``(run, estimate, variance, z)``."""
    rest, out = list(ests), []
    while len(rest) >= 3:
        e = np.array([x[1] for x in rest])
        w = 1.0 / np.array([x[2] for x in rest])
        W, S = float(w.sum()), float(w @ e)
        mean_o = (S - w * e) / (W - w)
        z = _beyond_margin(e - mean_o, margin) / np.sqrt(1.0 / w + 1.0 / (W - w))
        j = int(np.argmax(np.abs(z)))
        if abs(z[j]) <= z_crit:
            break
        out.append((*rest.pop(j), float(z[j])))
    return out


def effective_runs(weights) -> float:
    """Kish's effective number of runs of a weighted average: ``(sum u)^2 / sum u^2`` over the
    positive weights (0 without any)."""
    u = np.asarray([w for w in weights if w > 0 and math.isfinite(w)], float)
    return float(u.sum() ** 2 / np.sum(u * u)) if u.size else 0.0


def joint_findings(shared, theta, cov, n_runs: int, named: dict, consistency: list[dict]) -> list[dict]:
    """The report's finding objects for the shared parameters, their 95 % intervals widened to
    hold jointly as in a single-run report.

    Estimate and interval are the fixed-effect meta-analysis over the runs (:func:`meta_analysis`
    of each :func:`check_consistency` entry): the inverse-variance mean of the runs' own
    estimates, each run weighted by its whole single-run error budget (sandwich variance plus the
    resolution floor's variance), half-width ``1.96 sqrt(d / sum w_i)`` with ``d = max(1, chi2 /
    dof)`` the over-dispersion of the runs about that mean (scatter beyond the runs' own
    variances, whatever its cause, widens the interval by as much; it never narrows it). The
    floor stands for a per-run resolution error of the sampled comparison, independent between
    runs (their rates, roads and records differ), so it averages down with the runs' number as
    their sandwich errors do, in proportion to each run's share of the weights: a run far more
    precise than the floor carries no more weight than the floor allows. The stacked fit's value
    (``theta``, whose weights ignore the floor) is kept as ``stacked_estimate``; the meta-analytic
    mean is reported because the interval is the variance of that mean: the stacked value carries
    the resolution error of the few runs that dominate its weights. A parameter no run has its own
    estimate of keeps the stacked value with its sandwich error and the single-run floor."""
    from ..diagnosis import joint_intervals

    cons = {c["parameter"]: c for c in consistency}
    findings = []
    for i, c in enumerate(shared):
        k = cons.get(c.target, {})
        n_inf = max(int(k.get("runs", n_runs)), 1)
        meta = (k.get("meta") or meta_analysis(k)) if k.get("per_run") else None
        src = meta or k
        disp = max(1.0, float(src.get("chi2", 0.0)) / max(float(src.get("dof", 1)), 1.0))
        if meta:
            th = c.kind.to_theta(meta["estimate"])
            se = meta["se"] * math.sqrt(disp)
            f = _finding_for(c, th, se, 0.0)
            n_eff = meta["effective_runs"]
        else:
            th = float(theta[i])
            se = math.sqrt(max(cov[i, i], 0.0) * disp)
            f = _finding_for(c, th, se, _practical(c, None))
            n_eff = 1.0
        z = abs(th) / se if se > 0 else math.inf
        f["z"] = float(z)
        f["overdispersion"] = float(disp)
        f["runs_informing"] = n_inf
        f["effective_runs"] = float(n_eff)
        f["stacked_estimate"] = float(c.to_estimate(theta[i]))
        nm = named.get(c.target, 0)
        f["evidence"] = (f"fitted jointly over the {n_runs} runs (each logger's sensor effects as nuisance "
                         f"parameters); the inverse-variance mean of the {n_inf} runs' own estimates: "
                         f"{c.to_estimate(th):.5g}, z = {z:.3g}; {nm} of the {n_runs} single-run diagnoses name it; "
                         f"the runs' own estimates scatter {math.sqrt(disp):.3g} x their single-run errors.")
        findings.append(f)
    return joint_intervals(findings)
