"""Quoted numbers: every measured number in README.md and docs/*.md is written from a result file.

A number in the text sits between two HTML comments (invisible when the markdown is rendered)
that name the committed JSON file it comes from, the value inside it and its format::

    median <!-- q:docs/figures/paper/summary.json:headline.drift_off_beta_s.noisy.median:.2f -->7.00<!-- /q --> s

- the file: a path from the repository root, a JSON file under ``benchmarks/results/``,
  ``docs/validation/``, ``docs/figures/`` (the summaries the commands write beside their figures)
  or ``examples/`` (the committed example report);
- the key: dot-separated object keys and list indices (``solver_comparison.1.noisy_drift_off_s.5``);
  a key that holds dots, slashes or spaces goes in square brackets
  (``cases.[fixed/jaxdrift].path_steps_per_s``, ``by_threshold.[0.5].undisturbed``); ``*`` takes
  every element and ``|AGG`` reduces them (``rows.*.stabilised.*|maxdev1``: the largest
  ``|ratio - 1|``; aggregates ``max min len sum median spread maxdev1 maxabs inv sqrt ratio diff``; ``a:b`` takes a slice of a list
  like ``*``, and ``[?field=value]`` the elements whose ``field`` equals ``value``
  (``rows.[?fs=200].stabilised.*|max``; also ``>=``, ``<=`` and several joined by ``&``);
  ``[(a,b)]`` picks two keys for ``|ratio`` or ``|diff`` (``cases.[(diffrax,jaxdrift)].ns|ratio``;
  ``[(a, x;b, y)]`` with ``;`` where the keys hold commas));
- the format: a Python format spec (``.2f``, ``.3g``, ``d``, ``,d``, ``.0%``), optionally followed
  by ``*FACTOR`` to scale first (``.0f*100``: metres as centimetres; ``.2f*9.313225746154785e-10``:
  bytes as GiB). ``d`` rounds a float to the nearest integer. A string value is written as it is
  with an empty spec.

A block (a table, a paragraph) sits between ``<!-- NAME -->`` and ``<!-- /NAME -->`` where NAME is
a renderer registered in :data:`BLOCKS` (a function of the repository root returning the text).

``python benchmarks/readme_table.py`` rewrites every marker in README.md and docs/*.md from its
file; ``--check`` only compares and exits 1 naming each difference. ``tests/test_quoted_numbers.py``
runs the same check (it reads the files, it reruns nothing), so a number edited by hand, or a
result file regenerated without rewriting the docs, fails the tests.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

ROOT = Path(__file__).resolve().parent.parent
RESULT_DIRS = ("benchmarks/results/", "docs/validation/", "docs/figures/", "examples/")

#: one inline quoted number: file, key, format, the text between the markers
INLINE = re.compile(
    r"<!-- q:(?P<file>[^:\s]+):(?P<key>[^\n]+?):(?P<fmt>[^:\s]*) -->(?P<val>[^<\n]*)<!-- /q -->"
)
_KEY_PART = re.compile(r"\[([^\]]*)\]|([^.\[\]]+)")

#: block renderers: name -> function(root) -> text written between <!-- name --> and <!-- /name -->
BLOCKS: dict[str, Callable[[Path], str]] = {}


def block(name: str):
    """Register a block renderer under ``name``."""

    def deco(fn):
        BLOCKS[name] = fn
        return fn

    return deco


@dataclass(frozen=True)
class Quote:
    doc: str
    line: int
    file: str
    key: str
    fmt: str
    text: str


class QuoteError(ValueError):
    pass


def doc_files(root: Path = ROOT) -> list[Path]:
    """The documents whose numbers are quoted: README.md and docs/*.md."""
    return [root / "README.md", *sorted((root / "docs").glob("*.md"))]


_cache: dict[tuple[Path, str], Any] = {}


def load(root: Path, file: str) -> Any:
    if not any(file.startswith(d) for d in RESULT_DIRS) or not file.endswith(".json"):
        raise QuoteError(f"{file}: quoted numbers come from a JSON file under {', '.join(RESULT_DIRS)}")
    k = (root, file)
    if k not in _cache:
        path = root / file
        if not path.is_file():
            raise QuoteError(f"{file}: no such result file")
        _cache[k] = json.loads(path.read_text())
    return _cache[k]


def _flat(obj):
    if isinstance(obj, list):
        for o in obj:
            yield from _flat(o)
    elif obj is not None:
        yield obj


#: aggregates over the values a ``*`` collects (None dropped): ``key|max``
AGGREGATES: dict[str, Callable[[list], Any]] = {
    "max": max, "min": min, "len": len, "sum": sum,
    "median": lambda v: sorted(v)[len(v) // 2] if len(v) % 2 else 0.5 * sum(sorted(v)[len(v) // 2 - 1:len(v) // 2 + 1]),
    "spread": lambda v: max(v) - min(v),  # max - min
    "maxdev1": lambda v: max(abs(x - 1.0) for x in v),  # largest |x - 1| of ratios
    "maxabs": lambda v: max(abs(x) for x in v),
    "inv": lambda v: 1.0 / v[0] if len(v) == 1 else None,  # 1/x of one value (a ratio turned round)
    "sqrt": lambda v: v[0] ** 0.5 if len(v) == 1 else None,  # standard deviation from a variance
    "ratio": lambda v: v[0] / v[1] if len(v) == 2 else None,  # of two values picked by [(a,b)]
    "diff": lambda v: v[0] - v[1] if len(v) == 2 else None,
}


def lookup(obj: Any, key: str) -> Any:
    """The value at a dotted ``key`` inside a JSON object.

    ``a.b.0.[x/y]``: object keys and list indices; ``*`` takes every element of a list (or every
    value of an object) and the rest of the key inside each, giving a list (``2:5``: a slice); ``key|AGG`` reduces
    that list by an aggregate of :data:`AGGREGATES` (``rows.*.stabilised.*|maxdev1``).
    """
    key, _, agg = key.partition("|")
    if agg and agg not in AGGREGATES:
        raise QuoteError(f"key {key!r}: unknown aggregate {agg!r} (one of {', '.join(AGGREGATES)})")
    parts, pos = [], 0
    for m in _KEY_PART.finditer(key):
        if m.start() != pos:
            raise QuoteError(f"bad key {key!r} at character {pos}")
        pos = m.end() + (1 if m.end() < len(key) and key[m.end()] == "." else 0)
        parts.append(m.group(1) if m.group(1) is not None else m.group(2))
    if pos != len(key) or not parts:
        raise QuoteError(f"bad key {key!r}")
    value = _walk(obj, parts, key)
    if agg:
        vals = list(_flat(value if isinstance(value, list) else [value]))
        if not vals:
            raise QuoteError(f"key {key!r}: nothing to aggregate")
        return AGGREGATES[agg](vals)
    return value


def _holds(obj: dict, cond: str) -> bool:
    """``field=value`` or ``field>=value`` on one element (numbers compared as floats)."""
    field, op, want = re.fullmatch(r"([^=<>]+)(>=|<=|=)(.*)", cond).groups()
    value = obj.get(field)
    try:
        v, w = float(value), float(want)
    except (TypeError, ValueError):
        return op == "=" and str(value) == want
    return v == w if op == "=" else v >= w if op == ">=" else v <= w


def _walk(obj: Any, parts: list[str], key: str, starred: bool = False) -> Any:
    for i, part in enumerate(parts):
        if part == "*" or (isinstance(obj, list) and (re.fullmatch(r"-?\d*:-?\d*", part) or part.startswith("?"))) \
                or (isinstance(obj, dict) and part.startswith("(") and part.endswith(")")):
            if part.startswith("("):  # "[(a,b)]": the values of keys a and b, in that order, like '*'
                inner = part[1:-1]
                names = inner.split(";" if ";" in inner else ",")  # ';' where a key holds commas
                missing = [k for k in names if k not in obj]
                if missing:
                    raise QuoteError(f"key {key!r}: no {missing[0]!r}")
                obj = [obj[k] for k in names]
            elif part.startswith("?"):  # "[?field=value]": the elements whose field equals value, like '*'
                obj = [o for o in obj if isinstance(o, dict) and all(_holds(o, c) for c in part[1:].split("&"))]
            elif part != "*":  # a slice "a:b" of a list, taken like '*'
                lo, hi = (int(v) if v else None for v in part.split(":"))
                obj = obj[lo:hi]
            items = obj if isinstance(obj, list) else list(obj.values()) if isinstance(obj, dict) else None
            if items is None:
                raise QuoteError(f"key {key!r}: '*' inside a {type(obj).__name__}")
            return [_walk(o, parts[i + 1:], key, True) for o in items]
        if isinstance(obj, list):
            try:
                obj = obj[int(part)]
            except (ValueError, IndexError):
                raise QuoteError(f"key {key!r}: {part!r} is not an index of a list of {len(obj)}") from None
        elif isinstance(obj, dict):
            if part not in obj:
                if starred:  # under a '*': an element without this key gives None (dropped)
                    return None
                raise QuoteError(f"key {key!r}: no {part!r} (has {', '.join(map(str, list(obj)[:12]))})")
            obj = obj[part]
        else:
            raise QuoteError(f"key {key!r}: {part!r} inside a {type(obj).__name__}")
    return obj


def fmt_value(value: Any, fmt: str) -> str:
    """Format ``value`` by ``fmt`` (a format spec, optionally ``*FACTOR``)."""
    spec, _, factor = fmt.partition("*")
    if isinstance(value, str) and not factor:
        return value if not spec else format(float(value), spec)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise QuoteError(f"value {value!r} is not a number")
    v = value * float(factor) if factor else value
    if spec.endswith("d"):
        v = int(round(v))
    return format(v, spec)


def quotes(text: str, doc: str = "") -> list[Quote]:
    out = []
    for m in INLINE.finditer(text):
        out.append(Quote(doc, text.count("\n", 0, m.start()) + 1, m["file"], m["key"], m["fmt"], m["val"]))
    return out


def expected(q: Quote, root: Path = ROOT) -> str:
    try:
        return fmt_value(lookup(load(root, q.file), q.key), q.fmt)
    except QuoteError as e:
        raise QuoteError(f"{q.doc}:{q.line}: {e}") from None


def _blocks(text: str):
    for name in BLOCKS:
        start, end = f"<!-- {name} -->", f"<!-- /{name} -->"
        i = text.find(start)
        while i >= 0:
            j = text.find(end, i)
            if j < 0:
                raise QuoteError(f"{start} without {end}")
            yield name, i + len(start), j
            i = text.find(start, j)


def rewrite(text: str, doc: str = "", root: Path = ROOT) -> str:
    """``text`` with every quoted number and block written from its file."""

    def sub(m):
        q = Quote(doc, text.count("\n", 0, m.start()) + 1, m["file"], m["key"], m["fmt"], m["val"])
        return m.group(0).replace(f"-->{m['val']}<!--", f"-->{expected(q, root)}<!--", 1)

    text = INLINE.sub(sub, text)
    for name, a, b in sorted(_blocks(text), key=lambda t: -t[1]):
        text = text[:a] + "\n" + BLOCKS[name](root) + "\n" + text[b:]
    return text


def check(text: str, doc: str = "", root: Path = ROOT) -> list[str]:
    """Every difference between ``text`` and its result files, as ``doc:line: ...`` messages."""
    problems = []
    for q in quotes(text, doc):
        try:
            want = expected(q, root)
        except QuoteError as e:
            problems.append(str(e))
            continue
        if q.text != want:
            problems.append(f"{doc}:{q.line}: quotes {q.text!r} but {q.file} {q.key} gives {want!r}")
    for name, a, b in _blocks(text):
        if text[a:b] != "\n" + BLOCKS[name](root) + "\n":
            line = text.count("\n", 0, a) + 1
            problems.append(f"{doc}:{line}: block {name} differs from what its renderer writes")
    return problems


# ---------------------------------------------------------------------------------------------
# blocks
# ---------------------------------------------------------------------------------------------
_THROUGHPUT_ROWS = (("fixed/jaxdrift", "fixed 1 ms"), ("fixed/jaxdrift-fast", "fixed 1 ms, fast mode (float32 + Kahan)"),
                    ("adaptive/jaxdrift", "adaptive rtol 1e-6"))


@block("throughput-table")
def throughput_table(root: Path) -> str:
    """The README's throughput table from ``benchmarks/results/throughput-idle.json``."""
    res = load(root, "benchmarks/results/throughput-idle.json")
    cases, cfg, mach = res["cases"], res["config"], res["machine"]
    when = f", {res['date'][:10]}" if res.get("date") else ""
    lines = [
        f"Half-car noisy-force study, {cfg['T']:g} s at {cfg['fs']:g} Hz, {cfg['paths']} paths per call, "
        f"float64 unless noted, {mach['cpu_count']}-core {mach.get('cpu', '')} machine (load average "
        f"{mach['load_average_at_start'][0]:.1f} at start{when}); generated from "
        "`benchmarks/results/throughput-idle.json` by `python benchmarks/readme_table.py`:",
        "",
        "| mode | jaxdrift path-steps/s | vs diffrax Dopri5 | vs scipy RK45 |",
        "|---|---:|---:|---:|",
    ]
    for key, label in _THROUGHPUT_ROWS:
        c = cases.get(key)
        if c is None:
            continue
        vs_d = f"{c['vs_diffrax']:.2f}x" if c.get("vs_diffrax") else ""
        vs_s = f"{c['vs_scipy']:.0f}x" if c.get("vs_scipy") else ""
        lines.append(f"| {label} | {c['path_steps_per_s']:.3g} | {vs_d} | {vs_s} |")
    mems = [m for m in (res.get("memory"), res.get("memory_float64")) if m and m.get("peak_rss_bytes")]
    if mems:
        m0 = mems[0]
        lines += ["", f"{m0['paths']:,} paths x {m0['T']:g} s at 1 kHz with statistics every 0.1 s "
                      f"(chunks of {m0['chunk_size']}), peak RSS: "
                      + ", ".join(f"{m['mode']} mode {m['peak_rss_bytes'] / 2**30:.2f} GiB in {m['wall_s']:.0f} s"
                                  for m in mems) + "."]
    return "\n".join(lines)


@block("real-logs-table")
def _real_logs_table(root: Path) -> str:
    """docs/real-data.md: one row per log of docs/validation/real_logs.json (benchmarks/validation/real_logs.py)."""
    r = json.loads((root / "docs/validation/real_logs.json").read_text())

    def g(x):
        return f"{x:.3g}"

    rows = ["| log | hardware (`ver_hw`) | gyro / attitude time base | independent bias (SE) | clear | jaxdrift findings "
            "| attitude error before -> after [rad] |", "|---|---|---|---|---|---|---|"]
    for L in r["logs"]:
        i, gy, at = L["independent"], L["gyro"], L["attitude"]
        tb = (f"{gy['rate_hz']:.0f} Hz, jitter {100 * gy['jitter_std']:.1f} % (std), {gy['gaps']} gaps up to "
              f"{1000 * gy['longest_gap_s']:.0f} ms / {at['rate_hz']:.0f} Hz")
        ind = ", ".join(f"{g(b)} ({g(s)})" for b, s in zip(i["bias"], i["se"]))
        clear = " ".join(a for a, c in zip("xyz", i["clear"]) if c) or "none"
        fs = []
        for f in L["findings"]:
            if f["cause"] == "reference_inconsistent":
                fs.append(f"`reference_inconsistent` {f['axis']} {g(f['span_s'][0])}-{g(f['span_s'][1])} s ({g(f['estimate'])} rad/s)")
            elif f["cause"] == "gyro_noise":
                fs.append(f"`gyro_noise` {g(f['estimate'])} ({f['estimate_kind']})")
            else:
                fs.append(f"`{f['cause']}` {f['channel']} {g(f['estimate'])} [{g(f['interval'][0])}, {g(f['interval'][1])}]")
        nd = ", ".join(f"{d['cause'].replace('gyro_', '')} {d['channel']}" for d in L["not_determined"])
        if nd:
            fs.append("not determined: " + nd)
        e, gn = L["attitude_error_rms"], L["report_gain"]
        rows.append(f"| {L['log']} ({gy['duration_s']:.1f} s) | {L['hardware']} | {tb} | {ind} | {clear} | {'; '.join(fs)} "
                    f"| {g(e['before'])} -> {g(e['after'])} (report: {g(gn['before'])} -> {g(gn['after'])}) |")
    return "\n".join(rows)
