"""The corrections of measured input channels: one frozen record and one convention.

A force channel's correction (``docs/measured-data.md``)::

    read(t) = (measured(t + delay) - offset) * gain / (1 + drift * (t - t_mid)),   gain = 1 / scale
    read_1 = true_1 + leak_1 * true_2,   read_2 = true_2 + leak_2 * true_1

Before all of it, a channel that clips at its range (``clip``: the pinned value of each side,
``None`` where it does not clip) has its pinned samples restored from the samples around them
(:func:`unclip`): the one correction that reads the signal's shape, not a formula of its value.

``t_mid`` is the middle of the run (``(t[0] + t[-1]) / 2``), so a drift of the scale over the run
leaves its mean scale in ``scale``. ``leak`` is the share of the other force channel read in this
one (crosstalk); the true forces are the exact solution of the two lines (:func:`unmix`). A gyro channel's correction is ``true = (measured - bias) /
scale``. Reports carry the JSON form (``offset``, ``scale``, ``delay``, and ``drift`` where it is
not zero; ``bias``, ``scale`` for gyros); everything else (the diagnosis, durability, the series
output, the campaign, the generators) uses these records.

Where the measured signal is shifted by ``delay`` is the caller's named choice: ``"linear"``
interpolation between samples (the series output, durability, the generators), or a band-limited
(FFT) shift done by the diagnosis's own resampler, which then calls :meth:`ForceCorrection.finish`
on the shifted samples.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from ._timebase import true_runs

FORCE_CHANNELS = ("f1", "f2")
_JSON_KEYS = ("offset", "scale", "delay")
_OPTIONAL_KEYS = ("drift", "leak")
#: the samples on each side of a pinned burst that the restoration reads
UNCLIP_FLANK = 6
#: the order of the differences whose squares the restoration makes smallest
UNCLIP_ORDER = 4


def unclip(t, x, lo: float | None = None, hi: float | None = None) -> np.ndarray:
    """The samples ``x`` (on the uniform times ``t``) with every burst pinned at ``hi`` (or ``lo``)
    restored: over the burst and :data:`UNCLIP_FLANK` samples on each side, the pinned samples
    take the values that make the sum of the squared :data:`UNCLIP_ORDER`-th differences smallest
    (the smoothest fill the unpinned samples allow), with every one at or beyond the level, since
    the true force went at least that far (bounded least squares, ``scipy.optimize.lsq_linear``).
    A burst at either end of the record has one flank and is left pinned (an extrapolation, not a
    restoration). Returns a new array; without a level, ``x`` as floats.

    What it restores depends on how smooth the force is at the sampling rate. Measured against
    the truth on forces clipped at their 99 % and 95 % quantiles at 250 Hz with 2 N of noise
    (``tests/test_unclip.py``, a draw the method was not chosen on), as the share of the RMS the
    clipping took from the pinned samples that is left: 3-12 % on two-tone forces at 5-10 Hz,
    9-22 % on road-like noise low-passed at 10 Hz, 27-49 % on a 2 Hz force whose bursts last 7-17
    samples (16-47 N left: the flanks' noise, carried into a long fill). On the independent
    generator's passenger car (road class C, 15 m/s, 250 Hz, f1 clipped on 1 % of the samples)
    166 N of 573 N are left; a cubic through two samples on each side left 416 N. It never leaves
    more than the clipping did."""
    x = np.asarray(x, dtype=float)
    if lo is None and hi is None:
        return x
    import scipy.optimize

    out = x.copy()
    n = len(x)
    for level, side in ((hi, 1.0), (lo, -1.0)):
        if level is None:
            continue
        pinned = x == level
        for a, b in true_runs(pinned):
            i0, i1 = a - UNCLIP_FLANK, b + UNCLIP_FLANK
            if i0 < 0 or i1 > n:
                continue
            unknown = pinned[i0:i1]  # this burst's samples and any other burst's in the window
            if (i1 - i0) - int(unknown.sum()) < UNCLIP_ORDER:
                continue
            d = np.diff(np.eye(i1 - i0), UNCLIP_ORDER, axis=0)
            rhs = -d[:, ~unknown] @ x[i0:i1][~unknown]
            bounds = (level, np.inf) if side > 0 else (-np.inf, level)
            sol = scipy.optimize.lsq_linear(d[:, unknown], rhs, bounds=bounds).x
            mine = np.flatnonzero(unknown) + i0
            keep = (mine >= a) & (mine < b)
            out[mine[keep]] = sol[keep]
    return out


def unmix(g1, g2, leak1: float, leak2: float):
    """The true forces ``(f1, f2)`` from the read ones ``g1 = f1 + leak1 f2``, ``g2 = f2 + leak2 f1``
    (numpy or jax arrays, spline coefficients: anything linear). Without crosstalk the inputs are
    returned as they are."""
    if leak1 == 0.0 and leak2 == 0.0:
        return g1, g2
    det = 1.0 - leak1 * leak2
    return (g1 - leak1 * g2) / det, (g2 - leak2 * g1) / det


@dataclass(frozen=True)
class ForceCorrection:
    """One force channel: ``offset`` [N], ``gain`` = 1/scale, ``delay`` [s], ``drift`` [1/s],
    ``leak``: the share of the other channel's true force this channel reads (crosstalk; undone by
    :class:`Corrections`, which sees both channels)."""

    offset: float = 0.0
    gain: float = 1.0
    delay: float = 0.0
    drift: float = 0.0
    leak: float = 0.0
    #: ``(lo, hi)``: the values at which the channel is pinned at the ends of its range (``None``
    #: for a side it does not reach), or ``None``: it does not clip
    clip: tuple[float | None, float | None] | None = None

    @property
    def scale(self) -> float:
        return 1.0 / self.gain

    @property
    def is_identity(self) -> bool:
        return self == ForceCorrection()

    def drift_factor(self, t) -> np.ndarray | float:
        """``1 / (1 + drift (t - t_mid))`` on the run's times ``t`` (1.0 without drift)."""
        if self.drift == 0.0:
            return 1.0
        t = np.asarray(t, dtype=float)
        return 1.0 / (1.0 + self.drift * (t - 0.5 * (t[0] + t[-1])))

    def restore(self, t, measured) -> np.ndarray:
        """The measured samples with the bursts pinned at the channel's range restored
        (:func:`unclip`); unchanged (as floats) where it does not clip."""
        return unclip(t, measured, *(self.clip or (None, None)))

    def finish(self, shifted: np.ndarray, t=None) -> np.ndarray:
        """The channel's read force (the true one where nothing leaks in) from the measured samples
        already shifted by ``delay`` (``t``: their times, needed only with a drift)."""
        out = (shifted - self.offset) * self.gain
        return out if self.drift == 0.0 else out * self.drift_factor(t)

    def apply(self, t, measured, delay_method: str = "linear") -> np.ndarray:
        """The channel's read force on the samples ``t`` of ``measured`` (the true one where
        nothing leaks in: :meth:`Corrections.apply` undoes a leak). ``delay_method``: ``"linear"``
        interpolation, the end value held beyond the run."""
        if delay_method != "linear":
            raise ValueError(f"delay_method must be 'linear' here, got {delay_method!r}")
        t = np.asarray(t, dtype=float)
        f = self.restore(t, measured)
        if self.delay:
            f = np.interp(t + self.delay, t, f)
        return self.finish(f, t)

    def to_json(self) -> dict:
        out = {"offset": float(self.offset), "scale": float(1.0 / self.gain), "delay": float(self.delay)}
        for k in _OPTIONAL_KEYS:
            if getattr(self, k) != 0.0:
                out[k] = float(getattr(self, k))
        if self.clip is not None:
            out["clip"] = [None if v is None else float(v) for v in self.clip]
        return out

    @classmethod
    def from_json(cls, d: dict | None) -> "ForceCorrection":
        d = d or {}
        unknown = set(d) - set(_JSON_KEYS) - set(_OPTIONAL_KEYS) - {"clip"}
        if unknown:
            raise ValueError(f"unknown correction keys {sorted(unknown)}; expected {list(_JSON_KEYS)} "
                             f"and optionally {[*_OPTIONAL_KEYS, 'clip']}")
        clip = d.get("clip")
        if clip is not None:
            if len(clip) != 2:
                raise ValueError(f"a correction's clip is [low, high] (null for a side it does not reach), got {clip!r}")
            clip = tuple(None if v is None else float(v) for v in clip)
        return cls(offset=float(d.get("offset", 0.0)), gain=1.0 / float(d.get("scale", 1.0)),
                   delay=float(d.get("delay", 0.0)), drift=float(d.get("drift", 0.0)),
                   leak=float(d.get("leak", 0.0)), clip=clip)


@dataclass(frozen=True)
class Corrections:
    """The corrections of both force channels (``Corrections()`` corrects nothing)."""

    f1: ForceCorrection = ForceCorrection()
    f2: ForceCorrection = ForceCorrection()

    def __getitem__(self, ch: str) -> ForceCorrection:
        if ch not in FORCE_CHANNELS:
            raise KeyError(ch)
        return getattr(self, ch)

    def items(self):
        return ((ch, self[ch]) for ch in FORCE_CHANNELS)

    def with_channel(self, ch: str, **changes) -> "Corrections":
        """A copy with channel ``ch``'s fields changed (the record itself never changes)."""
        return replace(self, **{ch: replace(self[ch], **changes)})

    def with_record(self, ch: str, c: ForceCorrection) -> "Corrections":
        """A copy with channel ``ch``'s record replaced by ``c``."""
        return replace(self, **{ch: c})

    def only_delay(self) -> "Corrections":
        """The same delays, nothing else (the shifted measured forces)."""
        return Corrections(**{ch: ForceCorrection(delay=c.delay) for ch, c in self.items()})

    @property
    def leaks(self) -> tuple[float, float]:
        """The crosstalk shares ``(leak of f2 in f1, leak of f1 in f2)``."""
        return self.f1.leak, self.f2.leak

    def unmix(self, read: dict) -> dict:
        """The true forces from the channels' read ones (:func:`unmix`; unchanged without crosstalk)."""
        f1, f2 = unmix(read["f1"], read["f2"], *self.leaks)
        return {"f1": f1, "f2": f2}

    def restore(self, t, forces: dict) -> dict[str, np.ndarray]:
        """The measured forces with each channel's pinned bursts restored (:meth:`ForceCorrection.restore`)."""
        return {ch: c.restore(t, forces[ch]) for ch, c in self.items()}

    def apply(self, t, forces: dict, delay_method: str = "linear") -> dict[str, np.ndarray]:
        return self.unmix({ch: c.apply(t, forces[ch], delay_method) for ch, c in self.items()})

    def as_rows(self) -> np.ndarray:
        """``(5, 2)``: offset, scale, delay, drift, leak (rows) per force channel (columns)."""
        return np.array([[getattr(c, k) for _, c in self.items()] for k in ("offset", "scale", "delay", "drift", "leak")],
                        dtype=float)

    def to_json(self) -> dict:
        return {ch: c.to_json() for ch, c in self.items()}

    @classmethod
    def from_json(cls, d: dict | None) -> "Corrections":
        d = d or {}
        return cls(**{ch: ForceCorrection.from_json(d.get(ch)) for ch in FORCE_CHANNELS})


NO_CORRECTION = Corrections()


@dataclass(frozen=True)
class GyroCorrection:
    """One gyro axis: ``true = (measured - bias) / scale``; ``bias_drift``: the intensity of the
    bias's random walk [rad/s/sqrt(s)] where one was found (None: none)."""

    bias: float = 0.0
    scale: float = 1.0
    bias_drift: float | None = None

    def to_json(self) -> dict:
        return {f.name: float(getattr(self, f.name)) for f in fields(self) if getattr(self, f.name) is not None}


def corrections_json(corrections: dict) -> dict:
    """A dict of records (and plain dicts) as the report's JSON."""
    return {k: (v.to_json() if hasattr(v, "to_json") else v) for k, v in corrections.items()}
