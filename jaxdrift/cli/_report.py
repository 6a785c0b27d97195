"""``jaxdrift report REPORT.json --html PAGE.html``: the page of a report, rebuilt from its JSON;
and what every command shares to end: the verdict in the terminal and the HTML page.

The summary goes to stdout (one line with -q); when the report itself goes to stdout
(``--json -``) the summary goes to stderr, so a pipe gets the JSON alone.
"""

from __future__ import annotations

import json
import sys

DESCRIPTION = """\
Rebuild the HTML page of a report from its JSON alone: a diagnosis report (jaxdrift diagnose
--json), durability.json (jaxdrift durability) or campaign.json (jaxdrift campaign). The page is
one self-contained file (figures inline as SVG, no script, no network) that opens offline and
prints. Time series are drawn from the report's series_preview block, which the commands store
when they write a page (--html); a report without it gets a page without them. Also prints the
report's summary (one line with -q).

exit codes: 0 written, 2 bad input or unwritable output (nothing written)
"""


def add_parser(subparsers) -> None:
    import argparse

    p = subparsers.add_parser("report", help="the HTML page of a report (diagnosis, durability, campaign) from its JSON",
                              description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("report", metavar="REPORT.json", help="a report written by diagnose, durability or campaign")
    p.add_argument("--html", required=True, metavar="PAGE.html", help="where to write the page")
    p.set_defaults(func=run_report)


def read_report(path: str, option: str = "REPORT.json") -> dict:
    from ..errors import UsageError
    from ..report._html import report_kind

    try:
        with open(path, encoding="utf-8") as fh:
            doc = json.load(fh)
    except OSError as e:
        raise UsageError(f"{path}: cannot read: {e.strerror}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise UsageError(f"{path}: not a JSON file: {e}") from None
    if not isinstance(doc, dict):
        raise UsageError(f"{path}: not a jaxdrift report (a JSON object is expected)")
    try:
        report_kind(doc)
    except ValueError as e:
        raise UsageError(f"{path}: {e}") from None
    return doc


def write_page(path: str, doc: dict, option: str = "--html", run_pages: dict | None = None) -> None:
    from ..io._outputs import write_text
    from ..report._html import render

    write_text(path, render(doc, run_pages=run_pages), option)


def finish(doc: dict, outputs: dict, command: str, to_stderr: bool = False) -> None:
    """The verdict in the terminal: the summary (one line with -q) on stdout, or on stderr when
    stdout carries the report."""
    from ..report._summary import one_line, summary_lines
    from . import _common as c

    name = f"jaxdrift {command}"
    text = one_line(doc, outputs, name) if c.VERBOSITY < 1 else "\n".join(summary_lines(doc, outputs, name))
    print(text, file=sys.stderr if to_stderr else sys.stdout, flush=True)


def json_to_stdout(doc: dict) -> None:
    from ..io._outputs import check_report_finite, finite_json

    check_report_finite(doc)
    sys.stdout.write(json.dumps(finite_json(doc), indent=2, allow_nan=False) + "\n")
    sys.stdout.flush()


def run_report(args) -> int:
    from ..io import check_outputs

    check_outputs([("--html", args.html, "file")], [args.report])
    doc = read_report(args.report)
    write_page(args.html, doc)
    finish(doc, {"report": args.report, "page": args.html}, "report")
    return 0
