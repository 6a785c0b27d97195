"""One self-contained HTML page per report: a vehicle or attitude diagnosis, a durability
analysis, a campaign.

The page is built from the report's JSON alone (figures from its ``series_preview`` block, see
:mod:`jaxdrift.report._preview`), so ``jaxdrift report REPORT.json --html PAGE.html`` rebuilds it.
No script, no external resource: figures are inline SVG, styles inline, and a Content Security
Policy forbids anything else, so the page opens offline and prints. Every string that comes from a
report (channel and topic names, file names, a log's metadata) is escaped with ``html.escape``:
it is text, never markup. Finding kinds and fields this module does not know are shown as they
are (label, estimate, interval, then each further field), so a newer report still shows all it
says.
"""

from __future__ import annotations

import html
import json
import math
import os

from . import _figures as F
from ._panels import NO_SERIES, series_t0, series_traces, group_panel

__all__ = ["render", "report_kind", "finding_label"]

# --------------------------------------------------------------------------------- text helpers


def esc(x) -> str:
    return html.escape(str(x), quote=True)


def num(v, digits: int = 5) -> str:
    if isinstance(v, bool) or v is None:
        return {True: "yes", False: "no", None: "–"}[v]
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            return str(v)
        return f"{v:.{digits}g}"
    return str(v)


def finding_label(f: dict) -> str:
    """``cause[parameter or channel]`` as the CLI and the summary name a finding."""
    cause = str(f.get("cause", "?"))
    part = f.get("part")
    tail = f" (part {part['index']})" if isinstance(part, dict) and "index" in part else ""
    for k in ("parameter", "channel", "axis", "sensor", "instance"):
        if f.get(k) not in (None, ""):
            return f"{cause}[{f[k]}]{tail}"
    return cause + tail


def interval_text(f: dict) -> str:
    iv = f.get("interval")
    if isinstance(iv, (list, tuple)) and len(iv) == 2 and all(isinstance(v, (int, float)) for v in iv):
        return f"[{num(iv[0])}, {num(iv[1])}]"
    return "–"


def confirmed_text(f: dict) -> str:
    if "confirmed" not in f:
        return "–"
    return "confirmed" if f["confirmed"] else "not confirmed"


def generic(v, depth: int = 0) -> str:
    """Any JSON value as escaped HTML: objects as definition lists, lists of scalars inline."""
    if isinstance(v, dict):
        if not v:
            return "<span class=muted>(empty)</span>"
        items = "".join(f"<dt>{esc(k)}</dt><dd>{generic(x, depth + 1)}</dd>" for k, x in v.items())
        return f"<dl class=kv>{items}</dl>"
    if isinstance(v, list):
        if not v:
            return "<span class=muted>(none)</span>"
        if all(not isinstance(x, (dict, list)) for x in v):
            shown = ", ".join(esc(num(x)) for x in v[:40])
            more = f" … ({len(v)} values)" if len(v) > 40 else ""
            return f"<span class=mono>{shown}{more}</span>"
        return "<ul>" + "".join(f"<li>{generic(x, depth + 1)}</li>" for x in v[:200]) + "</ul>"
    return esc(num(v))


# ----------------------------------------------------------------------------------- the page

CSS = """
:root{--fg:#1b1f24;--muted:#5b6470;--line:#d8dde3;--ok:#1e7b34;--no:#a15c00;--bg2:#f5f7f9}
*{box-sizing:border-box}
body{font:15px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;color:var(--fg);
 max-width:1100px;margin:0 auto;padding:1.2rem 1.5rem 3rem}
h1{font-size:1.5rem;margin:.2rem 0 .3rem}h2{font-size:1.2rem;margin:1.8rem 0 .5rem;border-bottom:1px solid var(--line);padding-bottom:.2rem}
h3{font-size:1.02rem;margin:1.2rem 0 .3rem}
.muted{color:var(--muted)}.mono{font-family:ui-monospace,SFMono-Regular,Menlo,Consolas,monospace;font-size:.88em;overflow-wrap:anywhere}
table{border-collapse:collapse;width:100%;margin:.4rem 0;font-size:.92rem}
th,td{border-bottom:1px solid var(--line);padding:.3rem .45rem;text-align:left;vertical-align:top}
th{background:var(--bg2);font-weight:600}
td.mono{white-space:nowrap}td.n{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
.verdict{background:var(--bg2);border-left:4px solid #1f77b4;padding:.6rem .9rem;margin:.6rem 0}
.tag{display:inline-block;border-radius:3px;padding:0 .35rem;font-size:.8rem;font-weight:600}
.tag.ok{background:#dff3e4;color:var(--ok)}.tag.no{background:#fdebd3;color:var(--no)}
.finding{border:1px solid var(--line);border-radius:6px;padding:.5rem .9rem;margin:.8rem 0;break-inside:avoid}
figure{margin:.5rem 0;break-inside:avoid}figure svg{max-width:100%;height:auto;display:block}
figcaption{font-size:.85rem;color:var(--muted)}
dl.kv{display:grid;grid-template-columns:max-content 1fr;gap:.1rem .8rem;margin:.2rem 0}
dl.kv dt{color:var(--muted)}dl.kv dd{margin:0;overflow-wrap:anywhere}
nav{font-size:.9rem;margin:.3rem 0 1rem}nav a{margin-right:.8rem}
ul{margin:.2rem 0;padding-left:1.3rem}
@media print{body{max-width:none;padding:0;font-size:10pt}nav{display:none}h2{break-after:avoid}
 a{color:inherit;text-decoration:none}.finding,figure,table{break-inside:avoid}}
"""

CSP = "default-src 'none'; style-src 'unsafe-inline'; img-src data:"


def page(title: str, subtitle: str, sections: list[tuple[str, str, str]]) -> str:
    """``sections``: (id, heading, body HTML). The heading and title are escaped here."""
    nav = "".join(f'<a href="#{esc(i)}">{esc(h)}</a>' for i, h, _ in sections if h)
    body = "".join(f'<section id="{esc(i)}">' + (f"<h2>{esc(h)}</h2>" if h else "") + f"{b}</section>"
                   for i, h, b in sections)
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f'<meta http-equiv="Content-Security-Policy" content="{CSP}">'
            '<meta name="viewport" content="width=device-width, initial-scale=1">'
            '<link rel="icon" href="data:,">'
            f"<title>{esc(title)}</title><style>{CSS}</style></head><body>"
            f"<header><h1>{esc(title)}</h1><div class=muted>{subtitle}</div></header>"
            f"<nav>{nav}</nav>{body}"
            '<footer class=muted><p>Made by jaxdrift from the report\'s JSON (the machine interface); '
            "rebuild with <span class=mono>jaxdrift report REPORT.json --html PAGE.html</span>.</p></footer>"
            "</body></html>\n")


def fig(svg_text: str, caption: str = "") -> str:
    cap = f"<figcaption>{esc(caption)}</figcaption>" if caption else ""
    return f"<figure>{svg_text}{cap}</figure>"


# --------------------------------------------------------------------------------- findings

_KNOWN = {"cause", "parameter", "channel", "estimate", "unit", "interval", "evidence", "confirmed"}


def findings_table(findings: list[dict], prefix: str = "verdict") -> str:
    rows = []
    for i, f in enumerate(findings, 1):
        if not isinstance(f, dict):
            continue
        conf = confirmed_text(f)
        cls = "ok" if f.get("confirmed") else "no" if "confirmed" in f else ""
        tag = f'<span class="tag {cls}">{esc(conf)}</span>' if cls else esc(conf)
        rows.append(f'<tr id="{prefix}-{i}"><td class=n>{i}</td><td class=mono>{esc(finding_label(f))}</td>'
                    f"<td class=n>{esc(num(f.get('estimate')))} {esc(f.get('unit') or '')}</td>"
                    f"<td class=n>{esc(interval_text(f))}</td><td>{tag}</td>"
                    f"<td>{esc(f.get('evidence', ''))}</td></tr>")
    if not rows:
        return "<p>No findings in this report.</p>"
    return ("<table><thead><tr><th>#</th><th>finding</th><th>estimate</th><th>interval</th><th>confirmed</th>"
            "<th>why</th></tr></thead><tbody>" + "".join(rows) + "</tbody></table>")


def extra_fields(f: dict, skip=()) -> str:
    extra = {k: v for k, v in f.items() if k not in _KNOWN and k not in skip}
    return generic(extra) if extra else ""


def _number(v):
    if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
        return float(v)
    if isinstance(v, dict):
        for k in ("estimate", "value", "bias", "mean"):
            if k in v:
                return _number(v[k])
    return None


def _reference_value(f: dict):
    unit = str(f.get("unit") or "")
    if unit == "ratio" or str(f.get("cause", "")).endswith("scale"):
        return 1.0
    if f.get("cause") in ("force_noise", "gyro_noise", "accel_noise") or f.get("estimate_kind"):
        return None
    return 0.0


def interval_svg(f: dict):
    est = _number(f.get("estimate"))
    iv = f.get("interval")
    if est is None or not (isinstance(iv, (list, tuple)) and len(iv) == 2 and all(_number(x) is not None for x in iv)):
        return None
    extra = []
    for k in ("onboard", "onboard_estimate", "estimator"):
        v = _number(f.get(k))
        if v is not None:
            extra.append((f"{k.replace('_', ' ')} estimate", v))
    return F.interval_figure(est, (float(iv[0]), float(iv[1])), str(f.get("unit") or "–"), _reference_value(f),
                             finding_label(f), extra)


def finding_sections(findings, body_for=None) -> str:
    out = []
    for i, f in enumerate(findings, 1):
        if not isinstance(f, dict):
            continue
        head = (f'<h3>{i}. <span class=mono>{esc(finding_label(f))}</span> = {esc(num(f.get("estimate")))} '
                f'{esc(f.get("unit") or "")} <span class=muted>{esc(interval_text(f))}</span> '
                f'<span class=muted>({esc(confirmed_text(f))})</span></h3>')
        parts = [head, f"<p>{esc(f.get('evidence', ''))}</p>"]
        s = interval_svg(f)
        if s:
            parts.append(fig(s, "The estimate (point) with its interval (band); the dashed line is no error."))
        if body_for:
            parts.append(body_for(f) or "")
        more = extra_fields(f)
        if more:
            parts.append(f"<details open><summary>all fields</summary>{more}</details>")
        out.append(f'<div class=finding id="finding-{i}">' + "".join(parts) + "</div>")
    return "".join(out) or "<p>No findings.</p>"


def gain_html(g) -> str:
    if not isinstance(g, dict) or g.get("metric") is None:
        return "<p>No gain: nothing was corrected.</p>"
    b, a = _number(g.get("before")), _number(g.get("after"))
    ratio = f" ({b / a:.3g}x smaller)" if b and a else ""
    head = (f'<p><b>{esc(g.get("metric"))}</b>: {esc(num(g.get("before")))} → {esc(num(g.get("after")))} '
            f'{esc(g.get("unit") or "")}{esc(ratio)}</p>')
    lines = []
    for k, v in g.items():
        if k.endswith("_error") and isinstance(v, dict) and isinstance(v.get("before"), dict):
            b1, a1 = v["before"], v.get("after") or {}
            lines.append(f"<li>{esc(k.replace('_', ' '))} RMS {esc(num(b1.get('rms')))} → {esc(num(a1.get('rms')))}"
                         f"{', drifts off after ' + esc(num(b1.get('drift_off_time_s'))) + ' → ' + esc(num(a1.get('drift_off_time_s'))) + ' s' if 'drift_off_time_s' in b1 else ''}</li>")
    rest = {k: v for k, v in g.items() if k not in ("metric", "before", "after", "unit")}
    return (head + (f"<ul>{''.join(lines)}</ul>" if lines else "")
            + (f"<details><summary>every gain figure</summary>{generic(rest)}</details>" if rest else ""))


def cannot_show(report: dict) -> str:
    items = [n for n in report.get("notes") or [] if isinstance(n, str) and n.lower().startswith(("could not", "not identifiable", "weakly"))]
    for d in report.get("not_determined") or []:
        items.append(f"{finding_label(d)}: {d.get('reason', '')}" if isinstance(d, dict) else str(d))
    obs = report.get("observability") or {}
    items += [str(x) for x in obs.get("not_observed") or []]
    if not items:
        return "<p>Nothing: every cause the diagnosis looks for could be tested in this run.</p>"
    return "<ul>" + "".join(f"<li>{esc(x)}</li>" for x in dict.fromkeys(items)) + "</ul>"


def other_notes(report: dict) -> str:
    items = [n for n in report.get("notes") or [] if not (isinstance(n, str) and n.lower().startswith(("could not", "not identifiable", "weakly")))]
    obs = report.get("observability") or {}
    items += list(obs.get("notes") or [])
    return "<ul>" + "".join(f"<li>{generic(x)}</li>" for x in items) + "</ul>" if items else ""


def time_base_html(tb) -> str:
    if not isinstance(tb, dict):
        return "<p class=muted>No time-base block in this report.</p>"
    rows = [("sample rate", f"{num(tb.get('fs'))} Hz"),
            ("jitter (std, max) / step", f"{num(tb.get('jitter_std_rel'), 3)}, {num(tb.get('jitter_max_rel'), 3)}"),
            ("gaps", str(len(tb.get("gaps") or []))),
            ("segments", str(len(tb.get("segments") or []))),
            ("resampled", f"{num(tb.get('resampled'))} {'(' + str(tb.get('method')) + ')' if tb.get('method') else ''}")]
    head = "<table>" + "".join(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in rows) + "</table>"
    return head + f"<details><summary>the whole block</summary>{generic(tb)}</details>"


def provenance_html(p) -> str:
    if not isinstance(p, dict):
        return "<p class=muted>No provenance in this report.</p>"
    return generic(p)


def rest_html(report: dict, known: set) -> str:
    rest = {k: v for k, v in report.items() if k not in known and k != "series_preview"}
    return generic(rest) if rest else ""


# ----------------------------------------------------------------------------------- vehicle


def vehicle_page(r: dict, title: str) -> str:
    run = r.get("run") or {}
    findings = [f for f in r.get("findings") or [] if isinstance(f, dict)]
    t0, mk = series_t0(r), F.report_markers(r)

    def residual_for(f):
        res = f.get("residual") or {}
        ch = res.get("channel")
        p = group_panel(r, f"residual_{ch}") if ch else None
        if not p:
            return ""
        unit = res.get("unit", "")
        trs = {k: v for k, v in series_traces(r).items() if v.get("group") == f"residual_{ch}"}
        b = next(iter(trs.values())).get("band_hz")
        band = f" below {num(b[1])} Hz (the band it was compared in)" if b else ""
        plotted = " → ".join(num(trs[k].get("rms")) for k in (f"residual_{ch}_model", f"residual_{ch}_extended")
                             if k in trs and trs[k].get("rms") is not None)
        panels = [(f"{ch} residual [{unit}]", p[1])]
        z = group_panel(r, f"residual_{ch}_zoom")
        zoom = ""
        if z:
            zoom = fig(F.time_figure([(f"{ch} residual [{unit}]", z[1])], (), f"{ch} residual: its worst stretch", t0=t0, height=2.0),
                       "The stretch where the residual with the model as given was largest, every sample drawn.")
        return fig(F.time_figure(panels, mk, f"{ch} residual{band} before and after the extended model", t0=t0, height=2.3),
                   f"The residual of the {ch} channel{band} with the model as given (red) and extended (blue), "
                   f"its envelope over the run (the least and largest sample of each bin): RMS of what is drawn "
                   f"{plotted or '–'} {unit}; the finding's own share of it: {num(res.get('rms_without'))} → "
                   f"{num(res.get('rms_with'))} {unit}.") + zoom

    n = len(findings)
    conf = sum(1 for f in findings if f.get("confirmed"))
    verdict = (f"<div class=verdict><p><b>{n} finding{'s' * (n != 1)}</b>"
               f"{f', {conf} confirmed' if any('confirmed' in f for f in findings) else ''}, in the order the diagnosis ranks them.</p>"
               + findings_table(findings) + gain_html(r.get("gain")) + "</div>")
    drift = []
    for g, lab in (("beta", "pitch beta [deg]"), ("z3", "heave z3 [m]")):
        p = group_panel(r, g, lab)
        if p:
            drift.append(p)
    if drift:
        drift_html = fig(F.time_figure(drift, mk, "Measured motion against the force-driven simulation", clip_to="measured", t0=t0),
                         "Black: measured; red: simulated with the model as given; blue: with the extended model. "
                         "The y axis spans 3x the measured range (a drifting simulation leaves it).")
        forces = [p for p in (group_panel(r, "f1", "f1 [N]"), group_panel(r, "f2", "f2 [N]")) if p]
        if forces:
            drift_html += fig(F.time_figure(forces, mk, "Measured wheel forces and their corrections", t0=t0, height=2.0))
    else:
        drift_html = NO_SERIES
    se = r.get("simulation_error")
    drift_html += f"<h3>Simulation error</h3>{generic(se)}" if se else ""
    sub = (f"vehicle run <span class=mono>{esc(run.get('file', ''))}</span>: {esc(num(run.get('samples')))} samples, "
           f"{esc(num(run.get('duration_s')))} s, channels {esc(', '.join(map(str, run.get('channels') or [])))}")
    secs = [("verdict", "Verdict", verdict),
            ("findings", "Findings", finding_sections(findings, residual_for)),
            ("drift", "Drift: measured against simulated", drift_html),
            ("extended", "Extended model", generic(r.get("extended_model"))),
            ("timebase", "Time base", time_base_html(run.get("time_base"))),
            ("cannot", "What could not be shown", cannot_show(r))]
    notes = other_notes(r)
    if notes:
        secs.append(("notes", "Notes", notes))
    rest = rest_html(r, {"schema", "kind", "findings", "gain", "run", "notes", "extended_model", "simulation_error",
                         "provenance", "not_determined", "observability"})
    if rest:
        secs.append(("other", "Other report fields", rest))
    secs.append(("provenance", "Provenance", provenance_html(r.get("provenance"))))
    return page(title, sub, secs)


# ---------------------------------------------------------------------------------- attitude


def attitude_page(r: dict, title: str) -> str:
    run = r.get("run") or {}
    findings = [f for f in r.get("findings") or [] if isinstance(f, dict)]
    t0, mk = series_t0(r), F.report_markers(r)
    n = len(findings)
    verdict = (f"<div class=verdict><p><b>{n} finding{'s' * (n != 1)}</b>, ranked by their test statistic "
               "(white noise last).</p>" + findings_table(findings) + gain_html(r.get("gain")) + "</div>")

    def spectrum_for(f):
        spec = _spectrum_in(f)
        return fig(F.spectrum_figure(spec, f"{finding_label(f)}: spectrum")) if spec else ""

    panels = [p for p in (group_panel(r, ax, f"{ax} [rad/s]") for ax in ("wx", "wy", "wz")) if p]
    sig = []
    if panels:
        sig.append(fig(F.time_figure(panels, mk, "Gyro against the reference attitude's rate", t0=t0, height=2.0),
                       "Black: the gyro as logged; green: the rate of the reference attitude (differences of its "
                       "quaternions). Shaded: gaps; dashed: segment starts, and where the log says the primary gyro or "
                       "estimator switched or the attitude was reset."))
    p = group_panel(r, "attitude_error", "attitude error [deg]")
    if p:
        sig.append(fig(F.time_figure([p], mk, "Attitude error: gyro-integrated against the reference", t0=t0),
                       "Red: the gyro as measured; blue: after the report's corrections."))
    p = group_panel(r, "array_residual", "rigidity residual [m/s^2]")
    if p:
        sig.append(fig(F.time_figure([p], mk, "Accelerometer array: rigidity residual", t0=t0)))
    spectra = (r.get("series_preview") or {}).get("spectra") or {}
    if spectra:
        sig.append(fig(F.spectrum_figure(spectra, "Gyro spectrum (vibration)"), "Welch estimate of each axis's rate, its mean removed."))
    for key in ("vibration", "spectrum"):
        spec = _spectrum_in(r.get(key)) if isinstance(r.get(key), dict) else None
        if spec:
            sig.append(fig(F.spectrum_figure(spec, f"{key} (from the report)")))
    sig_html = "".join(sig) or NO_SERIES
    sub = (f"attitude run: {esc(num(run.get('rows')))} rows, {esc(num(run.get('duration_s')))} s, "
           f"{esc(num(run.get('reference_rows')))} reference rows")
    secs = [("verdict", "Verdict", verdict),
            ("findings", "Findings", finding_sections(findings, spectrum_for)),
            ("signals", "Signals", sig_html),
            ("corrections", "Corrections", generic(r.get("extended_model"))),
            ("timebase", "Time base", time_base_html(run.get("time_base"))),
            ("cannot", "What could not be shown", cannot_show(r))]
    notes = other_notes(r)
    if notes:
        secs.append(("notes", "Notes", notes))
    if r.get("allan"):
        secs.append(("allan", "Allan deviation", generic(r.get("allan"))))
    rest = rest_html(r, {"schema", "kind", "findings", "gain", "run", "notes", "extended_model", "provenance",
                         "not_determined", "observability", "allan"})
    if rest:
        secs.append(("other", "Other report fields", rest))
    secs.append(("provenance", "Provenance", provenance_html(r.get("provenance"))))
    return page(title, sub, secs)


def _spectrum_in(d) -> dict | None:
    """A spectrum a report may carry in a finding (e.g. ``vibration``): a dict with a frequency
    list and a value list of the same length, or several under axis names."""
    if not isinstance(d, dict):
        return None
    fk = next((k for k in ("f", "f_hz", "frequency_hz", "frequencies_hz", "freq_hz") if isinstance(d.get(k), list)), None)
    if fk:
        for vk, v in d.items():
            if vk != fk and isinstance(v, list) and len(v) == len(d[fk]) and v and all(isinstance(x, (int, float)) for x in v):
                return {vk: {"f": d[fk], "y": v, "unit": d.get("unit", ""), "label": vk}}
    for k, v in d.items():
        if isinstance(v, dict):
            s = _spectrum_in(v)
            if s:
                return {f"{k} {kk}": vv for kk, vv in s.items()}
    return None


# -------------------------------------------------------------------------------- durability


def durability_page(s: dict, title: str) -> str:
    runs = s.get("runs") or {}
    ratios = s.get("damage_ratio_to_stabilised") or {}
    mc = s.get("monte_carlo") or {}
    q = mc.get("damage_ratio_quantiles") or {}
    ref = s.get("reference", "stabilised")
    rows = "".join(f"<tr><td class=mono>{esc(v)}</td><td class=n>{esc(num(x, 4))}</td>"
                   f"<td class=n>{esc(num(q[v][0], 4) + ' – ' + num(q[v][2], 4) if v in q else '–')}</td></tr>"
                   for v, x in ratios.items())
    verdict = (f"<div class=verdict><p>Pseudo-damage (sum n S^K, K = {esc(num(s.get('basquin_k')))}) of each simulation "
               f"variant relative to <b>{esc(ref)}</b>, with the 5–95 % band under force noise of "
               f"{esc(num(mc.get('noise_N')))} N ({esc(mc.get('noise_source', ''))}, {esc(num(mc.get('paths')))} draws).</p>"
               "<table><thead><tr><th>variant</th><th>damage / reference</th><th>noise 5–95 %</th></tr></thead>"
               f"<tbody>{rows}</tbody></table></div>")
    table = ["<table><thead><tr><th>variant</th><th>section</th><th>damage</th><th>equivalent range [N]</th>"
             "<th>cycles</th><th>max range [N]</th><th>RMS [N]</th><th>max |f| [N]</th></tr></thead><tbody>"]
    for v, secs in runs.items():
        for sec, d in (secs or {}).items():
            if isinstance(d, dict):
                table.append(f"<tr><td class=mono>{esc(v)}</td><td class=mono>{esc(sec)}</td>"
                             + "".join(f"<td class=n>{esc(num(d.get(k), 4))}</td>" for k in
                                       ("damage", "equivalent_range_N", "cycles", "max_range", "rms", "max_abs"))
                             + "</tr>")
    table.append("</tbody></table>")
    figs = []
    if ratios:
        names = list(ratios)
        err = None
        if all(v in q for v in names):
            err = ([q[v][0] for v in names], [q[v][2] for v in names])
        figs.append(fig(F.bar_figure(names, [(f"damage / {ref}", [ratios[v] for v in names], err)],
                                     f"damage / {ref} damage [1]", "Damage relative to the reference variant"),
                        "Bars: the nominal ratio; whiskers: the 5–95 % band under force noise."))
    by = s.get("damage_ratio_to_stabilised_by_force") or {}
    if by:
        names = list(by)
        secs_ = sorted({k for v in by.values() for k in v})
        figs.append(fig(F.bar_figure(names, [(sec, [by[v].get(sec, float("nan")) for v in names], None) for sec in secs_],
                                     f"damage / {ref} damage [1]", "Damage ratio per section force")))
    panels = [p for p in (group_panel(s, "f3", "section force f3 [N]"), group_panel(s, "f4", "section force f4 [N]")) if p]
    if panels:
        figs.append(fig(F.time_figure(panels, (), "Section forces of the variants", t0=series_t0(s), height=2.6)))
    else:
        figs.append(NO_SERIES)
    prov = s.get("provenance") or {}
    sub = f"durability analysis of <span class=mono>{esc(prov.get('input', ''))}</span>"
    secs = [("verdict", "Verdict", verdict), ("damage", "Damage per variant and section", "".join(table) + "".join(figs))]
    rest = rest_html(s, {"schema", "runs", "damage_ratio_to_stabilised", "damage_ratio_to_stabilised_by_force",
                         "monte_carlo", "provenance", "reference", "basquin_k"})
    secs.append(("monte-carlo", "Monte Carlo", generic(mc)))
    if rest:
        secs.append(("other", "Other fields", rest))
    secs.append(("provenance", "Provenance", provenance_html(prov)))
    return page(title, sub, secs)


# ---------------------------------------------------------------------------------- campaign


def _run_page_link(entry: dict, run_pages: dict) -> str:
    name = str(entry.get("name") or os.path.splitext(os.path.basename(str(entry.get("run", ""))))[0])
    href = run_pages.get(name) or entry.get("report")
    if not href:
        return f"<span class=mono>{esc(name)}</span>"
    return f'<a class=mono href="{esc(href)}">{esc(name)}</a>'


_CONS = {True: '<span class="tag ok">consistent</span>', False: '<span class="tag no">runs differ</span>'}


def campaign_page(doc: dict, title: str, run_pages: dict | None = None) -> str:
    run_pages = run_pages or {}
    joint = doc.get("joint") or {}
    jf = [f for f in joint.get("findings") or [] if isinstance(f, dict)]
    runs = [r for r in doc.get("runs") or [] if isinstance(r, dict)]
    ok = [r for r in runs if r.get("status") == "ok"]
    verdict = (f"<div class=verdict><p><b>{len(jf)} joint finding{'s' * (len(jf) != 1)}</b> over {len(ok)} of "
               f"{len(runs)} runs.</p>" + findings_table(jf, "joint") + "</div>")
    forest = []
    cons = {c.get("parameter"): c for c in (joint.get("consistency") or {}).get("parameters") or [] if isinstance(c, dict)}
    for j in (f for f in jf if f.get("cause") != "parameter_error" and isinstance(f.get("per_run"), list)):
        # a nonlinear cause fitted jointly: each run's own size at the joint law
        lab = f"{j.get('cause')}[{j.get('parameter')}]"
        rows = [(str(r.get("run")), float(r["estimate"]), r.get("interval") if isinstance(r.get("interval"), list) else None)
                for r in j["per_run"] if isinstance(r, dict) and _number(r.get("estimate")) is not None]
        if rows and isinstance(j.get("interval"), list):
            forest.append(fig(F.forest_figure(lab, rows, (float(j["estimate"]), tuple(j["interval"])),
                                              str(j.get("unit") or ""), reference=None),
                              f"{lab}: each run's own size at the joint law (squares, lines), the joint estimate and "
                              "interval (blue line, band); runs that never reach it are not drawn."))
    jf_lin = [f for f in jf if f.get("cause") in (None, "parameter_error")]
    params = [f.get("parameter") for f in jf_lin if f.get("parameter")] + [p for p in cons if p not in [f.get("parameter") for f in jf_lin]]
    for p in params:
        rows = []
        for r in ok:
            for f in r.get("findings") or []:
                if (isinstance(f, dict) and f.get("parameter") == p and f.get("cause") in (None, "parameter_error")
                        and _number(f.get("estimate")) is not None):
                    iv = f.get("interval") if isinstance(f.get("interval"), list) and len(f["interval"]) == 2 else None
                    rows.append((str(r.get("name", r.get("run"))), float(f["estimate"]), iv))
        j = next((f for f in jf_lin if f.get("parameter") == p), None)
        joint_iv = (float(j["estimate"]), tuple(j["interval"])) if j and isinstance(j.get("interval"), list) else None
        if rows or joint_iv:
            forest.append(fig(F.forest_figure(str(p), rows, joint_iv, str((j or {}).get("unit") or "ratio")),
                              f"{p}: each run's own estimate and interval (squares, lines), the joint estimate and "
                              "interval (blue line, band); dashed: the model as given."))
    crow = "".join(f"<tr><td class=mono>{esc(p)}</td><td class=n>{esc(num(c.get('chi2'), 4))}</td><td class=n>{esc(num(c.get('dof')))}</td>"
                   f"<td class=n>{esc(num(c.get('p_value'), 3))}</td><td>{_CONS[bool(c.get('consistent'))]}</td>"
                   f"<td>{esc(', '.join(str(d.get('run')) for d in c.get('disagreeing_runs') or [] if isinstance(d, dict)))}</td></tr>"
                   for p, c in cons.items())
    cons_html = ("<table><thead><tr><th>parameter</th><th>chi²</th><th>dof</th><th>p</th><th>check</th><th>disagreeing runs</th></tr></thead>"
                 f"<tbody>{crow}</tbody></table>" if crow else "<p>No consistency check (fewer than two runs name a parameter).</p>")
    rrows = []
    for r in runs:
        fl = ", ".join(finding_label(f) for f in r.get("findings") or [] if isinstance(f, dict))
        g = r.get("gain") if isinstance(r.get("gain"), dict) else {}
        gtxt = f"{num(g.get('before'))} → {num(g.get('after'))} {g.get('unit') or ''}" if g.get("metric") else "–"
        st = r.get("status")
        tag = f'<span class="tag {"ok" if st == "ok" else "no"}">{esc(st)}</span>'
        rrows.append(f"<tr><td>{_run_page_link(r, run_pages)}</td><td class=mono>{esc(r.get('logger') or '–')}</td>"
                     f"<td class=n>{esc(num(r.get('repetitions')))}</td><td>{tag}</td><td class=mono>{esc(fl or r.get('message') or '')}</td>"
                     f"<td class=n>{esc(gtxt)}</td></tr>")
    runs_html = ("<table><thead><tr><th>run</th><th>logger</th><th>repetitions</th><th>status</th><th>findings</th><th>gain</th></tr></thead>"
                 f"<tbody>{''.join(rrows)}</tbody></table>")
    secs = [("verdict", "Verdict", verdict),
            ("forest", "Joint parameters: every run's interval", "".join(forest) or "<p>No parameter named.</p>"),
            ("consistency", "Consistency across runs", cons_html),
            ("runs", "Runs", runs_html)]
    dur = doc.get("durability")
    if isinstance(dur, dict):
        secs.append(("damage", "Damage per run and section", campaign_damage_html(dur)))
    if joint.get("extended_model"):
        secs.append(("extended", "Joint extended model", generic(joint.get("extended_model"))))
    rest = rest_html(doc, {"schema", "joint", "runs", "durability", "provenance"})
    if rest:
        secs.append(("other", "Other fields", rest))
    secs.append(("provenance", "Provenance", provenance_html(doc.get("provenance"))))
    return page(title, f"campaign of {len(runs)} runs", secs)


def campaign_damage_html(dur: dict) -> str:
    out = []
    per = dur.get("per_run")
    sections = [str(x) for x in dur.get("sections") or []]
    if isinstance(per, list) and per and all(isinstance(p, dict) for p in per):
        names, series = [], {}
        for p in per:
            names.append(str(p.get("name", p.get("run", "?"))))
            dmg = p.get("damage_x_repetitions") or p.get("damage") or {}
            for var, vals in (dmg.items() if isinstance(dmg, dict) else []):
                if isinstance(vals, list):
                    pairs = zip(sections or [f"#{i}" for i in range(len(vals))], vals)
                elif isinstance(vals, dict):
                    pairs = vals.items()
                else:
                    pairs = [("", vals)]
                for sec, v in pairs:
                    series.setdefault(f"{var} {sec}".strip(), {})[names[-1]] = _number(v)
        if series:
            keep = [k for k in series if k.startswith(("stabilised", "extended", "measured"))] or list(series)
            out.append(fig(F.bar_figure(names, [(k, [series[k].get(n) if series[k].get(n) is not None else float("nan")
                                                     for n in names], None) for k in keep[:6]],
                                        "repetitions x damage [N^K]", "Damage per run and section (log scale)", log=True),
                           "Each run's pseudo-damage times its repetitions, per section force and variant."))
            rows = "".join(f"<tr><td class=mono>{esc(n)}</td>" + "".join(
                f"<td class=n>{esc(num(series[k].get(n), 4))}</td>" for k in series) + "</tr>" for n in names)
            out.append("<table><thead><tr><th>run</th>" + "".join(f"<th>{esc(k)}</th>" for k in series)
                       + f"</tr></thead><tbody>{rows}</tbody></table>")
    ratios = dur.get("damage_ratio_to_stabilised")
    if isinstance(ratios, dict):
        out.append("<p>Campaign damage / " + esc(dur.get("reference", "stabilised")) + ": "
                   + ", ".join(f"{esc(k)} {esc(num(_number(v), 4))}" for k, v in ratios.items()) + "</p>")
    out.append(f"<details><summary>the whole durability block</summary>{generic(dur)}</details>")
    return "".join(out)


# ------------------------------------------------------------------------------------ entry


def report_kind(doc: dict) -> str:
    schema = str(doc.get("schema", ""))
    if schema.startswith("jaxdrift.campaign"):
        return "campaign"
    if schema.startswith("jaxdrift.durability"):
        return "durability"
    if doc.get("kind") in ("vehicle", "attitude"):
        return doc["kind"]
    raise ValueError(f"not a jaxdrift report (schema {schema!r}, kind {doc.get('kind')!r})")


def render(doc: dict, title: str | None = None, run_pages: dict | None = None) -> str:
    """The page of a report (diagnosis, durability, campaign) as one HTML string."""
    kind = report_kind(doc)
    name = title or {"vehicle": "Vehicle run diagnosis", "attitude": "Attitude run diagnosis",
                     "durability": "Durability analysis", "campaign": "Campaign"}[kind]
    if kind == "vehicle":
        return vehicle_page(doc, name)
    if kind == "attitude":
        return attitude_page(doc, name)
    if kind == "durability":
        return durability_page(doc, name)
    return campaign_page(doc, name, run_pages)


def load(path: str) -> dict:
    with open(path) as fh:
        return json.load(fh)
