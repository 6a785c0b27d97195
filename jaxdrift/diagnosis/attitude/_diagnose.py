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
    positions = None
    if run["acc"] is not None:
        if sensors_path is None:
            raise _usage_error(f"{run_path}: the run has accelerometer columns; give their positions with --sensors SENSORS.json")
        positions = read_sensors(sensors_path, run["acc"].shape[1])
    elif sensors_path is not None:
        raise _usage_error(f"{sensors_path}: sensor positions given but {run_path} has no accelerometer columns (a1x, a1y, a1z, ...)")
    report, plots = diagnose_attitude(run, positions)
    if plots_dir is not None:
        os.makedirs(plots_dir, exist_ok=True)
        report["plots"] = write_plots(plots, plots_dir)
    return report

