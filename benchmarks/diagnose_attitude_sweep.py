"""Seeded sweep of the attitude diagnosis over hidden gyro effects.

Each run is drawn from the master seed: sampling rate (100, 200, 400 or 1000 Hz), length 30-150 s,
white gyro noise 1e-4 to 2e-3 rad/sqrt(s) (log-uniform), a reference attitude on every row or
every 10th or 40th row, road roughness and curve rate, and one of: nothing but noise; a bias on one
channel (12 to 90 times ``N / sqrt(T)``, i.e. at least 2.4 times the detection threshold
``5 N / sqrt(T)``); a scale error of 1-5 % on one channel; a bias random walk of 2e-4 to 2e-3
rad/s/sqrt(s) on one channel; a bias and a scale together. The run is written by
``jaxdrift.studies._attgen.make_attitude_run`` and diagnosed by ``run_attitude_diagnosis``.

Scored per run: ``first`` (the true systematic causes, with their channels, are the leading
findings; for a noise-only run the noise finding is first) and, for every true effect and the noise
level, whether the true value lies inside the reported 95 % interval (an effect not reported counts
as a miss). Scale errors are not screened for detectability: a small scale on a slowly turning axis
can lie under the 5-standard-error threshold, and then "not reported" is the right answer; such
runs print a rough signal-to-noise ``|s - 1| rms(rate) sqrt(T) / N`` of the scale error (the
detection threshold is 5 standard errors).

Reproduce::

    python benchmarks/diagnose_attitude_sweep.py --seed 1 --n 30
    python benchmarks/diagnose_attitude_sweep.py --seed 3 --n 30 --effects drift
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

AXES = ("wx", "wy", "wz")


EFFECTS = ("none", "bias", "scale", "drift", "bias+scale")


def draw(rng, effects=EFFECTS):
    """One run's configuration: keyword arguments of make_attitude_run and the true effects."""
    import numpy as np

    rate = float(rng.choice([100.0, 200.0, 400.0, 1000.0]))
    T = float(rng.uniform(30, 150))
    arw = float(np.exp(rng.uniform(np.log(1e-4), np.log(2e-3))))
    ref = ["all", 10, 40][int(rng.integers(3))]
    effect = effects[int(rng.integers(len(effects)))]
    ch = int(rng.integers(3))
    kw = dict(duration=T, rate_hz=rate, arw=arw, reference=ref, road_rms_deg=float(rng.uniform(0.3, 1.5)),
              curve_rate=float(rng.uniform(0.05, 0.3)))
    truth = []
    if effect in ("bias", "bias+scale"):
        b = [0.0, 0.0, 0.0]
        b[ch] = float(12 * arw / np.sqrt(T) * np.exp(rng.uniform(0, 2)) * rng.choice([-1, 1]))
        kw["bias"] = tuple(b)
        truth.append(("gyro_bias", AXES[ch], b[ch]))
    if effect in ("scale", "bias+scale"):
        ch2 = 2 if effect == "bias+scale" and ch != 2 else ch
        s = [1.0, 1.0, 1.0]
        s[ch2] = 1 + float(rng.choice([-1, 1]) * rng.uniform(0.01, 0.05))
        kw["scale"] = tuple(s)
        truth.append(("gyro_scale", AXES[ch2], s[ch2]))
    if effect == "drift":
        r = [0.0, 0.0, 0.0]
        r[ch] = float(np.exp(rng.uniform(np.log(2e-4), np.log(2e-3))))
        kw["rrw"] = tuple(r)
        truth.append(("gyro_bias_drift", AXES[ch], r[ch]))
    return effect, kw, truth


def _inside(f, true):
    import numpy as np

    lo, hi = np.asarray(f["interval"][0], float), np.asarray(f["interval"][1], float)
    return bool(np.all((lo <= np.asarray(true)) & (np.asarray(true) <= hi)))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=1, help="master seed of the draws (default 1)")
    ap.add_argument("--n", type=int, default=30, help="number of runs (default 30)")
    ap.add_argument("--effects", default=",".join(EFFECTS),
                    help=f"comma-separated effects to draw from (default {','.join(EFFECTS)})")
    ap.add_argument("--json", default=None, help="write the per-run results to this JSON file")
    a = ap.parse_args(argv)

    import numpy as np

    from jaxdrift.studies._attgen import make_attitude_run
    from jaxdrift.diagnosis.attitude._diagnose import run_attitude_diagnosis

    effects = tuple(a.effects.split(","))
    if not set(effects) <= set(EFFECTS):
        ap.error(f"--effects: choose from {', '.join(EFFECTS)}")
    rng = np.random.default_rng(a.seed)
    rows, n_first, n_in, n_total = [], 0, 0, 0
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.n):
            effect, kw, truth = draw(rng, effects)
            t0 = time.perf_counter()
            tr = make_attitude_run(tmp, 1000 + 100 * a.seed + r, name=f"r{r}", **kw)
            rep = run_attitude_diagnosis(tr["paths"]["run"], None, None)
            got = [(f["cause"], f.get("channel")) for f in rep["findings"]]
            want = [(c, ch) for c, ch, _ in truth] or [("gyro_noise", None)]
            first = set(got[: len(want)]) == set(want)
            misses = []
            for c, ch, v in truth + [("gyro_noise", None, kw["arw"])]:
                match = [f for f in rep["findings"] if (f["cause"], f.get("channel")) == (c, ch)]
                inside = bool(match) and _inside(match[0], v)
                n_total += 1
                n_in += inside
                if not inside:
                    misses.append(f"{c} {ch or ''}: true {v:.4g}, "
                                  + (f"estimate {match[0]['estimate']:.4g} interval "
                                     f"[{match[0]['interval'][0]:.4g}, {match[0]['interval'][1]:.4g}]" if match
                                     else "not reported"))
            n_first += first
            yaw_rms = float(np.sqrt(np.mean(tr["w_true"][:, 2] ** 2)))
            scale_snr = None
            for c, ch, v in truth:
                if c == "gyro_scale":
                    # rough signal-to-noise of a scale error: |s - 1| rms(rate) sqrt(T) / N
                    w_rms = float(np.sqrt(np.mean(tr["w_true"][:, AXES.index(ch)] ** 2)))
                    scale_snr = abs(v - 1) * w_rms * np.sqrt(kw['duration']) / kw['arw']
                    misses.append(f"scale signal-to-noise about {scale_snr:.1f}")
            line = (f"{r:3d} {effect:10s} {kw['rate_hz']:5.0f} Hz {kw['duration']:5.1f} s N {kw['arw']:.1e} "
                    f"ref {kw['reference']!s:>3} yaw rms {yaw_rms:.3f}: first {'ok' if first else 'NO'} {got[:3]}"
                    + ("; " + "; ".join(misses) if misses else "") + f" ({time.perf_counter() - t0:.1f} s)")
            print(line, flush=True)
            rows.append({"run": r, "effect": effect, "config": {k: v for k, v in kw.items()}, "truth": truth,
                         "findings": got, "first": first, "misses": misses, "yaw_rate_rms": yaw_rms,
                         "scale_snr": scale_snr})
    print(f"\nright causes first: {n_first} of {a.n}; true values inside their 95 % intervals: {n_in} of {n_total}")
    if a.json:
        import datetime as _dt

        from _common import machine_info

        Path(a.json).write_text(json.dumps({"benchmark": "diagnose_attitude_sweep", "args": vars(a),
                                            "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
                                            "machine": machine_info(), "seed": a.seed, "n": a.n, "first": n_first, "inside": n_in,
                                            "total": n_total, "runs": rows}, indent=1, default=str) + "\n")


if __name__ == "__main__":
    main()
