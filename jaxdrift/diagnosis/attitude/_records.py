"""The records the attitude diagnosis's steps return (:mod:`._pipeline`).

Every step is a function of the records before it and returns a new, frozen one; no step changes
a record, dict or list it was given. What a step says beside its findings (notes, what was and was
not observed, causes it cannot determine) is a :class:`Said`, added up in the order the steps run.

- :class:`Said`: notes, ``observability`` and ``not_determined`` entries.
- :class:`GyroNoise`: the white gyro noise (level, floor, weights) and its finding;
  :func:`._pipeline.gyro_noise_step`, then :func:`._vibration.vibration_step` and
  :func:`._realworld.noise_kind_step` return revised ones.
- :class:`Vibration`: the vibration found (spans, level per axis, peaks) and its finding.
- :class:`Alignment`: the reference's clock offset and frame rotation, and the run with the
  aligned reference.
- :class:`GyroModel`: the corrected gyro (corrections, bias path, scales and their standard
  errors, where the biases came from).
- :class:`Comparison`: what a source of biases (reference, static segment, array) found and
  measured: the gyro model, findings, simulation errors, gain, figures, the series for Allan.
- :class:`Diagnosis`: everything the report is assembled from (:func:`._report.assemble_report`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...io._corrections import GyroCorrection
from ._common import CHANNELS

__all__ = ["Said", "GyroNoise", "Vibration", "Alignment", "GyroModel", "Comparison", "Diagnosis"]


@dataclass(frozen=True)
class Said:
    """What a step says beside its findings, in the order it said it."""

    notes: tuple = ()
    observed: tuple = ()
    not_observed: tuple = ()
    not_determined: tuple = ()  # ({cause, channel, reason}, ...)

    def __add__(self, other: Said) -> Said:
        return Said(self.notes + other.notes, self.observed + other.observed,
                    self.not_observed + other.not_observed, self.not_determined + other.not_determined)

    @staticmethod
    def undetermined(cause: str, channel: str, reason: str) -> Said:
        """A cause the run cannot determine (report ``not_determined``; also ``observability``)."""
        return Said(not_observed=(f"{cause} of {channel} ({reason})",),
                    not_determined=({"cause": cause, "channel": channel, "reason": reason},))


@dataclass(frozen=True)
class GyroNoise:
    """The gyro's white noise as the later steps use it."""

    segments: tuple  # [i0, i1) row ranges with finite rates (between gaps)
    wn: dict  # the high-order difference estimate (:func:`._noise.estimate_white_noise`)
    floor: float  # below this a level is the file's rounding
    found: bool
    sigma_axis: np.ndarray  # per-sample standard deviation per axis (0 where not found)
    var_rate: float  # N^2, the weights of the reference fit
    finding: dict | None  # the gyro_noise finding (estimate or upper bound), None where none
    said: Said = Said()


@dataclass(frozen=True)
class Vibration:
    """Vibration told apart from the white noise (:mod:`._vibration`)."""

    spans: list
    level: np.ndarray
    peaks: list
    rows: int
    finding: dict


@dataclass(frozen=True)
class Alignment:
    """The reference's clock offset and frame rotation (``None`` where not estimated) and the run
    whose reference is aligned where they were significant (else the run given)."""

    alignment: dict | None
    run: dict
    said: Said = Said()


@dataclass(frozen=True)
class GyroModel:
    """The corrected gyro model: ``(w - bias_path) / scale``."""

    corrections: dict  # channel -> GyroCorrection; sensorN -> {"position": [...]}
    bias_path: np.ndarray
    scale: np.ndarray
    bias_source: str | None = None  # "reference", "static" or "array"
    scale_se: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_se: np.ndarray = field(default_factory=lambda: np.zeros(3))
    bias_fit: dict = field(default_factory=dict)  # channel -> (estimate, 95 % half-width), named or not

    @classmethod
    def uncorrected(cls, n: int) -> GyroModel:
        return cls({c: GyroCorrection() for c in CHANNELS}, np.zeros((n, 3)), np.ones(3))


@dataclass(frozen=True)
class Comparison:
    """What a source of biases found, and the gyro model after it."""

    model: GyroModel
    findings: tuple = ()  # ((finding, z), ...)
    noise_findings: tuple = ()  # further noise findings (accel_noise), listed after the gyro noise
    sim_err: dict = field(default_factory=dict)
    gain: dict | None = None
    plots: dict = field(default_factory=dict)
    allan_series: np.ndarray | None = None
    allan_label: str | None = None
    said: Said = Said()
    still_rows: tuple | None = None  # (i0, i1) of the static segment where one gave the biases


@dataclass(frozen=True)
class Diagnosis:
    """Everything the report of one sensor's run is assembled from."""

    run: dict
    positions: object
    n_ref: int
    noise: GyroNoise
    vibration: Vibration | None
    alignment: dict | None
    comparison: Comparison
    allan: dict | None
    said: Said

    @property
    def plots(self) -> dict:
        return {**self.comparison.plots, **({"allan": self.allan} if self.allan is not None else {})}
