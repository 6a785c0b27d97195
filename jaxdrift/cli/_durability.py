"""``jaxdrift durability``: section forces, fatigue pseudo-damage and its noise band for a run.

Thin: reads and validates the inputs (the same reader and rules as ``diagnose``), calls
:func:`jaxdrift.durability_analysis`, writes the outputs atomically. Exit codes: 0 written, 2 bad
input (message on stderr, nothing written), 1 internal failure.
"""

from __future__ import annotations

import json
import math

DESCRIPTION = """\
Durability analysis of a measured vehicle run: the chassis spring (section) forces f3, f4 of the
simulation variants force_driven, pitch_spring, stabilised (measured pitch prescribed), extended
(stabilised with the diagnosis's corrections) and measured (from s1, s2), their rainflow counts
(ASTM E1049-85), pseudo-damage sum n S^K, and how much of it force noise of the diagnosed level
could move (Monte-Carlo over --paths draws). Method and numbers: docs/durability.md.

writes into DIR: durability.json, section_forces.csv, section_forces.png,
rainflow_histogram.png, damage_ratio.png, and jaxdrift-manifest.json (SHA-256 of each file,
written last: a folder without it was not finished)

Ends with the damage ratios on stdout (one line with -q). --html PAGE.html also writes one
self-contained page (damage tables and plots, the section forces); durability.json then carries
the decimated section forces behind it (series_preview).

exit codes: 0 written, 2 bad input (nothing written), 1 internal failure
"""


def add_parser(subparsers) -> None:
    import argparse

    p = subparsers.add_parser("durability", help="section forces and fatigue damage of the simulation variants",
                              description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run", metavar="RUN.csv", help="measured vehicle run (t, f1, f2; beta for the stabilised variants)")
    p.add_argument("--model", metavar="MODEL.json", help="vehicle model (default: the seed's table)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
    p.add_argument("--paths", type=int, default=100, help="Monte-Carlo force-noise draws (default 100; 0: none)")
    p.add_argument("--basquin-k", type=float, default=5.0, help="Basquin slope K of sum n S^K (default 5)")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise draws (default 0)")
    p.add_argument("--pitch-spring-k", type=float, metavar="NM_PER_RAD",
                   help="stiffness of the rotational spring to ground (default: the rule in docs/durability.md)")
    p.add_argument("--pitch-spring-d", type=float, metavar="NMS_PER_RAD",
                   help="its damping (default: critical damping of the stiffness)")
    p.add_argument("--report", metavar="REPORT.json",
                   help="the run's diagnosis report (jaxdrift diagnose --json); default: diagnose the run now")
    p.add_argument("--window", type=float, nargs=2, metavar=("T0", "T1"),
                   help="time window of the zoomed section-force plot [s] (default: 2 s around the largest f3)")
    p.add_argument("--html", metavar="PAGE.html", help="also write the analysis as one self-contained HTML page")
    p.add_argument("--quiet", action="store_true", help="no progress bar (as the global -q)")
    from ._common import add_run_options

    add_run_options(p)
    p.set_defaults(func=run_durability)


def _read_report(path, UsageError) -> dict:
    try:
        with open(path) as fh:
            rep = json.load(fh)
    except OSError as e:
        raise UsageError(f"--report {path}: cannot read: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise UsageError(f"--report {path}, line {e.lineno}, column {e.colno}: invalid JSON: {e.msg}") from None
    if not isinstance(rep, dict) or rep.get("schema") != "jaxdrift.diagnosis/1" or rep.get("kind") != "vehicle":
        raise UsageError(f"--report {path}: not a vehicle diagnosis report (schema jaxdrift.diagnosis/1, kind vehicle)")
    ext = rep.get("extended_model")
    if not isinstance(ext, dict) or "parameters" not in ext or "corrections" not in ext:
        raise UsageError(f"--report {path}: has no extended_model with parameters and corrections")
    return rep


def _check_args(args, UsageError) -> None:
    if args.paths < 0:
        raise UsageError(f"--paths must be >= 0, got {args.paths}")
    if not (math.isfinite(args.basquin_k) and args.basquin_k > 0):
        raise UsageError(f"--basquin-k must be a positive number, got {args.basquin_k}")
    for name in ("pitch_spring_k", "pitch_spring_d"):
        v = getattr(args, name)
        if v is not None and not (math.isfinite(v) and v >= 0):
            raise UsageError(f"--{name.replace('_', '-')} must be a number >= 0, got {v}")
    if args.window is not None and not (args.window[1] > args.window[0]):
        raise UsageError(f"--window: need T1 > T0, got {args.window[0]} {args.window[1]}")


def run_durability(args) -> int:
    from ..durability._outputs import OUTPUT_FILES
    from ..errors import InputError, UsageError
    from ..io import DEFAULT_MODEL, DEFAULT_MODEL_LABEL, check_outputs, load_run, read_model
    from . import _common as c

    _check_args(args, UsageError)
    # before any computation: no input overwritten, every output writable
    check_outputs([("--out", args.out, "dir", OUTPUT_FILES), ("--html", args.html, "file")],
                  [args.run, args.model, args.report])
    try:
        model = read_model(args.model) if args.model else dict(DEFAULT_MODEL)
        run = load_run(args.run, "durability", model=model if args.model else None, **c.run_options(args))
    except InputError as e:
        raise UsageError(str(e)) from None
    if not args.model:
        c.info(f"no --model given: using {DEFAULT_MODEL_LABEL}")
    report = _read_report(args.report, UsageError) if args.report else None
    for w in run.warnings:
        c.warn(w)
    for n in run.info["notes"]:
        c.info(n)
    import jax

    jax.config.update("jax_enable_x64", True)
    def analyse():
        from ..durability import durability_analysis
        from ..durability._outputs import write_outputs

        res = durability_analysis(run, model, paths=args.paths, basquin_k=args.basquin_k, seed=args.seed,
                                  pitch_spring_k=args.pitch_spring_k, pitch_spring_d=args.pitch_spring_d,
                                  report=report, progress=not args.quiet and c.VERBOSITY >= 1)
        res.summary["provenance"]["reading"] = {k: v for k, v in run.info.items() if k != "quantum"}
        res.summary["provenance"]["options"].update(c.run_options(args))
        if args.html:
            from ..report._preview import durability_preview

            res.summary["series_preview"] = durability_preview(res)  # additive: the page's section forces
        return res, write_outputs(res, args.out, window=args.window)

    out, rc = c.guarded("durability", analyse)
    if rc:
        return rc
    res, written = out
    from ._report import finish, write_page

    import os

    with open(os.path.join(args.out, "durability.json")) as fh:  # the page is made of the JSON alone
        doc = json.load(fh)
    if args.html:
        write_page(args.html, doc)
    if args.quiet:
        c.set_verbosity(0)
    finish(doc, {"wrote": f"{len(written)} files to {args.out}", "page": args.html}, "durability")
    return 0
