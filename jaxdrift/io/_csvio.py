"""The vehicle-run API of the first reader, kept for its callers: :func:`read_vehicle_run`,
:func:`read_header`, :func:`write_vehicle_run` and the model file functions.

Reading goes through the one reader for every kind of run, :func:`jaxdrift.io.load_run`
(``_runs.py``); this module only keeps the names. Every refusal is an :class:`InputError` whose
message names the file, the line (1-based, as an editor shows it; the header is line 1) or the
column, and what is wrong; the CLI turns it into exit code 2.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..errors import InputError
from ._model import DEFAULT_MODEL, MODEL_KEYS, read_model, validate_model
from ._outputs import atomic_path
from ._runs import (JITTER_TOL, MIN_DURATION_S, MIN_SAMPLES, VEHICLE_OPTIONAL, VEHICLE_REQUIRED,
                    VehicleRun, load_run)
from ._table import read_header_any

__all__ = [
    "InputError", "VehicleRun", "MODEL_KEYS", "DEFAULT_MODEL", "VEHICLE_REQUIRED", "VEHICLE_OPTIONAL",
    "MIN_SAMPLES", "MIN_DURATION_S", "JITTER_TOL", "read_header", "read_vehicle_run", "read_model",
    "validate_model", "write_vehicle_run",
]


def read_header(path) -> list[str]:
    """The column names of a run file (CSV: stripped), or InputError if it cannot be read."""
    return read_header_any(path)


def read_vehicle_run(path, *, map=None, units=None, fs=None, force=False, model=None,  # noqa: A002
                     checks=False) -> VehicleRun:
    """Read and validate a vehicle run (CSV, Parquet or MF4; ``docs/measured-data.md``).

    The options are those of :func:`jaxdrift.io.load_run`; the plausibility checks (units, dead
    channels, glitches) run with ``checks=True``, as the command line always does."""
    return load_run(path, "vehicle", map=map, units=units, fs=fs, force=force, model=model, checks=checks)


def write_vehicle_run(path, t, channels: Mapping[str, np.ndarray]) -> None:
    """Write a vehicle run CSV (full float precision), columns ``t`` then the channels, atomically."""
    names = ["t"] + list(channels)
    cols = [np.asarray(t, dtype=float)] + [np.asarray(channels[c], dtype=float) for c in channels]
    data = np.column_stack(cols)
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="") as fh:
            fh.write(",".join(names) + "\n")
            np.savetxt(fh, data, delimiter=",", fmt="%.17g")
