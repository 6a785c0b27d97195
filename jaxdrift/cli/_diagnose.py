"""``jaxdrift diagnose``: diagnose a measured run (vehicle or attitude) and write a JSON report.

Thin: checks that every output can be written (and is no input), reads and checks the run
(:func:`jaxdrift.io.load_run`), calls the diagnosis, writes the report, the figures and the
series through :mod:`jaxdrift.io._outputs` (temporary file + rename). Exit codes: 0 report written,
2 bad input or unwritable output (message on stderr, nothing written), 1 internal failure,
130 interrupted.
"""

from __future__ import annotations

import os
import time

DESCRIPTION = """\
Diagnose a measured run: what the force-driven simulation gets wrong, why, the extended model,
and the gain. Formats, cause names and the report schema: docs/measured-data.md; the method:
docs/diagnosis.md.

A vehicle run (columns t, f1, f2 and optionally beta, beta_rate, z3, s1, s2) is compared with the
half-car MODEL.json (default: the seed's table). An attitude run (a header with wx) is diagnosed
against SENSORS.json (accelerometer positions). RUN may be CSV, Parquet (.parquet), MDF4 (.mf4,
needs `pip install jaxdrift[mdf]`), a PX4 ULog (.ulg, `pip install jaxdrift[ulog]`) or a ROS bag
(.bag, a ROS 2 bag folder, .db3, .mcap; `pip install jaxdrift[ros]`), read as an attitude run;
`jaxdrift topics LOG` lists a log's topics. --map and --units read other column names and units.
Jittered time, gaps and channels at different rates are resampled onto a uniform grid (never
across a gap; a reference stays on its own times); --strict-time refuses them instead. The run
is checked for plausibility (units, dead channels, glitches) before anything is computed.

Ends with the verdict on stdout (the findings with estimate, interval and whether confirmed,
the gain, what could not be shown; one line with -q); --json - writes the report to stdout
instead (the verdict then goes to stderr). --html PAGE.html also writes one self-contained page
(figures inline, opens offline, prints); the report then carries the decimated signals behind
its figures (series_preview), so `jaxdrift report REPORT.json --html PAGE.html` rebuilds it.

exit codes: 0 report written, 2 bad input or unwritable output (nothing written),
1 internal failure, 130 interrupted (Ctrl-C)
"""


def add_parser(subparsers) -> None:
    import argparse

    from ._common import add_run_options

    p = subparsers.add_parser(
        "diagnose",
        help="diagnose a measured vehicle or attitude run (JSON report, optional figures)",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run", metavar="RUN", help="measured run: CSV with a header row, .parquet or .mf4")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--model", metavar="MODEL.json",
                   help="vehicle model: all of a, b, m1, m2, m3, I, k1..k4, d1..d4, g (default: the seed's table)")
    g.add_argument("--sensors", metavar="SENSORS.json",
                   help="attitude runs: accelerometer positions {\"positions\": [[x, y, z], ...]}")
    p.add_argument("--json", required=True, metavar="REPORT.json",
                   help="where to write the report ('-': stdout, the summary then goes to stderr)")
    p.add_argument("--html", metavar="PAGE.html",
                   help="also write the report as one self-contained HTML page (and store the decimated "
                        "signals behind its figures in the report: series_preview)")
    p.add_argument("--plots", metavar="DIR", help="also write figures (PNG) into this folder")
    p.add_argument("--series", metavar="OUT.csv|OUT.parquet",
                   help="vehicle runs: also write the measured, simulated and extended-model signals "
                        "on the run's time base (columns: docs/measured-data.md)")
    add_run_options(p)
    p.set_defaults(func=run_diagnose)


def _kind(header, mapping_text, path=None) -> str:
    from ..io._logs import is_log
    from ..io._options import parse_map

    if path is not None and is_log(path):
        return "attitude"  # a logger file holds the rates (and the attitude) of a body

    mapped = parse_map(mapping_text) if mapping_text else {}
    return "attitude" if ("wx" in header or "wx" in mapped) else "vehicle"


def run_diagnose(args) -> int:
    from ..errors import UsageError
    from ..io import (DEFAULT_MODEL, DEFAULT_MODEL_LABEL, check_outputs, load_run, provenance, read_header,
                      read_model, write_report)
    from ..io._outputs import atomic_dir, write_table
    from . import _common as c

    t_start = time.monotonic()
    if args.series and not str(args.series).lower().endswith((".csv", ".parquet", ".pq")):
        raise UsageError(f"--series {args.series}: the name must end in .csv or .parquet")
    to_stdout = args.json == "-"
    check_outputs([("--json", None if to_stdout else args.json, "file"), ("--html", args.html, "file"),
                   ("--series", args.series, "file"), ("--plots", args.plots, "dir")],
                  [args.run, args.model, args.sensors])
    kind = _kind(read_header(args.run), args.map, args.run)
    opts = c.run_options(args)
    if kind == "attitude":
        if args.model:
            raise UsageError(f"{args.run}: an attitude run (column wx) takes --sensors, not --model")
        if args.series:
            raise UsageError("--series: only for vehicle runs (the attitude report holds its signals' summary)")
        from ..diagnosis.attitude import analysed_part, sensor_positions
        from ..io._attitude_files import read_attitude_run

        run, part_warning = analysed_part(read_attitude_run(args.run, checks=True, **opts))
        for w in [*run["warnings"], *([part_warning] if part_warning else [])]:
            c.warn(w)
        for n in run["info"]["notes"]:
            c.info(n)
        reading = run["info"]
        positions = sensor_positions(run, args.run, args.sensors)
        bar = c.progress(total=4, desc="diagnose", unit="step")  # from here on: computing
        bar.update(1)
        model_desc = {"sensors": os.path.basename(args.sensors) if args.sensors else None}
        try:
            from ..diagnosis.attitude import diagnose_attitude
            from ..diagnosis.attitude import write_plots

            report, plots = diagnose_attitude(run, positions)
            if args.html:
                from ..report._preview import attitude_preview

                preview = attitude_preview(run, plots, report)
        except UsageError:
            raise
        except Exception:  # noqa: BLE001 - anything else is our failure, not the user's
            return c.internal_failure("diagnose", "diagnosing the attitude run", bar)
        bar.update(2)
        if args.plots:
            with atomic_dir(args.plots, "--plots") as tmp:
                names = write_plots(plots, tmp)
            report["plots"] = [os.path.join(args.plots, os.path.basename(str(n))) for n in names]
    else:
        if args.sensors:
            raise UsageError(f"{args.run}: a vehicle run (no column wx) takes --model, not --sensors")
        model = read_model(args.model) if args.model else dict(DEFAULT_MODEL)
        run = load_run(args.run, "vehicle", model=model if args.model else None, **opts)
        if not args.model:
            c.info(f"no --model given: using {DEFAULT_MODEL_LABEL}")
        for w in run.warnings:
            c.warn(w)
        for n in run.info["notes"]:
            c.info(n)
        reading = run.info
        c.detail(f"read {run.n} samples at {run.info['rate_hz']:.6g} Hz ({run.info['format']}) in "
                 f"{time.monotonic() - t_start:.1f} s")
        bar = c.progress(total=4, desc="diagnose", unit="step")  # from here on: computing
        bar.update(1)
        model_desc = ({"file": os.path.basename(args.model)} if args.model else {"default": DEFAULT_MODEL_LABEL})
        model_desc["parameters"] = model
        try:
            from ..diagnosis.vehicle import diagnose_vehicle_run

            log = _BarLog(bar)
            if args.plots:
                with atomic_dir(args.plots, "--plots") as tmp:
                    report = diagnose_vehicle_run(run, model, tmp, log=log)
                report = _retarget(report, tmp, args.plots)
            else:
                report = diagnose_vehicle_run(run, model, None, log=log)
            for line in log:
                c.detail(line)
            bar.update(1)
            if args.series:
                from ..diagnosis import vehicle_series

                bar.set_postfix_str("series")
                write_table(args.series, vehicle_series(run, model, report), "--series")
            if args.html:
                from ..report._preview import vehicle_preview

                bar.set_postfix_str("page")
                preview = vehicle_preview(run, model, report)
            bar.update(1)
        except UsageError:
            raise
        except Exception as e:  # noqa: BLE001
            from ..errors import InputError

            if isinstance(e, InputError):
                raise
            return c.internal_failure("diagnose", "diagnosing the vehicle run", bar)
    report["provenance"] = provenance(
        "diagnose", [args.run, args.model, args.sensors], model=model_desc,
        options={"kind": kind, **opts, "plots": args.plots, "series": args.series})
    report["provenance"]["reading"] = {k: v for k, v in reading.items() if k != "quantum"}
    if args.html:
        report["series_preview"] = preview  # additive: the signals behind the page's figures
    from ._report import finish, json_to_stdout, write_page

    if to_stdout:
        json_to_stdout(report)  # refuses inf/NaN as write_report does
    else:
        write_report(args.json, report, "--json")  # refuses inf/NaN: a degenerate fit is said in words
    if args.html:
        write_page(args.html, report)
    bar.update(bar.total - bar.n)
    bar.close()
    if not to_stdout:
        c.info(f"report written to {args.json}" + (f", series to {args.series}" if args.series else ""))
    finish(report, {"report": None if to_stdout else args.json, "page": args.html, "series": args.series},
           "diagnose", to_stderr=to_stdout)
    return 0


class _BarLog(list):
    """The diagnosis's step log: each step shows on the progress bar (and with -v, afterwards)."""

    def __init__(self, bar):
        super().__init__()
        self._bar = bar

    def append(self, line):
        super().append(line)
        self._bar.set_postfix_str(str(line)[:40])


def _retarget(obj, old: str, new: str):
    """Paths inside the report that point into the temporary plots folder point to the real one."""
    if isinstance(obj, str):
        return obj.replace(old, new) if old in obj else obj
    if isinstance(obj, dict):
        return {k: _retarget(v, old, new) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_retarget(v, old, new) for v in obj]
    return obj
