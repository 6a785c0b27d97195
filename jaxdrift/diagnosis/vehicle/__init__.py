"""Diagnosis of a measured vehicle run: residuals, cause candidates, model extension, report.
"""

from __future__ import annotations

from ._diagnose import (
    Cause as Cause,
    ResidualPipeline as ResidualPipeline,
    diagnose_vehicle_run as diagnose_vehicle_run,
    DRIFT_THRESHOLD_RAD as DRIFT_THRESHOLD_RAD,
    SCHEMA as SCHEMA,
)

__all__ = ['Cause', 'DRIFT_THRESHOLD_RAD', 'ResidualPipeline', 'SCHEMA', 'diagnose_vehicle_run']
