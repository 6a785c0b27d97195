"""``jaxdrift topics LOG``: what a logger file holds, and its export to CSV as recorded."""

from __future__ import annotations

DESCRIPTION = """\
List the topics of a logger file: a PX4 ULog (.ulg, needs `pip install jaxdrift[ulog]`) or a ROS
bag (.bag, a ROS 2 bag folder, .db3, .mcap; needs `pip install jaxdrift[ros]`). For each topic
(and ULog instance): the number of samples, the rate (from the median step), the duration and the
fields. A field is read by `jaxdrift diagnose LOG --map wx=TOPIC:INSTANCE.FIELD,...` (ULog, e.g.
wx=sensor_gyro:1.x) or `--map wx=TOPIC.FIELD,...` (bags, e.g. wx=/imu/data.angular_velocity.x).
Defaults: ULog sensor_combined.gyro_rad[0..2] and vehicle_attitude.q[0..3]; a bag's
sensor_msgs/Imu topic (angular_velocity, and orientation where it is filled).

--export-csv OUT.csv writes the attitude run as recorded: t (seconds from the first rate sample,
jittered as logged, gaps kept), wx, wy, wz, and qw, qx, qy, qz only on the row nearest each
reference sample (empty elsewhere). `jaxdrift diagnose OUT.csv` reads it with the same time-base
policy as the log.

examples:
  jaxdrift topics flight.ulg
  jaxdrift topics flight.ulg --export-csv flight.csv
  jaxdrift topics flight.ulg --export-csv gyro1.csv --map wx=sensor_gyro:1.x,wy=sensor_gyro:1.y,wz=sensor_gyro:1.z

exit codes: 0 done, 2 bad input or unwritable output, 130 interrupted (Ctrl-C)
"""


def add_parser(subparsers) -> None:
    import argparse

    p = subparsers.add_parser("topics", help="list a logger file's topics (ULog, ROS bag); export it to CSV",
                              description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("log", metavar="LOG", help="a .ulg file, a ROS 1 .bag, or a ROS 2 bag (folder, .db3, .mcap)")
    p.add_argument("--export-csv", metavar="OUT.csv", help="write the attitude run as recorded (see above)")
    p.add_argument("--map", metavar="NAME=TOPIC.FIELD,...", help="with --export-csv: other topics or fields "
                   "for wx, wy, wz (and qw..qz)")
    p.add_argument("--json", metavar="TOPICS.json", help="also write the listing as JSON")
    p.set_defaults(func=run_topics)


def _fields(fields: list[str], width: int = 70) -> str:
    out = ", ".join(fields)
    return out if len(out) <= width else out[: width - 5].rsplit(", ", 1)[0] + ", ..."


def run_topics(args) -> int:
    from ..io import check_outputs, write_json
    from ..io._logs import list_topics, log_info
    from . import _common as c

    check_outputs([("--export-csv", args.export_csv, "file"), ("--json", args.json, "file")], [args.log])
    if args.export_csv:
        from ..io._export import export_recorded_csv

        done = export_recorded_csv(args.log, args.export_csv, args.map)
        for n in done["notes"]:
            c.info(n)
        cols = ", ".join(f"{k}={v}" for k, v in done["columns"].items())
        c.info(f"{args.export_csv}: {done['rows']} rows, reference on {done['reference_rows']} of them "
               f"(t = 0 at log time {done['t0_s']:.6f} s; {cols})")
        if not args.json:
            return 0
    elif args.map:
        from ..errors import UsageError

        raise UsageError("--map: only with --export-csv (for diagnose, give --map to `jaxdrift diagnose`)")
    rows = list_topics(args.log)
    meta = log_info(args.log)
    if args.json:
        write_json(args.json, {"log": str(args.log), "info": meta, "topics": rows}, "--json")
    if args.export_csv:
        return 0
    if meta:
        print("  ".join(f"{k}: {v}" for k, v in meta.items()))
    print(f"{'topic':<32} {'inst':>4} {'samples':>8} {'rate_hz':>9} {'duration_s':>10}  fields")
    for r in rows:
        print(f"{r['topic']:<32} {r['instance']:>4} {r['samples']:>8} {r['rate_hz']:>9.4g} "
              f"{r['duration_s']:>10.3f}  {_fields(r['fields'])}")
    return 0
