"""Benchmark: diagnose a 60 s, 1 kHz vehicle run (the bar: under a minute on this machine).

Generates a run with a hidden effect (``jaxdrift.studies._rungen``, not timed), then times
``jaxdrift diagnose`` phases: reading the CSV, the cause selection (residual pipeline), the whole
report including the engine's force-driven simulations (first call: includes JAX compilation;
second call: warm). Writes JSON and a markdown table.

    python benchmarks/diagnose.py [--duration 60] [--fs 1000] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--fs", type=float, default=1000.0)
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"))
    args = ap.parse_args()

    import jax

    jax.config.update("jax_enable_x64", True)
    from jaxdrift.diagnosis.vehicle import diagnose_vehicle_run
    from jaxdrift.studies import _rungen as rg
    from jaxdrift.io._csvio import DEFAULT_MODEL, read_vehicle_run, write_vehicle_run

    effects = [{"cause": "force_offset", "channel": "f1", "value": 50.0},
               {"cause": "force_noise", "value": 20.0}]
    chans = ("beta", "z3")
    t0 = time.perf_counter()
    cols, _ = rg.make_run(effects, duration=args.duration, fs=args.fs, speed=20.0, road_class="B",
                          seed=1, channels=chans)
    t_gen = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "run.csv")
        write_vehicle_run(path, cols["t"], {k: v for k, v in cols.items() if k != "t"})
        t0 = time.perf_counter()
        run = read_vehicle_run(path)
        t_read = time.perf_counter() - t0
    t0 = time.perf_counter()
    rep_fast = diagnose_vehicle_run(run, DEFAULT_MODEL, with_simulation=False)
    t_select = time.perf_counter() - t0
    t0 = time.perf_counter()
    rep = diagnose_vehicle_run(run, DEFAULT_MODEL)
    t_full_cold = time.perf_counter() - t0
    t0 = time.perf_counter()
    diagnose_vehicle_run(run, DEFAULT_MODEL)
    t_full_warm = time.perf_counter() - t0

    result = {
        "benchmark": "diagnose_vehicle_run",
        "samples": run.n, "duration_s": args.duration, "fs_hz": args.fs, "channels": list(chans),
        "hidden_effects": effects,
        "first_finding": rep["findings"][0],
        "seconds": {"generate_run_untimed_part": t_gen, "read_csv": t_read,
                    "diagnose_without_force_driven_simulation": t_select,
                    "diagnose_full_cold": t_full_cold, "diagnose_full_warm": t_full_warm,
                    "read_plus_full_cold": t_read + t_full_cold},
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                    "loadavg_1min": os.getloadavg()[0], "jax": jax.__version__},
        "same_findings_without_simulation": [f["cause"] for f in rep_fast["findings"]]
        == [f["cause"] for f in rep["findings"]],
    }
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "diagnose.json"), "w") as fh:
        json.dump(result, fh, indent=2, default=float)
    rows = "\n".join(f"| {k} | {v:.2f} |" for k, v in result["seconds"].items())
    md = (f"# diagnose benchmark ({run.n} samples, {args.fs:g} Hz)\n\n| phase | s |\n|---|---|\n{rows}\n\n"
          f"load average during the run: {result['machine']['loadavg_1min']:.1f} on {os.cpu_count()} cpus\n")
    with open(os.path.join(args.out, "diagnose.md"), "w") as fh:
        fh.write(md)
    print(md)


if __name__ == "__main__":
    main()
