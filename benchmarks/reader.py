"""Benchmark: read a 5 million row x 6 column vehicle run (target: < 10 s and < 1 GB peak).

Writes a CSV of ``--rows`` rows (columns t, f1, f2, beta, beta_rate, z3 at 1 kHz, printed with
shortest round-trip decimals; plausible signals, so that the plausibility checks pass), then reads
it with ``jaxdrift.io.load_run`` (all checks on) in a fresh Python process, ``--repeat`` times, and
records the wall time of the read and the process's peak resident memory (``ru_maxrss``), next to
the peak of a process that only imports the reader (the baseline). Optionally (``--parquet``) the
same for a Parquet copy. A benchmark, not a test: timings never enter the test suite.

    python benchmarks/reader.py [--rows 5000000] [--repeat 3] [--parquet] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, resource, sys, time
t0 = time.perf_counter()
from jaxdrift.io import load_run
t1 = time.perf_counter()
rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
if sys.argv[1] != "-":
    run = load_run(sys.argv[1])
    n = run.n
else:
    n = 0
t2 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "read_s": t2 - t1, "rows": n,
                  "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "rss_after_import_mib": rss0 / 1024}))
"""


def _write_run(path: str, rows: int) -> None:
    import numpy as np
    import pyarrow as pa
    import pyarrow.csv as pcsv

    rng = np.random.default_rng(0)
    t = np.arange(rows) / 1000.0
    w = 2 * np.pi * 1.3 * t
    cols = {"t": t,
            "f1": 3825.9 + 400 * np.sin(w) + rng.normal(0, 20, rows),
            "f2": 3825.9 - 300 * np.sin(0.7 * w) + rng.normal(0, 20, rows),
            "beta": 0.02 * np.sin(0.5 * w), "beta_rate": 0.02 * 0.5 * 2 * np.pi * 1.3 * np.cos(0.5 * w),
            "z3": 0.05 * np.sin(0.3 * w)}
    table = pa.table(cols)
    with open(path, "wb") as fh:
        fh.write((",".join(cols) + "\n").encode())
        pcsv.write_csv(table, fh, pcsv.WriteOptions(include_header=False, quoting_style="none"))


def _in_child(code: str) -> None:
    """Run ``code`` in a fresh process: the parent stays small, because a child's ``ru_maxrss``
    starts from the parent's resident size at fork (Linux keeps it across exec)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    subprocess.run([sys.executable, "-c", code], env=env, check=True)


def _child(arg: str) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-c", CHILD, arg], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rows", type=int, default=5_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--parquet", action="store_true", help="also time a Parquet copy")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as d:
        csv_path = os.path.join(d, "run.csv")
        t0 = time.perf_counter()
        _in_child(f"import sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); "
                  f"from reader import _write_run; _write_run({csv_path!r}, {args.rows})")
        gen_s = time.perf_counter() - t0
        size = os.path.getsize(csv_path)
        load0 = os.getloadavg()[0]
        base = _child("-")
        runs = [_child(csv_path) for _ in range(args.repeat)]
        result = {
            "benchmark": "reader", "rows": args.rows, "columns": 6, "csv_bytes": size,
            "csv_write_s": gen_s, "load_average_at_start": load0,
            "baseline_import_only": base,
            "csv": {"read_s": [r["read_s"] for r in runs], "peak_rss_mib": [r["peak_rss_mib"] for r in runs],
                    "read_s_min": min(r["read_s"] for r in runs),
                    "peak_rss_mib_max": max(r["peak_rss_mib"] for r in runs)},
            "targets": {"read_s": 10.0, "peak_rss_mib": 1024.0},
            "command": "python benchmarks/reader.py " + " ".join(sys.argv[1:]),
            "machine": {"python": platform.python_version(), "platform": platform.platform(),
                        "cpu_count": os.cpu_count()},
        }
        if args.parquet:
            pq_path = os.path.join(d, "run.parquet")
            _in_child(f"import pyarrow.csv as c, pyarrow.parquet as q; q.write_table(c.read_csv({csv_path!r}), {pq_path!r})")
            pr = [_child(pq_path) for _ in range(args.repeat)]
            result["parquet"] = {"bytes": os.path.getsize(pq_path), "read_s": [r["read_s"] for r in pr],
                                 "peak_rss_mib": [r["peak_rss_mib"] for r in pr]}
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "reader.json"), "w") as fh:
        json.dump(result, fh, indent=1)
    c = result["csv"]
    print(f"{args.rows} rows x 6 columns, CSV {size / 2**20:.0f} MiB: read in {c['read_s_min']:.2f} s "
          f"(runs {', '.join(f'{v:.2f}' for v in c['read_s'])}), peak RSS {c['peak_rss_mib_max']:.0f} MiB "
          f"(import only: {base['peak_rss_mib']:.0f} MiB); load average {load0:.1f}")
    if args.parquet:
        print(f"Parquet: read {min(result['parquet']['read_s']):.2f} s, peak RSS "
              f"{max(result['parquet']['peak_rss_mib']):.0f} MiB")


if __name__ == "__main__":
    main()
