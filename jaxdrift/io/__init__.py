"""Reading and writing measured runs and model files (numpy only).
"""

from __future__ import annotations

from ._csvio import (
    InputError as InputError,
    VehicleRun as VehicleRun,
    MODEL_KEYS as MODEL_KEYS,
    DEFAULT_MODEL as DEFAULT_MODEL,
    VEHICLE_REQUIRED as VEHICLE_REQUIRED,
    VEHICLE_OPTIONAL as VEHICLE_OPTIONAL,
    MIN_SAMPLES as MIN_SAMPLES,
    MIN_DURATION_S as MIN_DURATION_S,
    read_header as read_header,
    read_vehicle_run as read_vehicle_run,
    read_model as read_model,
    write_vehicle_run as write_vehicle_run,
)
from ._attitude_files import (
    read_attitude_run as read_attitude_run,
    read_sensors as read_sensors,
)

__all__ = ['DEFAULT_MODEL', 'InputError', 'MIN_DURATION_S', 'MIN_SAMPLES', 'MODEL_KEYS', 'VEHICLE_OPTIONAL', 'VEHICLE_REQUIRED', 'VehicleRun', 'read_attitude_run', 'read_header', 'read_model', 'read_sensors', 'read_vehicle_run', 'write_vehicle_run']
