"""Reading and writing measured runs and model files (numpy and pyarrow; no JAX).

:func:`load_run` is the one reader for every kind of run (vehicle, attitude, durability) and
format (CSV, Parquet, MDF4, PX4 ULog, ROS bags), with one time-base policy (:mod:`._timebase`:
jitter and gaps measured, resampling inside segments, references on their own times);
:mod:`._outputs` the one way results are written.
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
from ._corrections import (
    Corrections as Corrections,
    ForceCorrection as ForceCorrection,
    unclip as unclip,
)
from ._model import DEFAULT_MODEL_LABEL as DEFAULT_MODEL_LABEL
from ._runs import AttitudeRun as AttitudeRun, load_run as load_run
from ._outputs import (
    atomic_dir as atomic_dir,
    atomic_path as atomic_path,
    check_outputs as check_outputs,
    write_json as write_json,
    write_report as write_report,
    check_report_finite as check_report_finite,
)
from ._provenance import provenance as provenance
from ._attitude_files import (
    attitude_segments as attitude_segments,
    read_attitude_run as read_attitude_run,
    read_sensors as read_sensors,
)
from ._export import export_recorded_csv as export_recorded_csv
from ._logs import list_topics as list_topics, read_log as read_log
from ._timebase import GAP_FACTOR as GAP_FACTOR

__all__ = ['AttitudeRun', 'Corrections', 'DEFAULT_MODEL', 'DEFAULT_MODEL_LABEL', 'GAP_FACTOR', 'InputError', 'MIN_DURATION_S',
           'ForceCorrection', 'MIN_SAMPLES', 'MODEL_KEYS', 'VEHICLE_OPTIONAL', 'VEHICLE_REQUIRED', 'VehicleRun', 'atomic_dir', 'atomic_path',
           'attitude_segments', 'check_outputs', 'export_recorded_csv', 'list_topics', 'load_run', 'provenance', 'read_log',
           'read_attitude_run', 'read_header', 'read_model', 'read_sensors', 'read_vehicle_run',
           'unclip', 'write_json', 'write_report', 'check_report_finite', 'write_vehicle_run']
