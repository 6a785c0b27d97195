"""The HTML pages (issue 34): each kind of page opened in headless Chromium.

Every page is built by the command line as a user runs it (diagnose --html on the example vehicle
run and on a real PX4 ULog, durability --html, campaign DIR/index.html), opened over the DevTools
protocol (tests/_chromium.py) and checked for console errors, network requests (none but the
file itself), every finding of its JSON on the page, and that text from an input file (a CSV
column named as markup) stays text. The size and opening time of a page for a 60 s run at 1 kHz
are measured and printed, not asserted. With JAXDRIFT_SCREENSHOTS=DIR a screenshot of each kind
of page is written there (the README's are docs/figures/report/).
"""

from __future__ import annotations

import csv
import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from _chromium import Browser, chromium_path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
XSS = "<img src=x onerror=alert(1)>"
SCRIPT = "<script>alert(1)</script>"
ULOG = ROOT / "tests" / "data" / "ulog" / "sample_appended_multiple.ulg"

pytestmark = pytest.mark.skipif(chromium_path() is None, reason="no chromium (.ci/run installs it)")


@pytest.fixture(scope="module")
def browser():
    pytest.importorskip("websocket")
    with Browser() as b:
        yield b


def _shot(browser, name: str) -> None:
    where = os.environ.get("JAXDRIFT_SCREENSHOTS")
    if where:
        os.makedirs(where, exist_ok=True)
        browser.evaluate("window.scrollTo(0, 0)")
        browser.screenshot(os.path.join(where, name), height=1500)


def _open(browser, page: Path) -> tuple[float, str]:
    secs = browser.open(str(page))
    assert browser.console_errors() == []
    own = page.resolve().as_uri()
    assert [u for u in browser.requests() if u != own] == [], "the page requested something"
    return secs, browser.evaluate("document.body.innerText")


def _check_findings(browser, findings, prefix="finding"):
    from jaxdrift.report._html import finding_label

    assert findings
    for i, f in enumerate(findings, 1):
        text = browser.evaluate(f"(document.getElementById('{prefix}-{i}') || {{}}).innerText || ''")
        assert finding_label(f) in text, (i, finding_label(f))
        if f.get("evidence"):
            assert " ".join(f["evidence"].split())[:60] in " ".join(text.split())


def _no_injected_elements(browser):
    # the payload is an <img> with onerror: none may exist, and the page has no image at all
    assert browser.evaluate("document.querySelectorAll('img, script, iframe, [onerror]').length") == 0


# ------------------------------------------------------------------------------------ vehicle


@pytest.fixture(scope="module")
def vehicle(tmp_path_factory):
    """The example run in a file named as markup, its f1 column named ``<script>...`` (read
    through --map) and an unused column named as the image payload: the names reach the report
    (run file, provenance) and so the page."""
    from jaxdrift.cli import main

    d = tmp_path_factory.mktemp("vehicle")
    with open(ROOT / "examples" / "vehicle_run.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    rows[0] = [SCRIPT if c == "f1" else c for c in rows[0]] + [XSS]
    for r in rows[1:]:
        r.append("1.0")
    run = d / f"{XSS}.csv"
    with open(run, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    rc = main(["-q", "diagnose", str(run), "--model", str(ROOT / "examples" / "vehicle_model.json"),
               "--map", f"f1={SCRIPT}", "--json", str(d / "report.json"), "--html", str(d / "report.html")])
    assert rc == 0
    return d


def test_vehicle_page(browser, vehicle, capsys):
    rep = json.loads((vehicle / "report.json").read_text())
    assert "series_preview" in rep and all(len(tr["t"]) <= 2 * 1000 + 2 for tr in rep["series_preview"]["traces"].values())
    secs, text = _open(browser, vehicle / "report.html")
    _check_findings(browser, rep["findings"])
    assert "Drift: measured against simulated" in text and "Time base" in text and "What could not be shown" in text
    assert browser.evaluate("document.querySelectorAll('svg').length") >= 3
    _no_injected_elements(browser)
    assert XSS in text and SCRIPT in text  # shown as text
    _shot(browser, "vehicle.png")


def test_report_command_rebuilds_the_page_and_summary(vehicle, tmp_path, capsys):
    from jaxdrift.cli import main

    capsys.readouterr()
    assert main(["report", str(vehicle / "report.json"), "--html", str(tmp_path / "again.html")]) == 0
    out = capsys.readouterr().out
    rep = json.loads((vehicle / "report.json").read_text())
    assert out.startswith("jaxdrift report: ") and "gain:" in out and str(tmp_path / "again.html") in out
    assert all(f"{i}. " in out for i in range(1, len(rep["findings"]) + 1))
    # the page depends on the JSON only (figure ids are salted per figure, not per process)
    again = (tmp_path / "again.html").read_text()
    assert len(again) == pytest.approx(len((vehicle / "report.html").read_text()), rel=0.01)
    assert main(["-q", "report", str(vehicle / "report.json"), "--html", str(tmp_path / "q.html")]) == 0
    assert len(capsys.readouterr().out.strip().splitlines()) == 1


def test_markup_in_every_string_of_a_report_stays_text(browser, vehicle, tmp_path):
    """Markup in every place a report carries input text: finding fields (known and unknown),
    notes, trace labels inside the SVG figures, markers, provenance."""
    from jaxdrift.report._html import render

    rep = json.loads((vehicle / "report.json").read_text())
    rep["findings"][0]["evidence"] = XSS
    rep["findings"][0]["onboard"] = {"estimate": 0.93, "topic": XSS}
    rep["findings"].append({"cause": XSS, "channel": XSS, "estimate": 1.0, "unit": XSS, "interval": [0.5, 1.5]})
    rep["notes"].append(XSS)
    tr = next(iter(rep["series_preview"]["traces"].values()))
    tr["label"] = XSS
    rep["series_preview"]["markers"].append({"t": 1.0, "label": XSS})
    rep["provenance"][XSS] = XSS
    page = tmp_path / "xss.html"
    page.write_text(render(rep))
    _, text = _open(browser, page)
    _no_injected_elements(browser)
    assert text.count(XSS) >= 5
    svg_text = browser.evaluate("Array.from(document.querySelectorAll('svg text')).map(e => e.textContent).join('|')")
    assert XSS in svg_text


def test_json_to_stdout_keeps_the_pipe_clean(vehicle, capsys):
    """--json -: stdout is the report alone; the summary goes to stderr. The report given back
    through `jaxdrift report` (no diagnosis again)."""
    from jaxdrift.cli._report import finish, json_to_stdout

    rep = json.loads((vehicle / "report.json").read_text())
    capsys.readouterr()
    json_to_stdout(rep)
    finish(rep, {"report": None, "page": "p.html"}, "diagnose", to_stderr=True)
    cap = capsys.readouterr()
    assert json.loads(cap.out)["findings"] == rep["findings"]
    assert cap.err.startswith("jaxdrift diagnose: ")


# ----------------------------------------------------------------------------------- attitude


def test_attitude_page_from_a_real_ulog(browser, tmp_path, capsys):
    pytest.importorskip("pyulog")
    from jaxdrift.cli import main

    capsys.readouterr()
    rc = main(["diagnose", str(ULOG), "--json", "-", "--html", str(tmp_path / "a.html")])
    assert rc == 0
    cap = capsys.readouterr()
    rep = json.loads(cap.out)  # the report alone on stdout
    assert "jaxdrift diagnose: " in cap.err and "gyro_bias" in cap.err
    secs, text = _open(browser, tmp_path / "a.html")
    _check_findings(browser, rep["findings"])
    assert "Gyro against the reference attitude's rate" in browser.evaluate(
        "Array.from(document.querySelectorAll('svg text')).map(e => e.textContent).join(' ')")
    for ax in ("wx", "wy", "wz"):
        assert f"{ax}_reference" in rep["series_preview"]["traces"]
    assert rep["series_preview"]["spectra"]
    _shot(browser, "attitude.png")


# --------------------------------------------------------------------------------- durability


def test_durability_page(browser, vehicle, tmp_path, capsys):
    from jaxdrift.cli import main

    capsys.readouterr()
    rc = main(["durability", str(ROOT / "examples" / "vehicle_run.csv"), "--model",
               str(ROOT / "examples" / "vehicle_model.json"), "--report", str(vehicle / "report.json"),
               "--out", str(tmp_path / "dur"), "--paths", "2", "--quiet", "--html", str(tmp_path / "d.html")])
    assert rc == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and out[0].startswith("jaxdrift durability: damage / stabilised")
    doc = json.loads((tmp_path / "dur" / "durability.json").read_text())
    secs, text = _open(browser, tmp_path / "d.html")
    for v, r in doc["damage_ratio_to_stabilised"].items():
        assert v in text and f"{r:.4g}" in text
    assert "Section forces of the variants" in browser.evaluate(
        "Array.from(document.querySelectorAll('svg text')).map(e => e.textContent).join(' ')")
    _shot(browser, "durability.png")


# ----------------------------------------------------------------------------------- campaign


def test_campaign_pages(browser, tmp_path, capsys):
    pytest.importorskip("distributed")
    from benchmarks.validation import gen_campaign as gc
    from jaxdrift.cli import main

    data = tmp_path / "data"
    d = gc.draw_campaign(2, 6107, n_shared=1, durations=(3.0, 3.0), rates=(200,), params=("m3",),
                         motion_noise_share=0.0)
    gc.write_campaign(d, str(data), progress=False)
    out = tmp_path / "out"
    capsys.readouterr()
    rc = main(["campaign", "--manifest", str(data / "campaign.toml"), "--out", str(out), "--workers", "1",
               "--no-figures"])
    assert rc == 0
    summary = capsys.readouterr().out
    assert summary.startswith("jaxdrift campaign: 2 of 2 runs diagnosed") and "index.html" in summary
    doc = json.loads((out / "campaign.json").read_text())
    secs, text = _open(browser, out / "index.html")
    _check_findings(browser, doc["joint"]["findings"], "joint")
    assert "Consistency across runs" in text
    links = browser.evaluate("Array.from(document.querySelectorAll('#runs a')).map(a => a.getAttribute('href'))")
    assert sorted(links) == sorted(f"runs/{r['name']}.html" for r in doc["runs"])
    assert browser.evaluate("document.querySelectorAll('#forest svg').length") == len(doc["joint"]["findings"])
    _shot(browser, "campaign.png")
    for r in doc["runs"]:
        rep = json.loads((out / r["report"]).read_text())
        _open(browser, out / "runs" / f"{r['name']}.html")
        _check_findings(browser, rep["findings"])


# ------------------------------------------------------------------------ a long run's page


def test_page_of_a_60s_1khz_run_size_and_open_time(browser, vehicle, tmp_path):
    """Measured, not asserted (issue 34 aims at < 5 MB and < 2 s): the example report with the
    traces of a 60 s, 1 kHz run (60 001 samples each, decimated min/max per bin as the CLI does)."""
    import time

    from jaxdrift.report._html import render
    from jaxdrift.report._preview import minmax_decimate

    rep = json.loads((vehicle / "report.json").read_text())
    t = np.arange(60_001) / 1000.0
    rng = np.random.default_rng(0)
    for k, tr in rep["series_preview"]["traces"].items():
        y = np.cumsum(rng.standard_normal(t.size)) * 1e-3 + np.sin(2 * np.pi * 1.3 * t)
        y[rng.integers(0, t.size)] += 50.0  # a one-sample peak must survive decimation
        td, yd = minmax_decimate(t, y)
        assert yd.max() == y.max()
        tr["t"], tr["y"] = [float(f"{v:.6g}") for v in td], [float(f"{v:.6g}") for v in yd]
    t0 = time.perf_counter()
    html_text = render(rep)
    build = time.perf_counter() - t0
    page = tmp_path / "long.html"
    page.write_text(html_text)
    secs, _ = _open(browser, page)
    size = page.stat().st_size
    print(f"\n60 s at 1 kHz: page {size / 1e6:.2f} MB, built in {build:.2f} s, opened (load event) in {secs:.2f} s")
    if size > 5e6 or secs > 2.0:
        import warnings

        warnings.warn(f"page of a 60 s, 1 kHz run: {size / 1e6:.2f} MB, {secs:.2f} s (aim: < 5 MB, < 2 s)",
                      UserWarning, stacklevel=1)


# ---------------------------------------------------------------- the band a finding was judged in


@pytest.fixture(scope="module")
def banded(tmp_path_factory):
    """A run whose pitch carries 1e-5 rad of white sensor noise: its enforced moment is compared
    below a few Hz (``_problem.choose_bands``); over the full band the noise, differentiated twice,
    is all a figure would show (#46 item 3)."""
    from jaxdrift.cli import main
    from jaxdrift.studies import _rungen as rg

    d = tmp_path_factory.mktemp("banded")
    effects = [{"cause": "force_offset", "channel": "f1", "value": 60.0}, {"cause": "force_noise", "value": 20.0}]
    cols, _ = rg.make_run(effects, duration=30.0, fs=500.0, speed=15.0, road_class="B", seed=11, channels=("beta",))
    cols["beta"] = cols["beta"] + 1e-5 * np.random.default_rng(0).standard_normal(len(cols["t"]))
    run = d / "run.csv"
    with open(run, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(list(cols))
        w.writerows(zip(*[[f"{v:.10g}" for v in cols[k]] for k in cols]))
    assert main(["-q", "diagnose", str(run), "--json", str(d / "report.json"), "--html", str(d / "report.html")]) == 0
    return d


def test_residual_figures_plot_the_band_the_finding_was_judged_in(browser, banded):
    rep = json.loads((banded / "report.json").read_text())
    g = rep["gain"]
    assert g["metric"] == "enforced_moment_rms" and g["band_hz"][1] < 20.0
    tr = rep["series_preview"]["traces"]
    before, after = tr["residual_moment_model"], tr["residual_moment_extended"]
    # what is drawn is what was compared: its RMS is the gain's, before and after
    assert before["band_hz"] == g["band_hz"] and after["band_hz"] == g["band_hz"]
    assert before["rms"] == pytest.approx(g["before"], rel=1e-6) and after["rms"] == pytest.approx(g["after"], rel=1e-6)
    # the full band holds the sensor noise, differentiated twice: far larger than what was compared
    full = rep["simulation_error"]["enforced_moment"]["rms"]
    assert full > 10 * g["before"]
    assert max(abs(v) for v in before["y"]) < 0.2 * full
    # the zoom: the stretch where the residual was largest, every sample
    zb = tr["residual_moment_model_zoom"]
    assert zb["rms"] >= before["rms"] and len(zb["t"]) == int(round(2.0 * 500))
    _, text = _open(browser, banded / "report.html")
    assert f"below {g['band_hz'][1]:.4g} Hz".replace(".0 Hz", " Hz") in text or "the band it was compared in" in text
    assert "worst stretch" in text
