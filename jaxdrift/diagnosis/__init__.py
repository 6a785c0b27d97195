"""Diagnosis of measured runs: vehicle (forces and motion) and attitude (gyros, accelerometers).

The public API of the diagnosis: the two subpackages' names (:mod:`jaxdrift.diagnosis.vehicle`,
:mod:`jaxdrift.diagnosis.attitude`) and the helpers below, shared with the campaign, durability and
the report. No other layer imports a module of this package whose name starts with an underscore.
"""

from __future__ import annotations

from ._cause import AbstractCause as AbstractCause
from ._cause import DegreeOfFreedom as DegreeOfFreedom
from ._cause import ModelParameter as ModelParameter
from ._cause import NoiseLevel as NoiseLevel
from ._cause import RateEffect as RateEffect
from ._cause import SensorEffect as SensorEffect
from ._cause import SignalDetector as SignalDetector
from ._cause import StateForce as StateForce
from ._diffnoise import robust_diff_sigma as robust_diff_sigma
from ._intervals import joint_intervals as joint_intervals
from ._series import vehicle_series as vehicle_series
from .attitude import run_attitude_diagnosis as run_attitude_diagnosis
from .vehicle import diagnose_vehicle_run as diagnose_vehicle_run

__all__ = ['AbstractCause', 'DegreeOfFreedom', 'ModelParameter', 'NoiseLevel', 'RateEffect', 'SensorEffect', 'SignalDetector', 'StateForce',
           'diagnose_vehicle_run', 'joint_intervals', 'registered_causes', 'robust_diff_sigma',
           'run_attitude_diagnosis', 'vehicle_series']


def registered_causes() -> dict[str, tuple[AbstractCause, ...]]:
    """Every registered cause of both diagnoses, by domain: ``"vehicle"`` (the linear kinds, the
    force noise, the nonlinear catalogue's terms and the causes read off each force channel) and
    ``"attitude"``. Each is an :class:`AbstractCause`; what it can do is its capability mixins."""
    from .attitude._causes import ATTITUDE_CAUSES
    from .vehicle._causes import FORCE_NOISE, VEHICLE_CAUSES
    from .vehicle._mode import MODE
    from .vehicle._nonlinear import catalogue, signal_detectors

    vehicle = (*VEHICLE_CAUSES, FORCE_NOISE, *catalogue(), *signal_detectors(), MODE)
    return {"vehicle": vehicle, "attitude": tuple(ATTITUDE_CAUSES)}
