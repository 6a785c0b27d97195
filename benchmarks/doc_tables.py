"""Generated blocks in README.md and docs/: tables written from committed result files.

A block sits between two HTML comments that name its renderer::

    <!-- table:vehicle-sweep -->
    | measure | result | target |
    ...
    <!-- /table:vehicle-sweep -->

Each renderer in :data:`BLOCKS` reads the result file that a script wrote (the file is named in
the renderer's docstring and in :data:`SOURCES`) and returns the Markdown between the markers;
where the script that made the result has its own Markdown writer (``benchmarks/validation/sweep.py``,
``benchmarks/throughput.py``) the renderer calls it. No number in the docs is typed by hand: to
update the docs after a result file was regenerated, run::

    python benchmarks/doc_tables.py            # rewrite every block in place
    python benchmarks/doc_tables.py --check    # compare only; exit 1 naming each difference

``tests/test_docs.py`` runs the check on the committed files (it reruns no benchmark).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: one block: its name, the text between the markers
BLOCK = re.compile(r"<!-- table:(?P<name>[\w-]+) -->\n(?P<body>.*?)<!-- /table:(?P=name) -->", re.S)

#: renderers: name -> function(root) -> Markdown text
BLOCKS: dict[str, Callable[[Path], str]] = {}
#: name -> the result files a renderer reads (relative to the repository root)
SOURCES: dict[str, tuple[str, ...]] = {}


class BlockError(ValueError):
    pass


def block(name: str, *sources: str):
    """Register a renderer under ``name`` that reads ``sources``."""

    def deco(fn):
        BLOCKS[name] = fn
        SOURCES[name] = sources
        return fn

    return deco


def doc_files(root: Path = ROOT) -> list[Path]:
    """README.md and every Markdown page of the site (docs/, without the sweep reports in docs/validation/)."""
    return [root / "README.md", *sorted(p for p in (root / "docs").rglob("*.md") if "validation" not in p.relative_to(root / "docs").parts[:1])]


def load(root: Path, rel: str):
    return json.loads((root / rel).read_text())


def blocks(text: str):
    """(name, start, end) of each block's body in ``text``."""
    for m in BLOCK.finditer(text):
        yield m["name"], m.start("body"), m.end("body")


def render(name: str, root: Path = ROOT) -> str:
    if name not in BLOCKS:
        raise BlockError(f"no renderer named {name!r} (one of {', '.join(sorted(BLOCKS))})")
    return BLOCKS[name](root).rstrip("\n") + "\n"


def rewrite(text: str, root: Path = ROOT) -> str:
    """``text`` with every block written by its renderer."""
    for name, a, b in sorted(blocks(text), key=lambda t: -t[1]):
        text = text[:a] + render(name, root) + text[b:]
    return text


def check(text: str, doc: str = "", root: Path = ROOT) -> list[str]:
    """Each block of ``text`` that differs from what its renderer writes, as ``doc:line: ...``."""
    problems = []
    if text.count("<!-- table:") != len(list(blocks(text))):
        problems.append(f"{doc}: a <!-- table:NAME --> without its <!-- /table:NAME -->")
    for name, a, b in blocks(text):
        line = text.count("\n", 0, a)
        try:
            want = render(name, root)
        except BlockError as e:
            problems.append(f"{doc}:{line}: {e}")
            continue
        if text[a:b] != want:
            problems.append(f"{doc}:{line}: block {name} differs from what its renderer writes from "
                            f"{', '.join(SOURCES[name]) or 'the code'}")
    return problems


def _g(x, spec=".3g"):
    return "-" if x is None else format(x, spec)


# ---------------------------------------------------------------------------------------------
# the paper's study (jaxdrift paper --out docs/figures/paper)
# ---------------------------------------------------------------------------------------------
@block("paper-headline", "docs/figures/paper/summary.json")
def paper_headline(root: Path) -> str:
    """Drift-off times and moments of the seed's study, from ``docs/figures/paper/summary.json``
    (written by ``jaxdrift paper --out docs/figures/paper``)."""
    s = load(root, "docs/figures/paper/summary.json")
    h, d = s["headline"]["drift_off_beta_s"], s["drift_off_beta_s"]
    n = h["noisy"]

    def ci(q):
        return f"{n[q]:.2f} s [{n['ci_' + q][0]:.2f}, {n['ci_' + q][1]:.2f}]"

    em = s["enforced_moment_Nm"]
    rows = [
        "| quantity | paper | jaxdrift, fixed 1 ms steps [95 % interval] | jaxdrift, adaptive rtol 1e-4 |",
        "|---|---|---|---|",
        f"| drift-off, undisturbed forces | beyond 20 s | {h['undisturbed']} | {d['undisturbed']:.1f} s |",
        f"| drift-off, noisy forces | ~10 s | median {ci('median')}; q10 {ci('q10')}; q90 {ci('q90')} "
        f"| median {d['noisy']['median']:.2f} s |",
        f"| drift-off, paper's perturbed model | ~10 s | {h['perturbed_paper']:.2f} s | {d['perturbed_paper']:.2f} s |",
        f"| z3 error at the end, noisy forces | only with noise | {100 * s['error_at_end']['noisy']['z3_m_rms']:.0f} cm RMS | |",
        f"| enforced moment, true model, undisturbed forces | ~70 Nm | {em['unperturbed_undisturbed']['abs_max']:.0f} Nm | |",
        f"| enforced moment, perturbed model, noisy forces | +-800 Nm | +-{em['perturbed_noisy']['abs_max']:.0f} Nm | |",
        f"| inertia term I beta'' | ~15 kNm | {em['inertia_term']['abs_max'] / 1000:.1f} kNm | |",
    ]
    return "\n".join(rows)


@block("paper-solvers", "docs/figures/paper/summary.json")
def paper_solvers(root: Path) -> str:
    """How far the drift-off times depend on the step, the rounding and the solver, from
    ``docs/figures/paper/summary.json``."""
    s = load(root, "docs/figures/paper/summary.json")
    h = s["headline"]
    rows = ["| check | largest change of a drift-off time | noise samples |", "|---|---|---|",
            f"| fixed step 1 ms -> 0.5 ms | {h['step_check']['max_abs_s']:.2f} s | "
            f"spread q90 - q10: {h['step_check']['noisy_q90_minus_q10_s']:.1f} s |",
            f"| polynomial sin/cos -> `jnp.sin`/`jnp.cos` | {h['rounding_check']['max_abs_s']:.2f} s | |"]
    for a in s["solver_agreement"]:
        rows.append(f"| {a['solver']} against fixed 1 ms | {a['noisy_max_abs_s']:.2f} s "
                    f"| {a['noisy_n_within_0_05_s']} of {a['n']} within 0.05 s |")
    return "\n".join(rows)


# ---------------------------------------------------------------------------------------------
# the example run (examples/make_vehicle_example.py)
# ---------------------------------------------------------------------------------------------
@block("example-report", "examples/vehicle_report.json", "examples/vehicle_hidden_effects.json")
def example_report(root: Path) -> str:
    """The findings of ``examples/vehicle_report.json`` beside the hidden effects of
    ``examples/vehicle_hidden_effects.json`` (both written by ``examples/make_vehicle_example.py``)."""
    rep = load(root, "examples/vehicle_report.json")
    rows = ["| rank | cause | on | estimate | 95 % interval (joint) |", "|---|---|---|---|---|"]
    for i, f in enumerate(rep["findings"], 1):
        on = f.get("channel") or f.get("parameter") or ""
        iv = f.get("interval")
        ivs = f"[{iv[0]:.4g}, {iv[1]:.4g}]" if iv else ""
        rows.append(f"| {i} | `{f['cause']}` | {on} | {f['estimate']:.4g} {f.get('unit', '')} | {ivs} |")
    g = rep["gain"]
    be, af = g["beta_error"]["before"], g["beta_error"]["after"]
    rows += ["", "| gain on the run | model | extended model |", "|---|---|---|",
             f"| enforced moment RMS [N m] | {g['before']:.1f} | {g['after']:.1f} |",
             f"| force-driven pitch error RMS [rad] | {be['rms']:.3g} | {af['rms']:.3g} |",
             f"| drift-off time (0.5 deg) [s] | {_g(be['drift_off_time_s'])} | {_g(af['drift_off_time_s'])} |"]
    return "\n".join(rows)


# ---------------------------------------------------------------------------------------------
# independent validation (benchmarks/validation/sweep.py)
# ---------------------------------------------------------------------------------------------
def _sweep(rel: str):
    from benchmarks.validation import sweep

    def render(root: Path) -> str:
        return sweep.summary_table(load(root, rel))

    render.__doc__ = f"The summary table that ``benchmarks/validation/sweep.py`` writes for ``{rel}``."
    return render


VEHICLE_SWEEP = "docs/validation/20e4450-vehicle.json"
ATTITUDE_SWEEP = "docs/validation/3fca4b5-attitude.json"
NONLINEAR_SWEEP = "docs/validation/babf66a-nonlinear-vehicle.json"
block("vehicle-sweep", VEHICLE_SWEEP)(_sweep(VEHICLE_SWEEP))
block("attitude-sweep", ATTITUDE_SWEEP)(_sweep(ATTITUDE_SWEEP))
block("nonlinear-sweep", NONLINEAR_SWEEP)(_sweep(NONLINEAR_SWEEP))


@block("nonlinear-coverage", NONLINEAR_SWEEP)
def nonlinear_coverage(root: Path) -> str:
    """Per nonlinear cause: runs named first and intervals holding the truth (``sweep.py``'s JSON)."""
    s = load(root, NONLINEAR_SWEEP)
    per_t: dict[str, list[int]] = {}
    for k, v in s["single"]["per_target"].items():
        c = k.split(":")[0]
        a = per_t.setdefault(c, [0, 0])
        a[0] += v["right"]
        a[1] += v["n"]
    cov = s["coverage"]["per_cause"]
    rows = ["| cause | right first, single-effect runs | true value inside its interval |", "|---|---|---|"]
    for c in sorted(set(per_t) | set(cov)):
        r = per_t.get(c)
        cv = cov.get(c)
        first = f"{r[0]}/{r[1]}" if r else "-"
        inside = f"{cv['covered']}/{cv['n']}" if cv else "-"
        rows.append(f"| `{c}` | {first} | {inside} |")
    return "\n".join(rows)


CALIBRATION = "docs/validation/calibration.json"
GATE_TRUTH = "docs/validation/gate_truth.json"


@block("calibration", CALIBRATION)
def calibration(root: Path) -> str:
    """Per kind of estimate, the 95 % intervals holding the truth (``calibration_table.py``'s JSON)."""
    from benchmarks.validation import calibration_table

    return calibration_table.markdown(load(root, CALIBRATION))


@block("gate-truth", GATE_TRUTH)
def gate_truth(root: Path) -> str:
    """Per design, the runs whose true corrections both checks kept (``gate_truth.py``'s JSON)."""
    s = load(root, GATE_TRUTH)
    rows = ["| design | runs with a linear effect | true corrections all kept | dropped by a check |", "|---|---|---|---|"]
    for design, d in sorted(s["designs"].items()):
        drops = "; ".join(f"run {x['index']}: {', '.join((x.get('halves') or []) + (x.get('resim') or []))}"
                          for x in d["drops"]) or "-"
        rows.append(f"| {design} | {d['runs']} | {d['kept_all']} | {drops} |")
    rows += ["", f"Runs of `gate_truth.py` ({', '.join(s['files'])}), diagnosed by {', '.join(s['diagnosed_by'])}."]
    return "\n".join(rows)


# ---------------------------------------------------------------------------------------------
# durability (benchmarks/validation/durability_sweep.py, benchmarks/durability.py)
# ---------------------------------------------------------------------------------------------
@block("durability-sweep", "benchmarks/results/durability-sweep.json")
def durability_sweep(root: Path) -> str:
    """Damage ratio (computed / true pseudo-damage) per variant over the generated runs of
    ``benchmarks/results/durability-sweep.json`` (``benchmarks/validation/durability_sweep.py``)."""
    d = load(root, "benchmarks/results/durability-sweep.json")
    rows, meta = d["rows"], d["meta"]
    out = [f"{meta['n_runs']} generated runs of {meta['duration_s']:g} s (roads B-E, "
           f"{min(r['fs'] for r in rows):g}-{max(r['fs'] for r in rows):g} Hz, pitch noise up to "
           f"{max(r['pitch_noise_deg'] for r in rows):g} deg, force noise {meta['force_noise_N']:g} N, K = 5), "
           "both chassis springs:", "",
           "| variant | forces | worst \\|ratio - 1\\| | median ratio |", "|---|---|---|---|"]
    for v, label in (("stabilised", "stabilised (measured pitch, filtered derivatives)"),
                     ("stabilised_unfiltered", "stabilised, plain finite differences"),
                     ("force_driven", "force-driven"), ("pitch_spring", "pitch spring"), ("measured", "measured travel")):
        vals = sorted(x for r in rows if r.get(v) is not None for x in r[v])
        if not vals:
            continue
        med = vals[len(vals) // 2] if len(vals) % 2 else 0.5 * (vals[len(vals) // 2 - 1] + vals[len(vals) // 2])
        out.append(f"| {label} | {len(vals)} | {max(abs(x - 1) for x in vals):.3g} | {med:.4g} |")
    return "\n".join(out)


@block("durability-benchmark", "benchmarks/results/durability.json")
def durability_benchmark(root: Path) -> str:
    """Damage of the seed's half-car variants and the cost, from ``benchmarks/results/durability.json``
    (``python benchmarks/durability.py``)."""
    d = load(root, "benchmarks/results/durability.json")
    m = d["machine"]
    out = [f"{d['duration_s']:g} s at {d['fs_hz']:g} Hz, {d['paths']} noise paths, {m['cpu_count']}-core "
           f"{m.get('cpu_model', '')} machine ({d['recorded']}, `{d['command']}`): {d['total_s']:.0f} s wall, "
           f"{d['total_cpu_s']:.0f} CPU seconds.", "",
           "| variant | damage / stabilised damage | noise band (q05, q50, q95) |", "|---|---|---|"]
    for k, v in d["damage_ratio_to_stabilised"].items():
        q = d["damage_ratio_quantiles"].get(k, [])
        out.append(f"| {k} | {v:.3f} | {', '.join(f'{x:.3f}' for x in q)} |")
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------
# campaign (benchmarks/validation/campaign_validation.py)
# ---------------------------------------------------------------------------------------------
@block("scorecard", "benchmarks/results/scorecard.json")
def scorecard(root: Path) -> str:
    """Every world of ``benchmarks/scorecard.py`` at the committed baseline."""
    from benchmarks.scorecard import table

    d = load(root, "benchmarks/results/scorecard.json")
    return (f"Library at {d['library_commit']} ({d['date']}); `python benchmarks/scorecard.py` "
            f"reproduces it.\n\n" + table(d["full"]))


@block("campaign-validation", "benchmarks/results/campaign_validation.json")
def campaign_validation(root: Path) -> str:
    """The joint fit against single runs on a generated campaign, from
    ``benchmarks/results/campaign_validation.json`` (``benchmarks/validation/campaign_validation.py``)."""
    d = load(root, "benchmarks/results/campaign_validation.json")
    out = [f"{d['runs']} generated runs (seed {d['seed']}), {d['executor']['workers']} Dask workers, "
           f"{d['wall_s']:g} s wall:", "",
           "| parameter | true ratio | joint estimate [95 % interval] | single runs naming it / covering it "
           "| joint interval narrower than the median single one | consistency p |", "|---|---|---|---|---|---|"]
    cons = {c["parameter"]: c for c in d["consistency"]}
    for s in d["shared"]:
        lo, hi = s["joint_interval"]
        c = cons.get(s["parameter"], {})
        out.append(f"| {s['parameter']} | {s['true']:.4f} | {s['joint']:.4f} [{lo:.4f}, {hi:.4f}] | "
                   f"{s['named_by_single_runs']} / {s['single_runs_covering']} | {s['narrowing']:.1f}x | "
                   f"{_g(c.get('p_value'), '.2f')} |")
    sn = d["sensor_named_right"]
    out += ["", f"Sensor effects named right: {sn['single_run']} of {d['runs']} runs alone, "
                f"{sn['campaign']} in the campaign."]
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------
# variance (benchmarks/variance.py)
# ---------------------------------------------------------------------------------------------
@block("variance-halfcar", "benchmarks/results/variance-classC.json", "benchmarks/results/variance.json")
def variance_halfcar(root: Path) -> str:
    """Pitch standard deviation of the half-car: closed form and propagated covariance against
    Monte-Carlo, class C and the study's class D road (``python benchmarks/variance.py``)."""
    out = ["| road | t [s] | closed form / Monte-Carlo | propagated / Monte-Carlo |", "|---|---|---|---|"]
    for rel, road in (("benchmarks/results/variance-classC.json", "C"), ("benchmarks/results/variance.json", "D")):
        for r in load(root, rel)["tables"]["half-car: beta"]:
            out.append(f"| {road} | {r['t']:g} | {_g(r.get('closed_std_ratio'), '.2f')} | "
                       f"{_g(r.get('propagated_std_ratio'), '.2f')} |")
    return "\n".join(out)


@block("variance-pointmass", "benchmarks/results/variance.json")
def variance_pointmass(root: Path) -> str:
    """Point-mass and quaternion variances against their closed forms (``python benchmarks/variance.py``)."""
    d = load(root, "benchmarks/results/variance.json")
    out = ["| quantity | times | closed form / Monte-Carlo std, range | inside the 95 % interval |", "|---|---|---|---|"]
    for name, rows in d["tables"].items():
        if name.startswith("half-car"):
            continue
        r = [x["closed_std_ratio"] for x in rows if x.get("closed_std_ratio") is not None]
        ins = sum(bool(x.get("closed_inside")) for x in rows)
        out.append(f"| {name} | {len(rows)} | {min(r):.3f}-{max(r):.3f} | {ins}/{len(rows)} |")
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------
# performance (benchmarks/throughput.py, benchmarks/diagnose.py)
# ---------------------------------------------------------------------------------------------
_THROUGHPUT_ROWS = (("fixed/jaxdrift", "fixed 1 ms"), ("fixed/jaxdrift-fast", "fixed 1 ms, fast mode (float32 + Kahan)"),
                    ("adaptive/jaxdrift", "adaptive rtol 1e-6"))


@block("throughput-table", "benchmarks/results/throughput-idle.json")
def throughput_table(root: Path) -> str:
    """Throughput against diffrax and scipy from ``benchmarks/results/throughput-idle.json``
    (``python benchmarks/throughput.py``)."""
    res = load(root, "benchmarks/results/throughput-idle.json")
    cases, cfg, mach = res["cases"], res["config"], res["machine"]
    when = f", {res['date'][:10]}" if res.get("date") else ""
    lines = [
        f"Half-car noisy-force study, {cfg['T']:g} s at {cfg['fs']:g} Hz, {cfg['paths']} paths per call, "
        f"float64 unless noted, {mach['cpu_count']}-core {mach.get('cpu', '')} machine (load average "
        f"{mach['load_average_at_start'][0]:.1f} at start{when}):",
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


@block("diagnose-timing", "benchmarks/results/diagnose.json")
def diagnose_timing(root: Path) -> str:
    """Time to read and diagnose a long run, from ``benchmarks/results/diagnose.json``
    (``python benchmarks/diagnose.py``)."""
    d = load(root, "benchmarks/results/diagnose.json")
    s, m = d["seconds"], d["machine"]
    return "\n".join([
        f"A {d['duration_s']:g} s run at {d['fs_hz']:g} Hz ({d['samples']:,} samples), {m['cpus']}-core machine "
        f"({d['recorded']}, load average {m['loadavg_1min']:.1f}):", "",
        "| step | seconds |", "|---|---|",
        f"| read the CSV | {s['read_csv']:.1f} |",
        f"| diagnose, first call (compilation included) | {s['diagnose_full_cold']:.1f} |",
        f"| diagnose, second call | {s['diagnose_full_warm']:.1f} |",
        f"| diagnose without the force-driven re-simulation | {s['diagnose_without_force_driven_simulation']:.1f} |"])


# ---------------------------------------------------------------------------------------------
# the real-data corpus (benchmarks/validation/real_corpus.py)
# ---------------------------------------------------------------------------------------------
def _corpus_table(r) -> str:
    g = _g
    rows = ["| recording | device | format | length [s] | independent bias x, y, z [mrad/s] (SE) | clear | named "
            "| jaxdrift's gyro noise [rad/sqrt(s)] | still-span noise [rad/sqrt(s)] (ratio) | other findings | exit |",
            "|---|---|---|---|---|---|---|---|---|---|---|"]
    named = clear = n_ok = n_checked = 0
    for L in r["logs"]:
        ind, j = L.get("independent") or {}, L.get("jaxdrift") or {}
        ch = j.get("checks") or {}
        if not ind or not ch.get("ran"):
            rows.append(f"| {Path(L['file']).name} | {L['device']} | {L['format']} | | missing | | | | | | |")
            continue
        b = ", ".join(f"{1e3 * x:+.2f} ({1e3 * s:.2f})" for x, s in zip(ind["bias"], ind["se"]))
        cl = " ".join(a for a, c in zip("xyz", ind["clear"]) if c) or "none"
        named += ch["clear_named"]
        clear += ch["clear"]
        gn = ch.get("gyro_noise") or {}
        noise = f"{g(gn['estimate'])} ({gn['kind'].replace('_', ' ')})" if gn else "none"
        nc = ch.get("noise_check")
        still = "-"
        if nc:
            n_checked += 1
            n_ok += bool(nc["ok"])
            still = f"{g(nc['still'])} ({nc['ratio']:.2g}{'' if nc['ok'] else ', outside 3x'})"
        elif L.get("still_noise"):
            still = g(sum(L["still_noise"]["density"]) / 3)
        others = sorted({c for c in ch.get("causes", []) if c not in ("gyro_noise", "gyro_bias")})
        dur = L.get("gyro", {}).get("duration_s") if isinstance(L.get("gyro"), dict) else None
        rows.append(f"| {Path(L['file']).name} | {L['device']} | {L['format']} | {g(dur) if dur else ''} | {b} | {cl} "
                    f"| {ch['clear_named']}/{ch['clear']} | {noise} | {still} | {', '.join(others) or '-'} | {j.get('exit')} |")
    rows.append(f"| **all** | | | | | | **{named}/{clear}** | | **{n_ok}/{n_checked}** | | |")
    return "\n".join(rows)


@block("real-corpus-table", "docs/validation/real_corpus.json")
def real_corpus_table(root: Path) -> str:
    """One row per recording of ``docs/validation/real_corpus.json`` (``benchmarks/validation/real_corpus.py``)."""
    return _corpus_table(load(root, "docs/validation/real_corpus.json"))


@block("heldout-corpus-table", "docs/validation/heldout_corpus.json")
def heldout_corpus_table(root: Path) -> str:
    """The first held-out recordings (``tests/data/heldout/SOURCES.toml``), as the corpus table."""
    return _corpus_table(load(root, "docs/validation/heldout_corpus.json"))


@block("heldout2-corpus-table", "docs/validation/heldout2_corpus.json")
def heldout2_corpus_table(root: Path) -> str:
    """The second held-out recordings (``tests/data/heldout2/SOURCES.toml``), as the corpus table."""
    return _corpus_table(load(root, "docs/validation/heldout2_corpus.json"))


@block("heldout3-corpus-table", "docs/validation/heldout3_corpus.json")
def heldout3_corpus_table(root: Path) -> str:
    """The third held-out recordings (``tests/data/heldout3/SOURCES.toml``), as the corpus table."""
    return _corpus_table(load(root, "docs/validation/heldout3_corpus.json"))


@block("heldout4-corpus-table", "docs/validation/heldout4_corpus.json")
def heldout4_corpus_table(root: Path) -> str:
    """The fourth held-out recordings (``tests/data/heldout4/SOURCES.toml``), as the corpus table."""
    return _corpus_table(load(root, "docs/validation/heldout4_corpus.json"))


# ---------------------------------------------------------------------------------------------
# schemas: from the code's catalogue and from reports the code wrote
# ---------------------------------------------------------------------------------------------
@block("vehicle-causes")
def vehicle_causes(root: Path) -> str:
    """The vehicle causes registered in ``jaxdrift/diagnosis/vehicle/_causes.py`` (``VEHICLE_CAUSES``)."""
    from jaxdrift.diagnosis.vehicle._causes import VEHICLE_CAUSES

    rows = ["| cause | target key | unit | sensor effect (a campaign's nuisance) | method part of the interval |",
            "|---|---|---|---|---|"]
    for k in VEHICLE_CAUSES:
        rows.append(f"| `{k.name}` | `{k.target_key}` | {k.unit} | {'yes' if k.is_sensor else 'no'} | "
                    f"{k.method_rel:g} x size |")
    return "\n".join(rows)


def key_tree(obj, prefix: str = "", depth: int = 0, max_depth: int = 3) -> list[tuple[str, str]]:
    """(dotted key, JSON type) of every key of ``obj`` down to ``max_depth``; a list shows its first element as ``[]``."""
    out = []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out.append((prefix + k, _type(v)))
            if depth + 1 < max_depth:
                out += key_tree(v, prefix + k + ".", depth + 1, max_depth)
    elif isinstance(obj, list) and obj and isinstance(obj[0], dict):
        out += key_tree(obj[0], prefix.rstrip(".") + "[].", depth, max_depth)
    return out


def _type(v) -> str:
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "boolean"
    if isinstance(v, (int, float)):
        return "number"
    if isinstance(v, str):
        return "string"
    if isinstance(v, list):
        return "array"
    return "object"


@block("report-keys", "examples/vehicle_report.json")
def report_keys(root: Path) -> str:
    """The keys of a vehicle report, from ``examples/vehicle_report.json`` (written by ``jaxdrift diagnose``)."""
    rep = load(root, "examples/vehicle_report.json")
    rows = ["| key | type |", "|---|---|"]
    rows += [f"| `{k}` | {t} |" for k, t in key_tree(rep, max_depth=2)]
    return "\n".join(rows)


@block("campaign-keys", "examples/campaign.json")
def campaign_keys(root: Path) -> str:
    """The keys of ``campaign.json``, from ``examples/campaign.json`` (``examples/make_campaign_example.py``:
    a two-run campaign with ``--durability``, written by ``jaxdrift campaign``)."""
    doc = load(root, "examples/campaign.json")
    rows = ["| key | type |", "|---|---|"]
    rows += [f"| `{k}` | {t} |" for k, t in key_tree(doc, max_depth=3)
             if not k.startswith("runs[].findings") and not k.startswith("joint.findings[]")]
    return "\n".join(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare only, write nothing; exit 1 on a difference")
    args = ap.parse_args(argv)
    problems, changed, n = [], [], 0
    for path in doc_files(ROOT):
        rel = str(path.relative_to(ROOT))
        text = path.read_text()
        n += len(list(blocks(text)))
        if args.check:
            problems += check(text, rel, ROOT)
            continue
        new = rewrite(text, ROOT)
        if new != text:
            path.write_text(new)
            changed.append(rel)
    for p in problems:
        print(p, file=sys.stderr)
    print(f"{n} generated blocks in {len(doc_files(ROOT))} documents"
          + (f"; rewritten: {', '.join(changed)}" if changed else "")
          + (f"; {len(problems)} problems" if problems else ""))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
