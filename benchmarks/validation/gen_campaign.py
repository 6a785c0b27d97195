"""Independent generator of a test campaign: many runs of ONE vehicle (validation of ``jaxdrift
campaign``).

Built on ``gen_vehicle.py`` (its half-car, road, integrator and file writer; nothing from
jaxdrift). One nominal vehicle is drawn and one set of shared parameter errors (the vehicle's, the
same in every run); each run has its own road class, speed, sample rate, duration, channel set,
force noise and optional sensor noise on the motion. Sensor effects (an offset, a scale or a delay
on f1 or f2) belong to a logger: runs on the same logger share its effect; some loggers carry none.

``python gen_campaign.py --n 40 --seed S --out DIR`` writes ``DIR/run_NNN.csv`` (+ ``_model.json``,
``_truth.json`` as ``gen_vehicle.py`` writes them), ``DIR/model.json`` (the nominal vehicle given
to the campaign), ``DIR/campaign.toml`` (the manifest: runs, logger ids, repetitions) and
``DIR/truth.json`` (the shared parameter errors and every logger's effect).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))  # run as a script: the repository root
from benchmarks.validation import gen_vehicle as gv  # noqa: E402

#: sensor effects a logger may carry
SENSOR = [(c, ch) for c in ("force_offset", "force_scale", "force_delay") for ch in ("f1", "f2")]
#: channel sets of a campaign's runs (the motion the logger records varies from run to run)
CAMPAIGN_CHANNELS = ("beta", "beta_z3", "beta_s", "beta_z3_s", "beta_rate", "all")


def draw_campaign(n: int, seed: int, *, n_shared: int = 2, durations=(5.0, 10.0),
                  rates=(200, 250, 300, 400, 500), effect_free: float = 0.3, params=None,
                  motion_noise_share: float = 0.3) -> dict:
    """The campaign's design: the vehicle, its shared errors, the loggers and the runs' cases.
    ``params``: the parameters with shared errors (default: ``n_shared`` drawn from ``PARAMS``);
    ``motion_noise_share``: the probability that a run's motion channels carry sensor noise."""
    rng = np.random.default_rng(seed)
    vkind = str(rng.choice(sorted(gv.VEHICLES)))
    nominal = {k: float(v * rng.uniform(0.9, 1.1)) for k, v in gv.VEHICLES[vkind].items()}
    nominal["g"] = gv.G
    drawn = [str(p) for p in rng.choice(gv.PARAMS, size=n_shared, replace=False)]
    params = list(params) if params is not None else drawn
    # moderate errors: a single run names some of them, not all, with wide intervals
    shared = [{"cause": "parameter_error", "parameter": p,
               "value": 1.0 + float(rng.choice([-1.0, 1.0])) * gv._loguniform(rng, 0.02, 0.08)} for p in params]
    # loggers: each run picks one; about a third of the loggers are used by two or three runs
    loggers = []
    while sum(lg["runs"] for lg in loggers) < n:
        k = int(rng.choice([1, 1, 2, 3]))
        k = min(k, n - sum(lg["runs"] for lg in loggers))
        lid = f"L{len(loggers):02d}"
        if rng.random() < effect_free:
            effect = None
        else:
            c, ch = SENSOR[int(rng.integers(len(SENSOR)))]
            effect = gv.draw_effect(rng, c, ch, nominal)
        loggers.append({"id": lid, "runs": k, "effect": effect})
    owner = [lg for lg in loggers for _ in range(lg["runs"])]
    rng.shuffle(owner)
    cases = []
    for i in range(n):
        cls = str(rng.choice(list(gv.ISO_GD0)))
        chan = str(rng.choice(CAMPAIGN_CHANNELS))
        effects = [dict(e) for e in shared]
        if owner[i]["effect"] is not None:
            effects.append(dict(owner[i]["effect"]))
        load = nominal["m3"] * gv.G / 2
        effects.append({"cause": "force_noise", "value": load * gv._loguniform(rng, 1e-4, 1e-3)})
        motion_noise = {}
        if rng.random() < motion_noise_share:
            lvl = gv._loguniform(rng, 1.0, 10.0)
            for c in gv.CHANNEL_SETS[chan]:
                motion_noise[c] = lvl * {"beta": 3e-6, "z3": 3e-6, "s1": 3e-6, "s2": 3e-6, "beta_rate": 3e-5}[c]
        cases.append({
            "index": i, "stratum": "campaign", "what": [], "seed": int(rng.integers(2**31)),
            "vehicle_kind": vkind, "model": nominal, "road_class": cls,
            "speed": float(rng.uniform(*gv.SPEEDS[cls])), "fs": float(rng.choice(rates)),
            "duration": float(round(rng.uniform(*durations), 1)), "channel_set": chan,
            "channels": list(gv.CHANNEL_SETS[chan]), "precision": int(rng.integers(7, 10)),
            "t0": 0.0, "lead_in": float(rng.uniform(0.0, 0.5)), "effects": effects,
            "motion_noise": motion_noise, "column_order_seed": int(rng.integers(2**31)),
            "road_seed": int(rng.integers(2**31)), "noise_seed": int(rng.integers(2**31)),
            "logger": owner[i]["id"], "repetitions": int(rng.integers(1, 6)),
        })
    return {"schema": "independent.campaign/1", "seed": seed, "vehicle_kind": vkind, "model": nominal,
            "shared": shared, "loggers": loggers, "cases": cases}


def write_campaign(design: dict, out: str, *, progress: bool = True) -> list[str]:
    os.makedirs(out, exist_ok=True)
    names = []
    for case in design["cases"]:
        name = f"run_{case['index']:03d}"
        cols, _ = gv.generate(case)
        gv.write_run(out, name, case, cols)
        names.append(name)
        if progress:
            print(os.path.join(out, name + ".csv"), flush=True)
    with open(os.path.join(out, "model.json"), "w") as fh:
        json.dump({k: design["model"][k] for k in gv.KEYS}, fh, indent=1)
    lines = ["# campaign manifest (jaxdrift campaign --manifest): one [[run]] table per run",
             'model = "model.json"', ""]
    for name, case in zip(names, design["cases"]):
        lines += ["[[run]]", f'file = "{name}.csv"', f'logger = "{case["logger"]}"',
                  f"repetitions = {case['repetitions']}", ""]
    with open(os.path.join(out, "campaign.toml"), "w") as fh:
        fh.write("\n".join(lines))
    with open(os.path.join(out, "truth.json"), "w") as fh:
        json.dump(design, fh, indent=1)
    return names


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--shared", type=int, default=2, help="number of shared parameter errors")
    ap.add_argument("--durations", type=float, nargs=2, default=(5.0, 10.0))
    ap.add_argument("--rates", type=float, nargs="+", default=(200, 250, 300, 400, 500))
    a = ap.parse_args(argv)
    d = draw_campaign(a.n, a.seed, n_shared=a.shared, durations=tuple(a.durations), rates=tuple(a.rates))
    write_campaign(d, a.out)
    print("shared:", ", ".join(f"{e['parameter']} x{e['value']:.4f}" for e in d["shared"]))


if __name__ == "__main__":
    main()
