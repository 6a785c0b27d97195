"""``jaxdrift campaign``: many runs of one vehicle, diagnosed on Dask and jointly.

Thin: parses the arguments, calls :func:`jaxdrift.campaign`, prints the joint findings. Exit
codes: 0 written (runs that failed are listed in the summary), 2 bad input, 1 internal failure.
"""

from __future__ import annotations


DESCRIPTION = """\
Diagnose a test campaign: many runs of the same vehicle (other roads, speeds, days, loggers).
Each run is diagnosed as `jaxdrift diagnose` does, as one task on Dask (a LocalCluster of
--workers processes, or the workers of an existing --scheduler); then the vehicle's parameter
errors are fitted jointly over all runs, each logger's sensor effects (offset, scale, delay) as
nuisance parameters, with a consistency check across runs; with --durability also the campaign's
fatigue damage (repetitions x damage of each run, summed, with Monte-Carlo error bars).
Method and assumptions: docs/campaign.md.

runs: RUN files on the command line (one reading option set for all), or --manifest
campaign.toml with per-run file, map, units, fs, force, logger and repetitions:

  model = "model.json"
  [[run]]
  file = "day1/run_001.csv"
  logger = "DAQ-7"          # runs with one logger share its sensor effects
  repetitions = 120         # the test schedule's count (campaign damage)

writes into DIR: campaign.json (schema jaxdrift.campaign/1), summary.md, runs/NAME.json (each
run's own report), figures/ (forest_PARAM.png per joint parameter, damage_per_run.png) and
index.html (one self-contained page: the joint parameters as forest plots with every run's
interval, the consistency check, the runs linking to runs/NAME.html, each run's own page, the
damage per run and section), cache/ (each run's result under the SHA-256 of its input, model, options and the jaxdrift
version: a rerun recomputes only what changed; a run finished before a worker died is kept).

Monte Carlo across processes: start the same command once per process with --jax-coordinator,
--jax-processes and --jax-process-id (and one --scheduler for all): the force-noise draws of the
campaign damage are spread over every process's devices; process 0 writes DIR.

Ends with the joint findings on stdout (one line with -q).

exit codes: 0 written, 2 bad input (nothing computed), 1 internal failure, 130 interrupted
"""


def add_parser(subparsers) -> None:
    import argparse

    from ._common import add_run_options

    p = subparsers.add_parser("campaign", help="diagnose many runs of one vehicle jointly, on Dask",
                              description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("runs", nargs="*", metavar="RUN", help="measured vehicle runs (CSV, Parquet, MF4)")
    p.add_argument("--manifest", metavar="campaign.toml", help="the runs with per-run options (instead of RUN...)")
    p.add_argument("--model", metavar="MODEL.json", help="vehicle model (default: the manifest's, else the seed's table)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing; holds the cache)")
    p.add_argument("--workers", type=int, metavar="N",
                   help="LocalCluster worker processes, one thread each (default: all cores)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="use a running `dask scheduler` and its workers")
    p.add_argument("--durability", action="store_true", help="also the campaign's section-force damage")
    p.add_argument("--paths", type=int, default=64, help="force-noise draws per run for the damage band (default 64)")
    p.add_argument("--param-draws", type=int, default=32,
                   help="draws of the joint parameters for the damage band (default 32)")
    p.add_argument("--basquin-k", type=float, default=5.0, help="Basquin slope K of sum n S^K (default 5)")
    p.add_argument("--seed", type=int, default=0, help="seed of the Monte-Carlo draws (default 0)")
    p.add_argument("--no-figures", action="store_true", help="skip the figures")
    g = p.add_argument_group("Monte Carlo across processes (jax.distributed)")
    g.add_argument("--jax-coordinator", metavar="HOST:PORT", help="address of process 0")
    g.add_argument("--jax-processes", type=int, metavar="N", help="number of processes")
    g.add_argument("--jax-process-id", type=int, metavar="I", help="this process's id, 0..N-1")
    add_run_options(p)
    p.set_defaults(func=run_campaign)


def _jax_distributed(args, UsageError) -> int:
    given = [args.jax_coordinator, args.jax_processes, args.jax_process_id]
    if all(v is None for v in given):
        return 0
    if any(v is None for v in given):
        raise UsageError("--jax-coordinator, --jax-processes and --jax-process-id go together")
    if not args.scheduler:
        raise UsageError("several processes share one Dask cluster: give --scheduler tcp://HOST:PORT")
    import jax

    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address=args.jax_coordinator, num_processes=args.jax_processes,
                               process_id=args.jax_process_id)
    return args.jax_process_id


def run_campaign(args) -> int:
    from ..errors import UsageError
    from . import _common as c

    if args.workers is not None and args.scheduler:
        raise UsageError("--workers starts a LocalCluster; --scheduler uses an existing one: give one of them")
    if args.workers is not None and args.workers < 1:
        raise UsageError(f"--workers must be >= 1, got {args.workers}")
    if args.manifest and any(getattr(args, k) for k in ("map", "units", "fs", "force", "strict_time")):
        raise UsageError("with --manifest the reading options (--map, --units, --fs, --force, --strict-time) "
                         "go into its [[run]] tables")
    import jax

    jax.config.update("jax_enable_x64", True)
    pid = _jax_distributed(args, UsageError)
    def run():
        from ..campaign import campaign

        return campaign(args.runs, model=args.model, out=args.out, manifest=args.manifest, workers=args.workers,
                        scheduler=args.scheduler, durability=args.durability, paths=args.paths, seed=args.seed,
                        basquin_k=args.basquin_k, param_draws=args.param_draws, reading=c.run_options(args),
                        figures=not args.no_figures, progress=c.VERBOSITY >= 1, write=pid == 0)

    doc, rc = c.guarded("campaign", run)
    if rc:
        return rc
    runs = doc["runs"]
    failed = [r for r in runs if r["status"] != "ok"]
    for r in failed:
        c.warn(f"{r['run']}: {r['message']}")
    joint = doc.get("joint") or {}
    for f in joint.get("findings", []):
        c.info(f"joint: {f['parameter']} x{f['estimate']:.5g} [{f['interval'][0]:.5g}, {f['interval'][1]:.5g}]")
    for cons in joint.get("consistency", {}).get("parameters", []):
        if not cons["consistent"]:
            c.warn(f"{cons['parameter']} differs between runs (p = {cons['p_value']:.3g}, below "
                   f"{cons.get('level', 0.01):.2g}, the campaign's level shared over every parameter and run): "
                   + ", ".join(d["run"] for d in cons["disagreeing_runs"]))
    if pid == 0:
        from ._report import finish

        page, rc = c.guarded("campaign", lambda: write_pages(args.out, doc))
        if rc:
            return rc
        finish(doc, {"wrote": f"{args.out}/campaign.json, summary.md, runs/", "page": page}, "campaign")
    return 0


def write_pages(out: str, doc: dict) -> str:
    """DIR/index.html and runs/NAME.html for each run's report (built from the JSON files)."""
    import json
    import os

    from ._report import write_page

    run_pages = {}
    for r in doc.get("runs") or []:
        rel = r.get("report")
        if r.get("status") != "ok" or not rel or not os.path.isfile(os.path.join(out, rel)):
            continue
        with open(os.path.join(out, rel)) as fh:
            rep = json.load(fh)
        html_rel = os.path.splitext(rel)[0] + ".html"
        write_page(os.path.join(out, html_rel), rep, "--out")
        run_pages[str(r.get("name"))] = html_rel
    with open(os.path.join(out, "campaign.json")) as fh:  # the page is made of the JSON alone
        saved = json.load(fh)
    index = os.path.join(out, "index.html")
    write_page(index, saved, "--out", run_pages=run_pages)
    return index
