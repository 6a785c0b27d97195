"""``diagnose_vehicle_run``: residuals, causes, extended model, gain, report."""

from __future__ import annotations

from ...io._csvio import DEFAULT_MODEL, MODEL_KEYS, VehicleRun
from ...io._timebase import run_block
from ._adequacy import assess_model_form
from ...io._corrections import NO_CORRECTION
from ._causes import FORCE_NOISE, _apply
from ._confirm import confirm_by_resimulation, confirm_corrections, unconfirmed_findings
from ._extend import resimulate
from ._plots import write_vehicle_plots
from ._problem import _Problem
from .._intervals import joint_intervals
from ._report import (SCHEMA, cause_findings, enforced_terms, identifiability_notes, noise_level,
                      residual_gain, static_findings)
from ._residuals import ResidualPipeline
from ._select import _select


def diagnose_vehicle_run(run: VehicleRun, model: dict | None = None, plots_dir=None,
                         *, with_simulation: bool = True, log: list | None = None) -> dict:
    """Diagnose a vehicle run against a model; returns the report (``docs/measured-data.md``).

    ``model``: dict of the seed's keys (default: the seed's table). ``plots_dir``: write the
    figures there. ``with_simulation``: run the force-driven simulation for the pitch error
    (the slowest part; tests of the cause logic may skip it).
    """
    model = dict(DEFAULT_MODEL if model is None else model)
    pipe = ResidualPipeline(run)
    prob = _Problem(pipe, model)
    pipe = prob.pipe  # with the channels it compares band-limited
    sel0 = _select(prob, log=log)
    sel, held_out = confirm_corrections(prob, sel0, log)
    resim_out = []
    if with_simulation:
        sel, resim_out = confirm_by_resimulation(prob, sel, log)
    fit = sel.fit
    dynamic = len(fit.r) > 2

    # residuals before / after (physical units)
    res0 = pipe.residuals(model, NO_CORRECTION)
    p_ext, corr_ext = _apply(model, fit.causes, fit.theta)
    res1 = pipe.residuals(p_ext, corr_ext)

    noise = noise_level(prob, sel, corr_ext, p_ext)
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
    if noise["found"]:
        src = noise["source"]
        findings.append(FORCE_NOISE.finding(sigma, noise["lo"], noise["hi"], noise["kind"],
                                            src[0].upper() + src[1:] + "."))
    joint_intervals(findings)
    # model adequacy and the nonlinear suspension (_adequacy): its findings lead, as the linear
    # findings hold only if the model's form does; no other finding changes
    form = assess_model_form(prob, p_ext, corr_ext, res1, dynamic)
    findings = form["findings"] + findings
    if not findings:
        findings.append({"cause": "none", "evidence": (
            "no systematic cause passes the test and " + noise["source"] +
            ", indistinguishable from the numerical floor of the comparison.")})
    notes += identifiability_notes(prob, sel) + form["notes"]

    # extended model and gain
    params_ext = {k: float(p_ext[k]) for k in MODEL_KEYS}
    gain = residual_gain(prob, res0, res1, bool(fit.causes), corrections, dynamic)
    sim_err = enforced_terms(prob, model, res0)
    sims = {}
    if with_simulation and (run.has("beta") or run.has("z3")):
        sims = resimulate(pipe, model, p_ext, corr_ext, sigma, sim_err, gain)

    report = {
        "schema": SCHEMA,
        "kind": "vehicle",
        "simulation_error": sim_err,
        "findings": findings,
        "extended_model": {"parameters": params_ext, "corrections": corrections.to_json(),
                           **({"nonlinear": form["correction"]} if form["correction"] else {})},
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
