"""Real-data validation of the attitude diagnosis on PX4 flight-controller logs (ULog).

For each log: what it holds (hardware, gyro and attitude rates, gaps), an independent estimate of
the constant gyro bias, the flight controller's own bias estimate where the log has one
(``estimator_sensor_bias.gyro_bias``), the ``jaxdrift diagnose`` report, and the attitude error of
the gyro integrated from the first reference sample before and after the report's corrections.

The independent estimate shares no code with jaxdrift: the log is read with ``pyulog``; between
consecutive attitude samples the gyro (each sample's rate held over the step that ends at its
timestamp, cut at the attitude timestamps) is integrated with ``scipy.spatial.transform.Rotation``
and compared with the reference's relative rotation; the constant bias that makes them agree is the
least-squares solution over all intervals (three Gauss-Newton passes); intervals holding a gyro gap
(a step over 2.5 nominal) are skipped. Its standard error is the spread of 20 block estimates
(contiguous blocks in time) over sqrt(20). An axis is **clear** when the estimate exceeds 4 standard
errors and 3e-4 rad/s, and the constant-bias model fits: the first-half and second-half block means
agree within 4 combined standard errors or 25 %. (A reference that turns while the gyro does not,
as an estimator still converging, fails that check.)

Checks (per log): every clear axis is named as ``gyro_bias`` within 25 % of the independent value or
with an interval that contains it; no report value is inf or NaN; no ``gyro_scale`` off by more than
10 % and no ``gyro_bias`` over 0.2 rad/s; the attitude error falls wherever a bias was found.

Needs ``pip install -e ".[ulog]"`` (pyulog, and jaxdrift's ULog reader). Examples::

    python benchmarks/validation/real_logs.py tests/data/ulog/*.ulg --out docs/validation/real_logs.json
    python benchmarks/validation/real_logs.py tests/data/ulog/*.ulg --export /tmp/csv --out docs/validation/real_logs_csv.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation as R


def read_ulog(path):
    """Gyro (sensor_combined), attitude (vehicle_attitude) and the estimator's gyro bias, by pyulog."""
    try:
        from pyulog import ULog
    except ImportError:
        sys.exit("benchmarks/validation/real_logs.py needs pyulog: pip install pyulog")
    u = ULog(str(path), ["sensor_combined", "vehicle_attitude", "estimator_sensor_bias"])
    sc = u.get_dataset("sensor_combined")
    va = u.get_dataset("vehicle_attitude")
    out = {"tg": sc.data["timestamp"] * 1e-6, "w": np.column_stack([sc.data[f"gyro_rad[{i}]"] for i in range(3)]),
           "tq": va.data["timestamp"] * 1e-6, "q": np.column_stack([va.data[f"q[{i}]"] for i in range(4)]),
           "ver_hw": u.msg_info_dict.get("ver_hw"), "fc_bias": None}
    for d in u.data_list:
        if d.name == "estimator_sensor_bias" and d.multi_id == 0 and "gyro_bias[0]" in d.data:
            out["fc_bias"] = {"t": d.data["timestamp"] * 1e-6,
                              "b": np.column_stack([d.data[f"gyro_bias[{i}]"] for i in range(3)])}
    return out


def time_base(t):
    st = np.diff(t)
    nom = float(np.median(st))
    dev = st / nom - 1.0
    return {"n": int(len(t)), "duration_s": float(t[-1] - t[0]), "rate_hz": 1.0 / nom,
            "jitter_std": float(np.std(dev)), "jitter_max": float(np.max(np.abs(dev))),
            "gaps": int(np.sum(st > 2.5 * nom)), "longest_gap_s": float(st.max())}


def interval_errors(tg, w, tq, q, bias, scale=np.ones(3)):
    """Per reference interval: body-frame rotation vector of (gyro rel)^-1 (ref rel), and its length."""
    dtg = np.median(np.diff(tg))
    rq = R.from_quat(q[:, [1, 2, 3, 0]])
    i0 = np.searchsorted(tq, tg[0], side="left"); i1 = np.searchsorted(tq, tg[-1], side="right") - 1
    ia = np.arange(i0, i1)  # interval ia: tq[ia] .. tq[ia+1]
    # sample k holds its rate over (tg[k-1], tg[k]]; cut the time axis at every gyro stamp and reference stamp
    cuts = np.union1d(tg, tq[i0:i1 + 1])
    cuts = cuts[(cuts >= tq[i0]) & (cuts <= tq[i1])]
    k = np.searchsorted(tg, 0.5 * (cuts[1:] + cuts[:-1]))  # sample whose hold interval covers the piece
    k = np.clip(k, 0, len(tg) - 1)
    piece = R.from_rotvec((w[k] - bias) / scale * np.diff(cuts)[:, None])
    owner = np.searchsorted(tq[i0:i1 + 1], cuts[:-1], side="right") - 1
    # gap: a gyro step longer than 2.5 nominal inside the interval
    gstep = np.diff(tg, prepend=tg[0] - dtg)[k]
    bad = np.zeros(len(ia), bool); np.logical_or.at(bad, owner, gstep > 2.5 * dtg)
    starts = np.searchsorted(owner, np.arange(len(ia))); counts = np.bincount(owner, minlength=len(ia))
    prod = R.identity(len(ia))
    for j in range(int(counts.max())):
        m = counts > j
        sel = np.nonzero(m)[0]
        if len(sel) == 0:
            break
        p = prod[sel] * piece[starts[sel] + j]
        q_all = prod.as_quat(); q_all[sel] = p.as_quat(); prod = R.from_quat(q_all)
    ref = rq[ia].inv() * rq[ia + 1]
    e = (prod.inv() * ref).as_rotvec()
    dt = tq[ia + 1] - tq[ia]
    ok = ~bad & (counts > 0)
    wbar = np.stack([np.bincount(owner, weights=(w[k, c] - bias[c]) * np.diff(cuts), minlength=len(ia)) for c in range(3)], 1)
    return {"t": tq[ia], "dt": dt, "e": e, "ok": ok, "wbar": wbar / np.maximum(dt, 1e-12)[:, None]}

def constant_bias(tg, w, tq, q, n_blocks=20, iters=3):
    """Constant gyro bias that makes the integrated gyro follow the reference between consecutive
    reference samples: least squares over the intervals, SE from the spread of block estimates."""
    b = np.zeros(3)
    for _ in range(iters):
        ie = interval_errors(tg, w, tq, q, b)
        ok = ie["ok"]
        e, dt, t = ie["e"][ok], ie["dt"][ok], ie["t"][ok]
        # e = -(delta b) dt (body frame, small intervals): least squares delta b = -sum e / sum dt
        b = b - e.sum(0) / dt.sum()
    blk = np.minimum(((t - t[0]) / (t[-1] - t[0] + 1e-12) * n_blocks).astype(int), n_blocks - 1)
    est = np.array([b - e[blk == j].sum(0) / dt[blk == j].sum() for j in range(n_blocks) if np.any(blk == j)])
    se = est.std(0, ddof=1) / np.sqrt(len(est))
    half = len(est) // 2
    h1, h2 = est[:half].mean(0), est[half:].mean(0)
    h_se = np.hypot(est[:half].std(0, ddof=1) / np.sqrt(half), est[half:].std(0, ddof=1) / np.sqrt(len(est) - half))
    rms_rate = np.sqrt(np.mean((e / dt[:, None]) ** 2, 0))
    return {"bias": b, "se": se, "blocks": est, "first_half": h1, "second_half": h2, "halves_se": h_se,
            "intervals": int(ok.sum()), "intervals_skipped": int((~ok).sum())}

def attitude_error(tg, w, tq, q, bias, scale=np.ones(3)):
    """RMS angle between the gyro-integrated attitude (from the first reference sample) and the reference."""
    rq = R.from_quat(q[:, [1, 2, 3, 0]])
    i0 = np.searchsorted(tq, tg[0]); i1 = np.searchsorted(tq, tg[-1], side="right") - 1
    cuts = np.union1d(tg, tq[i0:i1 + 1]); cuts = cuts[(cuts >= tq[i0]) & (cuts <= tq[i1])]
    k = np.clip(np.searchsorted(tg, 0.5 * (cuts[1:] + cuts[:-1])), 0, len(tg) - 1)
    rv = (w[k] - bias) / scale * np.diff(cuts)[:, None]
    att = rq[i0]; errs = []
    refidx = np.searchsorted(cuts, tq[i0 + 1:i1 + 1])
    pieces = R.from_rotvec(rv)
    # cumulative product in chunks
    Q = np.empty((len(rv) + 1, 4)); Q[0] = att.as_quat(); cur = att
    for j in range(len(rv)):
        cur = cur * pieces[j]; Q[j + 1] = cur.as_quat()
    G = R.from_quat(Q[refidx])
    ang = (G.inv() * rq[i0 + 1:i1 + 1]).magnitude()
    return float(np.sqrt(np.mean(ang ** 2))), float(ang.max())


def bias_and_scale(tg, w, tq, q, n_blocks=20, iters=4):
    """Constant bias and scale per axis (``w = s omega + b``) by the same interval comparison: per
    axis, least squares of the interval errors on ``[dt, mean rate x dt]``; standard errors from the
    spread of 20 block estimates."""
    b, sc = np.zeros(3), np.ones(3)
    for _ in range(iters):
        ie = interval_errors(tg, w, tq, q, b, sc)
        ok = ie["ok"]
        e, dt, wb, t = ie["e"][ok], ie["dt"][ok], ie["wbar"][ok], ie["t"][ok]
        for c in range(3):
            X = np.column_stack([dt, wb[:, c] * dt]) / sc[c]
            db, dsc = np.linalg.lstsq(X, -e[:, c], rcond=None)[0]
            b[c] += db
            sc[c] += dsc
    blk = np.minimum(((t - t[0]) / (t[-1] - t[0] + 1e-12) * n_blocks).astype(int), n_blocks - 1)
    est = []
    for j in range(n_blocks):
        m = blk == j
        if m.sum() < 3:
            continue
        row = []
        for c in range(3):
            X = np.column_stack([dt[m], wb[m, c] * dt[m]]) / sc[c]
            row.append(np.linalg.lstsq(X, -e[m, c], rcond=None)[0][1] + sc[c])
        est.append(row)
    est = np.array(est)
    return {"bias": b, "scale": sc, "scale_se": est.std(0, ddof=1) / np.sqrt(len(est))}


def clear_axes(cb):
    out = []
    for c in range(3):
        b, se = cb["bias"][c], cb["se"][c]
        d = abs(cb["first_half"][c] - cb["second_half"][c])
        constant = d < 4.0 * cb["halves_se"][c] or d < 0.25 * abs(b)
        out.append(bool(abs(b) > 4.0 * se and abs(b) > 3e-4 and constant))
    return out


def _floats_ok(x):
    if isinstance(x, dict):
        return all(_floats_ok(v) for v in x.values())
    if isinstance(x, list):
        return all(_floats_ok(v) for v in x)
    if isinstance(x, float):
        return math.isfinite(x)
    if isinstance(x, str):
        import re
        return not re.search(r"(?<![A-Za-z])[-+]?(inf|nan)(?![A-Za-z])", x, re.I)
    return True


def analyse(path, csv_dir=None, export=None):
    """One log: the independent estimates, the report and the checks. The run diagnosed is the .ulg
    itself, or ``csv_dir/NAME.csv``, or (``export``: a folder) the log's CSV export as recorded,
    written there by :func:`jaxdrift.io.export_recorded_csv`."""
    import jaxdrift

    d = read_ulog(path)
    t0 = time.perf_counter()
    cb = constant_bias(d["tg"], d["w"], d["tq"], d["q"])
    t_ind = time.perf_counter() - t0
    if export:
        from jaxdrift.io import export_recorded_csv

        run_path = Path(export) / (Path(path).stem + ".csv")
        export_recorded_csv(str(path), str(run_path))
    else:
        run_path = Path(csv_dir) / (Path(path).stem + ".csv") if csv_dir else Path(path)
    t0 = time.perf_counter()
    rep = jaxdrift.run_attitude_diagnosis(str(run_path))
    t_diag = time.perf_counter() - t0
    corr = rep["extended_model"]["corrections"]
    b_j = np.array([corr[c]["bias"] for c in ("wx", "wy", "wz")])
    s_j = np.array([corr[c]["scale"] for c in ("wx", "wy", "wz")])
    before = attitude_error(d["tg"], d["w"], d["tq"], d["q"], np.zeros(3))
    after = attitude_error(d["tg"], d["w"], d["tq"], d["q"], b_j, s_j)
    after_ind = attitude_error(d["tg"], d["w"], d["tq"], d["q"], cb["bias"])
    clear = clear_axes(cb)
    bs = bias_and_scale(d["tg"], d["w"], d["tq"], d["q"])
    biases = {f["channel"]: f for f in rep["findings"] if f["cause"] == "gyro_bias"}
    checks = {"exit_0": True, "finite": _floats_ok(rep)}
    named = []
    for c, ch in enumerate(("wx", "wy", "wz")):
        if not clear[c]:
            continue
        f = biases.get(ch)
        ok = f is not None and (abs(f["estimate"] - cb["bias"][c]) <= 0.25 * abs(cb["bias"][c])
                                or f["interval"][0] <= cb["bias"][c] <= f["interval"][1])
        named.append(ok)
    checks["clear_biases_named"] = all(named)
    checks["no_absurd_scale_or_bias"] = all(
        not (f["cause"] == "gyro_scale" and abs(f["estimate"] - 1) > 0.1)
        and not (f["cause"] == "gyro_bias" and abs(f["estimate"]) > 0.2) for f in rep["findings"])
    checks["attitude_error_falls"] = (not biases) or after[0] < before[0]
    fc = None
    if d["fc_bias"] is not None:
        fc = {"first": d["fc_bias"]["b"][0].tolist(), "last": d["fc_bias"]["b"][-1].tolist(),
              "t_first": float(d["fc_bias"]["t"][0] - d["tg"][0]), "t_last": float(d["fc_bias"]["t"][-1] - d["tg"][0])}
    return {
        "log": Path(path).name, "hardware": d["ver_hw"], "diagnosed_from": run_path.name,
        "gyro": time_base(d["tg"]), "attitude": time_base(d["tq"]),
        "independent": {"bias": cb["bias"].tolist(), "se": cb["se"].tolist(), "first_half": cb["first_half"].tolist(),
                        "second_half": cb["second_half"].tolist(), "halves_se": cb["halves_se"].tolist(),
                        "clear": clear, "scale_with_bias": bs["scale"].tolist(), "scale_se": bs["scale_se"].tolist(),
                        "intervals": cb["intervals"], "intervals_skipped": cb["intervals_skipped"],
                        "attitude_error_rms_after": after_ind[0]},
        "flight_controller_bias": fc,
        "findings": [{k: f.get(k) for k in ("cause", "channel", "axis", "span_s", "estimate_kind", "estimate", "interval")}
                     for f in rep["findings"]],
        "not_determined": rep.get("not_determined", []),
        "report_gain": rep["gain"],
        "attitude_error_rms": {"before": before[0], "after": after[0], "unit": "rad"},
        "attitude_error_max": {"before": before[1], "after": after[1], "unit": "rad"},
        "checks": checks, "seconds": {"independent": t_ind, "diagnosis": t_diag},
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n\n", 1)[1])
    ap.add_argument("logs", nargs="+", help="ULog files (.ulg)")
    ap.add_argument("--csv", metavar="DIR", help="diagnose DIR/NAME.csv (CSV files made elsewhere) instead of the .ulg")
    ap.add_argument("--export", metavar="DIR", help="diagnose the logs' CSV exports as recorded (jittered t, gaps, the "
                    "reference on its own rows), written into DIR by jaxdrift.io.export_recorded_csv")
    ap.add_argument("--out", required=True, help="JSON results")
    a = ap.parse_args(argv)
    res = []
    for p in a.logs:
        r = analyse(p, a.csv, a.export)
        res.append(r)
        print(f"{r['log']}: {r['hardware']}; checks {r['checks']}; attitude error {r['attitude_error_rms']['before']:.4g} -> "
              f"{r['attitude_error_rms']['after']:.4g} rad", flush=True)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps({"logs": res}, indent=1, allow_nan=False) + "\n")
    return 0 if all(all(r["checks"].values()) for r in res) else 1


if __name__ == "__main__":
    sys.exit(main())
