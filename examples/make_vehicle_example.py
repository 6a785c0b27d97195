"""Regenerate the shipped vehicle example: a small measured run with hidden effects, its model,
the diagnosis report and a figure.

    python examples/make_vehicle_example.py

The "measurement" is a virtual one (jaxdrift.studies._rungen: the road-driven half-car on an ISO 8608
class B road with hills, 10 s at 200 Hz, 20 m/s). Hidden in it: the true chassis pitch inertia is
7 % below the model's, the rear force sensor reads 50 N high, and both forces carry white noise of
15 N. The model file is the seed's table. The report is then produced by the command line:

    jaxdrift diagnose examples/vehicle_run.csv --model examples/vehicle_model.json \
        --json examples/vehicle_report.json --plots examples/vehicle_plots
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))

HIDDEN = [
    {"cause": "parameter_error", "parameter": "I", "value": 0.93},
    {"cause": "force_offset", "channel": "f2", "value": 50.0},
    {"cause": "force_noise", "value": 15.0},
]


def main() -> None:
    from jaxdrift.studies import _rungen as rg
    from jaxdrift.io._csvio import DEFAULT_MODEL, write_vehicle_run

    cols, _ = rg.make_run(HIDDEN, duration=10.0, fs=200.0, speed=20.0, road_class="B", seed=4,
                          channels=("beta", "z3"))
    run = os.path.join(HERE, "vehicle_run.csv")
    write_vehicle_run(run, cols["t"], {k: v for k, v in cols.items() if k != "t"})
    model = os.path.join(HERE, "vehicle_model.json")
    with open(model, "w") as fh:
        json.dump(DEFAULT_MODEL, fh, indent=2)
        fh.write("\n")
    with open(os.path.join(HERE, "vehicle_hidden_effects.json"), "w") as fh:
        json.dump(HIDDEN, fh, indent=2)
        fh.write("\n")
    plots = os.path.join(HERE, "vehicle_plots")
    subprocess.run([sys.executable, "-m", "jaxdrift", "diagnose", run, "--model", model,
                    "--json", os.path.join(HERE, "vehicle_report.json"), "--plots", plots],
                   check=True)
    # ship one figure next to the report, drop the rest
    shutil.copy(os.path.join(plots, "enforced_moment.png"), os.path.join(HERE, "vehicle_enforced_moment.png"))
    shutil.copy(os.path.join(plots, "residual_envelope.png"), os.path.join(HERE, "vehicle_residual_envelope.png"))
    shutil.rmtree(plots)


if __name__ == "__main__":
    main()
