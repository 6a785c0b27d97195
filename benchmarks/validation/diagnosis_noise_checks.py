"""Three measurements behind docs/diagnosis.md's force-noise rules, each against something independent.

1. ``envelope``: the re-simulation gate's dynamic-band noise envelope
   (``_extend.noise_pitch_dynamic_rms``, a frequency-domain integral of the linearised model's
   response) against a Monte-Carlo of the same quantity: white unit force samples on both forces,
   held over each interval (scipy ``cont2discrete``, zero-order hold; ``dlsim``), the pitch
   high-passed by the report's own ``_dynamic_rms``; on the seed's car (``examples/vehicle_model.json``)
   at 500 Hz, ``--records`` records of ``--samples`` samples.
2. ``white_orders``: how far apart white noise's levels read from its 4th, 6th and 8th differences
   (the rule that decides estimate or upper bound) on records of 5000 samples.
3. ``independent_run``: the same three levels on the forces of one independent run
   (``benchmarks/validation/gen_vehicle.py``: the first case of the design drawn at 500 Hz, with no
   effect but 2 N of white force noise): real force content reads less at each higher order.

    python benchmarks/validation/diagnosis_noise_checks.py            # ~40 s; writes benchmarks/results/diagnosis-noise-checks.json
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import sys
import time

import numpy as np
import scipy.signal

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))  # run as a script: the repository root

from benchmarks._common import RESULTS, machine_info  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def envelope(records: int, samples: int, fs: float, seed: int) -> dict:
    import jaxdrift
    from jaxdrift.diagnosis.vehicle._extend import _dynamic_rms, _linear_force_system, noise_pitch_dynamic_rms

    p = jaxdrift.read_model(os.path.join(ROOT, "examples", "vehicle_model.json"))
    h = 1.0 / fs
    analytic = noise_pitch_dynamic_rms(p, h)
    A, B = _linear_force_system(p)
    C = np.zeros((1, 8))
    C[0, 3] = 1.0
    Ad, Bd, Cd, Dd, _ = scipy.signal.cont2discrete((A, B, C, np.zeros((1, 2))), h, method="zoh")
    rng = np.random.default_rng(seed)
    rms = []
    for _ in range(records):
        u = rng.standard_normal((samples, 2))
        _, y, _ = scipy.signal.dlsim((Ad, Bd, Cd, Dd, h), u)
        # the response to sample k shows from sample k+1 on (the sample is held over its interval)
        rms.append(_dynamic_rms(y[:, 0], h))
    rms = np.asarray(rms)
    mc = float(np.sqrt(np.mean(rms ** 2)))
    se = float(np.std(rms, ddof=1) / np.sqrt(records))
    return {"model": "examples/vehicle_model.json", "fs_hz": fs, "records": records, "samples": samples,
            "seed": seed, "analytic_per_N": analytic, "monte_carlo_per_N": mc, "monte_carlo_se_per_N": se,
            "record_rms_per_N": rms.tolist(), "relative_difference": analytic / mc - 1.0}


def _levels(x: np.ndarray) -> list[float]:
    from jaxdrift.diagnosis.vehicle._detectors import WHITE_ORDERS, _diff_sigma

    return [_diff_sigma(x, k) for k in WHITE_ORDERS]


def white_orders(n: int, draws: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    spread = []
    for _ in range(draws):
        lv = _levels(rng.standard_normal(n))
        spread.append(max(lv) / min(lv) - 1.0)
    spread = np.sort(spread)
    return {"samples": n, "draws": draws, "seed": seed, "max_over_min_minus_1_median": float(np.median(spread)),
            "max_over_min_minus_1_q95": float(np.quantile(spread, 0.95)),
            "max_over_min_minus_1_max": float(spread[-1])}


def independent_run(design_seed: int, noise: float, fs: float) -> dict:
    from benchmarks.validation import gen_vehicle as gv, sweep

    from jaxdrift.diagnosis.vehicle._detectors import WHITE_ORDERS

    for c in gv.design(200, design_seed):
        case = gv.make_case(c, **sweep.SIZING["vehicle"])
        if case["fs"] == fs:
            break
    else:
        raise SystemExit(f"no case at {fs} Hz in design seed {design_seed}")
    case = dict(case, effects=[{"cause": "force_noise", "value": noise}], motion_noise={})
    cols, _ = gv.generate(case)
    out = {"design_seed": design_seed, "index": case["index"], "vehicle_kind": case["vehicle_kind"],
           "road_class": case["road_class"], "speed_m_s": case["speed"], "fs_hz": case["fs"],
           "duration_s": case["duration"], "force_noise_N": noise, "orders": list(WHITE_ORDERS)}
    for ch in ("f1", "f2"):
        out[ch] = _levels(cols[ch])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("--records", type=int, default=16, help="Monte-Carlo records of the envelope check (default 16)")
    ap.add_argument("--samples", type=int, default=150000, help="samples per record (default 150000: 300 s at 500 Hz)")
    ap.add_argument("--seed", type=int, default=8117, help="noise seed of the Monte-Carlo checks (default 8117)")
    ap.add_argument("--design-seed", type=int, default=8117, help="independent design seed (default 8117)")
    ap.add_argument("--out", default=str(RESULTS / "diagnosis-noise-checks.json"))
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    res = {"benchmark": "diagnosis_noise_checks", "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
           "machine": machine_info(), "load_average_at_start": list(os.getloadavg())}
    res["envelope"] = envelope(a.records, a.samples, 500.0, a.seed)
    e = res["envelope"]
    print(f"envelope: analytic {e['analytic_per_N']:.4g} per N, Monte-Carlo {e['monte_carlo_per_N']:.4g} "
          f"+- {e['monte_carlo_se_per_N']:.2g} ({e['relative_difference']:+.2%})")
    res["white_orders"] = white_orders(5000, 400, a.seed + 1)
    w = res["white_orders"]
    print(f"white noise, 5000 samples: orders 4/6/8 apart by {w['max_over_min_minus_1_median']:.1%} (median), "
          f"{w['max_over_min_minus_1_q95']:.1%} (95th percentile)")
    res["independent_run"] = independent_run(a.design_seed, 2.0, 500.0)
    r = res["independent_run"]
    print(f"independent run {r['index']} (seed {r['design_seed']}, {r['fs_hz']:.0f} Hz, 2 N): f1 {r['f1']}, f2 {r['f2']}")
    res["wall_s"] = time.perf_counter() - t0
    with open(a.out, "w") as fh:
        json.dump(res, fh, indent=2)
        fh.write("\n")
    print(f"wrote {a.out} ({res['wall_s']:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
