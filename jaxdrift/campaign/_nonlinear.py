"""Nonlinear suspension causes fitted jointly over a campaign (``docs/campaign.md``, "Nonlinear
causes").

A bump stop, a progressive spring or an asymmetric damper belongs to the vehicle, as its mass does:
one law for every run. A run shows it only where it reaches it (a stop on a smooth road never does),
so the single-run diagnoses name it in some runs and size it each on its own.

The joint fit takes every such cause a single-run diagnosis named and confirmed, and sizes it in
every run at one law (:func:`size_task`, on the workers): each run's residual under the campaign's
extended model (the joint parameters, the run's logger's sensor effects) is regressed on the cause's
signature exactly as the single-run adequacy test does (``diagnosis.vehicle._adequacy``: the same
band, whitening, nuisance columns, the states iterated under the cause's force where the travel is
not measured), in the axle's spring channel where its travel is measured (the spring force itself),
else where it shows most (the largest |t|, as a single run names it). A measured stop read in the
moment came out 1.0 % soft, in the spring channel 0.2 % stiff, with a standard error of 0.25 % in
both (``tests/test_campaign_nonlinear.py``'s campaign); where the runs' channels disagree so, the
over-dispersion widens the joint interval. The other joint causes are nuisance columns beside it. A bump stop's travel is the vehicle's too: it is profiled over a grid
spanning the travels the runs named, the campaign's z^2 summed over runs, and its interval is the
projection of the joint 95 % region of travel and stiffness (chi-square of 2 degrees of freedom) as
in a single run.

The runs' sizes are combined by the fixed-effect meta-analysis of the shared parameters
(``_joint.meta_analysis``): each run weighted by its whole single-run error budget (the sandwich
variance and the cause's resolution floor), the interval widened by the runs' over-dispersion. A run
whose standard error is too wide for the joint size to pass the single-run test with power (or
that never reaches a stop's travel) cannot show it, and is listed as such. The joint law then goes
into every run's comparison as an extra spring force (``ResidualPipeline.with_extra``), so the
linear parameters are fitted again on a model that has it, and the campaign's extended model and
durability carry it (``extended_model.nonlinear``).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.stats

__all__ = ["NONLINEAR_JOINT", "named_terms", "size_task", "JointNonlinear"]

#: the nonlinear causes a campaign fits jointly (tyre lift-off is read off each run's forces)
NONLINEAR_JOINT = ("bump_stop", "damper_asymmetry", "progressive_spring")
#: bump-stop travels profiled, between the smallest and largest travel the runs named (widened by
#: ``STOP_WIDEN`` of the span on each side)
STOP_GRID, STOP_WIDEN = 15, 0.25
#: the finer grid of a stop's travel between the best travel's neighbours on the first grid
FINE_GRID = 9
#: a stop's travel grid is moved beyond its edge (from the edge, twice its span) while the best
#: travel lies on the edge, at most ``EDGE_MOVES`` times; travels below ``MIN_TRAVEL`` m are not profiled
EDGE_MOVES, MIN_TRAVEL = 3, 1e-4
#: rival causes on one axle are scored by their joint z^2 less this charge per profiled setting (a
#: stop's travel: Akaike's 2 per parameter, the profile's maximum over travels favouring it otherwise)
SETTING_CHARGE = 2.0


def named_terms(results, names) -> list[dict]:
    """The nonlinear causes the single-run diagnoses confirmed: per (cause, parameter) the runs
    naming it, their estimates and intervals and, for a stop, the travels they named."""
    acc: dict = {}
    for n, r in zip(names, results):
        if r.get("status") != "ok":
            continue
        rep = r["report"]
        nl = (rep.get("extended_model") or {}).get("nonlinear") or {}
        for f in rep.get("findings", []):
            if f.get("cause") not in NONLINEAR_JOINT or not f.get("confirmed") or "parameter" not in f:
                continue
            key = (f["cause"], f["parameter"])
            e = acc.setdefault(key, {"cause": f["cause"], "parameter": f["parameter"], "unit": f.get("unit"),
                                     "runs": [], "travels": []})
            e["runs"].append({"run": n, "estimate": float(f["estimate"]), "interval": f.get("interval")})
            u = nl.get(f"stop_u{f['parameter'][1]}")
            if f["cause"] == "bump_stop" and u is not None:
                e["travels"].append(float(u))
    # one cause per axle (the adequacy test names one per axle too): the one most runs name, the
    # others its rivals, between which the joint fit chooses (``JointNonlinear.choose_rivals``)
    by_axle: dict = {}
    for e in sorted(acc.values(), key=lambda e: -len(e["runs"])):
        if e["parameter"][1] in by_axle:
            by_axle[e["parameter"][1]].setdefault("rivals", []).append(e)
        else:
            by_axle[e["parameter"][1]] = e
    return sorted(by_axle.values(), key=lambda e: e["parameter"])


def _cause_of(term: dict, travel: float | None = None):
    from ..diagnosis.vehicle import BumpStop, DamperAsymmetry, ProgressiveSpring

    axle = int(term["parameter"][1]) - 3
    if term["cause"] == "bump_stop":
        return BumpStop(axle, 0.97, travel=travel)
    return {"damper_asymmetry": DamperAsymmetry, "progressive_spring": ProgressiveSpring}[term["cause"]](axle)


def _settings(term: dict) -> list:
    """The settings a term is sized at in every run: a stop's travels (a grid over the span the runs
    named), ``[None]`` for the others."""
    if term["cause"] != "bump_stop":
        return [None]
    if term.get("grid") is not None:
        return [None if x is None else float(x) for x in term["grid"]]
    if term.get("coarse") is not None:
        return list(term["coarse"])
    u = np.asarray(term["travels"], float)
    lo, hi = float(u.min()), float(u.max())
    span = max(hi - lo, 0.1 * abs(hi), 1e-4)
    grid = np.linspace(lo - STOP_WIDEN * span, hi + STOP_WIDEN * span, STOP_GRID)
    return sorted({float(x) for x in np.concatenate([grid, u]) if x > 0})


def _state_of(spec, model, model_given, causes, theta):
    """The run's problem (no extra force), the campaign's extended model on it, its residual and states."""
    from ..diagnosis.vehicle import apply_causes
    from ..diagnosis.vehicle import model_states
    from ._tasks import _problem

    prob = _problem(spec, model, model_given)
    prob = prob.with_pipe(prob.pipe.with_extra(None))
    p_ext, corr = apply_causes(model, causes, theta)
    return (prob, p_ext, corr, prob.pipe.residuals(p_ext, corr),
            model_states(prob.pipe, p_ext, corr, prob.travel_clean))


def size_task(spec, *, model: dict, model_given: bool, causes, theta, terms: list[dict], joint: list | None = None,
              sizes: bool = True, only: list | None = None):
    """One run's size of each joint nonlinear term at each of its settings (``_settings``): per
    setting ``{"setting", "theta", "se", "t", "channel"}`` (``theta`` None where the run never
    reaches the setting). ``joint``: the joint size of each term (theta and setting): the other terms
    enter as nuisance columns at it, and the run's extra spring forces under the joint law (fine
    grid, front and rear) are returned as ``extra`` when ``sizes=False`` (then without the sizes).
    ``only``: the indices of the terms sized (the others None, still nuisance columns)."""
    from ..diagnosis.vehicle import adequacy_tests as _tests, channel_test as _channel_test, refine_size as _refine
    from ..diagnosis.vehicle import signature_column as _column
    from ._tasks import _x64

    _x64()
    prob, p_ext, corr, res1, st = _state_of(spec, model, model_given, causes, theta)
    fs = 1.0 / prob.pipe.h
    joint = joint or [None] * len(terms)
    out = []
    for i, term in enumerate(terms if sizes else []):
        if only is not None and i not in only:
            out.append(None)
            continue
        others = [_cause_of(terms[k], (joint[k] or {}).get("setting")) for k in range(len(terms)) if k != i]
        for o in others:
            o.prepare(st)
        settings = _settings(term)
        cs = [_cause_of(term, x) for x in settings]
        tests = _tests(prob, p_ext, st, res1, cs)
        # the other joint terms as nuisance columns beside it (once per channel)
        n_oth = {nm: np.column_stack([d["N"]] + [_column(prob, st.p, o.axle, o.force(st), nm)[:, None] for o in others])
                 for nm, d in tests.items()} if others else {nm: d["N"] for nm, d in tests.items()}
        rows = []
        for j, (setting, c) in enumerate(zip(settings, cs)):
            best = None
            for nm, d in tests.items():
                col = d["S"][:, j]
                if not np.any(np.abs(col) > 1e-12 * max(float(np.max(np.abs(d["y"]))), 1e-300)):
                    continue  # the run never reaches it: no column
                d = {**d, "N": n_oth[nm]}
                t, th, se, *_ = _channel_test(d["y"], d["N"], col[:, None], fs, d["fc"])[0]
                direct = nm == f"spring{c.axle + 1}"
                if np.isfinite(se) and se > 0 and (best is None or (direct, abs(t)) > (best[4], abs(best[0]))):
                    best = (t, th, se, {**d, "S": col[:, None]}, direct)
            if best is None:
                rows.append({"setting": setting, "theta": None, "se": None, "t": None, "channel": None})
                continue
            t, th, se, d, _ = best
            th, se, _, t_fixed = _refine(prob, st, c, d, th, se)
            rows.append({"setting": setting, "theta": float(th), "se": float(se),
                         "t": float(t if t_fixed is None else t_fixed), "channel": d["name"]})
        out.append(rows)
    res = {"sizes": out}
    if not sizes and any(j is not None for j in joint):
        res["extra"], res["unsettled"] = _extra(prob, st, terms, joint)
    return res


def _extra(prob, st, terms, joint) -> tuple[list, list]:
    """The run's extra spring forces (front, rear; fine grid) under the joint law of every term, and
    the terms whose force could not be solved for (``_fixed_point``; they are left out)."""
    laws = []
    for term, j in zip(terms, joint):
        if j is None or j.get("theta") is None:
            continue
        c = _cause_of(term, j.get("setting"))
        c.prepare(st)
        laws.append((c, float(j["theta"]), f"{term['cause']}[{term['parameter']}]"))
    extra = [np.zeros_like(st.u[0]), np.zeros_like(st.u[0])]
    if not laws:
        return extra, []
    free = [a for a in (0, 1) if not prob.pipe.has_s[a] and any(c.axle == a for c, _, _ in laws)]
    forces, ok = _fixed_point(prob, st, [(c, th) for c, th, _ in laws], free)
    unsettled = [] if ok else [lab for c, _, lab in laws if c.axle in free]
    for (c, _, lab), f in zip(laws, forces):
        if lab not in unsettled:
            extra[c.axle] = extra[c.axle] + f
    return [np.asarray(e, float) for e in extra], unsettled


def _fixed_point(prob, st, laws, free, tol: float = 1e-7):
    """Each law's force ``theta F`` at the travel the model moves with the forces on it. The model is
    linear but for the forces, so this fixed point is the model's own nonlinear solution: ``x = x_lin
    + R(sum theta F(x))`` for the travel and rate ``x`` of the axles in ``free`` (those without a
    measured travel; a measured one is the states' own), ``R`` the linear model's response to extra
    spring forces (``travel_response``). Solved by Newton-Krylov (``scipy.optimize.newton_krylov``)
    for both axles at once (the body couples them): a relaxed iteration diverges where a law's loop
    gain exceeds one (a stop 5.5 x the spring driven at the wheel's resonance, a spring 90 %
    progressive where the linear model's travel overshoots on a rough road). On a run whose travel
    is measured, the force from its model travel this way agrees with the force at the measured
    travel to 0.5 % RMS (a stop 5.5 x k4; at the linear travel: 190 %;
    ``tests/test_campaign_nonlinear.py``). Returns the forces and whether it converged (residual
    below ``tol`` m, m/s); not converged, the forces at the linear travel."""
    import scipy.optimize

    from ..diagnosis.vehicle import States, travel_response

    n = len(st.u[0])

    def states(x):
        u, v = list(st.u), list(st.v)
        for k, a in enumerate(free):
            u[a], v[a] = x[2 * k * n:(2 * k + 1) * n], x[(2 * k + 1) * n:(2 * k + 2) * n]
        return States(tuple(u), tuple(v), st.s0, st.p)

    def forces(x):
        s_ = states(x)
        return [th * c.force(s_) for c, th in laws]

    f0 = forces(np.concatenate([np.concatenate([st.u[a], st.v[a]]) for a in free])) if free else forces(None)
    if not free:
        return f0, True

    def resid(x):
        fs = forces(x)
        if not all(np.all(np.isfinite(f)) for f in fs):
            return np.full_like(x, 1e6)
        tot = [sum((f for (c, _), f in zip(laws, fs) if c.axle == a), np.zeros(n)) for a in (0, 1)]
        du, dv = travel_response(prob.pipe, st.p, tuple(tot))
        s_ = states(x)
        return np.concatenate([np.concatenate([s_.u[a] - st.u[a] - du[a][:n], s_.v[a] - st.v[a] - dv[a][:n]])
                               for a in free])

    try:
        x = scipy.optimize.newton_krylov(resid, np.concatenate([np.concatenate([st.u[a], st.v[a]]) for a in free]),
                                         f_tol=tol, maxiter=60, method="lgmres")
    except (scipy.optimize.NoConvergence, ValueError, FloatingPointError, np.linalg.LinAlgError):
        return f0, False
    return forces(x), True


def _floor_theta(c, theta: float, st) -> float:
    """The cause's resolution floor (``c.resolution`` of its estimate) in theta, as a standard error."""
    est = c.to_estimate(theta, st)
    h = 1e-6 * max(abs(theta), 1e-3)
    slope = abs(c.to_estimate(theta + h, st) - est) / h
    return c.resolution * abs(est) / max(slope, 1e-300) / 1.96


class JointNonlinear:
    """The joint size of the campaign's nonlinear causes over ``specs`` (every diagnosed run, in the
    order of ``run_names``) on a Dask ``client``."""

    #: a run shows a cause when its joint size would pass a two-sided 5 % test with 95 % power there
    SHOW_Z = 1.96 + 1.645
    #: the joint size is confirmed at the adequacy test's level (two-sided 1e-3)
    CONFIRM_Z = float(scipy.stats.norm.isf(0.5e-3))

    def __init__(self, client, specs, run_names, model: dict, model_given: bool, terms: list[dict], *,
                 progress: bool = True, log: list | None = None):
        self.client, self.specs, self.names = client, list(specs), list(run_names)
        self.model, self.model_given, self.terms = model, model_given, terms
        self.progress = progress
        self.log = log if log is not None else []

    def size(self, causes, thetas, joint=None, sizes: bool = True, only=None) -> list[dict]:
        """Every run's sizes (:func:`size_task`) at the campaign's extended model: ``causes[i]``,
        ``thetas[i]`` the shared parameters with run ``i``'s sensor effects."""
        from ._executor import map_tasks

        items = list(range(len(self.specs)))
        return map_tasks(self.client, _size_call, items, desc="nonlinear causes, jointly", progress=self.progress,
                         specs=self.specs, model=self.model, model_given=self.model_given, causes=causes,
                         thetas=thetas, terms=self.terms, joint=joint, sizes=sizes, only=only)

    def combine(self, sizes: list[dict], p_joint: dict) -> list[dict]:
        """Per term the joint size (the best setting's meta-analysis over the runs) with its interval
        (None for a term not sized)."""
        from ..diagnosis.vehicle import JOINT_CHI2
        from ..diagnosis.vehicle import States

        st = States((), (), (), p_joint)
        out = []
        for i, term in enumerate(self.terms):
            settings = _settings(term)
            if sizes and sizes[0]["sizes"][i] is None:
                out.append(None)
                continue
            rows = [[run["sizes"][i][k] for run in sizes] for k in range(len(settings))]
            metas = [self._meta(term, r, st) for r in rows]
            ok = [k for k, m in enumerate(metas) if m is not None]
            if not ok:
                out.append(None)
                continue
            best = max(ok, key=lambda k: metas[k]["z2"])
            m = metas[best]
            zc = math.sqrt(JOINT_CHI2) if len(settings) > 1 else 1.96
            near = [k for k in ok if metas[k]["z2"] >= m["z2"] - JOINT_CHI2] if len(settings) > 1 else [best]
            lo = min(metas[k]["theta"] - zc * metas[k]["se"] for k in near)
            hi = max(metas[k]["theta"] + zc * metas[k]["se"] for k in near)
            shows = any(r["theta"] is not None and abs(m["theta"]) >= self.SHOW_Z * math.sqrt(r["se"] ** 2 + m["floor_se"] ** 2)
                        for r in rows[best])
            # the region's edge lies between its last setting and the next one out: the next one is said
            lo_k, hi_k = max(min(near) - 1, 0), min(max(near) + 1, len(settings) - 1)
            out.append({**m, "setting": settings[best], "setting_range": [settings[lo_k], settings[hi_k]],
                        "theta_interval": [lo, hi], "per_run": rows[best],
                        "confirmed": bool(math.sqrt(m["z2"]) >= self.CONFIRM_Z and shows)})
            self.log.append(f"joint {term['cause']}[{term['parameter']}]: theta {m['theta']:.5g} +- {m['se']:.3g} "
                            f"(z {math.sqrt(m['z2']):.3g}) at {settings[best]}")
        return out

    def _meta(self, term, rows, st) -> dict | None:
        """Inverse-variance mean over the runs with a size (each run's variance its sandwich one plus
        the floor's), its over-dispersion-widened standard error and z^2."""
        c = _cause_of(term, 0.0 if term["cause"] == "bump_stop" else None)
        th = [(r["theta"], r["se"]) for r in rows if r["theta"] is not None and r["se"]]
        if not th:
            return None
        med = float(np.median([t for t, _ in th]))
        fl = _floor_theta(c, med, st)
        e = np.array([t for t, _ in th])
        w = 1.0 / (np.array([s for _, s in th]) ** 2 + fl * fl)
        W = float(w.sum())
        mean = float(w @ e / W)
        chi2 = float(w @ (e - mean) ** 2)
        dof = max(len(th) - 1, 1)
        disp = max(1.0, chi2 / dof)
        se = math.sqrt(disp / W)
        return {"theta": mean, "se": se, "z2": mean * mean / (se * se), "chi2": chi2, "dof": dof,
                "overdispersion": disp, "floor_se": fl}

    def off_edge(self, i: int, m, causes, thetas, p_joint: dict, joint=None):
        """Term ``i``'s joint size with a stop's travel grid moved off the edge where the best travel lay
        there (``EDGE_MOVES``): the profile's maximum is not found at a grid's end. The grid it ends on is
        kept (``term["coarse"]``) for the later rounds."""
        t = self.terms[i]
        for _ in range(EDGE_MOVES if t["cause"] == "bump_stop" else 0):
            if m is None:
                break
            g = _settings(t)
            k = g.index(m["setting"])
            if 0 < k < len(g) - 1 or (k == 0 and g[0] <= 1.5 * MIN_TRAVEL) or len(g) < 3:
                break
            span = 2.0 * (g[-1] - g[0])
            t["coarse"] = sorted({float(x) for x in np.linspace(g[k], g[k] + (span if k else -span), STOP_GRID)
                                  if x >= MIN_TRAVEL})
            self.log.append(f"joint {t['cause']}[{t['parameter']}]: best travel {g[k]:.4g} m on the grid's edge; "
                            f"grid moved to {t['coarse'][0]:.4g}-{t['coarse'][-1]:.4g} m")
            m_new = self.combine(self.size(causes, thetas, joint=joint, only=[i]), p_joint)[i]
            if m_new is None:
                break
            m = m_new
        return m

    def choose_rivals(self, causes, thetas, p_joint: dict) -> None:
        """Where the single runs named different causes on one axle (a progressive spring in one run, a
        bump stop in two), each is fitted jointly (one law for all runs, the other axles' causes as
        nuisance) and the one that explains the runs best stays (``_score``: the meta-analysis z^2, which
        the runs' disagreement about one law deflates through the over-dispersion, less
        ``SETTING_CHARGE`` for a stop's travel). The others go into the report with their score
        (``term["rival_scores"]``; ``term["rivals"]`` holds the candidates until they are chosen)."""
        for i, t in enumerate(list(self.terms)):
            rivals = t.pop("rivals", None)
            if not rivals:
                continue
            scored = []
            for c in [t] + rivals:
                self.terms[i] = c
                m = self.combine(self.size(causes, thetas, only=[i]), p_joint)[i]
                scored.append((_score(c, self.off_edge(i, m, causes, thetas, p_joint)), c))
            scored.sort(key=lambda x: -x[0])
            self.terms[i] = best = scored[0][1]
            best["rival_scores"] = [{"cause": c["cause"], "runs": [r["run"] for r in c["runs"]],
                                     "score": sc if math.isfinite(sc) else None} for sc, c in scored[1:]]
            best["score"] = scored[0][0]
            self.log.append(f"axle {t['parameter'][1]}: " + ", ".join(f"{c['cause']} {sc:.4g}" for sc, c in scored)
                            + f" (joint z^2 less {SETTING_CHARGE:g} per travel): {best['cause']}")


def _size_call(i, *, specs, causes, thetas, **kw):
    return size_task(specs[i], causes=causes[i], theta=thetas[i], **kw)


def run_causes(fit, shared, theta) -> tuple[list, list]:
    """Per run (groups flattened) the shared causes with its logger's sensor effects, and their theta."""
    causes, thetas = [], []
    for g, grp in enumerate(fit.groups):
        for _ in grp:
            causes.append(list(shared) + list(fit.nuis[g]))
            thetas.append(np.concatenate([np.asarray(theta, float), fit.theta_n[g]]).tolist())
    return causes, thetas


def _joint_setting(comb) -> list:
    """The confirmed terms' joint law (theta, setting); None for the others (not carried)."""
    return [None if c is None or not c["confirmed"] else {"theta": c["theta"], "setting": c["setting"]} for c in comb]


def _score(term: dict, m) -> float:
    return -math.inf if m is None else float(m["z2"]) - (SETTING_CHARGE if term["cause"] == "bump_stop" else 0.0)


def fit_nonlinear(jn: "JointNonlinear", fit, shared, theta, p_joint: dict, joint=None):
    """One round: every run's sizes at the fit's vehicle (the other terms at ``joint``), combined;
    returns the combination and each run's extra forces under it. The first round (``joint`` None)
    chooses between rival causes on one axle (``JointNonlinear.choose_rivals``)."""
    causes, thetas = run_causes(fit, shared, theta)
    for t in jn.terms:
        t.pop("grid", None)
    if joint is None:
        jn.choose_rivals(causes, thetas, p_joint)
    comb = jn.combine(jn.size(causes, thetas, joint=joint), p_joint)
    comb = [jn.off_edge(i, c, causes, thetas, p_joint, joint) for i, c in enumerate(comb)]
    # a stop's travel: the profile again on a finer grid between the best travel's neighbours on the
    # first (the other terms sized again at their own best setting, each the others' nuisance there)
    if any(t["cause"] == "bump_stop" and c is not None for t, c in zip(jn.terms, comb)):
        for t, c in zip(jn.terms, comb):
            if c is None or t["cause"] != "bump_stop":
                t["grid"] = [None] if t["cause"] != "bump_stop" else None
                continue
            g = _settings(t)
            k = g.index(c["setting"])
            t["grid"] = sorted(set(np.linspace(g[max(k - 1, 0)], g[min(k + 1, len(g) - 1)], FINE_GRID).tolist())
                               | set(g))
        near = [None if c is None else {"theta": c["theta"], "setting": c["setting"]} for c in comb]
        comb_f = jn.combine(jn.size(causes, thetas, joint=near), p_joint)
        comb = [cf if (t["cause"] == "bump_stop" and cf is not None) else c for t, c, cf in zip(jn.terms, comb, comb_f)]
    law = _joint_setting(comb)
    extra = jn.size(causes, thetas, joint=law, sizes=False) if any(x is not None for x in law) else None
    return comb, extra


def nonlinear_findings(jn: "JointNonlinear", comb: list, p_joint: dict, not_carried=None) -> tuple[list[dict], dict]:
    """The report's joint findings of the nonlinear causes and the extended model's terms
    (``extended_model.nonlinear``, the single-run report's keys)."""
    from ..diagnosis.vehicle import States

    st = States((), (), (), p_joint)
    findings, correction = [], {}
    for term, m in zip(jn.terms, comb):
        if m is None:
            continue
        c = _cause_of(term, m["setting"])
        shows, cannot, per_run = [], [], []
        for name, r in zip(jn.names, m["per_run"]):
            if r["theta"] is None:
                cannot.append({"run": name, "why": "never reaches it"})
                continue
            v = r["se"] ** 2 + m["floor_se"] ** 2
            z_joint = abs(m["theta"]) / math.sqrt(v)
            ivr = sorted(c.to_estimate(r["theta"] + s * 1.96 * math.sqrt(v), st) for s in (-1, 1))
            per_run.append({"run": name, "estimate": float(c.to_estimate(r["theta"], st)), "interval": ivr,
                            "channel": r["channel"]})
            (shows if z_joint >= jn.SHOW_Z else cannot).append(
                {"run": name} if z_joint >= jn.SHOW_Z else
                {"run": name, "why": f"too imprecise (the joint size is {z_joint:.2g} of its standard error there)"})
        est = float(c.to_estimate(m["theta"], st))
        iv = sorted(float(c.to_estimate(x, st)) for x in m["theta_interval"])
        z = abs(m["theta"]) / m["se"]
        confirmed = m["confirmed"]
        named = [r["run"] for r in term["runs"]]
        ev = (f"fitted jointly over the {len(jn.names)} runs, one law for all (the joint parameters and each "
              f"logger's sensor effects in the model): the inverse-variance mean of the {len(per_run)} runs' own "
              f"sizes at that law, z = {z:.3g}; {len(named)} of the single-run diagnoses name it; "
              f"{len(shows)} runs show it, {len(cannot)} cannot"
              + (f" ({', '.join(r['run'] + ': ' + r['why'] for r in cannot)})" if cannot else "")
              + f"; the runs' sizes scatter {math.sqrt(m['overdispersion']):.3g} x their own errors.")
        f = {"cause": term["cause"], "parameter": term["parameter"], "confirmed": confirmed, "estimate": est,
             "unit": c.unit, "interval": iv, "z": float(z), "overdispersion": float(m["overdispersion"]),
             "runs_showing": [r["run"] for r in shows], "runs_cannot_show": cannot, "single_run_named": named,
             "per_run": per_run, "evidence": ev}
        if term.get("rival_scores"):
            f["rivals"] = list(term["rival_scores"])
        for rv in term.get("rival_scores", []):
            f["evidence"] += (f" {', '.join(rv['runs'])} named a {rv['cause'].replace('_', ' ')} on this axle "
                              f"instead; " + ("no run could size it jointly." if rv["score"] is None else
                                              f"fitted jointly it explains the runs less (joint z^2 less "
                                              f"{SETTING_CHARGE:g} per travel: {rv['score']:.4g} against "
                                              f"{term['score']:.4g})."))
        lab = f"{term['cause']}[{term['parameter']}]"
        nc = [n for n, x in zip(jn.names, not_carried or []) if lab in x]
        if nc:
            f["runs_not_carried"] = nc
            f["evidence"] += (f" Not carried into {', '.join(nc)}: the spring travel is not measured there and the "
                              f"model's travel under the law does not settle (its linear travel overshoots far beyond "
                              f"the law's range); those runs keep the linear model and are left out of the "
                              f"consistency check and of the joint parameters' estimates.")
        if term["cause"] == "bump_stop":
            f["travel"] = float(m["setting"])
            f["travel_interval"] = [float(x) for x in m["setting_range"]]
            f["evidence"] = (f"A stop {est:.4g} N/m beyond {1e3 * m['setting']:.4g} mm of compression "
                             f"(travel {1e3 * m['setting_range'][0]:.4g}-{1e3 * m['setting_range'][1]:.4g} mm "
                             f"within the joint 95 % region); " + ev)
        findings.append(f)
        if confirmed:
            correction.update(c.correction(m["theta"], st))
    return findings, correction
