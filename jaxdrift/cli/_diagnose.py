"""``jaxdrift diagnose``: diagnose a measured run (vehicle or attitude) and write a JSON report.

Thin: reads and validates the inputs (``_csvio``), calls the diagnosis, writes the report
atomically (temporary file + rename, so a failed run never leaves a partial report). Exit codes:
0 report written, 2 bad input (message on stderr, no report), 1 internal failure.
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
import traceback

DESCRIPTION = """\
Diagnose a measured run: what the force-driven simulation gets wrong, why, the extended model,
and the gain. Formats, cause names and the report schema: docs/measured-data.md; the method:
docs/diagnosis.md.

A vehicle run (columns t, f1, f2 and optionally beta, beta_rate, z3, s1, s2) is compared with the
half-car MODEL.json (default: the seed's table). An attitude run (a header with wx) is diagnosed
against SENSORS.json (accelerometer positions).

exit codes: 0 report written, 2 bad input (nothing written), 1 internal failure
"""


def add_parser(subparsers) -> None:
    import argparse

    p = subparsers.add_parser(
        "diagnose",
        help="diagnose a measured vehicle or attitude run (JSON report, optional figures)",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("run", metavar="RUN.csv", help="measured run (CSV with a header row)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--model", metavar="MODEL.json",
                   help="vehicle model: all of a, b, m1, m2, m3, I, k1..k4, d1..d4, g (default: the seed's table)")
    g.add_argument("--sensors", metavar="SENSORS.json",
                   help="attitude runs: accelerometer positions {\"positions\": [[x, y, z], ...]}")
    p.add_argument("--json", required=True, metavar="REPORT.json", help="where to write the report")
    p.add_argument("--plots", metavar="DIR", help="also write figures (PNG) into this folder")
    p.set_defaults(func=run_diagnose)


def _finite(obj):
    """Replace non-finite floats by None so that the report is strict JSON."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item):  # numpy scalar
        return _finite(obj.item())
    return obj


def write_report_atomic(path: str, report: dict) -> None:
    """Write JSON to ``path`` through a temporary file in the same folder and a rename."""
    text = json.dumps(_finite(report), indent=2, allow_nan=False)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".jaxdrift-report-", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text + "\n")
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it private; a report is an ordinary file
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def _check_output(path: str, UsageError) -> None:
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise UsageError(f"--json {path}: folder {folder} does not exist")
    if os.path.isdir(path):
        raise UsageError(f"--json {path}: is a folder, expected a file name")
    if not os.access(folder, os.W_OK):
        raise UsageError(f"--json {path}: folder {folder} is not writable")


def run_diagnose(args) -> int:
    from ..errors import UsageError
    from ..io._csvio import InputError, read_header

    _check_output(args.json, UsageError)
    try:
        header = read_header(args.run)
    except InputError as e:
        raise UsageError(str(e)) from None
    if "wx" in header:
        if args.model:
            raise UsageError(f"{args.run}: an attitude run (column wx) takes --sensors, not --model")
        try:
            from ..diagnosis.attitude._diagnose import run_attitude_diagnosis
        except ImportError as e:
            print(f"jaxdrift diagnose: internal error: the attitude diagnosis is not available ({e})",
                  file=sys.stderr)
            return 1
        try:
            report = run_attitude_diagnosis(args.run, args.sensors, args.plots)
        except UsageError:
            raise
        except Exception:  # noqa: BLE001 - anything else is our failure, not the user's
            print("jaxdrift diagnose: internal error while diagnosing the attitude run:",
                  file=sys.stderr)
            traceback.print_exc()
            return 1
    else:
        if args.sensors:
            raise UsageError(f"{args.run}: a vehicle run (no column wx) takes --model, not --sensors")
        from ..io._csvio import DEFAULT_MODEL, read_model, read_vehicle_run

        try:
            run = read_vehicle_run(args.run)
            model = read_model(args.model) if args.model else dict(DEFAULT_MODEL)
        except InputError as e:
            raise UsageError(str(e)) from None
        for w in run.warnings:
            print(f"jaxdrift diagnose: warning: {w}", file=sys.stderr)
        try:
            from ..diagnosis.vehicle._pipeline import diagnose_vehicle_run

            report = diagnose_vehicle_run(run, model, args.plots)
        except UsageError:
            raise
        except Exception:  # noqa: BLE001
            print("jaxdrift diagnose: internal error while diagnosing the vehicle run:",
                  file=sys.stderr)
            traceback.print_exc()
            return 1
    write_report_atomic(args.json, report)
    print(f"report written to {args.json}", file=sys.stderr)
    return 0
