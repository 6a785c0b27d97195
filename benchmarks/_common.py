"""Shared helpers of the benchmark scripts: machine/version record, timing, JSON + markdown output."""

from __future__ import annotations

import json
import os
import platform
import resource
import time
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def machine_info() -> dict:
    import jax
    import jaxlib
    import numpy

    info = {
        "python": platform.python_version(),
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "jax": jax.__version__,
        "jaxlib": jaxlib.__version__,
        "numpy": numpy.__version__,
        "devices": [str(d) for d in jax.devices()],
        "x64": bool(jax.config.jax_enable_x64),
    }
    for mod in ("diffrax", "equinox", "scipy"):
        try:
            info[mod] = __import__(mod).__version__
        except ImportError:
            pass
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    info["cpu_model"] = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return info


def timed(fn, *args, repeat: int = 3):
    """(first call seconds incl. compile, best of ``repeat`` further calls, result)."""
    import jax

    t = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    first = time.perf_counter() - t
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        best = min(best, time.perf_counter() - t)
    return first, best, out


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def write_results(name: str, payload: dict, table_md: str) -> tuple[Path, Path]:
    RESULTS.mkdir(parents=True, exist_ok=True)
    jp = RESULTS / f"{name}.json"
    mp = RESULTS / f"{name}.md"
    jp.write_text(json.dumps(payload, indent=2, default=float) + "\n")
    mp.write_text(table_md)
    return jp, mp


def timing_parser(doc: str, *, out: str, seconds: float, paths: int = 256, rounds: int = 3):
    """argparse parser with the options every interleaved-timing script shares."""
    import argparse

    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--paths", type=int, default=paths, help=f"paths per call (default {paths})")
    ap.add_argument("--seconds", type=float, default=seconds, help=f"simulated seconds (default {seconds:g})")
    ap.add_argument("--rounds", type=int, default=rounds, help=f"interleaved timing rounds (default {rounds})")
    ap.add_argument("--out", default=out, help=f"result name under benchmarks/results/ (default {out})")
    return ap


def interleaved_best(fns: dict, idx, rounds: int):
    """Compile every ``fns[k](idx)``, then time them in interleaved rounds on fresh path indices.

    A change of load hits every case alike; each keeps its best round. Returns ``(best seconds,
    outputs of the last round)`` keyed like ``fns``.
    """
    import jax

    for k, f in fns.items():
        print(f"compiling {k} ...", flush=True)
        jax.block_until_ready(f(idx))
    best, outs = {k: float("inf") for k in fns}, {}
    for r in range(rounds):
        idx_r = idx + (r + 1) * idx.shape[0]
        for k, f in fns.items():
            t = time.perf_counter()
            outs[k] = jax.block_until_ready(f(idx_r))
            best[k] = min(best[k], time.perf_counter() - t)
        print(f"round {r + 1}: " + ", ".join(f"{k} {best[k]:.2f} s" for k in fns), flush=True)
    return best, outs
