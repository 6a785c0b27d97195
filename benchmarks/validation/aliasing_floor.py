"""The force-noise floor of the vehicle diagnosis at a low sampling rate, and what causes it.

For one case of the independent design (``gen_vehicle.design``), made without any effect and
written with 9 digits, prints the force-noise level the diagnosis reads from the residual's low
band (``_Problem.lowband_noise`` at the nominal model) three ways: the run as drawn, the same run
sampled 4x faster, and that faster run decimated back to the drawn rate with an anti-aliasing
filter (scipy ``decimate``, FIR, zero phase). If the floor vanishes after decimation it is aliasing
of force content above the Nyquist frequency, not the pipeline.

    python benchmarks/validation/aliasing_floor.py --seed 31 --index 11   # ~15 s

writes ``benchmarks/results/aliasing-floor.json`` (``--out``; docs/diagnosis.md quotes it).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import sys
import tempfile

import numpy as np
import scipy.signal

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))  # run as a script: the repository root

from benchmarks._common import RESULTS, machine_info  # noqa: E402
from benchmarks.validation import gen_vehicle as gv, sweep  # noqa: E402



def lowband_sigma(full: dict, decim: int | None = None) -> tuple[float, float]:
    import jaxdrift
    from jaxdrift.diagnosis.vehicle._problem import _gauss_newton, _Problem
    from jaxdrift.diagnosis.vehicle._residuals import ResidualPipeline
    from jaxdrift.io._csvio import VehicleRun

    with tempfile.TemporaryDirectory() as d:
        paths = gv.make_run(full, d)
        run = jaxdrift.read_vehicle_run(paths["csv"])
        model = jaxdrift.read_model(paths["model"])
    if decim:
        cols = {k: scipy.signal.decimate(v, decim, ftype="fir", zero_phase=True) for k, v in run.channels.items()}
        run = VehicleRun(path=run.path, t=run.t[::decim][:len(cols["f1"])], channels=cols)
    prob = _Problem(ResidualPipeline(run), model)
    return prob.lowband_noise(_gauss_newton(prob, [], []).r)[0], 1.0 / run.dt


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=31, help="design seed (default 31)")
    ap.add_argument("--index", type=int, default=11, help="case index in the design (default 11)")
    ap.add_argument("--n", type=int, default=80, help="design size the case comes from (default 80)")
    ap.add_argument("--out", default=str(RESULTS / "aliasing-floor.json"), help="JSON result file")
    a = ap.parse_args(argv)
    case = next(c for c in gv.design(a.n, a.seed) if c["index"] == a.index)
    full = dict(gv.make_case(case, **sweep.SIZING["vehicle"]), effects=[], motion_noise={}, precision=9)
    print(f"case {a.index} of seed {a.seed}: {full['road_class']} road, {full['speed']:.1f} m/s, "
          f"{full['fs']:.0f} Hz, {full['duration']} s, channels {full['channel_set']}; no effect, no noise")
    res = {"benchmark": "aliasing_floor", "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
           "design_seed": a.seed, "index": a.index, "design_n": a.n,
           "case": {k: full[k] for k in ("road_class", "speed", "fs", "duration", "channel_set", "vehicle_kind")}}
    s, fs = lowband_sigma(full)
    res["as_drawn"] = {"fs_hz": fs, "lowband_sigma_N": s}
    print(f"as drawn ({fs:.0f} Hz): low-band force-noise level {s:.4g} N")
    fast = dict(full, fs=4 * full["fs"])
    s, fs = lowband_sigma(fast)
    res["fast"] = {"fs_hz": fs, "lowband_sigma_N": s}
    print(f"sampled 4x faster ({fs:.0f} Hz): {s:.4g} N")
    s, fs = lowband_sigma(fast, decim=4)
    res["decimated"] = {"fs_hz": fs, "lowband_sigma_N": s}
    print(f"4x faster, anti-aliased and decimated back ({fs:.0f} Hz): {s:.4g} N")
    res["machine"] = machine_info()
    with open(a.out, "w") as fh:
        json.dump(res, fh, indent=2)
        fh.write("\n")
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
