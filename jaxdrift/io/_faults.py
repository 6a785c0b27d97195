"""Logger faults found before anything is fitted: a channel that goes dead or sticks for part of a
run (numpy only).

A measured force is never exactly the same from one sample to the next for long: a tyre force on a
moving vehicle changes by far more than a logger's resolution every step. A channel that repeats
one value for :data:`STUCK_MIN_S` (and :data:`STUCK_MIN_SAMPLES` samples) or longer has stopped
measuring: ``dropout`` where it reads 0 (a loose connector, an amplifier that lost power),
``stuck`` where it holds another value (a frozen bus message).

:func:`find_faults` lists them per channel with their span; :func:`sound_part` gives the longest
stretch of rows free of every fault, on which a vehicle run is then analysed (a run whose sound part
is shorter than :data:`SOUND_MIN_SHARE` of it is refused, saying why). Causes fitted on a dead
stretch would read the silence as a scale, a drift or an offset.

A channel that clips at its range loses its peaks, not the rest of its record: it is a cause the
vehicle diagnosis reads off the forces and undoes in place (``force_clipping``), not a fault that
costs the run its clipped stretch.
"""

from __future__ import annotations

import numpy as np

from ._timebase import longest_run, true_runs

__all__ = ["find_faults", "sound_part", "STUCK_MIN_S", "STUCK_MIN_SAMPLES", "SOUND_MIN_SHARE"]

STUCK_MIN_S = 0.5
STUCK_MIN_SAMPLES = 50
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
        for i0, i1, v in _stuck(t, x, dt):
            kind = "dropout" if v == 0.0 else "stuck"
            out.append({"channel": c, "kind": kind, "span_s": [float(t[i0]), float(t[i1 - 1])], "rows": [int(i0), int(i1)],
                        "samples": int(i1 - i0), "value": v,
                        "evidence": (f"{c} reads exactly {v:.6g} on {i1 - i0} samples in a row "
                                     f"(t = {t[i0]:.6g} .. {t[i1 - 1]:.6g} s): "
                                     + ("the channel went dead" if kind == "dropout" else "the channel stuck"))})
    return out


def sound_part(n: int, faults: list[dict]) -> tuple[int, int]:
    """The longest stretch ``[i0, i1)`` of rows free of every fault."""
    bad = np.zeros(n, bool)
    for f in faults:
        i0, i1 = f["rows"]
        bad[i0:i1] = True
    return longest_run(~bad)
