"""Every quoted number in README.md and docs/*.md equals the result file it cites.

Reads the documents and the committed JSON results; reruns nothing. To update the documents
after regenerating a result: ``python benchmarks/readme_table.py``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
from benchmarks import _quoted

DOCS = _quoted.doc_files(ROOT)


@pytest.mark.parametrize("path", DOCS, ids=[p.name for p in DOCS])
def test_quoted_numbers_match_their_files(path):
    rel = str(path.relative_to(ROOT))
    problems = _quoted.check(path.read_text(), rel, ROOT)
    assert not problems, "\n".join(problems) + "\n(run `python benchmarks/readme_table.py` after regenerating a result)"


def test_the_docs_quote_numbers():
    n = sum(len(_quoted.quotes(p.read_text())) for p in DOCS)
    assert n >= 2000, n


def test_a_hand_edited_number_fails():
    text = "drift-off <!-- q:docs/figures/paper/summary.json:config.n_noise:d -->32<!-- /q --> samples"
    assert _quoted.check(text, "x.md", ROOT) == []
    bad = text.replace("-->32<", "-->31<")
    (msg,) = _quoted.check(bad, "x.md", ROOT)
    assert "x.md:1" in msg and "'31'" in msg and "'32'" in msg
    assert _quoted.rewrite(bad, "x.md", ROOT) == text


def test_every_marker_parses():
    """Each inline marker in the docs parses: a malformed marker would be skipped silently."""
    for p in DOCS:
        text = p.read_text()
        assert text.count("<!-- q:") == len(_quoted.quotes(text)), f"{p.name}: a malformed <!-- q: marker"
        assert text.count("<!-- /q -->") == len(_quoted.quotes(text)), f"{p.name}: a <!-- /q --> without its opening"


@pytest.mark.parametrize("fmt,value,want", [
    (".2f", 7.15, "7.15"), ("d", 89.0, "89"), (".0f*100", 0.1277, "13"), (".3g", 13374000.0, "1.34e+07"),
    (".0%", 0.8912, "89%"), ("", "inf", "inf"), (",d", 10000, "10,000"),
])
def test_formats(fmt, value, want):
    assert _quoted.fmt_value(value, fmt) == want


def test_keys():
    obj = {"a": [{"b": 1}, {"c/d": {"0.5": 2}}]}
    assert _quoted.lookup(obj, "a.0.b") == 1
    assert _quoted.lookup(obj, "a.1.[c/d].[0.5]") == 2
    with pytest.raises(_quoted.QuoteError, match="no 'x'"):
        _quoted.lookup(obj, "a.0.x")
    with pytest.raises(_quoted.QuoteError, match="not an index"):
        _quoted.lookup(obj, "a.5")
    with pytest.raises(_quoted.QuoteError, match="JSON file under"):
        _quoted.load(ROOT, "README.md")


def test_key_selections_and_aggregates():
    rows = {"rows": [{"fs": 200.0, "r": [1.02, 0.97]}, {"fs": 500.0, "r": [1.5, 1.1], "u": 9.0}, {"fs": 1000.0, "r": [3.0, 1.0]}],
            "ns": {"a": {"w": 10.0}, "b": {"w": 40.0}}, "v": [4.0]}
    assert _quoted.lookup(rows, "rows.*.r.*|len") == 6
    assert _quoted.lookup(rows, "rows.*.r.*|max") == 3.0
    assert _quoted.lookup(rows, "rows.[?fs=200].r.*|maxdev1") == pytest.approx(0.03)
    assert _quoted.lookup(rows, "rows.[?fs>=500].r.*|min") == 1.0
    assert _quoted.lookup(rows, "rows.[?fs>=500&fs<=500].r.*|min") == 1.1
    assert _quoted.lookup(rows, "rows.0:2.r.0|sum") == pytest.approx(2.52)
    assert _quoted.lookup(rows, "rows.*.u|len") == 1  # elements without the key are dropped under '*'
    assert _quoted.lookup(rows, "ns.[(b,a)].w|ratio") == 4.0
    assert _quoted.lookup({"c": {"x, y": 6.0, "z": 2.0}}, "c.[(x, y;z)]|ratio") == 3.0
    assert _quoted.lookup(rows, "v.0|sqrt") == 2.0 and _quoted.lookup(rows, "v.0|inv") == 0.25
    with pytest.raises(_quoted.QuoteError, match="unknown aggregate"):
        _quoted.lookup(rows, "v.0|mean")
    with pytest.raises(_quoted.QuoteError, match="no 'c'"):
        _quoted.lookup(rows, "ns.[(a,c)].w|ratio")


def test_transcribed_numbers_say_where_they_come_from():
    """A ``*-recorded.json`` holds numbers transcribed from runs that are not rerun (earlier code,
    an idle machine, long sweeps): it says so, names the machine, and every number names the
    commit that first recorded it."""
    files = sorted((ROOT / "benchmarks" / "results").glob("*-recorded.json"))
    assert files
    for f in files:
        d = json.loads(f.read_text())
        assert d.get("transcribed") is True and d.get("machine") and d.get("what"), f.name
        for name, group in d["values"].items():
            numbers = group["numbers"].values() if "numbers" in group else [group]
            for n in numbers:
                assert isinstance(n["value"], (int, float, list, dict)), (f.name, name)
                assert re.match(r"[0-9a-f]{7}\b", n["recorded_in"]), (f.name, name, n["recorded_in"])
