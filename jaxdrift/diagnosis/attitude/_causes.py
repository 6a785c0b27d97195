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

from ._common import finding

__all__ = ["AttitudeCause", "GYRO_NOISE", "GYRO_BIAS", "GYRO_SCALE", "GYRO_BIAS_DRIFT", "SENSOR_POSITION",
           "NONRIGID", "ACCEL_NOISE", "REFERENCE_INCONSISTENT", "ATTITUDE_CAUSES"]


class AttitudeCause:
    """A kind of attitude cause (abstract): its report name and the unit of its estimate."""

    name: ClassVar[str]
    unit: ClassVar[str]

    def __repr__(self) -> str:
        return self.name

    def finding(self, estimate, interval, evidence: str, z: float, **extra):
        """The report finding (keys in the contract's order) and its ranking statistic ``z``."""
        return finding(self.name, estimate, self.unit, interval, evidence, z, **extra)


@final
class GyroNoise(AttitudeCause):
    """Angle random walk of all three axes."""
    name, unit = "gyro_noise", "rad/sqrt(s)"


@final
class GyroBias(AttitudeCause):
    """measured = true + bias, per axis."""
    name, unit = "gyro_bias", "rad/s"


@final
class GyroScale(AttitudeCause):
    """measured = scale x true, per axis."""
    name, unit = "gyro_scale", "ratio"


@final
class GyroBiasDrift(AttitudeCause):
    """The bias is a random walk of this intensity, per axis."""
    name, unit = "gyro_bias_drift", "rad/s/sqrt(s)"


@final
class SensorPosition(AttitudeCause):
    """An accelerometer's true position = given position + estimate."""
    name, unit = "sensor_position", "m"


@final
class Nonrigid(AttitudeCause):
    """RMS of the array's rigidity residual beyond its noise."""
    name, unit = "nonrigid", "m/s^2"


@final
class AccelNoise(AttitudeCause):
    """White noise of the accelerometers."""
    name, unit = "accel_noise", "m/s^2"


@final
class ReferenceInconsistent(AttitudeCause):
    """The reference attitude turns where the gyro says the body is still: not a gyro error."""
    name, unit = "reference_inconsistent", "rad/s"


GYRO_NOISE, GYRO_BIAS, GYRO_SCALE, GYRO_BIAS_DRIFT = GyroNoise(), GyroBias(), GyroScale(), GyroBiasDrift()
SENSOR_POSITION, NONRIGID, ACCEL_NOISE = SensorPosition(), Nonrigid(), AccelNoise()
REFERENCE_INCONSISTENT = ReferenceInconsistent()
ATTITUDE_CAUSES = (GYRO_NOISE, GYRO_BIAS, GYRO_SCALE, GYRO_BIAS_DRIFT, SENSOR_POSITION, NONRIGID, ACCEL_NOISE,
                   REFERENCE_INCONSISTENT)
