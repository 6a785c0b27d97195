"""The docs: their size, their generated tables, and the behaviour they state.

- Prose budget: README.md and the site's pages (docs/, without the sweep reports in
  docs/validation/) hold at most 20,000 words of prose together, the README at most 1,200; tables,
  code blocks and HTML comments do not count. No Markdown file is more than 5 % HTML comments.
- Every generated table equals what its renderer in ``benchmarks/doc_tables.py`` writes from the
  committed result file (``python benchmarks/doc_tables.py`` rewrites them).
- Statements of the docs that a test can check (a number, what is counted where).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from benchmarks import doc_tables

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
DOCS = doc_tables.doc_files(ROOT)
PROSE_BUDGET, README_BUDGET, COMMENT_SHARE = 20_000, 1_200, 0.05


def prose_words(text: str) -> int:
    """Words of prose in Markdown: fenced code blocks, indented code blocks, table rows and HTML
    comments are left out; inline code spans count as one word each."""
    text = re.sub(r"<!--.*?-->", " ", text, flags=re.S)
    text = re.sub(r"^(```|~~~).*?^\1[^\n]*$", " ", text, flags=re.S | re.M)
    words = 0
    for line in text.splitlines():
        if line.lstrip().startswith("|") or line.startswith("    ") and not line.lstrip().startswith(("-", "*")):
            continue
        words += len(re.findall(r"`[^`]*`|[\w'.,;:()+\-/=%]+", line))
    return words


def test_prose_words_leave_out_tables_code_and_comments():
    text = "One two three.\n\n| a | b |\n|---|---|\n| x y z | w |\n\n```bash\nls -la here\n```\n<!-- a comment -->\n`a b` four"
    assert prose_words(text) == 5


def test_prose_budget():
    counts = {str(p.relative_to(ROOT)): prose_words(p.read_text()) for p in DOCS}
    total = sum(counts.values())
    report = ", ".join(f"{k} {v}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))
    assert counts["README.md"] <= README_BUDGET, report
    assert total <= PROSE_BUDGET, f"{total} words of prose: {report}"


@pytest.mark.parametrize("path", sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md", ROOT / "CHANGELOG.md"],
                         ids=lambda p: str(p.relative_to(ROOT)))
def test_html_comments_are_a_small_share(path):
    text = path.read_text()
    comments = sum(len(m) for m in re.findall(r"<!--.*?-->", text, flags=re.S))
    assert comments <= COMMENT_SHARE * max(len(text), 1), f"{comments} of {len(text)} characters are HTML comments"


def test_no_per_number_markers():
    for p in DOCS:
        assert "<!-- q:" not in p.read_text(), p


@pytest.mark.parametrize("path", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_generated_tables_match_their_result_files(path):
    rel = str(path.relative_to(ROOT))
    problems = doc_tables.check(path.read_text(), rel, ROOT)
    assert not problems, "\n".join(problems) + "\n(run `python benchmarks/doc_tables.py` after regenerating a result)"


def test_a_hand_edited_table_fails():
    text = "x\n<!-- table:diagnose-timing -->\n" + doc_tables.render("diagnose-timing") + "<!-- /table:diagnose-timing -->\n"
    assert doc_tables.check(text, "x.md") == []
    bad = text.replace("| read the CSV | ", "| read the CSV | 9")
    (msg,) = doc_tables.check(bad, "x.md")
    assert "x.md:" in msg and "diagnose-timing" in msg and "benchmarks/results/diagnose.json" in msg
    assert doc_tables.rewrite(bad) == text
    assert doc_tables.check("<!-- table:no-such -->\nx\n<!-- /table:no-such -->", "y.md")


def test_every_renderer_is_used_and_its_sources_exist():
    used = {name for p in DOCS for name, _, _ in doc_tables.blocks(p.read_text())}
    assert used == set(doc_tables.BLOCKS)
    for name, sources in doc_tables.SOURCES.items():
        for s in sources:
            assert (ROOT / s).is_file(), (name, s)


def test_no_transcribed_result_files():
    assert not list((ROOT / "benchmarks" / "results").glob("*-recorded.json"))


def test_readme_quick_start_has_two_commands_and_ci_runs_the_second():
    quick = README.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    (block,) = re.findall(r"```bash\n(.*?)```", quick, re.S)
    cmds = [line for line in block.splitlines() if line.strip() and not line.startswith("#")]
    assert len(cmds) == 2
    ci = (ROOT / ".ci" / "run").read_text()
    assert cmds[1].split("&& ", 2)[-1] in ci  # the test command


def test_interval_level_counts_every_finding_with_an_interval():
    """docs/reference/report.md: every finding with an estimate and an interval counts in
    ``interval_level``, the nonlinear suspension findings included (the pipeline puts them in
    front of the linear ones before ``joint_intervals``)."""
    import inspect

    from jaxdrift.diagnosis._intervals import joint_intervals
    from jaxdrift.diagnosis.vehicle import _report as _pipeline  # the report step assembles the findings

    findings = [{"cause": "bump_stop", "estimate": 8e5, "interval": [7e5, 9e5]},
                {"cause": "force_offset", "estimate": 50.0, "interval": [48.0, 52.0]},
                {"cause": "force_noise", "estimate": 15.0, "interval": [14.0, 16.0]},
                {"cause": "model_form", "estimate": 3.0}]
    findings = joint_intervals(findings)
    assert [f.get("interval_level", {}).get("findings") for f in findings] == [3, 3, 3, None]
    src = inspect.getsource(_pipeline)
    assert src.index('+ form["findings"] + findings') < src.index("joint_intervals(findings)")
    doc = (ROOT / "docs" / "reference" / "report.md").read_text()
    assert "the nonlinear suspension findings and unconfirmed findings included" in doc.replace("\n", " ")


# ------------------------------------------------------------------------------ doc numbers

def test_euler_position_variance_14_5_percent_below_at_10_steps():
    """docs/explanation/paper-study.md: at 10 steps the Euler position variance is 14.5 % below (2.8)."""
    from jaxdrift.analysis._pointmass import euler_variance, pointmass_variance
    from jaxdrift.models._params import PointMassParams

    p = PointMassParams(m=1.0, eta=0.0)
    dt, n = 0.01, 10
    ev = float(euler_variance(n * dt, 1.0, dt, p)[0][0])
    cf = float(np.ravel(pointmass_variance(n * dt, 1.0, dt, p)[0])[0])
    assert 1 - ev / cf == pytest.approx(1 - (n - 1) * (2 * n - 1) / (2 * n**2), abs=1e-12)
    assert 1 - ev / cf == pytest.approx(0.145, abs=1e-12)
    assert "14.5 % below\nthe continuous (2.8)" in (ROOT / "docs" / "explanation" / "paper-study.md").read_text()


def test_simulate_prescribed_pitch_starts_at_the_model_equilibrium():
    """The docstring: the initial state is static_equilibrium(params, "pitch") whatever the
    prescribed pitch at the start (the old docstring said: at the prescribed initial pitch)."""
    import jax.numpy as jnp

    import jaxdrift
    from jaxdrift.models._halfcar import equilibrium_forces

    p = jaxdrift.HalfCarParams()
    f1, f2, _, _ = equilibrium_forces(p)
    n, dt = 201, 0.01
    forces = jaxdrift.SampledSignal(0.0, dt, jnp.tile(jnp.array([f1, f2]), (n, 1)))
    pitch = jaxdrift.SampledSignal(0.0, dt, jnp.tile(jnp.array([0.05, 0.0, 0.0]), (n, 1)))
    sol, lam, inertia = jaxdrift.simulate_prescribed_pitch(p, forces, pitch, jnp.linspace(0.0, 1.0, 11))
    np.testing.assert_allclose(np.asarray(sol.ys[0]), np.asarray(jaxdrift.static_equilibrium(p, "pitch")), atol=0)
    assert abs(float(lam[0])) > 1.0  # the 0.05 rad start is off the equilibrium: a transient moment
    assert "whatever the prescribed pitch is at the start" in jaxdrift.simulate_prescribed_pitch.__doc__


# ------------------------------------------------------------------------------ notebooks

def test_notebook_output_dir(tmp_path, monkeypatch):
    from jaxdrift.studies._notebook import notebook_output_dir

    (tmp_path / "pyproject.toml").write_text("")
    (tmp_path / "notebooks").mkdir()
    monkeypatch.delenv("JAXDRIFT_NOTEBOOK_OUT", raising=False)
    monkeypatch.chdir(tmp_path / "notebooks")
    assert notebook_output_dir() == str(tmp_path / "build" / "notebooks")
    assert (tmp_path / "build" / "notebooks").is_dir() and sorted(p.name for p in (tmp_path / "notebooks").iterdir()) == []
    monkeypatch.setenv("JAXDRIFT_NOTEBOOK_OUT", str(tmp_path / "mine"))
    assert notebook_output_dir() == str(tmp_path / "mine")
    assert notebook_output_dir(str(tmp_path / "arg")) == str(tmp_path / "arg")
    for nb in (ROOT / "notebooks").glob("*.py"):
        src = nb.read_text()
        assert "OUT = notebook_output_dir()" in src and '"paper-out"' not in src, nb.name
