"""The verdict in the terminal: a short summary of a report, the way a test runner ends.

``summary_lines`` gives the findings in order (estimate, interval, confirmed or not), the gain,
what could not be shown and where the report and the page are; ``one_line`` the same in one line
(``-q``). Built from the report's JSON, as the page is.
"""

from __future__ import annotations

from ._html import finding_label, interval_text, num, report_kind

__all__ = ["summary_lines", "one_line"]

_WIDTH = 110


def _short(s: str, width: int = _WIDTH) -> str:
    s = " ".join(str(s).split())
    return s if len(s) <= width else s[: width - 3].rstrip() + "..."


def _finding_line(i: int, f: dict) -> str:
    est = f"{num(f.get('estimate'))} {f.get('unit') or ''}".strip() if f.get("estimate") is not None else ""
    conf = {True: "confirmed", False: "not confirmed"}.get(f.get("confirmed"), "")
    parts = [p for p in (est, interval_text(f) if f.get("interval") else "", conf) if p]
    return f"  {i}. {finding_label(f):<28} " + "  ".join(parts)


def _gain(g) -> str | None:
    if not isinstance(g, dict) or g.get("metric") is None:
        return None
    return f"{g['metric']} {num(g.get('before'))} -> {num(g.get('after'))} {g.get('unit') or ''}".rstrip()


def _could_not(doc: dict) -> list[str]:
    out = [n for n in doc.get("notes") or [] if isinstance(n, str) and n.lower().startswith("could not")]
    for d in doc.get("not_determined") or []:
        if isinstance(d, dict):
            out.append(f"{finding_label(d)}: {d.get('reason', '')}")
    return out


def _where(outputs: dict) -> str:
    return ", ".join(f"{k} {v}" for k, v in outputs.items() if v)


def summary_lines(doc: dict, outputs: dict, command: str = "jaxdrift") -> list[str]:
    """``outputs``: {"report": path, "page": path, ...} (None entries left out)."""
    kind = report_kind(doc)
    lines = []
    if kind in ("vehicle", "attitude"):
        fs = [f for f in doc.get("findings") or [] if isinstance(f, dict)]
        src = (doc.get("run") or {}).get("file")
        lines.append(f"{command}: {len(fs)} finding{'s' * (len(fs) != 1)} ({kind} run{' ' + str(src) if src else ''})")
        lines += [_finding_line(i, f) for i, f in enumerate(fs, 1)]
        g = _gain(doc.get("gain"))
        lines.append(f"  gain: {g}" if g else "  gain: none (nothing corrected)")
        for n in _could_not(doc):
            lines.append("  could not show: " + _short(n.removeprefix("Could not show: ")))
    elif kind == "durability":
        ref = doc.get("reference", "stabilised")
        q = (doc.get("monte_carlo") or {}).get("damage_ratio_quantiles") or {}
        lines.append(f"{command}: damage of each variant / {ref} (K = {num(doc.get('basquin_k'))})")
        for v, r in (doc.get("damage_ratio_to_stabilised") or {}).items():
            band = f"  noise 5-95 % [{num(q[v][0], 4)}, {num(q[v][2], 4)}]" if v in q else ""
            lines.append(f"  {v:<14} {num(r, 4)}{band}")
    else:
        joint = doc.get("joint") or {}
        runs = doc.get("runs") or []
        ok = [r for r in runs if r.get("status") == "ok"]
        fs = [f for f in joint.get("findings") or [] if isinstance(f, dict)]
        lines.append(f"{command}: {len(ok)} of {len(runs)} runs diagnosed; {len(fs)} joint finding{'s' * (len(fs) != 1)}")
        lines += [_finding_line(i, f) for i, f in enumerate(fs, 1)]
        for c in (joint.get("consistency") or {}).get("parameters") or []:
            if not c.get("consistent", True):
                lines.append(f"  {c.get('parameter')} differs between runs (p = {num(c.get('p_value'), 3)}): "
                             + ", ".join(str(d.get("run")) for d in c.get("disagreeing_runs") or []))
        for r in runs:
            if r.get("status") != "ok":
                lines.append(f"  failed: {r.get('name', r.get('run'))}: {_short(r.get('message', ''), 80)}")
        dur = doc.get("durability")
        if isinstance(dur, dict) and isinstance(dur.get("damage_ratio_to_stabilised"), dict):
            lines.append("  campaign damage / stabilised: " + ", ".join(
                f"{k} {num(_scalar(v), 4)}" for k, v in dur["damage_ratio_to_stabilised"].items()))
    w = _where(outputs)
    if w:
        lines.append(f"  {w}")
    return lines


def _scalar(v):
    if isinstance(v, dict):
        for k in ("estimate", "nominal", "value", "median"):
            if k in v:
                return v[k]
    if isinstance(v, list) and len(v) == 3:
        return v[1]
    return v


def one_line(doc: dict, outputs: dict, command: str = "jaxdrift") -> str:
    kind = report_kind(doc)
    if kind in ("vehicle", "attitude"):
        fs = [f for f in doc.get("findings") or [] if isinstance(f, dict)]
        body = ", ".join(f"{finding_label(f)} {num(f.get('estimate'))}" + ("" if f.get("confirmed", True) else "?")
                         for f in fs) or "no findings"
        g = _gain(doc.get("gain"))
        body += f"; gain {g}" if g else ""
    elif kind == "durability":
        body = ", ".join(f"{v} {num(r, 4)}" for v, r in (doc.get("damage_ratio_to_stabilised") or {}).items())
        body = f"damage / {doc.get('reference', 'stabilised')}: {body}"
    else:
        runs = doc.get("runs") or []
        fs = [f for f in (doc.get("joint") or {}).get("findings") or [] if isinstance(f, dict)]
        body = (f"{sum(r.get('status') == 'ok' for r in runs)}/{len(runs)} runs; "
                + (", ".join(f"{finding_label(f)} {num(f.get('estimate'))}" for f in fs) or "no joint findings"))
    w = _where(outputs)
    return f"{command}: {body}" + (f"; {w}" if w else "")
