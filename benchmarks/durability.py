"""Benchmark: ``jaxdrift durability`` on a 60 s, 1 kHz run with 256 Monte-Carlo paths (the
bar: under 2 minutes on 2 cores, with a progress bar).

Generates a run (``jaxdrift.studies.make_run``: class C road, 20 m/s, 15 N force noise, an offset
on f2, measured pitch with 0.01 deg of noise; not timed), writes it as CSV, then runs the command
line ``jaxdrift durability RUN.csv --out DIR --paths 256`` in this process and times it as a whole
(reading, the diagnosis, the nominal variants, the 256 Monte-Carlo paths with their rainflow
counts, the outputs). A second, warm call of the Monte-Carlo part alone separates compile time.
The machine's load average is recorded: on the shared machine other work slows every number.

    python benchmarks/durability.py [--duration 60] [--fs 1000] [--paths 256]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import tempfile
import time

import numpy as np

from _common import RESULTS, machine_info


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--fs", type=float, default=1000.0)
    ap.add_argument("--paths", type=int, default=256)
    ap.add_argument("--no-write", action="store_true", help="print only")
    a = ap.parse_args(argv)

    import jax

    jax.config.update("jax_enable_x64", True)
    from jaxdrift.cli import main as cli
    from jaxdrift.durability import monte_carlo_damage, section_forces
    from jaxdrift.io._csvio import DEFAULT_MODEL, read_vehicle_run, write_vehicle_run
    from jaxdrift.studies import make_run

    cols, _ = make_run([{"cause": "force_offset", "channel": "f2", "value": 60.0},
                        {"cause": "force_noise", "value": 15.0}], duration=a.duration, fs=a.fs,
                       speed=20.0, road_class="C", seed=4, channels=("beta",))
    cols["beta"] = cols["beta"] + np.deg2rad(0.01) * np.random.default_rng(1).standard_normal(cols["t"].size)
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "run.csv")
        write_vehicle_run(path, cols["t"], {k: v for k, v in cols.items() if k != "t"})
        t0, c0 = time.perf_counter(), _cpu()
        rc = cli(["durability", path, "--out", os.path.join(tmp, "out"), "--paths", str(a.paths)])
        t_total, c_total = time.perf_counter() - t0, _cpu() - c0
        rep = json.load(open(os.path.join(tmp, "out", "durability.json")))
        run = read_vehicle_run(path)
    assert rc == 0
    # warm: the Monte-Carlo part alone, compiled already by the run above
    res = section_forces(run.t, run["f1"], run["f2"], DEFAULT_MODEL, beta=run["beta"],
                         extended=rep["provenance"]["extended_model"])
    from jaxdrift.diagnosis.vehicle._pipeline import diagnose_vehicle_run

    t0 = time.perf_counter()
    diagnose_vehicle_run(run, DEFAULT_MODEL)
    t_diag = time.perf_counter() - t0
    t0, c0 = time.perf_counter(), _cpu()
    monte_carlo_damage(res["section_forces_fn"], rep["monte_carlo"]["noise_N"], a.paths,
                       variants=["force_driven", "pitch_spring", "stabilised", "extended"], progress=False)
    t_mc_warm, c_mc = time.perf_counter() - t0, _cpu() - c0
    load1 = os.getloadavg()
    result = {
        "benchmark": "jaxdrift durability", "duration_s": a.duration, "fs_hz": a.fs, "paths": a.paths,
        "samples": int(run.n), "total_s": round(t_total, 1), "total_cpu_s": round(c_total, 1),
        "diagnosis_warm_s": round(t_diag, 1), "monte_carlo_warm_s": round(t_mc_warm, 1),
        "monte_carlo_warm_cpu_s": round(c_mc, 1),
        "monte_carlo_warm_path_steps_per_s": round(4 * a.paths * (run.n - 1) / t_mc_warm),
        "load_average_before": load0, "load_average_after": load1,
        "damage_ratio_to_stabilised": rep["damage_ratio_to_stabilised"],
        "damage_ratio_quantiles": rep["monte_carlo"]["damage_ratio_quantiles"],
        "noise_N": rep["monte_carlo"]["noise_N"], "derivative_filter": rep["derivative_filter"]["cutoff_hz"],
        "command": "python benchmarks/durability.py", "machine": machine_info(),
    }
    print(json.dumps({k: v for k, v in result.items() if k != "machine"}, indent=1))
    if not a.no_write:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "durability.json").write_text(json.dumps(result, indent=1))
        md = ["# jaxdrift durability benchmark", "",
              f"{a.duration:g} s at {a.fs:g} Hz ({run.n} samples), {a.paths} Monte-Carlo paths x 4 simulated "
              f"variants; `{result['command']}`; load average before/after {load0[0]:.1f}/{load1[0]:.1f} "
              f"on {os.cpu_count()} cores.", "",
              "| | wall | CPU (all threads) |", "|---|---|---|",
              f"| whole command, cold (read, diagnosis, variants, Monte-Carlo with compilation, outputs) | {t_total:.1f} s | {c_total:.1f} s |",
              f"| diagnosis alone, warm | {t_diag:.1f} s | |",
              f"| Monte-Carlo part alone, warm ({result['monte_carlo_warm_path_steps_per_s']:.3g} path-steps/s) | {t_mc_warm:.1f} s | {c_mc:.1f} s |"]
        (RESULTS / "durability.md").write_text("\n".join(md) + "\n")


if __name__ == "__main__":
    main()
