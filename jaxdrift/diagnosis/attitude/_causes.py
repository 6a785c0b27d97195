"""The catalogue of attitude causes: one final class per cause kind (the vehicle's catalogue is
``diagnosis/vehicle/_causes.py``).

A kind owns its report name and unit and writes its findings; the steps that estimate a cause ask
the kind, none of them spells its name. Adding one: a subclass here, registered in
``ATTITUDE_CAUSES``, the step that estimates it, its generator entry (``studies/_attgen.py`` and the
independent ``benchmarks/validation/gen_attitude.py``), its tests and its row in
``docs/measured-data.md``.
"""

from __future__ import annotations

from typing import ClassVar, final

import numpy as np

from .._cause import AbstractCause, NoiseLevel, RateEffect
from ._common import finding

__all__ = ["AttitudeCause", "gyro_forward", "gyro_inverse", "GYRO_NOISE", "GYRO_BIAS", "GYRO_SCALE", "GYRO_BIAS_DRIFT", "SENSOR_POSITION",
           "NONRIGID", "ACCEL_NOISE", "REFERENCE_INCONSISTENT", "VIBRATION",
           "ATTITUDE_CAUSES"]


class AttitudeCause(AbstractCause):
    """A kind of attitude cause (abstract; the one abstract cause of every diagnosis is
    :class:`jaxdrift.diagnosis._cause.AbstractCause`): its report name and the unit of its
    estimate."""

    name: ClassVar[str]
    unit: ClassVar[str]

    def finding(self, estimate, interval, evidence: str, z: float, **extra):
        """The report finding (keys in the contract's order) and its ranking statistic ``z``."""
        return finding(self.name, estimate, self.unit, interval, evidence, z, **extra)


def _kind(cls_name: str, name: str, unit: str, doc: str, capabilities: tuple = ()) -> type:
    """A final subclass of :class:`AttitudeCause` (the attitude kinds differ only in these and their
    capability mixins, :mod:`jaxdrift.diagnosis._cause`)."""
    return final(type(cls_name, (AttitudeCause, *capabilities), {"name": name, "unit": unit, "__doc__": doc,
                                                                 "__module__": __name__}))


GyroNoise = _kind("GyroNoise", "gyro_noise", "rad/sqrt(s)", "Angle random walk of all three axes.", (NoiseLevel,))


@final
class GyroScale(AttitudeCause, RateEffect):
    """measured = scale x true, per axis (the first stage of the gyro's chain)."""

    name, unit = "gyro_scale", "ratio"
    forward_stage = 0

    def forward(self, w, value):
        return np.asarray(value, float) * w

    def inverse(self, w, value):
        return w / np.asarray(value, float)


@final
class GyroBias(AttitudeCause, RateEffect):
    """measured = true + bias, per axis (after the scale; a path ``(n, 3)`` where the bias
    drifts)."""

    name, unit = "gyro_bias", "rad/s"
    forward_stage = 1

    def forward(self, w, value):
        return w + value

    def inverse(self, w, value):
        return w - value


GyroBiasDrift = _kind("GyroBiasDrift", "gyro_bias_drift", "rad/s/sqrt(s)", "The bias is a random walk of this intensity, per axis.")
SensorPosition = _kind("SensorPosition", "sensor_position", "m", "An accelerometer's true position = given position + estimate.")
Nonrigid = _kind("Nonrigid", "nonrigid", "m/s^2", "RMS of the array's rigidity residual beyond its noise.")
AccelNoise = _kind("AccelNoise", "accel_noise", "m/s^2", "White noise of the accelerometers.", (NoiseLevel,))
Vibration = _kind("Vibration", "vibration", "rad/s", "High-frequency rate content that comes and goes (motors) or has spectral peaks: not white noise; estimate = the largest axis's per-sample level.")
ReferenceInconsistent = _kind("ReferenceInconsistent", "reference_inconsistent", "rad/s", "The reference attitude turns where the gyro says the body is still: not a gyro error.")

GYRO_NOISE, GYRO_BIAS, GYRO_SCALE, GYRO_BIAS_DRIFT = GyroNoise(), GyroBias(), GyroScale(), GyroBiasDrift()
SENSOR_POSITION, NONRIGID, ACCEL_NOISE = SensorPosition(), Nonrigid(), AccelNoise()
REFERENCE_INCONSISTENT = ReferenceInconsistent()
VIBRATION = Vibration()
ATTITUDE_CAUSES = (GYRO_NOISE, GYRO_BIAS, GYRO_SCALE, GYRO_BIAS_DRIFT, SENSOR_POSITION, NONRIGID, ACCEL_NOISE,
                   REFERENCE_INCONSISTENT, VIBRATION)


def gyro_forward(w_true, scale, additive):
    """The gyro's chain on the true rates: its scale, then the additive errors ``additive`` (the
    bias, its drift and the noise; per axis or a path ``(n, 3)``): what a generator records."""
    return GYRO_BIAS.forward(GYRO_SCALE.forward(w_true, scale), additive)


def gyro_inverse(w, scale, bias_path):
    """The correction of measured rates ``w``: the bias (path) taken off, then the scale divided
    out (the chain of :func:`gyro_forward` undone in reverse order)."""
    return GYRO_SCALE.inverse(GYRO_BIAS.inverse(w, bias_path), scale)
