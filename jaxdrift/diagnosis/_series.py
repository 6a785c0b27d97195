"""``jaxdrift diagnose --series``: the signals behind a vehicle report on the run's time base.

Columns: ``t``; the measured channels as read (SI); ``f1_corrected, f2_corrected``, the true-force
estimate of the report's ``extended_model.corrections`` (``(measured(t + delay) - offset) /
scale``, linear interpolation between samples, the end value held beyond the run); ``sim_z1,
sim_z2, sim_z3, sim_beta``, the force-driven model (A.3) with the given model and the measured
forces; ``ext_z1 .. ext_beta``, the same with the extended model's parameters, its confirmed
nonlinear suspension terms (``extended_model.nonlinear``) and the corrected forces. Both simulations start from each model's static equilibrium, as the diagnosis does, with
DOPRI5 at a fixed step (the sample interval, halved until at most 1 ms).
"""

from __future__ import annotations

import numpy as np

__all__ = ["vehicle_series", "corrected_forces", "simulate_force_driven", "SERIES_STATES"]

SERIES_STATES = ("z1", "z2", "z3", "beta")


def corrected_forces(run, corrections: dict) -> dict[str, np.ndarray]:
    """The report's force corrections (JSON) applied to the measured forces on the run's grid."""
    from ..io._corrections import Corrections

    return Corrections.from_json(corrections).apply(run.t, {ch: run[ch] for ch in ("f1", "f2")})


def simulate_force_driven(run, models: list[dict], forces: list[dict], nonlinear: list | None = None) -> list[np.ndarray]:
    """States ``(n, 10)`` of (A.3) for each (model, forces) pair, on ``run.t`` (``nonlinear``: per
    pair, the suspension's nonlinear terms or None)."""
    from ..analysis._force_driven import force_driven_states

    return force_driven_states(run.t, models, forces, dt=run.dt, nonlinear=nonlinear)


def vehicle_series(run, model: dict, report: dict) -> dict[str, np.ndarray]:
    """The columns described in the module docstring, as float64 arrays of length ``run.n``."""
    ext = report["extended_model"]
    fc = corrected_forces(run, ext["corrections"])
    from ..models._halfcar import NonlinearSuspension

    y0, y1 = simulate_force_driven(run, [model, ext["parameters"]],
                                   [{ch: run[ch] for ch in ("f1", "f2")}, fc],
                                   [None, NonlinearSuspension.from_json(ext.get("nonlinear"))])
    cols = {"t": run.t}
    cols.update({c: run[c] for c in sorted(run.channels)})
    cols["f1_corrected"], cols["f2_corrected"] = fc["f1"], fc["f2"]
    for prefix, ys in (("sim", y0), ("ext", y1)):
        for j, nm in enumerate(SERIES_STATES):
            cols[f"{prefix}_{nm}"] = ys[:, j]
    return cols
