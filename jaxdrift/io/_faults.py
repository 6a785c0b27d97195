"""Logger faults found before anything is fitted: a channel that goes dead, sticks, or clips for
part of a run (numpy only).

A measured force is never exactly the same from one sample to the next for long: a tyre force on a
moving vehicle changes by far more than a logger's resolution every step. A channel that repeats
one value for :data:`STUCK_MIN_S` (and :data:`STUCK_MIN_SAMPLES` samples) or longer has stopped
measuring: ``dropout`` where it reads 0 (a loose connector, an amplifier that lost power),
``stuck`` where it holds another value (a frozen bus message). A channel pinned at its extreme value
on :data:`CLIP_MIN_SAMPLES` samples or more, in runs of at least two, is ``clipped`` (an amplifier
or an ADC at the end of its range): its largest peaks are lost. A minimum of exactly 0 is not a
clip: a tyre cannot pull, so a wheel force that reads 0 while the wheel is in the air is the
physics of a tyre lifting off (the ``tyre_lift_off`` cause), not the logger's range.

:func:`find_faults` lists them per channel with their span; :func:`sound_part` gives the longest
stretch of rows free of every fault, on which a vehicle run is then analysed (a run whose sound part
is shorter than :data:`SOUND_MIN_SHARE` of it is refused, saying why). Causes fitted on a dead
stretch would read the silence as a scale, a drift or an offset.
"""

from __future__ import annotations

import numpy as np

from ._timebase import longest_run, true_runs

__all__ = ["find_faults", "sound_part", "STUCK_MIN_S", "STUCK_MIN_SAMPLES", "CLIP_MIN_SAMPLES",
           "SOUND_MIN_SHARE"]

STUCK_MIN_S = 0.5
STUCK_MIN_SAMPLES = 50
CLIP_MIN_SAMPLES = 5
SOUND_MIN_SHARE = 0.2


def _stuck(t, x, dt):
    """Runs of exactly repeated values, long enough to be a fault: [(i0, i1, value)]."""
    same = np.concatenate([[False], x[1:] == x[:-1]])  # sample i repeats sample i - 1
    out = []
    need = max(STUCK_MIN_SAMPLES, int(np.ceil(STUCK_MIN_S / dt)))
    for a, b in true_runs(same):
        i0 = a - 1  # the first sample of the repeated value
        if b - i0 >= need:
            out.append((i0, b, float(x[i0])))
    return out


def _clipped(x, skip):
    """(i0, i1, value, count) spanning the samples pinned at the channel's extreme, or None.
    ``skip``: samples of a stuck or dead stretch (a dead channel's zeros are its minimum, not a
    clip)."""
    fin = x[np.isfinite(x) & ~skip]
    if fin.size < 100:
        return None
    lo = float(fin.min())
    for v in (float(fin.max()), lo):
        if v == 0.0 == lo:
            continue  # a tyre in the air, not a clip
        at = (x == v) & ~skip
        n = int(at.sum())
        if n < CLIP_MIN_SAMPLES:
            continue
        runs = [(a, b) for a, b in true_runs(at) if b - a >= 2]
        if sum(b - a for a, b in runs) >= CLIP_MIN_SAMPLES:
            idx = np.flatnonzero(at)
            return int(idx[0]), int(idx[-1]) + 1, v, n
    return None


def find_faults(t: np.ndarray, channels: dict, names=None) -> list[dict]:
    """Faults of ``channels`` ({name: values on ``t``}), each ``{"channel", "kind", "span_s",
    "rows", "samples", "value", "evidence"}``; ``names``: the channels to check (default all)."""
    t = np.asarray(t, float)
    if len(t) < 2:
        return []
    dt = float((t[-1] - t[0]) / (len(t) - 1))
    out = []
    for c in names or list(channels):
        x = np.asarray(channels[c], float)
        skip = np.zeros(len(x), bool)
        for i0, i1, v in _stuck(t, x, dt):
            skip[i0:i1] = True
            kind = "dropout" if v == 0.0 else "stuck"
            out.append({"channel": c, "kind": kind, "span_s": [float(t[i0]), float(t[i1 - 1])], "rows": [int(i0), int(i1)],
                        "samples": int(i1 - i0), "value": v,
                        "evidence": (f"{c} reads exactly {v:.6g} on {i1 - i0} samples in a row "
                                     f"(t = {t[i0]:.6g} .. {t[i1 - 1]:.6g} s): "
                                     + ("the channel went dead" if kind == "dropout" else "the channel stuck"))})
        cl = _clipped(x, skip)
        if cl is not None:
            i0, i1, v, n = cl
            out.append({"channel": c, "kind": "clipped", "span_s": [float(t[i0]), float(t[i1 - 1])], "rows": [int(i0), int(i1)],
                        "samples": n, "value": v,
                        "evidence": (f"{c} sits at its extreme value {v:.6g} on {n} samples, in runs of two or more "
                                     f"(t = {t[i0]:.6g} .. {t[i1 - 1]:.6g} s): the channel clips at its range")})
    return out


def sound_part(n: int, faults: list[dict]) -> tuple[int, int]:
    """The longest stretch ``[i0, i1)`` of rows free of every fault (a clipped channel's pinned
    samples and the samples between them where they come in bursts are faults)."""
    bad = np.zeros(n, bool)
    for f in faults:
        i0, i1 = f["rows"]
        bad[i0:i1] = True
    return longest_run(~bad)
