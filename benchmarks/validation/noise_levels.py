"""The vehicle diagnosis' force-noise numbers on design cases of the independent generator.

For each case: the true force-noise level (0 for runs without noise), the sampling rate, road,
speed, channel set, whether motion noise was added, and what the diagnosis read: the residual's
low-band level after the fit (``sigma``), the forces' 4th-difference level (``hf``), whether the
level was reported, and the first finding. This is how the reporting rules for small levels in
docs/diagnosis.md ("Noise level") were measured, e.g. the low band of runs without noise at
500-2000 Hz:

    python benchmarks/validation/noise_levels.py --seed 777 --out /tmp/levels.jsonl \\
        --fs-min 300 --fs-max 600 --noise-free
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))  # run as a script: the repository root
from benchmarks.validation import gen_vehicle as gv, sweep  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, required=True, help="design seed (not the committed one)")
    ap.add_argument("--n", type=int, default=200, help="design size (default 200)")
    ap.add_argument("--out", required=True, help="JSON-lines file, appended to")
    ap.add_argument("--index", type=int, nargs="*", help="only these cases")
    ap.add_argument("--fs-min", type=float, default=0.0)
    ap.add_argument("--fs-max", type=float, default=1e9)
    ap.add_argument("--noise-free", action="store_true", help="only cases without force noise")
    ap.add_argument("--no-motion-noise", action="store_true", help="only cases without motion noise")
    a = ap.parse_args(argv)

    import jaxdrift
    from jaxdrift.diagnosis.vehicle import _pipeline, _report
    from jaxdrift.diagnosis.vehicle._detectors import _force_hf_noise

    rec = {}
    orig = _report.noise_level

    def recording(prob, sel, corr, p):
        o = orig(prob, sel, corr, p)
        rec.update(sigma_reported=o["sigma"], lo=o["lo"], hi=o["hi"], found=o["found"],
                   hf=_force_hf_noise(prob.pipe.run)[0], motion_band=bool(prob.pipe.band),
                   lowband=prob.lowband_noise(sel.fit.r)[0] if len(sel.fit.r) > 2 else None)
        return o

    _pipeline.noise_level = recording
    for case in gv.design(a.n, a.seed):
        if a.index and case["index"] not in a.index:
            continue
        full = gv.make_case(case, **sweep.SIZING["vehicle"])
        truth = next((e["value"] for e in full["effects"] if e["cause"] == "force_noise"), 0.0)
        if not (a.fs_min <= full["fs"] <= a.fs_max) or (a.noise_free and truth > 0) or \
                (a.no_motion_noise and full["motion_noise"]):
            continue
        d = tempfile.mkdtemp(prefix="noise-levels-")
        try:
            paths = gv.make_run(full, d)
            run = jaxdrift.read_vehicle_run(paths["csv"])
            rec.clear()
            rep = jaxdrift.diagnose_vehicle_run(run, jaxdrift.read_model(paths["model"]),
                                                with_simulation=False)
        finally:
            shutil.rmtree(d, ignore_errors=True)
        row = dict(seed=a.seed, index=case["index"], truth=truth, fs=full["fs"],
                   road=full["road_class"], speed=full["speed"], vehicle=full["vehicle_kind"],
                   channels=full["channel_set"], precision=full["precision"],
                   motion_noise=bool(full["motion_noise"]), first=rep["findings"][0]["cause"], **rec)
        with open(a.out, "a") as fh:
            fh.write(json.dumps(row) + "\n")
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
