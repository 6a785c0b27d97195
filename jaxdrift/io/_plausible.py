"""Plausibility checks of a run before any computation: unit mistakes, dead channels, glitches.

Each check names the column and the likely cause. The checks are deliberately coarse (a factor of
1.5 on the static load, 0.5 rad of pitch, 20 Hz of sample rate, three orders of magnitude for an
isolated sample), so that every file the contract describes passes and the usual unit mistakes
(kN, ms, degrees) do not: those change a value by a factor of 57 to 1000.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MAX_STEP_S", "plausibility_problems"]

STATIC_RATIO_TOL = 1.5
#: a step longer than this is no vehicle-dynamics run (most likely t in milliseconds)
MAX_STEP_S = 0.05
MAX_PITCH_RAD = 0.5
#: above the full scale of any MEMS gyro (4000 deg/s = 70 rad/s; hand-spun IMUs read 35 rad/s and
#: more), while rates in deg/s read as rad/s exceed it from 1.4 rad/s of true motion on
MAX_RATE_RAD_S = 80.0
MAX_SPRING_M = 0.5
MAX_EXCURSION_M = 20.0
MAX_ACCEL = 2000.0
SPIKE_FACTOR = 1e3
#: columns whose constancy says nothing (a reference quaternion may stand still)
_MAY_BE_CONSTANT = {"qw", "qx", "qy", "qz"}

_UNIT_HINT = {"force": "kN", "angle": "deg", "rate": "deg/s", "length": "mm"}


def _static_problem(t, f1, f2, model, model_label, name_of) -> str | None:
    """The mean of f1 + f2 over the whole run against the model's weight. Whatever the road, the
    tyres carry the weight on average (the chassis' mean vertical acceleration over a run is its
    change of vertical speed over the duration, nil for a run that starts and ends on the road);
    the start alone is not at rest on a rough road at speed (a class D run at 25 m/s: 0.666 of
    the weight over its first 0.2 s, 0.99 over the whole run)."""
    s = float(np.mean(f1 + f2))
    w = (model["m1"] + model["m2"] + model["m3"]) * model["g"]
    r = s / w
    if 1.0 / STATIC_RATIO_TOL <= r <= STATIC_RATIO_TOL:
        return None
    c1, c2 = name_of("f1"), name_of("f2")
    if 3e-4 <= r <= 3e-3:
        why = "forces in kN? (--units f1=kN,f2=kN)"
    elif 0.03 <= r <= 0.3:
        why = "forces in daN? (--units f1=daN,f2=daN), or a wrong model (--model)?"
    elif r < 0:
        why = "the sign convention? (a tyre force is positive when the tyre is compressed)"
    else:
        why = "a wrong model (--model) or wrong columns (--map)?"
    return (f"columns {c1}, {c2}: mean force sum f1 + f2 = {s:.4g} N over the whole run "
            f"(the static load), but {model_label} weighs (m1 + m2 + m3) g = {w:.5g} N "
            f"(ratio {r:.3g}): {why}")


def _spike(x) -> tuple[int, float] | None:
    """Index and factor of the worst isolated sample more than SPIKE_FACTOR times the spread of
    the central 98 % of the samples away from their median."""
    if x.size < 20:
        return None
    lo, med, hi = np.quantile(x, [0.01, 0.5, 0.99])
    spread = max(hi - lo, 1e-9 * abs(med), 1e-300)
    dev = np.abs(x - med)
    i = int(np.argmax(dev))
    f = dev[i] / spread
    return (i, float(f)) if f > SPIKE_FACTOR else None


def plausibility_problems(kind: str, t: np.ndarray, channels: dict, *, where, name_of,
                          model: dict | None = None, model_label: str = "the model",
                          quantity_of=lambda c: None, time_unit_known: bool = False) -> list[str]:
    """Messages for everything implausible in a run (empty when it looks fine).

    ``where(row, col)`` gives ``file, line L, column c``; ``name_of(col)`` the file's name of a
    contract column (after ``--map``). ``time_unit_known``: the format fixes the time unit (a
    ULog's microseconds, a bag's nanoseconds, an MDF4 master channel, ``--units t=...``), so a
    coarse step is a coarse log, never a unit mistake."""
    out = []
    bad = set()
    dt = float((t[-1] - t[0]) / (len(t) - 1))
    if dt > MAX_STEP_S and not time_unit_known:
        out.append(f"column {name_of('t')}: sample step {dt:.6g} s ({1 / dt:.3g} Hz) is far too "
                   f"coarse for vehicle dynamics: is t in milliseconds? (--units t=ms, or --fs)")
    for c, x in channels.items():
        if c in _MAY_BE_CONSTANT:
            continue
        fin = x[np.isfinite(x)]
        if fin.size and fin.min() == fin.max():
            v = float(fin[0])
            what = "all zero: a channel that was not recorded?" if v == 0 else f"all {v:.6g}: a dead channel?"
            out.append(f"column {name_of(c)}: constant, {what}")
            bad.add(c)
            continue
        sp = _spike(fin) if fin.size == x.size else None
        if sp is not None:
            i, f = sp
            out.append(f"{where(i, name_of(c))}: value {x[i]:.6g} lies {f:.2g} times the spread of the "
                       f"other samples away from their median: an isolated bad sample (logger glitch)?")
            bad.add(c)
            continue
        q = quantity_of(c)
        amax = float(np.max(np.abs(fin))) if fin.size else 0.0
        if c == "beta" and amax > MAX_PITCH_RAD:
            out.append(f"column {name_of(c)}: |beta| reaches {amax:.4g} rad (> {MAX_PITCH_RAD:g} rad = "
                       f"{np.degrees(MAX_PITCH_RAD):.0f} deg): degrees? (--units beta=deg)")
        elif q == "rate" and amax > MAX_RATE_RAD_S:
            out.append(f"column {name_of(c)}: |{c}| reaches {amax:.4g} rad/s (> {MAX_RATE_RAD_S:g}): "
                       f"deg/s? (--units {c}=deg/s)")
        elif c in ("s1", "s2") and amax > MAX_SPRING_M:
            out.append(f"column {name_of(c)}: spring travel reaches {amax:.4g} m (> {MAX_SPRING_M:g} m): "
                       f"millimetres? (--units {c}=mm)")
        elif c in ("z3", "zeta1", "zeta2") and float(np.ptp(fin)) > MAX_EXCURSION_M:
            out.append(f"column {name_of(c)}: range {float(np.ptp(fin)):.4g} m (> {MAX_EXCURSION_M:g} m): "
                       f"millimetres? (--units {c}=mm)")
        elif q == "acceleration" and amax > MAX_ACCEL:
            out.append(f"column {name_of(c)}: |{c}| reaches {amax:.4g} m/s^2 (> {MAX_ACCEL:g}): "
                       f"mm/s^2? (--units {c}=mm/s^2)")
    if kind in ("vehicle", "durability") and "f1" in channels and "f2" in channels and model is not None:
        if not bad & {"f1", "f2"}:
            msg = _static_problem(t, channels["f1"], channels["f2"], model, model_label, name_of)
            if msg:
                out.append(msg)
    return out
