"""``jaxdrift campaign`` against a separately started ``dask scheduler`` and two ``dask worker``
processes, one of them killed (SIGKILL) midway, compared with the same campaign on a LocalCluster.

    python benchmarks/validation/gen_campaign.py --n 6 --seed S --out DIR
    python benchmarks/validation/campaign_dask_cli.py DIR WORK [--json benchmarks/results/campaign_dask_cli.json]

Checks: the campaign finishes on the one worker left; every run whose result was in the cache when
the worker died is still there, unchanged; ``campaign.json`` equals the LocalCluster one apart from
``provenance``. Then the campaign command itself is killed midway and rerun: the rerun takes every
run that had finished from the cache. The workers get the thread limits a LocalCluster's nanny sets
(``OMP_NUM_THREADS=1`` ...), so both clusters run the same arithmetic.
"""

from __future__ import annotations

import argparse
import glob
import hashlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time

BIN = os.path.dirname(sys.executable)
THREADS = {k: "1" for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")}


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _cache(out):
    return {os.path.basename(p): hashlib.sha256(open(p, "rb").read()).hexdigest()
            for p in glob.glob(os.path.join(out, "cache", "diagnose-*.json"))}


def _campaign(manifest, out, *extra):
    return [os.path.join(BIN, "jaxdrift"), "-q", "campaign", "--manifest", manifest, "--out", out, *extra]


def _strip(doc):
    doc = dict(doc)
    doc.pop("provenance")
    return doc


def stop_processes(procs) -> None:
    """Terminate the scheduler, worker and campaign processes a check started (kill after 20 s)."""
    procs = list(procs)
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()


def report(result: dict, path: str | None) -> None:
    """Print the check's result with the load average, and write it to ``path`` (JSON)."""
    result["load_average"] = os.getloadavg()
    print(json.dumps(result, indent=1))
    if path:
        with open(path, "w") as fh:
            json.dump(result, fh, indent=1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data")
    ap.add_argument("work")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    manifest = os.path.join(a.data, "campaign.toml")
    n_runs = len(glob.glob(os.path.join(a.data, "run_*[0-9].csv")))
    os.makedirs(a.work, exist_ok=True)
    result = {"data": a.data, "runs": n_runs}

    local = os.path.join(a.work, "local")
    shutil.rmtree(local, ignore_errors=True)
    t0 = time.monotonic()
    subprocess.run(_campaign(manifest, local, "--workers", "2", "--no-figures"), check=True)
    result["local_wall_s"] = time.monotonic() - t0

    port = _port()
    env = dict(os.environ, **THREADS)
    procs = {"scheduler": subprocess.Popen([os.path.join(BIN, "dask"), "scheduler", "--port", str(port),
                                            "--no-dashboard"], env=env, stderr=subprocess.DEVNULL)}
    time.sleep(5)
    addr = f"tcp://127.0.0.1:{port}"
    for i in (1, 2):
        procs[f"worker{i}"] = subprocess.Popen([os.path.join(BIN, "dask"), "worker", addr, "--nthreads", "1",
                                                "--no-nanny", "--no-dashboard"], env=env, stderr=subprocess.DEVNULL)
    try:
        time.sleep(8)
        remote = os.path.join(a.work, "scheduler")
        shutil.rmtree(remote, ignore_errors=True)
        t0 = time.monotonic()
        camp = subprocess.Popen(_campaign(manifest, remote, "--scheduler", addr, "--no-figures"))
        while len(_cache(remote)) < max(1, n_runs // 3) and camp.poll() is None:
            time.sleep(0.5)
        before = _cache(remote)
        procs["worker1"].send_signal(signal.SIGKILL)
        result["killed_worker_after_runs_finished"] = len(before)
        rc = camp.wait()
        result["scheduler_wall_s"] = time.monotonic() - t0
        after = _cache(remote)
        result["campaign_rc"] = rc
        result["finished_runs_kept"] = all(after.get(k) == v for k, v in before.items())
        d1 = json.load(open(os.path.join(local, "campaign.json")))
        d2 = json.load(open(os.path.join(remote, "campaign.json")))
        result["same_campaign_json_apart_from_provenance"] = _strip(d1) == _strip(d2)
        result["executors"] = [d1["provenance"]["executor"], d2["provenance"]["executor"]]

        # the campaign command killed midway, then rerun: every finished run comes from the cache
        again = os.path.join(a.work, "killed")
        shutil.rmtree(again, ignore_errors=True)
        camp = subprocess.Popen(_campaign(manifest, again, "--scheduler", addr, "--no-figures"))
        while len(_cache(again)) < max(1, n_runs // 2) and camp.poll() is None:
            time.sleep(0.5)
        camp.send_signal(signal.SIGKILL)
        camp.wait()
        kept = _cache(again)
        subprocess.run(_campaign(manifest, again, "--scheduler", addr, "--no-figures"), check=True)
        d3 = json.load(open(os.path.join(again, "campaign.json")))
        result["command_killed_after_runs"] = len(kept)
        result["rerun_cached_runs"] = d3["provenance"]["cached_runs"]
        result["rerun_same_campaign_json"] = _strip(d3) == _strip(d1)
    finally:
        stop_processes(procs.values())
    report(result, a.json)


if __name__ == "__main__":
    main()
