"""Campaign throughput: runs diagnosed per second on a Dask LocalCluster of 1 and of 2 worker
processes (one thread each), the same runs, nothing cached.

    python benchmarks/validation/gen_campaign.py --n 8 --seed S --out DIR
    python benchmarks/campaign_throughput.py DIR --runs 8 --json benchmarks/results/campaign_throughput.json

The cluster is started and every worker has imported the diagnosis before the clock starts; the
clock covers submitting the runs to the last result (the per-run stage of ``jaxdrift campaign``,
which is where its time goes). The load average before and after is recorded: on a shared machine
other processes take their share of the cores.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import platform
import sys
import time
from importlib import metadata


def _warm():
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxdrift.diagnosis.vehicle._pipeline  # noqa: F401

    return os.getpid()


def measure(files, model_path, workers: int) -> dict:
    from jaxdrift.campaign._executor import dask_client, map_tasks
    from jaxdrift.campaign._manifest import RunSpec
    from jaxdrift.campaign._tasks import diagnose_task
    from jaxdrift.io import read_model

    model = read_model(model_path)
    specs = [RunSpec(path=f) for f in files]
    with dask_client(workers=workers) as (client, ex):
        client.run(_warm)
        load0 = os.getloadavg()
        t0 = time.perf_counter()
        res = map_tasks(client, diagnose_task, specs, desc=f"{workers} worker(s)", model=model, model_given=True,
                        model_desc={"file": os.path.basename(model_path)})
        wall = time.perf_counter() - t0
        load1 = os.getloadavg()
    ok = sum(r["status"] == "ok" for r in res)
    return {"workers": workers, "runs": len(specs), "ok": ok, "wall_s": wall, "runs_per_s": len(specs) / wall,
            "task_s": [r.get("seconds") for r in res], "load_average_before": load0, "load_average_after": load1}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dir", help="a folder written by gen_campaign.py")
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    files = sorted(glob.glob(os.path.join(a.dir, "run_*[0-9].csv")))[:a.runs]
    model = os.path.join(a.dir, "model.json")
    one = measure(files, model, 1)
    two = measure(files, model, 2)
    out = {"benchmark": "campaign throughput (per-run diagnosis on Dask)", "data": a.dir, "runs": len(files),
           "one_worker": one, "two_workers": two, "speedup": two["runs_per_s"] / one["runs_per_s"],
           "machine": {"platform": platform.platform(), "python": sys.version.split()[0], "cpus": os.cpu_count()},
           "versions": {k: metadata.version(k) for k in ("jaxdrift", "dask", "distributed", "jax", "numpy", "scipy")}}
    print(f"1 worker: {one['wall_s']:.1f} s, 2 workers: {two['wall_s']:.1f} s, speedup x{out['speedup']:.2f} "
          f"(load average {one['load_average_before'][0]:.1f} -> {two['load_average_after'][0]:.1f})")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
