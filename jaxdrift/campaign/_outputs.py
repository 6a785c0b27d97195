"""Outputs of a campaign, each written atomically: ``runs/NAME.json`` (each run's own report),
``figures/`` (a forest plot per joint parameter, damage per run and section), ``summary.md`` and
``campaign.json`` last."""

from __future__ import annotations

import os

import numpy as np

from ..diagnosis.vehicle import FORCE_NOISE, PARAMETER_ERROR
from ..io._outputs import atomic_dir, write_json, write_text

__all__ = ["OUTPUT_FILES", "write_campaign", "summary_markdown"]

OUTPUT_FILES = ("campaign.json", "summary.md")


def write_campaign(out: str, doc: dict, results, names, *, figures: bool = True) -> dict:
    """Write the campaign's folder (runs/, figures/, summary.md, campaign.json); returns the
    document as written (with its ``figures``)."""
    with atomic_dir(os.path.join(out, "runs"), "--out") as tmp:
        for n, r in zip(names, results):
            if r["status"] == "ok":
                write_json(os.path.join(tmp, f"{n}.json"), r["report"])
    if figures:
        with atomic_dir(os.path.join(out, "figures"), "--out") as tmp:
            doc = {**doc, "figures": [f"figures/{n}" for n in write_figures(tmp, doc, results, names)]}
    write_text(os.path.join(out, "summary.md"), summary_markdown(doc), "--out")
    write_json(os.path.join(out, "campaign.json"), doc, "--out")
    return doc


def _single_intervals(doc, results, names, param):
    rows = []
    for n, r in zip(names, results):
        if r["status"] != "ok":
            continue
        for f in r["report"].get("findings", []):
            if f.get("cause") == PARAMETER_ERROR.name and f.get("parameter") == param and f.get("interval"):
                rows.append((n, f["estimate"], f["interval"]))
    return rows


def write_figures(folder: str, doc: dict, results, names) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    joint = doc.get("joint") or {}
    for f in joint.get("findings", []):
        p = f["parameter"]
        rows = _single_intervals(doc, results, names, p)
        if f.get("cause") != PARAMETER_ERROR.name:  # a joint nonlinear cause: each run's own size at the joint law
            p = f"{f['cause']}_{p}"
            rows = [(r["run"], r["estimate"], r["interval"]) for r in f.get("per_run", [])]
        fig, ax = plt.subplots(figsize=(6.4, 1.2 + 0.22 * (len(rows) + 1)))
        ys = np.arange(len(rows) + 1)[::-1]
        for y, (n, est, iv) in zip(ys[1:], rows):
            ax.errorbar([est], [y], xerr=[[est - iv[0]], [iv[1] - est]], fmt="o", color="0.35", ms=3, capsize=2)
        ax.errorbar([f["estimate"]], [ys[0]], xerr=[[f["estimate"] - f["interval"][0]], [f["interval"][1] - f["estimate"]]],
                    fmt="D", color="C3", ms=5, capsize=3)
        ax.axvline(f["estimate"], color="C3", lw=0.6, ls=":")
        ax.set_yticks(ys, ["joint"] + [r[0] for r in rows], fontsize=7)
        if f.get("cause") == PARAMETER_ERROR.name:
            ax.set_xlabel(f"{p}: true / model (95 % intervals)")
            ax.set_title(f"{p}: joint fit and the {len(rows)} single-run findings naming it", fontsize=9)
        else:
            ax.set_xlabel(f"{p} [{f.get('unit', '')}] (95 % intervals)")
            ax.set_title(f"{p}: joint fit and the {len(rows)} runs' own sizes at the joint law", fontsize=9)
        fig.tight_layout()
        name = f"forest_{p}.png"
        fig.savefig(os.path.join(folder, name), dpi=110)
        plt.close(fig)
        written.append(name)
    dur = doc.get("durability")
    if dur and dur.get("per_run"):
        runs = dur["per_run"]
        variants = [v for v in ("force_driven", "pitch_spring", "stabilised", "extended", "measured")
                    if any(v in r["damage_x_repetitions"] for r in runs)]
        fig, axes = plt.subplots(2, 1, figsize=(max(6.4, 0.3 * len(runs) + 2), 5.5), sharex=True)
        x = np.arange(len(runs))
        w = 0.8 / max(len(variants), 1)
        for j, ax in enumerate(axes):
            for k, v in enumerate(variants):
                y = [r["damage_x_repetitions"].get(v, [np.nan, np.nan])[j] for r in runs]
                ax.bar(x + (k - len(variants) / 2 + 0.5) * w, y, w, label=v)
            ax.set_yscale("log")
            ax.set_ylabel(f"{dur['sections'][j]}: repetitions x damage")
        axes[0].legend(fontsize=7, ncol=len(variants))
        axes[1].set_xticks(x, [r["run"] for r in runs], rotation=90, fontsize=6)
        axes[0].set_title("pseudo-damage per run and section (x its repetitions)", fontsize=9)
        fig.tight_layout()
        fig.savefig(os.path.join(folder, "damage_per_run.png"), dpi=110)
        plt.close(fig)
        written.append("damage_per_run.png")
    return written


def _fmt_iv(iv):
    return f"[{iv[0]:.5g}, {iv[1]:.5g}]"


def summary_markdown(doc: dict) -> str:
    runs = doc["runs"]
    ok = [r for r in runs if r["status"] == "ok"]
    ex = doc["provenance"]["executor"]
    lines = [f"# Campaign: {len(runs)} runs ({len(ok)} diagnosed)", "",
             f"Executor: Dask, {ex['scheduler']}, {ex['workers']} workers; wall time "
             f"{doc['provenance']['wall_s']} s; {doc['provenance']['cached_runs']} runs from the cache.", ""]
    failed = [r for r in runs if r["status"] != "ok"]
    if failed:
        lines += ["## Runs that failed", ""] + [f"- `{r['run']}`: {r['message']}" for r in failed] + [""]
    joint = doc.get("joint")
    if joint:
        lines += ["## Joint vehicle parameters", "", "| parameter | estimate | 95 % interval (joint) | z |",
                  "|---|---|---|---|"]
        lin = [f for f in joint["findings"] if f.get("cause", PARAMETER_ERROR.name) == PARAMETER_ERROR.name]
        for f in lin:
            lines.append(f"| {f['parameter']} | {f['estimate']:.5g} | {_fmt_iv(f['interval'])} | {f['z']:.3g} |")
        if not lin:
            lines.append("| (none) | | | |")
        nl = [f for f in joint["findings"] if f not in lin]
        if nl:
            lines += ["", "## Nonlinear causes, fitted jointly", "",
                      "| cause | estimate | 95 % interval (joint) | confirmed | runs showing it | runs that cannot |",
                      "|---|---|---|---|---|---|"]
            for f in nl:
                lines.append(f"| {f['cause']}[{f['parameter']}] | {f['estimate']:.5g} {f.get('unit', '')} | {_fmt_iv(f['interval'])} | "
                             f"{'yes' if f.get('confirmed') else 'no'} | {', '.join(f.get('runs_showing', [])) or '-'} | "
                             + (", ".join(f"{r['run']} ({r['why']})" for r in f.get("runs_cannot_show", [])) or "-")
                             + " |")
            lines += [""] + [f"- {f['cause']}[{f['parameter']}]: {f['evidence']}" for f in nl]
        lines += ["", "## Consistency across runs", ""]
        for c in joint["consistency"]["parameters"]:
            verdict = "consistent" if c["consistent"] else "NOT consistent"
            lines.append(f"- {c['parameter']}: {verdict} (chi2 {c['chi2']:.3g} on {c['dof']} dof, p = {c['p_value']:.3g}; an alarm below {c.get('level', 0.01):.2g})"
                         + ("; disagreeing runs: " + ", ".join(f"{d['run']} ({d['estimate']:.5g})"
                                                                for d in c["disagreeing_runs"]) if c["disagreeing_runs"] else "")
                         + ("; left out: " + ", ".join(f"{d['run']} ({d['why']})" for d in c["left_out"])
                            if c.get("left_out") else "")
                         + ("; not tested (cannot separate it from the other shared parameters): "
                            + ", ".join(c["not_separable"]) if c.get("not_separable") else "")
                         + ("; not tested (its own estimate is outside the plausible range: its model did not fit "
                            "the run): " + ", ".join(c["implausible"]) if c.get("implausible") else ""))
        lines += ["", "## Runs", "", "| run | logger | single-run findings | sensor effects (campaign) | gain (campaign) |",
                  "|---|---|---|---|---|"]
        for r in runs:
            if r["status"] != "ok":
                continue
            single = ", ".join(_label(f) for f in r["findings"] if f.get("cause") not in ("none",)) or "none"
            camp = r.get("campaign", {})
            sens = ", ".join(_label(f) for f in camp.get("sensor_findings", [])) or "none"
            g = camp.get("gain") or {}
            gain = f"{g.get('metric', '')}: {g.get('before', float('nan')):.4g} -> {g.get('after', float('nan')):.4g}"
            lines.append(f"| {r['name']} | {r.get('logger') or '-'} | {single} | {sens} | {gain} |")
    dur = doc.get("durability")
    if dur:
        lines += ["", "## Campaign damage (repetitions x damage, summed)", "", "| variant | f3 | f4 | ratio to stabilised |",
                  "|---|---|---|---|"]
        for v, d in dur["campaign_damage"].items():
            ratio = dur["damage_ratio_to_stabilised"].get(v)
            lines.append(f"| {v} | {d[0]:.4g} | {d[1]:.4g} | {'' if ratio is None else f'{ratio:.4g}'} |")
        nq = dur[FORCE_NOISE.name].get("damage_ratio_quantiles") or {}
        for v, q in nq.items():
            if q:
                lines.append(f"\nForce noise ({dur[FORCE_NOISE.name]['paths']} draws per run): {v} / stabilised "
                             f"5-50-95 %: {q[0]:.4g}, {q[1]:.4g}, {q[2]:.4g}")
        pq = dur["joint_parameters"].get("extended_ratio_quantiles")
        if pq:
            lines.append(f"\nJoint parameters ({dur['joint_parameters']['draws']} draws): extended / stabilised "
                         f"5-50-95 %: {pq[0]:.4g}, {pq[1]:.4g}, {pq[2]:.4g}")
    return "\n".join(lines) + "\n"


def _label(f: dict) -> str:
    tgt = f.get("parameter") or f.get("channel") or ""
    est = f.get("estimate")
    return f"{f['cause']}[{tgt}]" + (f" {est:.4g}" if isinstance(est, (int, float)) else "")
