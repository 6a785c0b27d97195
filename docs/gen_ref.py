"""Pages generated when the site is built (mkdocs-gen-files): the command-line reference from
``jaxdrift.cli.build_parser()`` and the changelog from ``CHANGELOG.md``."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import mkdocs_gen_files

ROOT = Path(__file__).resolve().parent.parent


def _options_table(parser: argparse.ArgumentParser) -> list[str]:
    rows = ["| option | default | help |", "|---|---|---|"]
    for a in parser._actions:
        if isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        name = ", ".join(f"`{s}`" for s in a.option_strings) or f"`{a.metavar or a.dest}` (positional)"
        if a.option_strings and a.nargs != 0:
            name += f" `{a.metavar or a.dest.upper()}`"
        default = "" if a.default in (None, False, argparse.SUPPRESS) else f"`{a.default}`"
        text = (a.help or "").replace("|", "\\|").replace("\n", " ")
        if "%(" in text:
            try:
                text = text % {"default": a.default, "prog": parser.prog, "choices": a.choices}
            except (KeyError, ValueError, TypeError):
                pass
        rows.append(f"| {name} | {default} | {text} |")
    return rows


def cli_reference() -> str:
    """The command line's reference, one section per subcommand, from the argparse parser."""
    os.environ["COLUMNS"] = "100"
    from jaxdrift.cli import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    out = ["# Command line", "",
           "Generated from `jaxdrift.cli.build_parser()` when the site is built; "
           "`jaxdrift COMMAND --help` prints the same.", "",
           "```text", parser.format_help().rstrip(), "```", "", *_options_table(parser), ""]
    for name, p in sub.choices.items():
        out += [f"## jaxdrift {name}", "", "```text", p.format_help().rstrip(), "```", "", *_options_table(p), ""]
    return "\n".join(out)


with mkdocs_gen_files.open("reference/cli.md", "w") as fh:
    fh.write(cli_reference())
with mkdocs_gen_files.open("changelog.md", "w") as fh:
    fh.write((ROOT / "CHANGELOG.md").read_text())
