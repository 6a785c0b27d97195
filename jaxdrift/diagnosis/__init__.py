"""Diagnosis of measured runs: vehicle (forces and motion) and attitude (gyros, accelerometers).

The public API of the diagnosis: the two subpackages' names (:mod:`jaxdrift.diagnosis.vehicle`,
:mod:`jaxdrift.diagnosis.attitude`) and the helpers below, shared with the campaign, durability and
the report. No other layer imports a module of this package whose name starts with an underscore.
"""

from __future__ import annotations

from ._diffnoise import robust_diff_sigma as robust_diff_sigma
from ._intervals import joint_intervals as joint_intervals
from ._series import vehicle_series as vehicle_series
from .attitude import run_attitude_diagnosis as run_attitude_diagnosis
from .vehicle import diagnose_vehicle_run as diagnose_vehicle_run

__all__ = ['diagnose_vehicle_run', 'joint_intervals', 'robust_diff_sigma', 'run_attitude_diagnosis', 'vehicle_series']
