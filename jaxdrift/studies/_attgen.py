"""Seeded generator of attitude runs in the format of docs/measured-data.md (for tests and demos).

:func:`make_attitude_run` simulates a vehicle attitude history (:func:`jaxdrift.models._ins.vehicle_motion`),
samples its exact body rates and attitude, applies gyro effects (noise, bias, scale, bias random
walk), optionally an accelerometer array with gravity correction (3.3), a displaced sensor and a
non-rigid deformation, and writes ``run.csv`` (and ``sensors.json``). It returns the truth.

Conventions of the written file: ``wx, wy, wz`` at row ``k`` are the true body rate at ``t_k``
(not a step average) times ``scale`` plus the errors; the reference quaternion is the exact attitude
at ``t_k``. A diagnosis must therefore cope with an O(dt) discretisation mismatch, as with real data.
"""

from __future__ import annotations

import json
import os

import numpy as np

from ..diagnosis.attitude import gyro_forward
from ..models._ins import gyro_errors, vehicle_motion
from ..models._quaternion import rotation_matrix_np, skew_np

__all__ = ["make_attitude_run", "write_attitude_csv", "DEFAULT_POSITIONS"]

G = 9.81
# a plausible array: four corners of a 2.4 m x 1.4 m floor and one roof sensor (body frame, z down)
DEFAULT_POSITIONS = np.array(
    [[1.2, 0.7, 0.1], [1.2, -0.7, 0.1], [-1.2, 0.7, 0.1], [-1.2, -0.7, 0.1], [0.0, 0.0, -0.9]]
)


def write_attitude_csv(path, t, w, q_ref=None, acc=None, *, fmt="%.12g", extra=None):
    """Write an attitude run CSV: ``t, wx, wy, wz[, qw, qx, qy, qz][, a1x ... aNz]``.

    ``q_ref`` rows that are NaN are written as empty cells. ``acc`` has shape ``(n, N, 3)``.
    """
    cols = {"t": t, "wx": w[:, 0], "wy": w[:, 1], "wz": w[:, 2]}
    if q_ref is not None:
        for i, c in enumerate(("qw", "qx", "qy", "qz")):
            cols[c] = q_ref[:, i]
    if acc is not None:
        for i in range(acc.shape[1]):
            for j, ax in enumerate("xyz"):
                cols[f"a{i + 1}{ax}"] = acc[:, i, j]
    if extra:
        cols.update(extra)
    strs = []
    for v in cols.values():
        v = np.asarray(v, float)
        s = np.char.mod(fmt, v)
        s = np.where(np.isnan(v), "", s)
        strs.append(s)
    body = strs[0].astype(object)
    for s in strs[1:]:
        body = body + "," + s.astype(object)
    with open(path, "w") as fh:
        fh.write(",".join(cols) + "\n")
        fh.write("\n".join(body.tolist()))
        fh.write("\n")


def make_attitude_run(
    out_dir,
    seed: int,
    *,
    duration: float = 120.0,
    rate_hz: float = 500.0,
    arw: float = 0.0,
    bias=(0.0, 0.0, 0.0),
    scale=(1.0, 1.0, 1.0),
    rrw=(0.0, 0.0, 0.0),
    reference: str | int | None = "all",
    static_s: float = 0.0,
    positions=None,
    position_error: dict | None = None,
    nonrigid_rms: float = 0.0,
    accel_noise: float = 0.0,
    road_rms_deg: float = 0.5,
    curve_rate: float = 0.15,
    name: str = "run",
):
    """Write ``out_dir/<name>.csv`` (and ``<name>_sensors.json`` with an array) and return the truth.

    Args:
        reference: ``"all"`` (reference attitude on every row), an int ``k`` (every k-th row), or
            ``None`` (no reference columns).
        static_s: the vehicle stands still for this many seconds at the start.
        positions: ``(N, 3)`` sensor positions to write to the JSON (``None``: no array).
        position_error: ``{sensor (1-based): [dx, dy, dz]}``: true position = given + error.
        nonrigid_rms: RMS [m/s^2] per component of a deformation acceleration (sinusoidal modes,
            5-15 Hz) added to every sensor (zero mean per sensor).
        accel_noise: white noise [m/s^2] on every accelerometer component.
    """
    os.makedirs(out_dir, exist_ok=True)
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    n = int(round(duration * rate_hz)) + 1
    t = 12.5 + np.arange(n) * dt  # an arbitrary start time
    motion = vehicle_motion(seed, duration + 1.0, road_rms_deg=road_rms_deg, curve_rate=curve_rate, static_until=static_s)
    tl = t - t[0]
    q = motion.quaternion(tl)
    w_true = motion.body_rates(tl)
    err = gyro_errors(rng, n, dt, arw=arw, bias=bias, rrw=rrw)
    w_meas = gyro_forward(w_true, scale, err)  # the gyro's chain (the diagnosis undoes it with gyro_inverse)
    q_ref = None
    if reference is not None:
        q_ref = q * np.where(rng.random(n) < 0.5, 1.0, -1.0)[:, None]  # q and -q are the same attitude
        if reference != "all":
            keep = np.zeros(n, bool)
            keep[:: int(reference)] = True
            q_ref = np.where(keep[:, None], q_ref, np.nan)
    acc = None
    truth = {
        "dt": dt, "t": t, "q": q, "w_true": w_true, "gyro_error": err, "arw": arw, "bias": np.asarray(bias, float),
        "scale": np.asarray(scale, float), "rrw": np.asarray(rrw, float), "nonrigid_rms": nonrigid_rms,
        "position_error": position_error or {},
    }
    paths = {"run": os.path.join(out_dir, f"{name}.csv"), "sensors": None}
    if positions is not None:
        r = np.asarray(positions, float)
        r_true = r.copy()
        for k, d in (position_error or {}).items():
            r_true[int(k) - 1] += np.asarray(d, float)
        S = rotation_matrix_np(q)
        _, xdd = motion.position_acceleration(tl)
        alpha = motion.body_angular_acceleration(tl)
        K = skew_np(alpha) + skew_np(w_true) @ skew_np(w_true)  # S^T S''
        e3 = np.array([0.0, 0.0, 1.0])
        common = np.einsum("nji,nj->ni", S, xdd - G * e3) + G * e3  # S^T (x_C'' - g e3) + g e3
        acc = common[:, None, :] + np.einsum("nij,kj->nki", K, r_true)
        if nonrigid_rms:
            N = r.shape[0]
            f = rng.uniform(5.0, 15.0, (N, 3, 2))
            ph = rng.uniform(0, 2 * np.pi, (N, 3, 2))
            amp = rng.normal(size=(N, 3, 2))
            d = np.einsum("kjm,nkjm->nkj", amp, np.sin(2 * np.pi * f[None] * tl[:, None, None, None] + ph[None]))
            d *= nonrigid_rms / np.sqrt(np.mean(d**2))
            acc = acc + d
            truth["nonrigid_actual_rms"] = float(np.sqrt(np.mean(d**2)))
        if accel_noise:
            acc = acc + rng.normal(size=acc.shape) * accel_noise
        paths["sensors"] = os.path.join(out_dir, f"{name}_sensors.json")
        with open(paths["sensors"], "w") as fh:
            json.dump({"positions": r.tolist()}, fh)
        truth["positions_true"] = r_true
    write_attitude_csv(paths["run"], t, w_meas, q_ref, acc)
    truth["paths"] = paths
    return truth
