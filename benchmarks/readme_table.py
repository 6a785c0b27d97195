"""Write every quoted number and table in README.md and docs/*.md from its committed result file.

Numbers sit between markers that name their file, key and format (see ``benchmarks/_quoted.py``
for the syntax), e.g. ``<!-- q:docs/figures/paper/summary.json:headline.drift_off_beta_s.noisy.median:.2f -->7.00<!-- /q -->``;
tables between ``<!-- NAME -->`` and ``<!-- /NAME -->`` for a renderer registered there (the
README's throughput table: ``<!-- throughput-table -->``). Run after regenerating a result file::

    python benchmarks/readme_table.py            # rewrite the markers in place
    python benchmarks/readme_table.py --check    # compare only; exit 1 and name each difference
    python benchmarks/readme_table.py --list     # every quoted number: document, line, file, key

``tests/test_quoted_numbers.py`` runs the check.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _quoted  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare only, write nothing; exit 1 on a difference")
    ap.add_argument("--list", action="store_true", help="list every quoted number and block")
    args = ap.parse_args(argv)
    root = _quoted.ROOT
    problems, n_q, n_b, changed = [], 0, 0, []
    for path in _quoted.doc_files(root):
        rel = str(path.relative_to(root))
        text = path.read_text()
        qs = _quoted.quotes(text, rel)
        n_q += len(qs)
        n_b += sum(1 for _ in _quoted._blocks(text))
        if args.list:
            for q in qs:
                print(f"{rel}:{q.line}: {q.text} <- {q.file} {q.key}")
        if args.check or args.list:
            problems += _quoted.check(text, rel, root)
            continue
        try:
            new = _quoted.rewrite(text, rel, root)
        except _quoted.QuoteError as e:
            problems.append(str(e))
            continue
        if new != text:
            path.write_text(new)
            changed.append(rel)
    for p in problems:
        print(p, file=sys.stderr)
    print(f"{n_q} quoted numbers and {n_b} blocks in {len(_quoted.doc_files(root))} documents"
          + (f"; rewritten: {', '.join(changed)}" if changed else "")
          + (f"; {len(problems)} problems" if problems else ""))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
