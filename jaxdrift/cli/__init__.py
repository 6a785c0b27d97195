"""The ``jaxdrift`` command line.

The CLI is thin: each subcommand lives in its own private module that exposes
``add_parser(subparsers)`` (registering arguments and ``set_defaults(func=...)``).
JAX is imported lazily by the subcommand, so ``jaxdrift --help`` is instant.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from ..errors import InputError, UsageError

__all__ = ["UsageError", "build_parser", "main"]

# (module, help) for each subcommand; a module provides add_parser(subparsers).
_SUBCOMMANDS = [
    "jaxdrift.cli._paper",
    "jaxdrift.cli._diagnose",
    "jaxdrift.cli._attitude",
    "jaxdrift.cli._durability",
    "jaxdrift.cli._topics",
    "jaxdrift.cli._campaign",
    "jaxdrift.cli._report",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="jaxdrift",
        description=(
            "Monte-Carlo drift analysis of force-driven multibody vehicle models.\n\n"
            "Vehicle models driven by measured wheel forces drift: force noise integrates like\n"
            "Brownian motion and no model equals the real vehicle. jaxdrift simulates thousands of\n"
            "noise samples and perturbed models, compares with analytic variances, and diagnoses\n"
            "measured runs. Run `jaxdrift <command> --help` for each command."
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    v = parser.add_mutually_exclusive_group()
    v.add_argument("-q", "--quiet", action="store_true", help="errors and warnings only: no progress bars or notes")
    v.add_argument("-v", "--verbose", action="store_true", help="more detail: how the run was read, timings")
    sub = parser.add_subparsers(dest="command", metavar="<command>")
    for modname in _SUBCOMMANDS:
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as e:  # a subcommand module not shipped yet
            if e.name == modname:
                continue
            raise
        mod.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """The ``jaxdrift`` command. Exit codes: 0 done, 2 bad input or an output that cannot be
    written (message, nothing written), 1 internal failure, 130 interrupted (Ctrl-C)."""
    from . import _common

    if argv is None:  # the real command line (tests call main([...]) in-process)
        _common.install_interrupt_handler()
        _common.route_warnings()
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.version:
        from .. import __version__

        print(__version__)
        return 0
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    _common.set_verbosity(0 if args.quiet else 2 if args.verbose else 1, args.command)
    # One JAX CPU device per core before any subcommand touches JAX, so Monte-Carlo runs use
    # every core (JAXDRIFT_CPU_DEVICES=1 or XLA_FLAGS keep the user's choice; see README). Only
    # when run as the program (argv from the command line): a caller that passes argv in-process
    # (tests, notebooks) keeps its devices, and one whose JAX already started cannot change them.
    if argv is None:
        from ..ensemble._devices import use_all_cores

        try:
            use_all_cores()
        except RuntimeError:
            pass
    try:
        rc = args.func(args)
    except (UsageError, InputError) as e:
        _common.close_progress_bars()
        print(f"jaxdrift {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"jaxdrift {args.command}: interrupted", file=sys.stderr)
        return 130
    return int(rc or 0)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
