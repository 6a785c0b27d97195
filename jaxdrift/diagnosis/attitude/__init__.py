"""Diagnosis of an attitude run: gyro errors from the Allan deviation, accelerometer array checks.
"""

from __future__ import annotations

from ._diagnose import (
    run_attitude_diagnosis as run_attitude_diagnosis,
    read_attitude_run as read_attitude_run,
    read_sensors as read_sensors,
    estimate_white_noise as estimate_white_noise,
    diagnose_attitude as diagnose_attitude,
)

__all__ = ['diagnose_attitude', 'estimate_white_noise', 'read_attitude_run', 'read_sensors', 'run_attitude_diagnosis']
