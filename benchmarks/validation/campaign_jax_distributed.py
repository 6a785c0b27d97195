"""The campaign's force-noise Monte Carlo across two processes joined by ``jax.distributed``,
against the same campaign in one process.

    python benchmarks/validation/gen_campaign.py --n 2 --seed S --out DIR --durations 4 4
    python benchmarks/validation/campaign_jax_distributed.py DIR WORK [--json OUT.json]

Starts a ``dask scheduler`` and one ``dask worker``; runs ``jaxdrift campaign --durability`` once as
one process, then as two processes (``--jax-coordinator/--jax-processes/--jax-process-id``, the same
``--scheduler``), and compares the campaign damage's force-noise quantiles (every path's noise is a
function of (key, path) only, so the two agree to rounding).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
from benchmarks.validation.campaign_dask_cli import report, stop_processes  # noqa: E402

BIN = os.path.dirname(sys.executable)


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data")
    ap.add_argument("work")
    ap.add_argument("--paths", type=int, default=8)
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    manifest = os.path.join(a.data, "campaign.toml")
    os.makedirs(a.work, exist_ok=True)
    env = dict(os.environ, OMP_NUM_THREADS="1", JAX_PLATFORMS="cpu")
    env.pop("XLA_FLAGS", None)
    port = _port()
    addr = f"tcp://127.0.0.1:{port}"
    procs = [subprocess.Popen([os.path.join(BIN, "dask"), "scheduler", "--port", str(port), "--no-dashboard"],
                              env=env, stderr=subprocess.DEVNULL)]
    time.sleep(5)
    procs.append(subprocess.Popen([os.path.join(BIN, "dask"), "worker", addr, "--nthreads", "1", "--no-dashboard"],
                                  env=env, stderr=subprocess.DEVNULL))
    common = ["--manifest", manifest, "--durability", "--paths", str(a.paths), "--param-draws", "4",
              "--scheduler", addr, "--no-figures"]
    out = {}
    try:
        time.sleep(8)
        one = os.path.join(a.work, "one")
        shutil.rmtree(one, ignore_errors=True)
        t0 = time.monotonic()
        subprocess.run([os.path.join(BIN, "jaxdrift"), "-q", "campaign", *common, "--out", one], env=env, check=True)
        out["one_process_s"] = time.monotonic() - t0
        two = os.path.join(a.work, "two")
        shutil.rmtree(two, ignore_errors=True)
        jport = _port()
        t0 = time.monotonic()
        ps = [subprocess.Popen([os.path.join(BIN, "jaxdrift"), "-q", "campaign", *common, "--out", two,
                                "--jax-coordinator", f"127.0.0.1:{jport}", "--jax-processes", "2",
                                "--jax-process-id", str(i)], env=env) for i in (0, 1)]
        out["two_process_rc"] = [p.wait() for p in ps]
        out["two_processes_s"] = time.monotonic() - t0
        d1 = json.load(open(os.path.join(one, "campaign.json")))["durability"]
        d2 = json.load(open(os.path.join(two, "campaign.json")))["durability"]
        q1, q2 = d1["force_noise"]["damage_quantiles"], d2["force_noise"]["damage_quantiles"]
        rel = 0.0
        for v in q1:
            for s1, s2 in zip(q1[v], q2[v]):
                for x, y in zip(s1, s2):
                    rel = max(rel, abs(x - y) / abs(x))
        out["max_relative_difference"] = rel
        out["computed_in"] = [d1["force_noise"]["computed_in"], d2["force_noise"]["computed_in"]]
    finally:
        stop_processes(procs)
    report(out, a.json)


if __name__ == "__main__":
    main()
