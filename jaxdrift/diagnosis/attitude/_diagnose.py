"""Diagnosis of attitude runs (docs/measured-data.md): gyro noise, bias, scale, bias drift, sensor
positions and rigidity of an accelerometer array, with 95 % intervals.

The entry point :func:`run_attitude_diagnosis` reads the files (:mod:`jaxdrift.io._attitude_files`),
runs the pipeline (:func:`jaxdrift.diagnosis.attitude._pipeline.diagnose_attitude`) and writes the
figures. The steps live in modules named after what they compute (see docs/attitude.md for the
derivations):

- ``_noise``: gyro white noise from high-order differences; Allan deviation (N, B, K);
- ``_gyro``: biases, scales and bias drift from a reference attitude (Gauss-Newton, REML), biases
  from a static segment;
- ``_array``: accelerometer array: sensor positions, gyro biases through the centripetal terms,
  rigidity residual;
- ``_report``: ranking, the report dict, the figures;
- ``_pipeline``: the named steps in order over one state.
"""

from __future__ import annotations

import os

from ...errors import UsageError
from ...io._attitude_files import read_attitude_run, read_sensors as _read_sensors
from ...models._accel_array import check_positions
from ._noise import estimate_white_noise
from ._pipeline import diagnose_attitude
from ._report import write_plots

__all__ = ["run_attitude_diagnosis", "read_attitude_run", "read_sensors", "estimate_white_noise", "diagnose_attitude"]


def _usage_error(msg):
    return UsageError(msg)


def read_sensors(path, n_expected=None):
    """Read and validate ``{"positions": [[x, y, z], ...]}``: N >= 4 and positions not coplanar."""
    return _read_sensors(path, n_expected, check_geometry=check_positions)


def run_attitude_diagnosis(run_path: str, sensors_path: str | None = None, plots_dir: str | None = None) -> dict:
    """Diagnose an attitude run (docs/measured-data.md); return the report dict (kind "attitude").

    Raises :class:`jaxdrift.cli.UsageError` on bad input before anything is written. With
    ``plots_dir``, writes ``allan.png`` (and ``attitude_error.png``, ``array_residual.png`` where the
    run has what they need) after the analysis succeeded.
    """
    run = read_attitude_run(run_path)
    report, plots = diagnose_attitude(run, sensor_positions(run, run_path, sensors_path))
    if plots_dir is not None:
        os.makedirs(plots_dir, exist_ok=True)
        report["plots"] = write_plots(plots, plots_dir)
    return report


def sensor_positions(run: dict, run_path, sensors_path):
    """The accelerometer positions a run needs: read from ``sensors_path`` where the run has
    accelerometer columns (None where it has none); a UsageError where one is given without the
    other."""
    if run["acc"] is not None:
        if sensors_path is None:
            raise _usage_error(f"{run_path}: the run has accelerometer columns; give their positions with --sensors SENSORS.json")
        return read_sensors(sensors_path, run["acc"].shape[1])
    if sensors_path is not None:
        raise _usage_error(f"{sensors_path}: sensor positions given but {run_path} has no accelerometer columns (a1x, a1y, a1z, ...)")
    return None


def analysed_part(run: dict) -> tuple[dict, str | None]:
    """The run the diagnosis analyses, and a warning where that is not all of it. A run split by
    gaps (NaN rows between its segments) goes whole where the pipeline analyses segments jointly
    (``SEGMENTS_JOINT`` in ``_pipeline``); otherwise its longest segment does, and the warning
    names what is left out (never NaN rows into a diagnosis that assumes finite rates)."""
    from ...io import attitude_segments
    from ._pipeline import SEGMENTS_JOINT

    segs = run.get("time_base", {}).get("segments") or [[0, len(run["t"])]]
    if SEGMENTS_JOINT or segs == [[0, len(run["t"])]]:
        return run, None
    parts = attitude_segments(run)
    best = max(parts, key=lambda p: len(p["t"]))
    out = dict(run)
    out.update({k: best[k] for k in ("t", "w", "q_ref", "acc")})
    out["time_base"] = {**run["time_base"], "analysed_segment": list(best["rows"])}
    i0, i1 = best["rows"]
    return out, (f"{run['path']}: {len(segs)} segments split by gaps; the attitude diagnosis analyses the longest, "
                 f"{run['t'][i0]:.6g} .. {run['t'][i1 - 1]:.6g} s ({i1 - i0} of {sum(b - a for a, b in segs)} rows)")
