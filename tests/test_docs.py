"""The README's commands run as written, and the numbers and claims the docs make."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from jaxdrift.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
ACTIVATE = ". .venv/bin/activate"


def _shell_commands(text):
    """(position, command) for every command in the README's ```bash blocks (continuations
    joined, ``&&`` chains split, comments dropped) and every inline `jaxdrift ...` span."""
    out = []
    for m in re.finditer(r"```bash\n(.*?)```", text, re.S):
        body = m.group(1).replace("\\\n", " ")
        for line in body.splitlines():
            line = line.split(" #")[0].strip()
            if not line or line.startswith("#"):
                continue
            for part in line.split("&&"):
                out.append((m.start(), part.strip()))
    for m in re.finditer(r"`((?:\.venv/bin/)?jaxdrift [^`]*)`", text):
        out.append((m.start(), m.group(1)))
    return out


COMMANDS = _shell_commands(README)
JAXDRIFT = [(pos, c) for pos, c in COMMANDS if re.match(r"(\.venv/bin/)?jaxdrift\b", c)]


def test_the_readme_has_commands():
    assert len(JAXDRIFT) >= 8
    assert f"`{ACTIVATE}`" in README or any(c == ACTIVATE for _, c in COMMANDS)


@pytest.mark.parametrize("pos,cmd", JAXDRIFT, ids=[c[:60] for _, c in JAXDRIFT])
def test_readme_jaxdrift_commands_parse(pos, cmd, capsys):
    """Each names an existing subcommand with existing options (argparse exits 2 otherwise), and
    a bare ``jaxdrift`` comes only after the quick start activated the environment."""
    argv = shlex.split(cmd)
    if argv[0] == "jaxdrift":
        first_activate = README.index(ACTIVATE)
        assert pos > first_activate, f"{cmd!r} runs before the README activates .venv"
    args = argv[1:]
    if args in (["--help"], []):
        return
    ns = build_parser().parse_args(args)
    assert ns.command, cmd
    with pytest.raises(SystemExit) as e:  # and its --help runs
        build_parser().parse_args([ns.command, "--help"])
    assert e.value.code == 0
    assert ns.command in capsys.readouterr().out


def test_readme_scripts_exist():
    for _, cmd in COMMANDS:
        argv = shlex.split(cmd)
        for a in argv:
            if a.endswith(".py") and "/" in a:
                assert (ROOT / a).is_file(), a
        if argv[:1] == ["jaxdrift"] and "diagnose" in argv:
            for a in argv:
                if a.startswith("examples/"):
                    assert (ROOT / a).is_file(), a


def test_cheap_readme_commands_run(capsys):
    from jaxdrift.cli import main

    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0 and "diagnose" in capsys.readouterr().out
    assert main(["--version"]) == 0


# ------------------------------------------------------------------------------ doc numbers

def test_euler_position_variance_14_5_percent_below_at_10_steps():
    """docs/paper-study.md: at 10 steps the Euler position variance is 14.5 % below (2.8)."""
    from jaxdrift.analysis._pointmass import euler_variance, pointmass_variance
    from jaxdrift.models._params import PointMassParams

    p = PointMassParams(m=1.0, eta=0.0)
    dt, n = 0.01, 10
    ev = float(euler_variance(n * dt, 1.0, dt, p)[0][0])
    cf = float(np.ravel(pointmass_variance(n * dt, 1.0, dt, p)[0])[0])
    assert 1 - ev / cf == pytest.approx(1 - (n - 1) * (2 * n - 1) / (2 * n**2), abs=1e-12)
    assert 1 - ev / cf == pytest.approx(0.145, abs=1e-12)
    assert "14.5 % below the continuous (2.8)" in (ROOT / "docs" / "paper-study.md").read_text()


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


def test_solver_independence_is_claimed_only_where_measured():
    text = README + (ROOT / "docs" / "paper-study.md").read_text()
    assert "agree sample by sample between adaptive rtol 1e-4" not in text
    assert "drift-off times agree to a fraction of a\nsecond, sample by sample" not in text
    # the disagreement at rtol 1e-4 is quoted from the committed summary (its value is checked by
    # tests/test_quoted_numbers.py), in the README and in docs/paper-study.md
    for doc in (README, (ROOT / "docs" / "paper-study.md").read_text()):
        assert "summary.json:solver_agreement.0.noisy_max_abs_s:" in doc
        assert "summary.json:solver_agreement.1.noisy_max_abs_s:" in doc


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
