"""``diagnose_vehicle_run``: residuals, causes, extended model, gain, report."""

from __future__ import annotations

from ...io._csvio import DEFAULT_MODEL, MODEL_KEYS, VehicleRun
from ...io._timebase import run_block
from ._adequacy import assess_model_form
from ...io._corrections import NO_CORRECTION
from ._causes import FORCE_NOISE, _apply
from ._detectors import NOISE_MIN_N, read_signals, with_detections
from ._confirm import confirm_by_resimulation, confirm_corrections, unconfirmed_findings
from ._extend import resimulate
from ._plots import write_vehicle_plots
from ._problem import _Problem
from .._intervals import joint_intervals
from ._report import (NOISE_CONFIRMED_MIN_N, SCHEMA, cause_findings, enforced_terms, identifiability_notes, noise_level,
                      residual_gain, static_findings)
from ._residuals import ResidualPipeline
from ._select import _select


def select_with_form(prob: _Problem, log: list | None = None) -> tuple[_Problem, object, dict | None]:
    """The linear causes, chosen once the model's form is right.

    A nonlinear suspension force the model lacks leaves a residual that linear causes partly take
    (a bump stop read as a stiffer spring, a softer damper and a moved centre of gravity), and once
    they are fitted the adequacy test has too little left to see. So the adequacy test runs on
    the fitted model and, where it finds no catalogue cause there, on the model with no causes;
    the linear causes are then chosen again on a comparison whose model carries the confirmed
    nonlinear cause's force (``ResidualPipeline.with_extra``). That choice is kept when the
    adequacy test of its fit names the same nonlinear causes again; otherwise the first one
    stands. Returns the problem (carrying the force where the second choice is kept), the
    selection and the adequacy test of its fit (``None`` for a run with no dynamic channel)."""
    sel = _select(prob, log=log)
    if len(sel.fit.r) <= 2:
        return prob, sel, None
    model, pipe = prob.model, prob.pipe

    def form_of(causes, theta):
        p, corr = _apply(model, causes, theta)
        return assess_model_form(prob, p, corr, pipe.residuals(p, corr), True)

    def named(form, confirmed=True):
        return {(f["cause"], f["parameter"]) for f in form["findings"]
                if "parameter" in f and (f.get("confirmed") or not confirmed)}

    form_sel = form = form_of(sel.fit.causes, sel.fit.theta)
    if form["extra"] is None and sel.fit.causes:
        form = form_of([], [])
    if form["extra"] is None:
        return prob, sel, form_sel
    prob_x = prob.with_pipe(pipe.with_extra(form["extra"]))
    sel_x = _select(prob_x, log=log)
    form_x = form_of(sel_x.fit.causes, sel_x.fit.theta)
    extra_x = form_x["extra"] if form_x["extra"] is not None else form["extra"]
    # kept when the adequacy test of the new fit still names the nonlinear causes (their
    # correction confirmed out of sample or not): the first choice's linear causes were chosen on
    # a model that lacks them, the new ones on a model that has them
    kept = named(form) <= named(form_x, confirmed=False)
    if log is not None:
        log.append(f"linear causes chosen again with {sorted(named(form))}: {[c.label for c in sel_x.fit.causes]}, "
                   f"first choice {[c.label for c in sel.fit.causes]}: "
                   + ("kept" if kept else "the nonlinear causes are not named again, the first choice stands"))
    if not kept:
        return prob, sel, form_sel
    return prob.with_pipe(pipe.with_extra(extra_x)), sel_x, form_x


def diagnose_vehicle_run(run: VehicleRun, model: dict | None = None, plots_dir=None,
                         *, with_simulation: bool = True, log: list | None = None) -> dict:
    """Diagnose a vehicle run against a model; returns the report (``docs/measured-data.md``).

    ``model``: dict of the seed's keys (default: the seed's table). ``plots_dir``: write the
    figures there. ``with_simulation``: run the force-driven simulation for the pitch error
    (the slowest part; tests of the cause logic may skip it).
    """
    model = dict(DEFAULT_MODEL if model is None else model)
    # the causes read off the forces themselves lead (each detection's inverse applied to the
    # measured samples before anything is fitted, and reported with the extended model's corrections)
    run, detected = read_signals(run)
    pipe = ResidualPipeline(run)
    prob = _Problem(pipe, model)
    pipe = prob.pipe  # with the channels it compares band-limited
    # prob carries a nonlinear cause's force where one is found; form0: the adequacy test of sel0's fit
    prob, sel0, form0 = select_with_form(prob, log)
    sel, held_out = confirm_corrections(prob, sel0, log)
    resim_out = []
    if with_simulation:
        sel, resim_out = confirm_by_resimulation(prob, sel, log)
    fit = sel.fit
    dynamic = len(fit.r) > 2

    # the adequacy test of the fitted linear model (_adequacy): the nonlinear causes and model-form
    # findings lead, as the linear findings hold only if the model's form does; their intervals
    # count in the joint level
    lin = pipe.with_extra(None)
    prob_lin = prob.with_pipe(lin)
    p_ext, corr_ext = _apply(model, fit.causes, fit.theta)
    if form0 is not None and fit is sel0.fit:  # the checks kept every cause: tested already
        form = form0
    else:
        form = assess_model_form(prob_lin, p_ext, corr_ext, lin.residuals(p_ext, corr_ext), dynamic)
    # residuals before (the model) / after (the extended model, its nonlinear causes included)
    res0 = lin.residuals(model, NO_CORRECTION)
    prob = prob.with_pipe(lin.with_extra(form["extra"]))
    pipe = prob.pipe
    res1 = pipe.residuals(p_ext, corr_ext)

    # the force noise from what the extended model leaves: where it carries a nonlinear force, that
    # force as the adequacy test refitted it last, not as it stood when the linear causes were
    # chosen (a stop's force of 7 x the spring, refitted by 0.04 %, left a residual that read as
    # 10 x the true noise)
    noise = noise_level(prob, sel, corr_ext, p_ext, None if form["extra"] is None else prob.weighted(res1))
    restored = [d.channel for d, _ in detected if d.restores]
    if restored:  # what a restoration of lost samples missed is a force error the residual keeps
        noise = {**noise, "kind": "upper_bound", "lo": 0.0, "source": noise["source"] + (
            f"; what the restoration of {' and '.join(restored)}'s lost samples missed counts in it, so "
            f"the level is an upper bound")}
    sigma = noise["sigma"]
    notes = list(noise["notes"])

    # findings: the confirmed causes (in the extended model), then those a check did not confirm
    corrections = corr_ext
    findings = cause_findings(prob, sel, model, res1, sigma)
    for f in findings:
        f["confirmed"] = True
    findings += unconfirmed_findings(prob, sel0, model, sigma, held_out, resim_out)
    if not dynamic and sigma > 0:
        static, corrections = static_findings(res0, sigma, corrections)
        findings += static
    src = noise["source"]
    if noise["found"]:
        findings.append(FORCE_NOISE.finding(sigma, noise["lo"], noise["hi"], noise["kind"],
                                            src[0].upper() + src[1:] + "."))
    elif sigma >= NOISE_CONFIRMED_MIN_N:
        # too small to report as a level, above the comparison's own floor: never silence, a bound
        b = noise["bound"]
        findings.append(FORCE_NOISE.finding(sigma, 0.0, b, "upper_bound", (
            f"Too small to measure, at most {b:.3g} N: {src} (below the {NOISE_MIN_N:g} N a level is "
            f"reported at); the bound is the upper end of that level's 95 % interval.")))
    # below the comparison's own floor: still a statement, the floor as the bound (after the joint
    # widening, which it does not take part in: the floor is no statistical interval)
    b = max(noise["bound"], NOISE_CONFIRMED_MIN_N)
    floor_bound = None if (noise["found"] or sigma >= NOISE_CONFIRMED_MIN_N) else FORCE_NOISE.finding(
        sigma, 0.0, b, "upper_bound", (
            f"At most {b:.3g} N, the comparison's own floor: {src}; a force noise below "
            f"{NOISE_CONFIRMED_MIN_N:g} N cannot be told from the comparison's own error."))
    findings = [{**d.finding(det), "confirmed": True} for d, det in detected] + form["findings"] + findings
    findings = _stand_ins(findings, form.get("unseen") or [])
    # logger faults (found by the reader before anything was fitted; the run is their sound part)
    # lead the list: every other finding holds for the sound part only
    faults = (getattr(run, "time_base", None) or {}).get("logger_faults") or []
    findings = [{"cause": "channel_fault", "channel": f["channel"], "kind": f["kind"], "span_s": f["span_s"],
                 "estimate": float(f["span_s"][1] - f["span_s"][0]), "unit": "s", "interval": None,
                 "evidence": f["evidence"] + "; the run is analysed without it"} for f in faults] + findings
    findings = joint_intervals(findings)
    if not findings:
        findings.append({"cause": "none", "evidence": (
            "no systematic cause passes the test and " + noise["source"] +
            ", indistinguishable from the numerical floor of the comparison.")})
    if floor_bound is not None:
        findings.append(floor_bound)
    notes += identifiability_notes(prob, sel) + form["notes"]

    # extended model and gain
    params_ext = {k: float(p_ext[k]) for k in MODEL_KEYS}
    gain = residual_gain(prob, res0, res1, bool(fit.causes) or form["extra"] is not None, corrections, dynamic)
    sim_err = enforced_terms(prob_lin, model, res0)
    nonlinear = {k: v for d, det in detected for k, v in d.model_terms(det).items()} | form["correction"]
    sims = {}
    if with_simulation and (run.has("beta") or run.has("z3")):
        sims, sim_err, gain = resimulate(lin, model, p_ext, corr_ext, sigma, sim_err, gain, nonlinear)

    report = {
        "schema": SCHEMA,
        "kind": "vehicle",
        "simulation_error": sim_err,
        "findings": findings,
        "extended_model": {"parameters": params_ext, "corrections": with_detections(corrections, detected).to_json(),
                           **({"nonlinear": nonlinear} if nonlinear else {})},
        "gain": gain,
        "run": {"file": str(run.path), "samples": run.n, "dt_s": run.dt,
                "duration_s": float(run.t[-1] - run.t[0]),
                "channels": sorted(run.channels), "residual_channels": prob.names,
                "time_base": run_block(getattr(run, "time_base", None))},
        "notes": notes,
    }
    if plots_dir is not None:
        write_vehicle_plots(plots_dir, run, model, p_ext, pipe, prob, res0, res1, sims,
                            sigma, report)
    return report


#: the linear parameter a nonlinear suspension cause of each axle looks like (front: the k3/d3
#: spring and damper over s1; rear: k4/d4): a stop or a progressive spring a stiffer spring, an
#: asymmetric damper a damper rate
_STANDS_IN = {("bump_stop", 0): "k3", ("progressive_spring", 0): "k3", ("damper_asymmetry", 0): "d3",
              ("bump_stop", 1): "k4", ("progressive_spring", 1): "k4", ("damper_asymmetry", 1): "d4"}


def _stand_ins(findings, unseen):
    """A linear parameter of an axle whose nonlinear suspension causes the run could not show may
    stand in for one of them (a stop or a progressive spring reads as a stiffer spring, an
    asymmetric damper as a damper rate): the finding says so (``may_stand_in_for``), not only the
    notes. Returns the findings with the key set (new dicts where it is)."""
    out = list(findings)
    for i, f in enumerate(findings):
        if f.get("cause") != "parameter_error":
            continue
        names = sorted({n for n, axle in unseen if _STANDS_IN.get((n, axle)) == f.get("parameter")})
        if names:
            out[i] = {**f, "may_stand_in_for": names, "evidence": f["evidence"] + (
                f" It may stand in for a {' or '.join(names)} on this axle, which the run could not show "
                f"(no spring travel measured, or too noisy): a linear change of the parameter is what such a "
                f"cause looks like without one.")}
    return out
