"""Diagnosis of a measured vehicle run: residuals, cause candidates, model extension, report.

Modules, in the order the diagnosis runs them: ``_residuals`` (the residual pipeline, on the exact
discretisation of ``_discretise``), ``_detectors`` and ``_motion_noise`` (noise on forces and on
the measured motion), ``_causes`` (the candidates as parameters), ``_problem`` (weighted residual,
noise response, fit), ``_select`` (which causes), ``_confirm`` (each correction must improve the
model on the whole run and on each half), ``_extend`` (re-simulation of the extended model), ``_report`` and ``_plots``
(the report), ``_pipeline`` (``diagnose_vehicle_run``).
"""

from __future__ import annotations

from ._causes import Cause as Cause
from ._pipeline import diagnose_vehicle_run as diagnose_vehicle_run
from ._extend import DRIFT_THRESHOLD_RAD as DRIFT_THRESHOLD_RAD
from ._report import SCHEMA as SCHEMA
from ._residuals import ResidualPipeline as ResidualPipeline

__all__ = ['Cause', 'DRIFT_THRESHOLD_RAD', 'ResidualPipeline', 'SCHEMA', 'diagnose_vehicle_run']
