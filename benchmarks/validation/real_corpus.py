"""Real-data corpus: an independent gyro-bias estimate for every recording of
``tests/data/real/SOURCES.toml``, and jaxdrift's attitude diagnosis of the same file against it.

Part 1, the independent estimate, uses numpy and scipy only (no jaxdrift code); the files are read
with pyulog, rosbags, asammdf or numpy:

1. gyro ``w`` (rad/s) on its own time stamps, reference attitude ``q`` (body to world, scalar
   first) on its own. ROS ``sensor_msgs/Imu``: header stamps. MDF4 GNSS/IMU: roll, pitch, heading
   (deg) read as z-y-x Euler angles.
2. Reference body rates from consecutive reference samples (``(q_k^-1 q_k+1).as_rotvec() / dt``).
   **Clock offset**: the lag that maximises the cross-correlation of ``|w|`` and ``|reference rate|``
   on a common uniform grid (parabolic peak refinement). **Frame rotation**: ``Rotation.align_vectors``
   of the reference body rates onto the gyro rates (at the estimated offset) when the excitation
   spans at least two axes; with one axis excited, only an axis convention (the signed permutation
   that fits the rates best, if it halves the misfit of the identity). Both are applied for motion
   capture (``csv``); for the other readers they are reported, and applied only when the rotation
   exceeds 45 degrees (another axis convention) or the offset exceeds two gyro steps with a
   correlation over 0.5.
3. Between consecutive reference samples the gyro (each sample's rate held over the step that ends
   at its time stamp, cut at the reference stamps) is integrated with ``scipy Rotation``, and the
   constant bias that makes it follow the reference's relative rotation is fitted by least squares
   over all intervals (Gauss-Newton, 3 passes); intervals holding a gyro gap (a step over 2.5
   nominal) are skipped. A PX4 log's rates are means over their own windows (``gyro_integral_dt``,
   used where the windows cover at least 80 % of the time): there an interval holding a step longer
   than its sample's window (a message the logger dropped) is skipped too, and the attitude is
   stamped by ``timestamp_sample`` (the IMU sample it is of, a window's end) where the log has it;
   such a reference's clock offset is reported, never applied. Standard error: spread of 20 contiguous time-block estimates / sqrt(20).
   Each half of the log is fitted separately. An axis is **clear** when ``|b| > 4 SE``,
   ``|b| > 0.3 mrad/s`` and the halves agree (within 4 combined SE or 25 % of ``b``).
4. White gyro noise on still spans: 1 s windows in which the reference turns less than 0.02 rad/s
   and the gyro's standard deviation is below 0.02 rad/s; per-sample std of first differences /
   sqrt(2), times sqrt(dt): ``N`` in rad/sqrt(s). None where there is no still span. Where a ULog
   says when the motors are armed (``actuator_armed``), only 0.5 s windows with the motors off.
5. The onboard estimator's gyro bias (PX4 ``estimator_sensor_bias``): first, last and mean per
   instance.

Part 2 runs ``jaxdrift diagnose FILE --json OUT`` (one at a time) with the ``--map`` the format
needs, and checks: every clear axis named as ``gyro_bias`` within 25 % of the independent value or
with an interval that contains it; nothing absurd (a scale off by more than 10 %, a bias over
0.2 rad/s, inf or NaN); whether the file needed ``--force``; the exit code; and the noise rule
(``noise_check``): a ``gyro_noise`` estimate within 3x of the still span's white noise, or an
upper bound not below a third of it with the vibration named.

Writes ``docs/validation/real_corpus.json`` and prints a Markdown table::

    python benchmarks/validation/real_corpus.py                 # both parts
    python benchmarks/validation/real_corpus.py --independent   # part 1 only
    python benchmarks/validation/real_corpus.py --only broad_07  # files whose name contains it

Fetched recordings are not committed (``tests/data/real/README.md``); a missing file is reported
as missing and skipped.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation as R

ROOT = Path(__file__).resolve().parents[2]
SOURCES = ROOT / "tests" / "data" / "real" / "SOURCES.toml"
OUT = ROOT / "docs" / "validation" / "real_corpus.json"

N_BLOCKS = 20
CLEAR_Z = 4.0
CLEAR_MIN = 3e-4


# ----------------------------------------------------------------------------------------- readers
def read_ulog(path):
    from pyulog import ULog

    u = ULog(str(path), ["sensor_combined", "vehicle_attitude", "estimator_sensor_bias", "actuator_armed"])
    sc = u.get_dataset("sensor_combined")
    va = u.get_dataset("vehicle_attitude")
    tq = va.data["timestamp"] * 1e-6
    sample_stamped = "timestamp_sample" in va.data and np.all(np.diff(va.data["timestamp_sample"].astype(float)) >= 0)
    if sample_stamped:
        tq = va.data["timestamp_sample"] * 1e-6  # the IMU sample the attitude is of: a window's end
    tg = sc.data["timestamp"] * 1e-6
    win = None
    if "gyro_integral_dt" in sc.data:
        win = sc.data["gyro_integral_dt"].astype(float)
        win = win * 1e-6 if np.median(win) >= 1.0 else win  # microseconds (PX4 after v1.8) or seconds
        steps = np.diff(tg)
        if not np.all(win > 0) or np.sum(np.minimum(win[1:], steps)) < 0.8 * (tg[-1] - tg[0]):
            win = None  # no windows, or windows that leave most of the time unmeasured: points
    out = {"tg": tg, "win": win, "ref_sample_stamped": bool(sample_stamped),
           "w": np.column_stack([sc.data[f"gyro_rad[{i}]"] for i in range(3)]).astype(float),
           "tq": tq,
           "q": np.column_stack([va.data[f"q[{i}]"] for i in range(4)]).astype(float),
           "hardware": u.msg_info_dict.get("ver_hw"), "onboard": [], "armed": None}
    for d in u.data_list:
        if d.name == "actuator_armed" and "armed" in d.data and len(d.data["armed"]):
            out["armed"] = (d.data["timestamp"] * 1e-6, d.data["armed"].astype(bool))
        if d.name == "estimator_sensor_bias" and "gyro_bias[0]" in d.data:
            b = np.column_stack([d.data[f"gyro_bias[{i}]"] for i in range(3)]).astype(float)
            dev = d.data.get("gyro_device_id")
            out["onboard"].append({"instance": int(d.multi_id), "n": int(len(b)),
                                   "device_id": int(dev[-1]) if dev is not None else None,
                                   "first": b[0].tolist(), "last": b[-1].tolist(),
                                   "mean": b.mean(0).tolist()})
    return out


def _topic(spec):
    return spec.split(".")[0]


def _orientation(m):
    """The quaternion of a sensor_msgs/Imu, nav_msgs/Odometry, geometry_msgs/PoseStamped or
    geometry_msgs/TransformStamped message."""
    if hasattr(m, "orientation"):
        return m.orientation
    if hasattr(m, "transform"):
        return m.transform.rotation
    return m.pose.pose.orientation if hasattr(m.pose, "pose") else m.pose.orientation


def read_rosbag(path, entry):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    gtopic, rtopic = _topic(entry["gyro"]), _topic(entry["ref"])
    tg, w, tq, q = [], [], [], []
    # a ROS 2 bag without message definitions inside needs the standard ones
    with AnyReader([Path(path)], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as rd:
        conns = [c for c in rd.connections if c.topic in (gtopic, rtopic)]
        for c, _, raw in rd.messages(connections=conns):
            m = rd.deserialize(raw, c.msgtype)
            t = m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec
            if c.topic == gtopic and hasattr(m, "angular_velocity"):
                a = m.angular_velocity
                tg.append(t); w.append((a.x, a.y, a.z))
            if c.topic == rtopic:
                o = _orientation(m)
                tq.append(t); q.append((o.w, o.x, o.y, o.z))
    tg, w, tq, q = map(np.asarray, (tg, w, tq, q))
    ig, iq = np.argsort(tg, kind="stable"), np.argsort(tq, kind="stable")
    return {"tg": tg[ig], "w": w[ig], "tq": tq[iq], "q": q[iq], "hardware": None, "onboard": []}


def read_csv(path):
    a = np.genfromtxt(path, delimiter=",", names=True)
    t = a["t"].astype(float)
    w = np.column_stack([a["wx"], a["wy"], a["wz"]]).astype(float)
    q = np.column_stack([a["qw"], a["qx"], a["qy"], a["qz"]]).astype(float)
    ok = np.all(np.isfinite(q), 1)
    return {"tg": t, "w": w, "tq": t[ok], "q": q[ok], "hardware": None, "onboard": []}


def read_mdf(path):
    from asammdf import MDF

    m = MDF(str(path))
    gx, gy, gz = (m.get(n) for n in ("AngularRateX", "AngularRateY", "AngularRateZ"))
    ro, pi, he = (m.get(n) for n in ("Roll", "Pitch", "Heading"))
    w = np.deg2rad(np.column_stack([gx.samples, gy.samples, gz.samples]).astype(float))
    eul = np.column_stack([he.samples, pi.samples, ro.samples]).astype(float)
    q = R.from_euler("ZYX", eul, degrees=True).as_quat()[:, [3, 0, 1, 2]]
    return {"tg": np.asarray(gx.timestamps, float), "w": w, "tq": np.asarray(he.timestamps, float),
            "q": q, "hardware": None, "onboard": []}


def read_entry(entry):
    path = ROOT / entry["file"]
    kind = entry["reader"]
    if kind == "ulog":
        d = read_ulog(path)
    elif kind == "rosbag":
        d = read_rosbag(path, entry)
    elif kind == "csv":
        d = read_csv(path)
    elif kind == "mdf":
        d = read_mdf(path)
    else:
        raise ValueError(f"unknown reader {kind!r}")
    # drop repeated stamps (a reference logged twice at one time carries no interval)
    for tk, vk in (("tg", "w"), ("tq", "q")):
        keep = np.concatenate([[True], np.diff(d[tk]) > 0])
        d[tk], d[vk] = d[tk][keep], d[vk][keep]
        if tk == "tg" and d.get("win") is not None:
            d["win"] = d["win"][keep]
    return d


# ------------------------------------------------------------------------------ independent estimate
def time_base(t):
    st = np.diff(t)
    nom = float(np.median(st))
    return {"n": int(len(t)), "duration_s": float(t[-1] - t[0]), "rate_hz": 1.0 / nom,
            "jitter_std": float(np.std(st / nom - 1.0)), "gaps": int(np.sum(st > 2.5 * nom)),
            "longest_step_s": float(st.max())}


def ref_rates(tq, q):
    rq = R.from_quat(q[:, [1, 2, 3, 0]])
    dt = np.diff(tq)
    return 0.5 * (tq[1:] + tq[:-1]), (rq[:-1].inv() * rq[1:]).as_rotvec() / dt[:, None]


def clock_offset(tg, w, tq, q):
    """Lag (s) to add to the reference's stamps so |reference rate| lines up with |gyro|."""
    tr, wr = ref_rates(tq, q)
    dt = max(np.median(np.diff(tg)), np.median(np.diff(tq)))
    lo, hi = max(tg[0], tr[0]), min(tg[-1], tr[-1])
    if hi - lo < 20 * dt:
        return 0.0, 0.0
    grid = np.arange(lo, hi, dt)
    a = np.interp(grid, tg, np.linalg.norm(w, axis=1))
    b = np.interp(grid, tr, np.linalg.norm(wr, axis=1))
    a, b = a - a.mean(), b - b.mean()
    if a.std() == 0 or b.std() == 0:
        return 0.0, 0.0
    maxlag = int(min(len(grid) // 4, max(5, round(0.5 / dt))))
    lags = np.arange(-maxlag, maxlag + 1)
    cc = np.array([np.dot(a[max(0, -k):len(a) - max(0, k)], b[max(0, k):len(b) - max(0, -k)])
                   for k in lags]) / (len(a) * a.std() * b.std())
    j = int(np.argmax(cc))
    frac = 0.0
    if 0 < j < len(cc) - 1:
        den = cc[j - 1] - 2 * cc[j] + cc[j + 1]
        frac = 0.5 * (cc[j - 1] - cc[j + 1]) / den if den != 0 else 0.0
    # b shifted by +k matches a: reference happens k steps later -> subtract
    return float(-(lags[j] + frac) * dt), float(cc[j])


def frame_rotation(tg, w, tq, q):
    """Rotation C with w_gyro ~ C w_ref (body rates), by align_vectors; None if not excited enough."""
    tr, wr = ref_rates(tq, q)
    wg = np.column_stack([np.interp(tr, tg, w[:, c]) for c in range(3)])
    m = np.linalg.norm(wr, axis=1) > 0.05
    if m.sum() < 20:
        return None, None
    s = np.linalg.svd(wr[m], compute_uv=False)
    if s[1] < 0.1 * s[0]:
        # one axis excited: only an axis convention (signed permutation) can be told
        cands = [c for c in R.create_group("O")]
        res = [np.sum((wg[m] - c.apply(wr[m])) ** 2) for c in cands]
        j = int(np.argmin(res))
        ident = int(np.argmin([c.magnitude() for c in cands]))
        if j != ident and res[j] < 0.5 * res[ident]:
            return cands[j], float(s[1] / s[0])
        return None, float(s[1] / s[0])
    rot, _ = R.align_vectors(wg[m], wr[m])
    return rot, float(s[1] / s[0])


def interval_errors(tg, w, tq, q, bias, win=None):
    """Per reference interval: rotation vector of (integrated gyro)^-1 (reference), in the body.
    ``win``: each gyro sample's logged window (PX4 ``gyro_integral_dt``); an interval holding a
    step longer than its sample's window (a message the logger dropped) is skipped."""
    dtg = np.median(np.diff(tg))
    rq = R.from_quat(q[:, [1, 2, 3, 0]])
    i0 = np.searchsorted(tq, tg[0], side="left")
    i1 = np.searchsorted(tq, tg[-1], side="right") - 1
    ia = np.arange(i0, i1)
    cuts = np.union1d(tg, tq[i0:i1 + 1])
    cuts = cuts[(cuts >= tq[i0]) & (cuts <= tq[i1])]
    k = np.clip(np.searchsorted(tg, 0.5 * (cuts[1:] + cuts[:-1])), 0, len(tg) - 1)
    piece = R.from_rotvec((w[k] - bias) * np.diff(cuts)[:, None])
    owner = np.searchsorted(tq[i0:i1 + 1], cuts[:-1], side="right") - 1
    gstep = np.diff(tg, prepend=tg[0] - dtg)[k]
    bad = np.zeros(len(ia), bool)
    np.logical_or.at(bad, owner, gstep > 2.5 * dtg)
    if win is not None:
        np.logical_or.at(bad, owner, gstep > 1.05 * win[k])
    starts = np.searchsorted(owner, np.arange(len(ia)))
    counts = np.bincount(owner, minlength=len(ia))
    prod = np.tile([0.0, 0.0, 0.0, 1.0], (len(ia), 1))
    for j in range(int(counts.max()) if len(counts) else 0):
        sel = np.nonzero(counts > j)[0]
        prod[sel] = (R.from_quat(prod[sel]) * piece[starts[sel] + j]).as_quat()
    e = (R.from_quat(prod).inv() * (rq[ia].inv() * rq[ia + 1])).as_rotvec()
    dt = tq[ia + 1] - tq[ia]
    return {"t": tq[ia], "dt": dt, "e": e, "ok": ~bad & (counts > 0)}


def _fit(tg, w, tq, q, iters=3, win=None):
    b = np.zeros(3)
    for _ in range(iters):
        ie = interval_errors(tg, w, tq, q, b, win)
        ok = ie["ok"]
        b = b - ie["e"][ok].sum(0) / ie["dt"][ok].sum()
    ie = interval_errors(tg, w, tq, q, b, win)
    return b, ie


def constant_bias(tg, w, tq, q, win=None):
    b, ie = _fit(tg, w, tq, q, win=win)
    ok = ie["ok"]
    e, dt, t = ie["e"][ok], ie["dt"][ok], ie["t"][ok]
    blk = np.minimum(((t - t[0]) / (t[-1] - t[0] + 1e-12) * N_BLOCKS).astype(int), N_BLOCKS - 1)
    est = np.array([b - e[blk == j].sum(0) / dt[blk == j].sum() for j in range(N_BLOCKS) if np.any(blk == j)])
    se = est.std(0, ddof=1) / np.sqrt(len(est))
    # each half fitted on its own
    tm = 0.5 * (t[0] + t[-1])
    halves = []
    for lo, hi in ((-np.inf, tm), (tm, np.inf)):
        mg = (tg > lo - 1.0) & (tg < hi + 1.0)
        mq = (tq >= max(lo, tq[0])) & (tq <= min(hi, tq[-1]))
        hb, hie = _fit(tg[mg], w[mg], tq[mq], q[mq], iters=2, win=None if win is None else win[mg])
        hok = hie["ok"]
        ht = hie["t"][hok]
        hblk = np.minimum(((ht - ht[0]) / (ht[-1] - ht[0] + 1e-12) * (N_BLOCKS // 2)).astype(int), N_BLOCKS // 2 - 1)
        hest = np.array([hb - hie["e"][hok][hblk == j].sum(0) / hie["dt"][hok][hblk == j].sum()
                         for j in range(N_BLOCKS // 2) if np.any(hblk == j)])
        halves.append((hb, hest.std(0, ddof=1) / np.sqrt(len(hest))))
    (h1, s1), (h2, s2) = halves
    clear = []
    for c in range(3):
        d = abs(h1[c] - h2[c])
        constant = d < CLEAR_Z * math.hypot(s1[c], s2[c]) or d < 0.25 * abs(b[c])
        clear.append(bool(abs(b[c]) > CLEAR_Z * se[c] and abs(b[c]) > CLEAR_MIN and constant))
    rate_resid = np.sqrt(np.mean((e / dt[:, None]) ** 2, 0))
    return {"bias": b.tolist(), "se": se.tolist(), "first_half": h1.tolist(), "first_half_se": s1.tolist(),
            "second_half": h2.tolist(), "second_half_se": s2.tolist(), "clear": clear,
            "intervals": int(ok.sum()), "intervals_skipped": int((~ok).sum()),
            "residual_rate_rms": rate_resid.tolist()}


def still_noise(tg, w, tq, q, armed=None):
    """White gyro noise density (rad/sqrt(s)) per axis on 1 s still windows, or None. Where the
    log says when the motors are armed (PX4 ``actuator_armed``), only 0.5 s windows with the motors
    off count: a multirotor armed on the ground holds still but shakes its gyro."""
    dtg = float(np.median(np.diff(tg)))
    tr, wr = ref_rates(tq, q)
    n = max(8, int(round((1.0 if armed is None else 0.5) / dtg)))
    if armed is not None:  # the armed state at each gyro sample (the last message before it)
        ta, a = armed
        k = np.searchsorted(ta, tg, side="right") - 1
        motors = np.where(k < 0, a[0], a[np.clip(k, 0, None)])
    if len(tg) < 2 * n:
        return None
    refmax = np.interp(tg, tr, np.linalg.norm(wr, axis=1))
    sel, spans = [], []
    for s in range(0, len(tg) - n, n):
        sl = slice(s, s + n)
        st = np.diff(tg[sl])
        if np.any(st > 1.5 * dtg):
            continue
        if armed is not None and motors[sl].any():
            continue
        if refmax[sl].max() < 0.02 and w[sl].std(0).max() < 0.02:
            sel.append(np.diff(w[sl], axis=0))
            spans.append([float(tg[s]), float(tg[s + n - 1])])
    if len(sel) < 1:
        return None
    d = np.concatenate(sel)
    sig = d.std(0) / np.sqrt(2)
    return {"windows": len(sel), "seconds": len(sel) * n * dtg, "sigma_per_sample": sig.tolist(),
            "density": (sig * np.sqrt(dtg)).tolist(), "motors_off": armed is not None,
            "windows_s": spans}


def independent(entry):
    t0 = time.perf_counter()
    d = read_entry(entry)
    tg, w, tq, q = d["tg"], d["w"], d["tq"], d["q"]
    q = q / np.linalg.norm(q, axis=1)[:, None]
    out = {"hardware": d["hardware"], "gyro": time_base(tg), "reference": time_base(tq)}
    off, cc = clock_offset(tg, w, tq, q)
    out["clock_offset_s"], out["clock_offset_corr"] = off, cc
    rot, cond = frame_rotation(tg, w, tq + off, q)
    out["frame_rotation_deg"] = None if rot is None else float(np.degrees(rot.magnitude()))
    out["frame_rotvec"] = None if rot is None else rot.as_rotvec().tolist()
    out["rate_excitation_ratio"] = cond
    dtg = float(np.median(np.diff(tg)))
    mocap = entry["reader"] == "csv"
    # an attitude stamped with the IMU sample it is of (PX4 ``timestamp_sample``) has no clock offset
    # to the gyro: the cross-correlation's lag is then its noise (-21 ms on a vibrating log)
    apply_off = mocap or (abs(off) > 2 * dtg and cc > 0.5 and not d.get("ref_sample_stamped"))
    apply_rot = rot is not None and (mocap or out["frame_rotation_deg"] > 45.0)
    out["applied"] = {"clock_offset": bool(apply_off), "frame_rotation": bool(apply_rot)}
    if apply_off:
        tq = tq + off
    if apply_rot:
        # reference body frame -> gyro frame: q_ref_in_gyro_frame = q_ref * C^-1
        rq = R.from_quat(q[:, [1, 2, 3, 0]]) * rot.inv()
        q = rq.as_quat()[:, [3, 0, 1, 2]]
    out["independent"] = constant_bias(tg, w, tq, q, d.get("win"))
    out["gyro_windows"] = d.get("win") is not None
    out["still_noise"] = still_noise(tg, w, tq, q, d.get("armed"))
    out["onboard_bias"] = d["onboard"] or None
    out["independent_seconds"] = time.perf_counter() - t0
    return out


# -------------------------------------------------------------------------------------- jaxdrift
def jaxdrift_args(entry):
    kind = entry["reader"]
    if kind == "rosbag":
        g, r = _topic(entry["gyro"]), _topic(entry["ref"])
        field = entry["ref"].split(".", 1)[1] if "." in entry["ref"] else "orientation"  # e.g. transform.rotation
        m = [f"w{a}={g}.angular_velocity.{a}" for a in "xyz"] + [f"q{a}={r}.{field}.{a}" for a in "wxyz"]
        return ["--map", ",".join(m)]
    if kind == "mdf":
        return ["--map", "wx=AngularRateX,wy=AngularRateY,wz=AngularRateZ"]
    return []


def _finite(x):
    if isinstance(x, dict):
        return all(_finite(v) for v in x.values())
    if isinstance(x, list):
        return all(_finite(v) for v in x)
    if isinstance(x, float):
        return math.isfinite(x)
    return True


def run_jaxdrift(entry, res, tmp):
    exe = str(Path(sys.executable).with_name("jaxdrift"))
    path = str(ROOT / entry["file"])
    out = {}
    for force in (False, True):
        js = Path(tmp) / ("r%d.json" % force)
        cmd = [exe, "-q", "diagnose", path, "--json", str(js)] + jaxdrift_args(entry) + (["--force"] if force else [])
        t0 = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
        out = {"cmd": " ".join(cmd[1:]).replace(str(ROOT) + "/", ""), "exit": p.returncode,
               "seconds": time.perf_counter() - t0, "needs_force": force,
               "stderr_tail": p.stderr[-3000:]}
        if p.returncode == 0 and js.exists():
            out["report"] = json.loads(js.read_text())
            break
        if p.returncode != 2:  # crash or interrupt: --force would not help
            break
    rep = out.get("report")
    if rep is None:
        out["checks"] = {"ran": False}
        return out
    findings = rep.get("findings", [])
    named = {f["channel"]: f for f in findings if f.get("cause") == "gyro_bias" and "channel" in f}
    ind = res["independent"]
    axes = []
    for c, ax in enumerate(("wx", "wy", "wz")):
        b = ind["bias"][c]
        f = named.get(ax)
        row = {"axis": ax, "independent": b, "se": ind["se"][c], "clear": ind["clear"][c],
               "jaxdrift": None if f is None else f.get("estimate"),
               "interval": None if f is None else f.get("interval")}
        if f is not None and f.get("estimate") is not None:
            e = f["estimate"]
            iv = f.get("interval") or [e, e]
            row["ok"] = bool(abs(e - b) <= 0.25 * abs(b) or (iv[0] <= b <= iv[1]))
        else:
            row["ok"] = False
        axes.append(row)
    absurd = []
    for f in findings:
        if f.get("cause") == "gyro_scale" and f.get("estimate") is not None:
            if abs(f["estimate"] - 1.0) > 0.10:
                absurd.append(f"scale {f.get('channel')} {f['estimate']:.3g}")
        if f.get("cause") == "gyro_bias" and f.get("estimate") is not None and abs(f["estimate"]) > 0.2:
            absurd.append(f"bias {f.get('channel')} {f['estimate']:.3g}")
    if not _finite(rep):
        absurd.append("inf/NaN in the report")
    noise = [f for f in findings if f.get("cause") == "gyro_noise"]
    # the rule: an estimate within 3x of the still span's white noise; else an upper bound
    # (not below the still level / 3) with the vibration named
    still = res.get("still_noise")
    noise_check = None
    if still and noise and len(noise) > 1 and still.get("windows_s"):
        # a log diagnosed in parts (one per gyro): the part that holds most of the still windows
        def held(f):
            a, b = (f.get("part") or {}).get("span_s", [-np.inf, np.inf])
            return sum(a <= 0.5 * (u + v) <= b for u, v in still["windows_s"])
        noise = sorted(noise, key=held, reverse=True)
    if still and noise and noise[0].get("estimate"):
        lvl = float(np.mean(still["density"]))
        est, kind = float(noise[0]["estimate"]), noise[0].get("estimate_kind")
        vib = any(f.get("cause") == "vibration" for f in findings)
        ok = (1 / 3 <= est / lvl <= 3) if kind == "estimate" else (est >= lvl / 3 and vib)
        noise_check = {"still": lvl, "jaxdrift": est, "kind": kind, "ratio": est / lvl, "vibration": vib,
                       "ok": bool(ok)}
    out["checks"] = {"ran": True, "axes": axes,
                     "clear_named": sum(a["ok"] for a in axes if a["clear"]),
                     "clear": sum(a["clear"] for a in axes), "absurd": absurd,
                     "causes": [f.get("cause") + (" " + f["channel"] if "channel" in f else "") for f in findings],
                     "gyro_noise": None if not noise else {"estimate": noise[0].get("estimate"),
                                                           "kind": noise[0].get("estimate_kind")},
                     "noise_check": noise_check,
                     "reference_inconsistent": sum(f.get("cause") == "reference_inconsistent" for f in findings),
                     "not_determined": rep.get("not_determined"),
                     "segments": len(((rep.get("run") or {}).get("time_base") or {}).get("segments") or [])}
    out.pop("report")
    return out


# ------------------------------------------------------------------------------------------ main
def _fmt(v, p=3):
    return "-" if v is None else f"{v:.{p}g}"


def table(results):
    rows = ["| file | device | format | duration [s] | gyro / ref [Hz] | independent bias [mrad/s] (SE) | clear | "
            "onboard mean [mrad/s] | still noise [rad/sqrt(s)] | jaxdrift (exit, force) | clear named | absurd |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        if "error" in r:
            rows.append(f"| {Path(r['file']).name} | {r['device']} | {r['format']} | | | reader failed: {r['error'][:120]} | | | | | | |")
            continue
        ind = r["independent"]
        bias = ", ".join(f"{1e3 * b:+.2f} ({1e3 * s:.2f})" for b, s in zip(ind["bias"], ind["se"]))
        clear = " ".join(a for a, c in zip("xyz", ind["clear"]) if c) or "none"
        ob = r.get("onboard_bias")
        obs = "-" if not ob else ", ".join(f"{1e3 * v:+.2f}" for v in ob[0]["mean"])
        sn = r.get("still_noise")
        sns = "-" if not sn else _fmt(max(sn["density"]))
        j = r.get("jaxdrift")
        if j is None:
            js, cn, ab = "not run", "-", "-"
        else:
            ch = j["checks"]
            js = f"{j['exit']}{', --force' if j['needs_force'] else ''}"
            cn = f"{ch['clear_named']}/{ch['clear']}" if ch.get("ran") else "-"
            ab = "; ".join(ch.get("absurd", [])) or "none" if ch.get("ran") else "-"
        rows.append(f"| {Path(r['file']).name} | {r['device']} | {r['format']} | {r['gyro']['duration_s']:.1f} | "
                    f"{r['gyro']['rate_hz']:.1f} / {r['reference']['rate_hz']:.1f} | {bias} | {clear} | {obs} | {sns} | {js} | {cn} | {ab} |")
    return "\n".join(rows)


def _versions():
    v = {"python": platform.python_version(), "numpy": np.__version__}
    import scipy
    v["scipy"] = scipy.__version__
    for mod in ("pyulog", "rosbags", "asammdf"):
        try:
            from importlib.metadata import version
            v[mod] = version(mod)
        except Exception:  # noqa: BLE001 - a missing optional reader is reported, not fatal
            v[mod] = None
    try:
        from importlib.metadata import version
        v["jaxdrift"] = version("jaxdrift")
    except Exception:  # noqa: BLE001
        v["jaxdrift"] = None
    return v


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sources", default=str(SOURCES))
    ap.add_argument("--out", default=str(OUT))
    ap.add_argument("--independent", action="store_true", help="part 1 only (no jaxdrift run)")
    ap.add_argument("--only", default=None, help="only files whose name contains this")
    a = ap.parse_args(argv)
    entries = tomllib.loads(Path(a.sources).read_text())["log"]
    if a.only:
        entries = [e for e in entries if a.only in e["file"]]
    results = []
    for e in entries:
        r = {k: e[k] for k in ("file", "repo", "commit", "path", "device", "format", "reader")}
        if not (ROOT / e["file"]).exists():
            r["error"] = "missing (fetched data are not committed: tests/data/real/README.md)"
            results.append(r)
            print(f"{e['file']}: missing", file=sys.stderr)
            continue
        try:
            r.update(independent(e))
        except Exception as exc:  # noqa: BLE001 - a reader failure is a result of the corpus
            r["error"] = f"{type(exc).__name__}: {exc}"
            results.append(r)
            print(f"{e['file']}: {r['error']}", file=sys.stderr)
            continue
        if not a.independent:
            with tempfile.TemporaryDirectory() as tmp:
                r["jaxdrift"] = run_jaxdrift(e, r, tmp)
        print(f"{e['file']}: done", file=sys.stderr)
        results.append(r)
    try:
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True,
                                text=True).stdout.strip()
    except OSError:
        commit = None
    doc = {"what": "independent gyro-bias estimates on real recordings and jaxdrift's diagnosis against them",
           "script": "benchmarks/validation/real_corpus.py", "jaxdrift_commit": commit,
           "machine": {"platform": platform.platform(), "cpu_count": os.cpu_count()},
           "versions": _versions(), "criteria": {"clear": "|b| > 4 SE, |b| > 0.3 mrad/s, halves agree (4 SE or 25 %)",
                                                 "named": "gyro_bias within 25 % or interval contains the value"},
           "logs": results}
    if a.only is None or a.out != str(OUT):
        Path(a.out).parent.mkdir(parents=True, exist_ok=True)
        Path(a.out).write_text(json.dumps(doc, indent=1, default=float) + "\n")
    print(table(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
