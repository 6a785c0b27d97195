"""Attitude reports of generated runs and of the three real corpora, for a report-equality check.

    python benchmarks/validation/attitude_equality_runs.py OUT [--generated DIR]
    python benchmarks/validation/report_equality.py compare OLD NEW --json eq.json

The generated runs (``--generated``, default ``/tmp/eq/genatt``) are ``gen_attitude.make_run`` of
``design(16, 20261301)`` with the sweep's sizing, written there first if the folder is empty; the
recordings come from ``tests/data/{real,heldout,heldout2}/SOURCES.toml`` (the files not committed
are fetched as the README beside each says; missing ones are skipped and said). Each run goes
through ``jaxdrift diagnose`` (the jaxdrift on ``PYTHONPATH`` or installed) with the reader's
``--map``, again with ``--force`` where it is refused.
"""

from __future__ import annotations

import argparse
import glob
import os
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))


def _generate(folder: str) -> None:
    from benchmarks.validation import gen_attitude, sweep

    os.makedirs(folder, exist_ok=True)
    if glob.glob(os.path.join(folder, "*.csv")):
        return
    for c in gen_attitude.design(16, 20261301):
        full = gen_attitude.make_case(c, **sweep.SIZING["attitude"])
        gen_attitude.make_run(full, folder, name=f"a{c['index']:02d}")


def _diagnose(out: str, name: str, args: list[str]) -> None:
    from jaxdrift.cli import main

    js = os.path.join(out, name + ".json")
    rc = None
    for force in (False, True):
        try:
            rc = main(["-q", "diagnose", *args, "--json", js] + (["--force"] if force else []))
        except SystemExit as e:
            rc = e.code
        if rc != 2:
            break
    print(name, rc, flush=True)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out")
    ap.add_argument("--generated", default="/tmp/eq/genatt")
    a = ap.parse_args(argv)
    from benchmarks.validation import real_corpus

    os.makedirs(a.out, exist_ok=True)
    _generate(a.generated)
    for f in sorted(glob.glob(os.path.join(a.generated, "*.csv"))):
        sensors = f[:-4] + "_sensors.json"
        _diagnose(a.out, "gen_" + Path(f).stem, [f] + (["--sensors", sensors] if os.path.exists(sensors) else []))
    for sub in ("real", "heldout", "heldout2"):
        src = ROOT / "tests" / "data" / sub / "SOURCES.toml"
        if not src.exists():
            continue
        for e in tomllib.loads(src.read_text())["log"]:
            p = ROOT / e["file"]
            if not p.exists():
                print("missing", p)
                continue
            _diagnose(a.out, f"{sub}_{p.stem}", [str(p)] + real_corpus.jaxdrift_args(e))


if __name__ == "__main__":
    main()
