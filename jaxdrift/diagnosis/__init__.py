"""Diagnosis of measured runs: vehicle (forces and motion) and attitude (gyros, accelerometers).
"""

from __future__ import annotations

from .attitude import run_attitude_diagnosis as run_attitude_diagnosis
from .vehicle import diagnose_vehicle_run as diagnose_vehicle_run

__all__ = ['diagnose_vehicle_run', 'run_attitude_diagnosis']
