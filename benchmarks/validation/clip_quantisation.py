"""Does ``force_clipping`` tell a clip from a coarsely printed peak? Every force channel of the
runs given (clipped ones named ``clipped*.csv``, the others without clipping) is rounded to steps
of 0 (as written), 1, 10, 50 and 100 N and read by the detector alone; printed per step: false
alarms on the unclipped channels, clips found on the clipped runs' clipped channel.

    python benchmarks/validation/clip_quantisation.py RUN.csv ...
"""

from __future__ import annotations

import argparse
import json
import os

import numpy as np


def main(argv=None):
    import jaxdrift
    from jaxdrift.diagnosis.vehicle._nonlinear import ForceClipping

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+")
    a = ap.parse_args(argv)
    runs = []
    for p in a.runs:
        r = jaxdrift.read_vehicle_run(p)
        clipped = None
        truth = p.replace(".csv", "_truth.json")
        if os.path.exists(truth):
            with open(truth) as fh:
                clipped = next((e["channel"] for e in json.load(fh)["effects"] if e["cause"] == "force_clipping"), None)
        runs.append((r, clipped))
    for q in (0.0, 1.0, 10.0, 50.0, 100.0):
        false, n_free, found, n_clip = 0, 0, 0, 0
        for r, clipped in runs:
            for ch in ("f1", "f2"):
                x = r[ch] if q == 0 else np.round(r[ch] / q) * q
                hit = ForceClipping(ch).detect(x, 1.0) is not None
                if ch == clipped:
                    n_clip, found = n_clip + 1, found + hit
                else:
                    n_free, false = n_free + 1, false + hit
        print(f"steps of {q:g} N: false alarms {false}/{n_free} channels, clips found {found}/{n_clip}")


if __name__ == "__main__":
    main()
