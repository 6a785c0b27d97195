"""The one abstract cause every diagnosis names, and the capabilities a cause may have.

Every cause of the vehicle and attitude diagnoses is an :class:`AbstractCause`: a report name and
the unit of its estimate. What a cause can do is a capability, an abstract mixin (as diffrax's
solvers declare ``AbstractAdaptiveSolver``): code that needs a capability asks for the mixin,
never for a concrete class, and each concrete cause is final and owns its behaviour.

- :class:`SensorEffect`: what a sensor does to one recorded channel (the forward effect a generator
  applies) and its inverse (the correction the diagnosis applies): the vehicle's force offset,
  scale, delay, gain drift and crosstalk.
- :class:`ModelParameter`: an error of a parameter of the vehicle model (the true model a
  generator simulates, the model the diagnosis corrects).
- :class:`StateForce`: a force the linear model lacks, a function of its own states, per unit of
  the cause's size (damper asymmetry, progressive spring, bump stop, the bare state terms).
- :class:`DegreeOfFreedom`: a body the model lacks, with its own motion (a mass on a spring-damper
  inside the rigid chassis: the unmodelled mode), by what it adds to the residual channels.
- :class:`SignalDetector`: a cause read off a measured signal by a detector before anything is
  fitted (a tyre that lifts off).
- :class:`NoiseLevel`: a white-noise level, reported as an estimate or an upper bound.
- :class:`RateEffect`: what a gyro does to the three body rates (the forward effect a generator
  applies, at its ``forward_stage``) and its inverse (the correction the diagnosis applies): the
  attitude's gyro scale and bias.

The registries stay with their diagnoses (``vehicle._causes.VEHICLE_CAUSES``,
``vehicle._nonlinear.catalogue``, ``attitude._causes.ATTITUDE_CAUSES``);
:func:`jaxdrift.diagnosis.registered_causes` lists them all.
"""

from __future__ import annotations

import abc
from typing import ClassVar

__all__ = ["AbstractCause", "SensorEffect", "ModelParameter", "StateForce", "DegreeOfFreedom", "SignalDetector", "NoiseLevel",
           "RateEffect"]


class AbstractCause(abc.ABC):
    """A cause a diagnosis names (abstract): ``name`` (the report's ``cause``) and ``unit`` (of its
    estimate). Subclasses are final; their instances are registered once."""

    name: ClassVar[str]
    unit: ClassVar[str]

    def __repr__(self) -> str:
        return self.name


class SensorEffect(abc.ABC):
    """Capability: a sensor effect on one recorded channel, with its forward effect (``forward``,
    at its ``forward_stage`` in the sensor's chain) and its inverse (``adjust``: the channel's
    correction record with the effect added)."""

    @abc.abstractmethod
    def forward(self, measured: dict, target: str, value: float, read) -> dict:
        """The measured channels with the effect applied (a generator's forward model)."""

    @abc.abstractmethod
    def adjust(self, c, theta: float):
        """The channel's correction record with this effect's inverse added."""


class ModelParameter(abc.ABC):
    """Capability: an error of a model parameter (``true_model`` for a generator, ``correct`` for
    the diagnosis)."""

    @abc.abstractmethod
    def true_model(self, model: dict, target: str, value: float) -> dict:
        """The vehicle's true model, given the model the user has and the error."""

    @abc.abstractmethod
    def correct(self, model: dict, params: dict, corr, target: str, theta: float):
        """The model and corrections with the error undone."""


class StateForce(abc.ABC):
    """Capability: a force the linear model lacks, a function of the model's own states (``force``
    per unit of the size ``theta``, its plausible range ``bounds``)."""

    @abc.abstractmethod
    def force(self, st) -> object:
        """The extra spring force per unit theta at the states ``st`` [N]."""

    @abc.abstractmethod
    def bounds(self, st) -> tuple[float, float]:
        """The plausible range of theta at the states ``st``."""


class DegreeOfFreedom(abc.ABC):
    """Capability: a body the model lacks, with its own motion (a mass on a spring-damper inside
    the model's rigid chassis): ``residual_response``, what it adds to the residual channels."""

    @abc.abstractmethod
    def residual_response(self, pipe, mode) -> dict:
        """The residual channels' part that ``mode`` makes, by channel name."""


class SignalDetector(abc.ABC):
    """Capability: read off one measured channel (``channel``) by a detector (``detect``) before
    anything is fitted, reported by ``finding``. What a detection changes, where it changes
    anything: the channel's correction record (:meth:`corrected`, which the diagnosis applies to the
    measured samples before the fit and reports with the extended model's corrections, so the
    series output and durability undo it by the same record), and the extended model's nonlinear
    terms (:meth:`model_terms`). The defaults change nothing: the cause is only reported.

    Adding a cause read off a force channel (the vehicle's tyre lift-off and force clipping):

    1. Write one ``@final`` class in ``diagnosis/vehicle/_nonlinear.py``, an
       :class:`AbstractCause` with this capability: ``name``, ``unit``, ``__init__(channel)``.
    2. :meth:`detect` on the channel's measured samples (``sigma``: the forces' top-band noise
       level), returning what it found or ``None``; :meth:`finding` the report's finding of it
       (``cause``, ``channel``, ``estimate``, ``unit``, ``interval`` or ``None`` for a value read
       exactly, ``evidence``).
    3. Its inverse, where there is one: :meth:`corrected` (a field of the channel's
       :class:`~jaxdrift.io._corrections.ForceCorrection`, so the diagnosis, the series output,
       durability and the campaign undo it by one record) or :meth:`model_terms`.
    4. Its forward effect for generators (``forward``), and the independent generator
       (``benchmarks/validation/gen_vehicle.py``) taught the effect in its own code.
    5. Register an instance per channel in ``_nonlinear.signal_detectors`` and add a case to
       ``tests/test_cause_contract.py``.
    """

    channel: str
    #: its inverse restores samples the sensor lost, approximately: what the restoration misses
    #: stays in the residual as a force error, so the run's force-noise level is an upper bound
    restores: ClassVar[bool] = False

    @abc.abstractmethod
    def detect(self, signal, sigma: float) -> dict | None:
        """What the detector found in the signal, or None."""

    @abc.abstractmethod
    def finding(self, det: dict) -> dict:
        """The report finding of a detection."""

    def corrected(self, c, det: dict):
        """The channel's correction record ``c`` with the detection's inverse added."""
        return c

    def model_terms(self, det: dict) -> dict:
        """What the detection adds to the extended model's nonlinear terms (JSON form)."""
        return {}


class NoiseLevel(abc.ABC):
    """Capability: a white-noise level, an estimate or an upper bound (``estimate_kind``). The
    steps that measure it write its finding; the level is not a parameter of a fit."""


class RateEffect(abc.ABC):
    """Capability: an effect of a gyro on the body rates ``w`` ``(n, 3)`` [rad/s], with its forward
    effect (``forward``: what the sensor does to the true rates) and its inverse (``inverse``: the
    correction). ``value`` broadcasts against ``w``: one per axis, or a path ``(n, 3)`` (a bias that
    drifts). Effects compose in the order of their ``forward_stage`` (lower first); the inverse
    undoes them in the reverse order."""

    forward_stage: ClassVar[int]

    @abc.abstractmethod
    def forward(self, w, value):
        """The rates with the effect applied."""

    @abc.abstractmethod
    def inverse(self, w, value):
        """The rates with the effect undone: ``inverse(forward(w, v), v) == w``."""
