"""The clipped runs of ``clip_sweep.py`` diagnosed by another jaxdrift (an older checkout on
``PYTHONPATH``): each ``clippedNN.csv`` of the folder read as the command line reads it (with the
reader's checks, which before 2026-12-04 cut a run to its longest stretch free of a clipped
channel's bursts, or refused it) and as the library reads it (no checks), both diagnosed without
the re-simulation.

    PYTHONPATH=/path/to/old/checkout python benchmarks/validation/clip_sweep_before.py OUT_OF_CLIP_SWEEP --json FILE

Writes per run: what the command line's reader kept (or why it refused), the systematic findings
of both readings, and the library reading's force-noise interval.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
from multiprocessing import Pool


def _systematic(rep):
    return sorted({(f["cause"], f.get("channel") or f.get("parameter")) for f in rep["findings"]
                   if f["cause"] not in ("force_noise", "none", "channel_fault", "force_clipping")})


def _one(path: str) -> dict:
    import jaxdrift
    from jaxdrift.io import load_run

    model = jaxdrift.read_model(path.replace(".csv", "_model.json"))
    with open(path) as fh:
        rows = sum(1 for _ in fh) - 1
    out = {"run": os.path.basename(path), "rows": rows}
    try:
        run = load_run(path, "vehicle", checks=True, model=model)
        out["cli_kept"] = run.n
        out["cli_findings"] = _systematic(jaxdrift.diagnose_vehicle_run(run, model, with_simulation=False))
    except Exception as e:  # the reader refused the run: what a user of the command line got
        out["cli_refused"] = str(e)[-200:]
        out["cli_findings"] = None
    rep = jaxdrift.diagnose_vehicle_run(jaxdrift.read_vehicle_run(path), model, with_simulation=False)
    out["library_findings"] = _systematic(rep)
    nf = [f for f in rep["findings"] if f["cause"] == "force_noise"]
    out["noise_interval"] = nf[0]["interval"] if nf else None
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder")
    ap.add_argument("--json", required=True)
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    paths = sorted(glob.glob(os.path.join(a.folder, "clipped*.csv")))
    with Pool(a.jobs) as p:
        res = p.map(_one, paths)
    for r in res:
        print(r)
    with open(a.json, "w") as fh:
        json.dump(res, fh, indent=1)


if __name__ == "__main__":
    main()
