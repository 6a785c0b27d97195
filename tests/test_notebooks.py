"""The notebooks (jupytext percent-format .py files) are valid notebooks and run top to bottom in
their small configuration, so they never rot."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ["section2_pointmass.py", "section4_halfcar.py", "drift_variance.py", "durability.py"]


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_notebook_is_a_valid_percent_notebook(name):
    import jupytext

    nb = jupytext.read(ROOT / "notebooks" / name)
    kinds = [c.cell_type for c in nb.cells]
    assert kinds.count("markdown") >= 2 and kinds.count("code") >= 3


@pytest.mark.parametrize("name, expected", [
    ("section2_pointmass.py", ["fig2_pointmass_std.png"]),
    # two notebooks run in the second tier (CI): the section-4 study's steps (tests/test_paper.py) and
    # the drift variances (tests/test_variance.py) are checked in the default suite
    pytest.param("section4_halfcar.py", ["fig4_road_forces.png", "fig8_enforced_moment.png", "summary.json"],
                 marks=pytest.mark.tier2),
    pytest.param("drift_variance.py", ["drift_variance.png", "drift_variance.json"], marks=pytest.mark.tier2),
    ("durability.py", ["damage_vs_duration.png", "pitch_spring_sweep.png", "durability_notebook.json",
                       "durability.json", "damage_ratio.png"]),
])
def test_notebook_runs_in_small_configuration(name, expected, tmp_path):
    env = dict(os.environ, JAXDRIFT_NOTEBOOK_SMALL="1", JAXDRIFT_NOTEBOOK_OUT=str(tmp_path), MPLBACKEND="Agg",
               PYTHONWARNINGS="error::RuntimeWarning")
    proc = subprocess.run([sys.executable, str(ROOT / "notebooks" / name)], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    for f in expected:
        assert (tmp_path / f).stat().st_size > 0
