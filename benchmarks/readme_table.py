"""Write the README's throughput table from ``benchmarks/results/throughput-idle.json``.

The table sits between the markers ``<!-- throughput-table -->`` and ``<!-- /throughput-table -->``
in ``README.md``; everything between them is replaced. Run after ``benchmarks/throughput.py``::

    python benchmarks/readme_table.py
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
START, END = "<!-- throughput-table -->", "<!-- /throughput-table -->"
ROWS = (("fixed/jaxdrift", "fixed 1 ms"), ("fixed/jaxdrift-fast", "fixed 1 ms, fast mode (float32 + Kahan)"),
        ("adaptive/jaxdrift", "adaptive rtol 1e-6"))


def render(res: dict) -> str:
    cases, cfg = res["cases"], res["config"]
    lines = [
        f"Half-car noisy-force study, {cfg['T']:g} s at {cfg['fs']:g} Hz, {cfg['paths']} paths per call, "
        f"float64 unless noted, {res['machine']['cpu_count']}-core machine (load average "
        f"{res['machine']['load_average_at_start'][0]:.1f} at start); generated from "
        "`benchmarks/results/throughput-idle.json` by `python benchmarks/readme_table.py`:",
        "",
        "| mode | jaxdrift path-steps/s | vs diffrax Dopri5 | vs scipy RK45 |",
        "|---|---:|---:|---:|",
    ]
    for key, label in ROWS:
        c = cases.get(key)
        if c is None:
            continue
        vs_d = f"{c['vs_diffrax']:.2f}x" if c.get("vs_diffrax") else ""
        vs_s = f"{c['vs_scipy']:.0f}x" if c.get("vs_scipy") else ""
        lines.append(f"| {label} | {c['path_steps_per_s']:.3g} | {vs_d} | {vs_s} |")
    mems = [m for m in (res.get("memory"), res.get("memory_float64")) if m and m.get("peak_rss_bytes")]
    if mems:
        m0 = mems[0]
        lines += ["", f"{m0['paths']:,} paths x {m0['T']:g} s at 1 kHz with statistics every 0.1 s "
                      f"(chunks of {m0['chunk_size']}), peak RSS: "
                      + ", ".join(f"{m['mode']} mode {m['peak_rss_bytes'] / 2**30:.2f} GiB in {m['wall_s']:.0f} s"
                                  for m in mems) + "."]
    return "\n".join(lines)


def main() -> int:
    res = json.loads((ROOT / "benchmarks" / "results" / "throughput-idle.json").read_text())
    readme = ROOT / "README.md"
    text = readme.read_text()
    if START not in text or END not in text:
        print(f"README.md has no {START} ... {END} block", file=sys.stderr)
        return 2
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    readme.write_text(head + START + "\n" + render(res) + "\n" + END + tail)
    print("README.md throughput table updated")
    return 0


if __name__ == "__main__":
    sys.exit(main())
