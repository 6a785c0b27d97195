"""Benchmark: read a 5 million row x 6 column vehicle run (target: < 10 s and < 1 GB peak), and a
30-minute PX4 ULog (about 450,000 gyro samples; target: < 10 s and < 1 GB peak).

Writes a CSV of ``--rows`` rows (columns t, f1, f2, beta, beta_rate, z3 at 1 kHz, printed with
shortest round-trip decimals; plausible signals, so that the plausibility checks pass), then reads
it with ``jaxdrift.io.load_run`` (all checks on) in a fresh Python process, ``--repeat`` times, and
records the wall time of the read and the process's peak resident memory (``ru_maxrss``), next to
the peak of a process that only imports the reader (the baseline). Optionally (``--parquet``) the
same for a Parquet copy. A benchmark, not a test: timings never enter the test suite.

    python benchmarks/reader.py [--rows 5000000] [--repeat 3] [--parquet] [--out benchmarks/results]
    python benchmarks/reader.py --ulog SRC.ulg [--minutes 30] [--repeat 3]
    python benchmarks/reader.py --bag [--minutes 5] [--repeat 3]

``--ulog``: a real log (the pyulog project's ``test/sample.ulg``, 69 s from an AUAV-X2.1 flight
controller) is repeated end to end, every message of every topic with its timestamps shifted,
into a log of ``--minutes`` (pyulog then reads it as one log); the read is
``jaxdrift.io.read_attitude_run`` (the default topics, the full time-base policy), and the same
for the log's CSV export as recorded (``jaxdrift topics --export-csv``). Writes
``reader-ulog.json``. ``--bag``: a ROS 2 bag of ``--minutes`` of sensor_msgs/Imu at 200 Hz, written
by rosbags and read the same way (``reader-bag.json``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, resource, sys, time
t0 = time.perf_counter()
from jaxdrift.io import load_run
t1 = time.perf_counter()
rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
if sys.argv[1] != "-":
    run = load_run(sys.argv[1])
    n = run.n
else:
    n = 0
t2 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "read_s": t2 - t1, "rows": n,
                  "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "rss_after_import_mib": rss0 / 1024}))
"""


ULOG_CHILD = r"""
import json, resource, sys, time
t0 = time.perf_counter()
from jaxdrift.io import read_attitude_run
t1 = time.perf_counter()
run = read_attitude_run(sys.argv[1])
t2 = time.perf_counter()
tb = run["time_base"]
print(json.dumps({"import_s": t1 - t0, "read_s": t2 - t1, "rows": len(run["t"]),
                  "reference_samples": 0 if run["q_ref_t"] is None else len(run["q_ref_t"]),
                  "fs": tb["fs"], "gaps": len(tb["gaps"]), "segments": len(tb["segments"]),
                  "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def long_ulog(src: str, out: str, minutes: float) -> dict:
    """``src`` repeated end to end into a log of at least ``minutes``: the definitions once, then
    the data section (every message) again and again, the ``timestamp`` of every data and
    logging message shifted by the log's length (plus one nominal step) per copy; subscriptions
    ('A') only in the first copy. Returns what was written."""
    import numpy as np
    from pyulog import ULog

    raw = np.fromfile(src, dtype=np.uint8)
    fmts = ULog(src, parse_header_only=True).message_formats
    pos, first_data, offs, types = 16, None, [], []
    while pos + 3 <= len(raw):
        size = int(raw[pos]) | int(raw[pos + 1]) << 8
        typ = chr(raw[pos + 2])
        if pos + 3 + size > len(raw):
            break
        if first_data is None and typ in "ADLCO":
            first_data = pos
        if first_data is not None:
            offs.append(pos)
            types.append(typ)
        pos += 3 + size
    offs, types = np.asarray(offs), np.asarray(types)
    subs = {}  # msg_id -> has timestamp first
    for p, ty in zip(offs, types):
        if ty == "A":
            size = int(raw[p]) | int(raw[p + 1]) << 8
            msg_id = int(raw[p + 4]) | int(raw[p + 5]) << 8
            name = bytes(raw[p + 6: p + 3 + size]).decode()
            subs[msg_id] = fmts[name].fields[0][2] == "timestamp"
    ts_pos, ids = [], []
    for p, ty in zip(offs, types):
        if ty == "D":
            msg_id = int(raw[p + 3]) | int(raw[p + 4]) << 8
            if subs.get(msg_id):
                ts_pos.append(p + 5)
                ids.append(msg_id)
        elif ty in "L":
            ts_pos.append(p + 4)
            ids.append(-1)
    ts_pos, ids = np.asarray(ts_pos), np.asarray(ids)
    gather = ts_pos[:, None] + np.arange(8)
    stamps = raw[gather].copy().view("<u8").ravel()
    # the copy length: the span of the most frequent topic (the gyro), plus one 4 ms step
    top = np.bincount(ids[(ids >= 0) & (stamps > 0)]).argmax()
    live = stamps[(ids == top) & (stamps > 0)]
    span = int(live.max() - live.min()) + 4000
    copies = int(np.ceil(minutes * 60e6 / span))
    # (or of any topic within 20 % of it: the attitude ends a little after the gyro); a topic whose
    # stamps reach further (one logged since boot) would go backwards from one copy to the next:
    # it stays in the first copy only
    ext = {int(i): stamps[(ids == i) & (stamps > 0)] for i in np.unique(ids[ids >= 0])}
    ext = {i: int(v.max() - v.min()) for i, v in ext.items() if v.size}
    span = max([e for e in ext.values() if e <= 1.2 * span] + [span]) + 4000
    long_ids = {i for i, e in ext.items() if e >= span}
    body = raw[first_data:pos]
    keep = np.ones(len(body), bool)  # the copies without subscriptions
    for p, ty in zip(offs, types):
        size = int(raw[p]) | int(raw[p + 1]) << 8
        if ty == "A" or (ty == "D" and (int(raw[p + 3]) | int(raw[p + 4]) << 8) in long_ids):
            keep[p - first_data: p - first_data + 3 + size] = False
    with open(out, "wb") as fh:
        fh.write(raw[:pos].tobytes())
        for k in range(1, copies):
            b = body.copy()
            shifted = np.where(stamps > 0, stamps + np.uint64(k * span), stamps)
            b[gather - first_data] = shifted.view(np.uint8).reshape(-1, 8)
            fh.write(b[keep].tobytes())
    return {"source": os.path.basename(src), "copies": copies, "span_s": span * 1e-6,
            "topics_in_first_copy_only": len(long_ids),
            "duration_s": copies * span * 1e-6, "bytes": os.path.getsize(out)}


def _ulog_child(arg: str) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-c", ULOG_CHILD, arg], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def ulog_benchmark(args) -> None:
    import importlib.metadata as md

    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "long.ulg")
        made = long_ulog(args.ulog, path, args.minutes)
        load0 = os.getloadavg()[0]
        runs = [_ulog_child(path) for _ in range(args.repeat)]
        csv_path = os.path.join(d, "long.csv")
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "jaxdrift", "-q", "topics", path, "--export-csv", csv_path],
                       env=dict(os.environ, PYTHONPATH=str(ROOT)), check=True)
        export_s = time.perf_counter() - t0
        csv_runs = [_ulog_child(csv_path) for _ in range(args.repeat)]
        result = {
            "benchmark": "reader-ulog", "log": made, "load_average_at_start": load0,
            "ulog": {"read_s": [r["read_s"] for r in runs], "peak_rss_mib": [r["peak_rss_mib"] for r in runs],
                     "read_s_min": min(r["read_s"] for r in runs),
                     "peak_rss_mib_max": max(r["peak_rss_mib"] for r in runs), "run": runs[0]},
            "csv_export": {"export_s": export_s, "bytes": os.path.getsize(csv_path),
                           "read_s": [r["read_s"] for r in csv_runs],
                           "peak_rss_mib": [r["peak_rss_mib"] for r in csv_runs], "run": csv_runs[0]},
            "targets": {"read_s": 10.0, "peak_rss_mib": 1024.0},
            "command": "python benchmarks/reader.py " + " ".join(sys.argv[1:]),
            "machine": {"python": platform.python_version(), "platform": platform.platform(),
                        "cpu_count": os.cpu_count()},
            "versions": {p: md.version(p) for p in ("numpy", "scipy", "pyarrow", "pyulog")},
        }
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "reader-ulog.json"), "w") as fh:
        json.dump(result, fh, indent=1)
    u, c = result["ulog"], result["csv_export"]
    print(f"ULog {made['duration_s'] / 60:.1f} min ({made['bytes'] / 2**20:.0f} MiB, {u['run']['rows']} grid rows, "
          f"{u['run']['reference_samples']} reference samples): read in {u['read_s_min']:.2f} s "
          f"(runs {', '.join(f'{v:.2f}' for v in u['read_s'])}), peak RSS {u['peak_rss_mib_max']:.0f} MiB; "
          f"its CSV export ({c['bytes'] / 2**20:.0f} MiB): read in {min(c['read_s']):.2f} s, peak RSS "
          f"{max(c['peak_rss_mib']):.0f} MiB; load average {load0:.1f}")


def write_imu_bag(path: str, minutes: float, rate: float = 200.0) -> int:
    """A ROS 2 bag of ``minutes`` of sensor_msgs/Imu at ``rate`` (1 % jitter, orientation filled)."""
    import numpy as np
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    n = int(minutes * 60 * rate)
    rng = np.random.default_rng(0)
    t = 1000.0 + np.cumsum(np.full(n, 1.0 / rate) * (1 + 0.01 * rng.uniform(-1, 1, n)))
    w = 0.1 * np.sin(np.outer(t, [1.0, 1.3, 0.7]))
    zeros = np.zeros(9)
    with Writer(path, version=9) as wr:
        c = wr.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=store)
        for i in range(n):
            sec = int(t[i])
            msg = T["sensor_msgs/msg/Imu"](
                header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
                    sec=sec, nanosec=int((t[i] - sec) * 1e9)), frame_id="imu"),
                orientation=T["geometry_msgs/msg/Quaternion"](w=1.0, x=0.0, y=0.0, z=0.0),
                orientation_covariance=zeros,
                angular_velocity=T["geometry_msgs/msg/Vector3"](x=w[i, 0], y=w[i, 1], z=w[i, 2]),
                angular_velocity_covariance=zeros,
                linear_acceleration=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=9.81),
                linear_acceleration_covariance=zeros)
            wr.write(c, int(t[i] * 1e9), store.serialize_cdr(msg, "sensor_msgs/msg/Imu"))
    return n


def bag_benchmark(args) -> None:
    import importlib.metadata as md

    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "imu_bag")
        n = write_imu_bag(path, args.minutes)
        load0 = os.getloadavg()[0]
        runs = [_ulog_child(path) for _ in range(args.repeat)]
    result = {"benchmark": "reader-bag", "messages": n, "minutes": args.minutes, "load_average_at_start": load0,
              "read_s": [r["read_s"] for r in runs], "peak_rss_mib": [r["peak_rss_mib"] for r in runs],
              "messages_per_s": n / min(r["read_s"] for r in runs),
              "command": "python benchmarks/reader.py " + " ".join(sys.argv[1:]),
              "machine": {"python": platform.python_version(), "platform": platform.platform(),
                          "cpu_count": os.cpu_count()},
              "versions": {p: md.version(p) for p in ("numpy", "scipy", "rosbags")}}
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "reader-bag.json"), "w") as fh:
        json.dump(result, fh, indent=1)
    print(f"ROS 2 bag, {n} Imu messages ({args.minutes:g} min at 200 Hz): read in {min(result['read_s']):.2f} s "
          f"({result['messages_per_s']:.0f} messages/s), peak RSS {max(result['peak_rss_mib']):.0f} MiB; "
          f"load average {load0:.1f}")


def _write_run(path: str, rows: int) -> None:
    import numpy as np
    import pyarrow as pa
    import pyarrow.csv as pcsv

    rng = np.random.default_rng(0)
    t = np.arange(rows) / 1000.0
    w = 2 * np.pi * 1.3 * t
    cols = {"t": t,
            "f1": 3825.9 + 400 * np.sin(w) + rng.normal(0, 20, rows),
            "f2": 3825.9 - 300 * np.sin(0.7 * w) + rng.normal(0, 20, rows),
            "beta": 0.02 * np.sin(0.5 * w), "beta_rate": 0.02 * 0.5 * 2 * np.pi * 1.3 * np.cos(0.5 * w),
            "z3": 0.05 * np.sin(0.3 * w)}
    table = pa.table(cols)
    with open(path, "wb") as fh:
        fh.write((",".join(cols) + "\n").encode())
        pcsv.write_csv(table, fh, pcsv.WriteOptions(include_header=False, quoting_style="none"))


def _in_child(code: str) -> None:
    """Run ``code`` in a fresh process: the parent stays small, because a child's ``ru_maxrss``
    starts from the parent's resident size at fork (Linux keeps it across exec)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    subprocess.run([sys.executable, "-c", code], env=env, check=True)


def _child(arg: str) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-c", CHILD, arg], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rows", type=int, default=5_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--parquet", action="store_true", help="also time a Parquet copy")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    ap.add_argument("--ulog", metavar="SRC.ulg", help="time a long ULog made from this real log instead")
    ap.add_argument("--minutes", type=float, default=30.0, help="with --ulog or --bag: the length of the log made")
    ap.add_argument("--bag", action="store_true", help="time a ROS 2 bag of sensor_msgs/Imu at 200 Hz instead")
    args = ap.parse_args()
    if args.ulog:
        ulog_benchmark(args)
        return
    if args.bag:
        bag_benchmark(args)
        return

    with tempfile.TemporaryDirectory() as d:
        csv_path = os.path.join(d, "run.csv")
        t0 = time.perf_counter()
        _in_child(f"import sys; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); "
                  f"from reader import _write_run; _write_run({csv_path!r}, {args.rows})")
        gen_s = time.perf_counter() - t0
        size = os.path.getsize(csv_path)
        load0 = os.getloadavg()[0]
        base = _child("-")
        runs = [_child(csv_path) for _ in range(args.repeat)]
        result = {
            "benchmark": "reader", "rows": args.rows, "columns": 6, "csv_bytes": size,
            "csv_write_s": gen_s, "load_average_at_start": load0,
            "baseline_import_only": base,
            "csv": {"read_s": [r["read_s"] for r in runs], "peak_rss_mib": [r["peak_rss_mib"] for r in runs],
                    "read_s_min": min(r["read_s"] for r in runs),
                    "peak_rss_mib_max": max(r["peak_rss_mib"] for r in runs)},
            "targets": {"read_s": 10.0, "peak_rss_mib": 1024.0},
            "command": "python benchmarks/reader.py " + " ".join(sys.argv[1:]),
            "machine": {"python": platform.python_version(), "platform": platform.platform(),
                        "cpu_count": os.cpu_count()},
        }
        if args.parquet:
            pq_path = os.path.join(d, "run.parquet")
            _in_child(f"import pyarrow.csv as c, pyarrow.parquet as q; q.write_table(c.read_csv({csv_path!r}), {pq_path!r})")
            pr = [_child(pq_path) for _ in range(args.repeat)]
            result["parquet"] = {"bytes": os.path.getsize(pq_path), "read_s": [r["read_s"] for r in pr],
                                 "peak_rss_mib": [r["peak_rss_mib"] for r in pr]}
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "reader.json"), "w") as fh:
        json.dump(result, fh, indent=1)
    c = result["csv"]
    print(f"{args.rows} rows x 6 columns, CSV {size / 2**20:.0f} MiB: read in {c['read_s_min']:.2f} s "
          f"(runs {', '.join(f'{v:.2f}' for v in c['read_s'])}), peak RSS {c['peak_rss_mib_max']:.0f} MiB "
          f"(import only: {base['peak_rss_mib']:.0f} MiB); load average {load0:.1f}")
    if args.parquet:
        print(f"Parquet: read {min(result['parquet']['read_s']):.2f} s, peak RSS "
              f"{max(result['parquet']['peak_rss_mib']):.0f} MiB")


if __name__ == "__main__":
    main()
