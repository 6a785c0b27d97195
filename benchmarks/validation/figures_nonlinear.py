"""Figures of docs/diagnosis.md, "Nonlinear suspension": what each nonlinear effect leaves in the
residuals of the linear model (one figure each, committed as docs/figures/nonlinear_*.png).

One run of the independent generator per effect (passenger car, ISO class C road at 15 m/s, 500 Hz,
8 s, pitch, heave and both spring travels measured, no noise), compared with the linear model it is
given: the rear spring force residual (model spring force driven by the measured wheel force against
``k s + d s'`` of the measured travel) against the state it depends on; for tyre lift-off the
measured front wheel force and its histogram. ``python benchmarks/validation/figures_nonlinear.py
[--out docs/figures]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))  # run as a script: the repository root

from benchmarks.validation import gen_vehicle as gen  # noqa: E402

EFFECTS = {
    "damper_asymmetry": {"cause": "damper_asymmetry", "parameter": "d4", "value": 1.5},
    "progressive_spring": {"cause": "progressive_spring", "parameter": "k4", "stiffening": 0.6},
    "bump_stop": {"cause": "bump_stop", "parameter": "k4", "share": 0.03, "ratio": 6.0},
    "tyre_lift_off": {"cause": "tyre_lift_off", "channel": "f1", "share": 0.03},
}


def _case(effect: dict) -> dict:
    model = {k: float(v) for k, v in gen.VEHICLES["passenger"].items()}
    model["g"] = gen.G
    return {"index": 0, "stratum": "single", "what": [], "seed": 1, "vehicle_kind": "passenger",
            "model": model, "road_class": "C", "speed": 15.0, "fs": 500.0, "duration": 8.0,
            "channel_set": "beta_z3_s", "channels": list(gen.CHANNEL_SETS["beta_z3_s"]), "precision": 9,
            "t0": 0.0, "lead_in": 0.2, "effects": [dict(effect)], "motion_noise": {},
            "column_order_seed": 1, "road_seed": 20240, "noise_seed": 2}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(HERE.parents[1] / "docs" / "figures"))
    a = ap.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import jaxdrift
    from jaxdrift.diagnosis.vehicle._causes import FORCE_CHANNELS
    from jaxdrift.diagnosis.vehicle._nonlinear import model_states
    from jaxdrift.diagnosis.vehicle._residuals import ResidualPipeline

    os.makedirs(a.out, exist_ok=True)
    tmp = tempfile.mkdtemp()
    for name, eff in EFFECTS.items():
        case = _case(eff)
        paths = gen.make_run(case, tmp, name)
        run = jaxdrift.read_vehicle_run(paths["csv"])
        model = jaxdrift.read_model(paths["model"])
        fig, ax = plt.subplots(1, 2, figsize=(9, 3.4))
        if name == "tyre_lift_off":
            t = run.t - run.t[0]
            ax[0].plot(t, run["f1"], lw=0.6)
            ax[0].axhline(0.0, color="k", lw=0.5)
            ax[0].set(xlabel="t [s]", ylabel="measured f1 [N]", title="front wheel force: flat at zero in the air")
            ax[1].hist(run["f1"], bins=120, color="C1")
            ax[1].set(xlabel="f1 [N]", ylabel="samples", title="an atom of samples at the floor")
        else:
            pipe = ResidualPipeline(run)
            from jaxdrift.io._corrections import NO_CORRECTION as zero
            r = pipe.residuals(model, zero).channels["spring2"]
            st = model_states(pipe, model, zero)
            n = len(r) - pipe.trim
            u, v = st.u[1][::pipe.U][:n], st.v[1][::pipe.U][:n]
            r = r[:n]
            x, lab = (v, "rear damper velocity s2' [m/s] (compression > 0)") if name == "damper_asymmetry" else \
                (1e3 * u, "rear spring travel from static u2 [mm] (compression > 0)")
            ax[0].plot(run.t[:n] - run.t[0], r, lw=0.6)
            ax[0].set(xlabel="t [s]", ylabel="rear spring force residual [N]", title=f"{name}: residual of the linear model")
            ax[1].plot(x, r, ".", ms=1.5, alpha=0.5)
            ax[1].set(xlabel=lab, ylabel="residual [N]", title="against the state it depends on")
        fig.tight_layout()
        fig.savefig(os.path.join(a.out, f"nonlinear_{name}.png"), dpi=110)
        plt.close(fig)
        print(os.path.join(a.out, f"nonlinear_{name}.png"), flush=True)


if __name__ == "__main__":
    main()
