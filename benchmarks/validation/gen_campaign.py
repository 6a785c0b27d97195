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
                  motion_noise_share: float = 0.3, nonlinear=0, road_classes=None) -> dict:
    """The campaign's design: the vehicle, its shared errors, the loggers and the runs' cases.
    ``params``: the parameters with shared errors (default: ``n_shared`` drawn from ``PARAMS``);
    ``motion_noise_share``: the probability that a run's motion channels carry sensor noise;
    ``nonlinear``: how many shared nonlinear suspension causes the vehicle has (0-2, one per axle;
    :func:`draw_nonlinear`), or their list of (cause, parameter); ``road_classes``: the classes the runs' roads are drawn from."""
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
        cls = str(rng.choice(list(road_classes or gv.ISO_GD0)))
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
    design = {"schema": "independent.campaign/1", "seed": seed, "vehicle_kind": vkind, "model": nominal,
              "shared": shared, "loggers": loggers, "cases": cases}
    if nonlinear:
        draw_nonlinear(design, nonlinear, np.random.default_rng([seed, 7]))
    return design


#: the shared nonlinear causes a campaign's vehicle may have (one per axle)
NONLINEAR = [("bump_stop", "k3"), ("bump_stop", "k4"), ("damper_asymmetry", "d3"), ("damper_asymmetry", "d4"),
             ("progressive_spring", "k3"), ("progressive_spring", "k4")]


def _linear_travel(case: dict) -> list:
    """Each axle's spring travel from its static value in the run's linear pre-run (the true
    vehicle with the shared parameter errors, on the run's road)."""
    p = gv.true_vehicle(case)
    v, T = case["speed"], case["duration"]
    x0 = -v * case["lead_in"]
    road = gv.FilteredRoad(np.random.default_rng(case["road_seed"]), case["road_class"], x0 + v * (T + 0.1) + 1.0,
                           interp=case.get("road_interp", "spline7"))
    tau = np.arange(int(round(T * case["fs"])) + 1) / case["fs"]
    sig = gv.signals(p, road, v, x0, gv.simulate(p, road, v, x0, T + 1e-9), tau)
    L, g = p["a"] + p["b"], p["g"]
    s0 = (p["m3"] * g * p["a"] / L / p["k3"], p["m3"] * g * p["b"] / L / p["k4"])
    return [sig["s1"] - s0[0], sig["s2"] - s0[1]]


def draw_nonlinear(design: dict, n, rng) -> list[dict]:
    """Give the campaign's vehicle ``n`` nonlinear suspension causes (on different axles), the same
    law in every run: a bump stop at a fixed travel (set so that about 40 % of the runs reach it on
    1-4 % of their samples or more, the others less or never), 3-10x the spring; a progressive
    spring 20-100 % stiffer at the median run's 99th-percentile travel; a damper with a
    rebound/compression ratio of 1.15-1.6 or its inverse. Sized on the runs' linear pre-runs;
    added to every case's effects and to ``design["shared"]``. ``n``: a count, or the list of
    (cause, parameter) to give it."""
    travel = [_linear_travel(c) for c in design["cases"]]
    axles, out = [], []
    chosen = list(n) if not isinstance(n, int) else [None] * n
    for pick in chosen:
        opts = [x for x in NONLINEAR if int(x[1][1]) - 3 not in axles]
        cause, par = tuple(pick) if pick is not None else opts[int(rng.integers(len(opts)))]
        i = int(par[1]) - 3
        axles.append(i)
        k = design["model"][f"k{i + 3}"] * next((e["value"] for e in design["shared"]
                                                 if e.get("parameter") == f"k{i + 3}"), 1.0)
        if cause == "bump_stop":
            share = float(rng.uniform(0.01, 0.04))
            ub = float(np.quantile([np.quantile(u[i], 1.0 - share) for u in travel], 0.6))
            e = {"cause": cause, "parameter": par, "fixed": True, "ratio": float(rng.uniform(3.0, 10.0)),
                 "travel": ub}
            e["value"] = e["ratio"] * k
        elif cause == "progressive_spring":
            u99 = float(np.median([np.quantile(np.abs(u[i]), 0.99) for u in travel]))
            e = {"cause": cause, "parameter": par, "fixed": True, "stiffening": float(rng.uniform(0.2, 1.0)),
                 "travel_99": u99}
            e["value"] = e["stiffening"] / (3.0 * u99 * u99)
        else:
            e = {"cause": cause, "parameter": par, "fixed": True,
                 "value": float(gv._loguniform(rng, 1.15, 1.6) ** rng.choice([-1.0, 1.0]))}
        out.append(e)
    for c in design["cases"]:
        c["effects"] = [dict(e) for e in out] + c["effects"]
    design["shared"] = design["shared"] + out
    return out


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
    ap.add_argument("--nonlinear", type=int, default=0, choices=(0, 1, 2),
                    help="number of shared nonlinear suspension causes (one per axle)")
    a = ap.parse_args(argv)
    d = draw_campaign(a.n, a.seed, n_shared=a.shared, durations=tuple(a.durations), rates=tuple(a.rates),
                      nonlinear=a.nonlinear)
    write_campaign(d, a.out)
    print("shared:", ", ".join(f"{e['cause']}[{e['parameter']}] {e['value']:.5g}" for e in d["shared"]))


if __name__ == "__main__":
    main()
