"""Diagnosis of a measured vehicle run: residuals, cause candidates, model extension, report.

Modules, in the order the diagnosis runs them: ``_detectors`` (the causes read off the forces
before anything is fitted, noise on the forces) and ``_motion_noise`` (noise on the measured
motion), ``_residuals`` (the residual pipeline, on the exact discretisation of ``_discretise``),
``_causes`` and ``_nonlinear`` (the catalogue: the candidates as parameters, the nonlinear causes),
``_problem`` (weighted residual, noise response, fit), ``_select`` (which causes), ``_adequacy``
(the model's form), ``_confirm`` (each correction must improve the model on the whole run and on
each half, and its re-simulation), ``_report`` (the report, with ``_extend``'s re-simulation of the
extended model and ``_plots``), ``_pipeline`` (``diagnose_vehicle_run``, which calls the steps in
that order).

The names below are the vehicle diagnosis's public API: the command line, the campaign (its joint
fit over runs re-uses the single-run problem, candidates and selection), durability and the
studies import these, never a module of this package.
"""

from __future__ import annotations

from ._causes import (
    ALPHA as ALPHA,
    FORCE_CHANNELS as FORCE_CHANNELS,
    FORCE_DELAY as FORCE_DELAY,
    FORCE_GAIN_DRIFT as FORCE_GAIN_DRIFT,
    FORCE_NOISE as FORCE_NOISE,
    FORCE_OFFSET as FORCE_OFFSET,
    FORCE_SCALE as FORCE_SCALE,
    PARAMETER_ERROR as PARAMETER_ERROR,
    SENSOR_KINDS as SENSOR_KINDS,
    VEHICLE_CAUSES as VEHICLE_CAUSES,
    Cause as Cause,
    kind_named as kind_named,
    _apply as apply_causes,
    _candidates as candidates,
    _clip_theta as clip_theta,
    _finding_for as finding_for,
    _practical as practical_size,
    _theta_bounds as theta_bounds,
)
from ._detectors import read_signals as read_signals
from ._extend import DRIFT_THRESHOLD_RAD as DRIFT_THRESHOLD_RAD
from ._nonlinear import nonlinear_cause_names as nonlinear_cause_names
# the adequacy test's pieces a campaign sizes a nonlinear cause with in every run (``campaign._nonlinear``)
from ._adequacy import (JOINT_CHI2 as JOINT_CHI2, _channel_test as channel_test, _column as signature_column,
                        _refine as refine_size, _tests as adequacy_tests)
from ._nonlinear import (BumpStop as BumpStop, DamperAsymmetry as DamperAsymmetry,
                         ProgressiveSpring as ProgressiveSpring, States as States, model_states as model_states,
                         travel_response as travel_response)
from ._pipeline import diagnose_vehicle_run as diagnose_vehicle_run
from ._problem import _Problem as Problem, _proj as projected_share
from ._report import SCHEMA as SCHEMA, residual_gain as residual_gain
from ._residuals import ResidualPipeline as ResidualPipeline
from ._select import _select as select_causes

__all__ = ['ALPHA', 'Cause', 'DRIFT_THRESHOLD_RAD', 'FORCE_CHANNELS', 'FORCE_DELAY', 'FORCE_GAIN_DRIFT', 'FORCE_NOISE',
           'FORCE_OFFSET', 'FORCE_SCALE', 'PARAMETER_ERROR', 'Problem', 'ResidualPipeline', 'SCHEMA', 'SENSOR_KINDS',
           'VEHICLE_CAUSES', 'apply_causes', 'candidates', 'cause_names', 'clip_theta', 'diagnose_vehicle_run',
           'finding_for', 'kind_named', 'nonlinear_cause_names', 'practical_size', 'projected_share',
           'read_signals', 'residual_gain', 'select_causes', 'theta_bounds', 'JOINT_CHI2', 'channel_test',
           'signature_column', 'refine_size', 'adequacy_tests', 'BumpStop', 'DamperAsymmetry', 'ProgressiveSpring',
           'States', 'model_states', 'travel_response']


def cause_names() -> tuple[str, ...]:
    """Every cause the vehicle diagnosis can name, from its registries: the linear kinds
    (``VEHICLE_CAUSES``) and the nonlinear ones (:func:`nonlinear_cause_names`). Generators, sweeps
    and contract tests take their list from here."""
    return (*(k.name for k in VEHICLE_CAUSES), *nonlinear_cause_names())
