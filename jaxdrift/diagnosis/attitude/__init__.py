"""Diagnosis of an attitude run: gyro errors from the Allan deviation, accelerometer array checks.
"""

from __future__ import annotations

from ._diagnose import (
    analysed_part as analysed_part,
    sensor_positions as sensor_positions,
    run_attitude_diagnosis as run_attitude_diagnosis,
    read_attitude_run as read_attitude_run,
    read_sensors as read_sensors,
    estimate_white_noise as estimate_white_noise,
    diagnose_attitude as diagnose_attitude,
)

from ._report import write_plots as write_plots
from ._causes import gyro_forward as gyro_forward, gyro_inverse as gyro_inverse

__all__ = ['analysed_part', 'diagnose_attitude', 'estimate_white_noise', 'gyro_forward', 'gyro_inverse',
           'read_attitude_run', 'read_sensors', 'run_attitude_diagnosis', 'sensor_positions', 'write_plots']
