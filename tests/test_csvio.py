"""Bad input to ``jaxdrift diagnose``: exit code 2, a message naming file/line/column, no report.

The reader is also checked on good input (warnings for unused columns, the default model)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from jaxdrift import cli
from jaxdrift.io._csvio import (DEFAULT_MODEL, MIN_SAMPLES, InputError, read_model,
                             read_vehicle_run, write_vehicle_run)


def _good_columns(n=400, fs=200.0):
    t = 3.0 + np.arange(n) / fs
    f1 = 3825.0 + 50 * np.sin(2 * np.pi * 1.3 * t)
    f2 = 3825.0 - 40 * np.sin(2 * np.pi * 0.7 * t)
    beta = 1e-3 * np.sin(2 * np.pi * 0.5 * t)
    return {"t": t, "f1": f1, "f2": f2, "beta": beta}


def _write_csv(path, cols, fmt="%.17g"):
    names = list(cols)
    data = np.column_stack([cols[c] for c in names])
    with open(path, "w") as fh:
        fh.write(",".join(names) + "\n")
        np.savetxt(fh, data, delimiter=",", fmt=fmt)


def _lines(path):
    with open(path) as fh:
        return fh.read().splitlines()


def _rewrite(path, lines):
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")


def _run_cli(tmp_path, capsys, run, model=None, extra=()):
    report = tmp_path / "report.json"
    argv = ["diagnose", str(run), "--json", str(report), *extra]
    if model is not None:
        argv += ["--model", str(model)]
    rc = cli.main(argv)
    err = capsys.readouterr().err
    return rc, err, report


@pytest.fixture
def good_run(tmp_path):
    path = tmp_path / "run.csv"
    _write_csv(path, _good_columns())
    return path


def _assert_refused(rc, err, report, *needles):
    assert rc == 2, err
    assert not report.exists(), "a refused run must not leave a report"
    assert not [p for p in os.listdir(report.parent) if p.startswith(".jaxdrift-report")]
    for needle in needles:
        assert needle in err, f"{needle!r} not in {err!r}"
    assert "Traceback" not in err


def test_good_run_reads(good_run):
    run = read_vehicle_run(good_run)
    assert run.n == 400 and run.dt == pytest.approx(0.005)
    assert set(run.channels) == {"f1", "f2", "beta"}
    assert run.warnings == ()


def test_extra_column_is_a_warning(tmp_path):
    cols = _good_columns()
    cols["temperature"] = np.full(400, 21.0)
    path = tmp_path / "run.csv"
    _write_csv(path, cols)
    run = read_vehicle_run(path)
    assert "temperature" not in run.channels
    assert any("temperature" in w for w in run.warnings)


@pytest.mark.parametrize("name,hint", [("Beta_rate", "beta_rate"), ("bta", "beta")])
def test_column_close_to_a_known_name_is_an_error(tmp_path, capsys, name, hint):
    """A typo in an optional column must not silently drop it: exit 2 with a hint;
    --force makes it a warning and the column is ignored."""
    cols = _good_columns()
    cols[name] = cols.pop("beta")
    path = tmp_path / "run.csv"
    _write_csv(path, cols)
    with pytest.raises(InputError, match=f"did you mean `{hint}`"):
        read_vehicle_run(path)
    rc, err, report = _run_cli(tmp_path, capsys, path)
    _assert_refused(rc, err, report, "run.csv", "line 1", repr(name), f"did you mean `{hint}`?")
    run = read_vehicle_run(path, force=True)
    assert "beta" not in run.channels and any(hint in w and "--force" in w for w in run.warnings)


@pytest.mark.parametrize("drop,needle", [("f2", "missing required column 'f2'"),
                                          ("t", "missing required column 't'")])
def test_missing_column(tmp_path, capsys, drop, needle):
    cols = _good_columns()
    del cols[drop]
    path = tmp_path / "run.csv"
    _write_csv(path, cols)
    rc, err, report = _run_cli(tmp_path, capsys, path)
    _assert_refused(rc, err, report, "run.csv", "line 1", needle)


def test_misnamed_column_gets_a_hint(tmp_path, capsys):
    cols = _good_columns()
    cols["F1"] = cols.pop("f1")
    path = tmp_path / "run.csv"
    _write_csv(path, cols)
    rc, err, report = _run_cli(tmp_path, capsys, path)
    _assert_refused(rc, err, report, "run.csv", "'f1'", "did you mean 'F1'")


def test_duplicate_column(tmp_path, capsys, good_run):
    lines = _lines(good_run)
    lines[0] = "t,f1,f1,beta"
    _rewrite(good_run, lines)
    rc, err, report = _run_cli(tmp_path, capsys, good_run)
    _assert_refused(rc, err, report, "run.csv", "line 1", "'f1' appears twice")


def test_non_increasing_time(tmp_path, capsys, good_run):
    """A row that repeats the time stamp of the row before is spread to the next stamp and said
    (line named); under --strict-time, and where stamps go backwards, the run is refused."""
    lines = _lines(good_run)
    # data row 50 is line 51; give it the time of the row before
    cells = lines[50].split(",")
    cells[0] = lines[49].split(",")[0]
    lines[50] = ",".join(cells)
    _rewrite(good_run, lines)
    run = read_vehicle_run(good_run)
    assert any("repeat the time stamp" in w and "line 51" in w for w in run.info["notes"]), run.info["notes"]
    assert run.n == 400 and run.dt == pytest.approx(0.005)
    rc, err, report = _run_cli(tmp_path, capsys, good_run, extra=["--strict-time"])
    _assert_refused(rc, err, report, "run.csv", "line 51", "column t", "not strictly increasing")
    # a stamp that goes backwards is refused in any mode
    cells[0] = lines[48].split(",")[0]
    lines[50] = ",".join(cells)
    _rewrite(good_run, lines)
    rc, err, report = _run_cli(tmp_path, capsys, good_run)
    _assert_refused(rc, err, report, "run.csv", "line 51", "column t", "not strictly increasing")


def test_non_uniform_time(tmp_path, capsys):
    cols = _good_columns()
    cols["t"] = cols["t"].copy()
    cols["t"][200:] += 0.001  # one step of 6 ms among 5 ms steps
    path = tmp_path / "run.csv"
    _write_csv(path, cols)
    rc, err, report = _run_cli(tmp_path, capsys, path, extra=["--strict-time"])
    _assert_refused(rc, err, report, "run.csv", "line 202", "column t", "non-uniform")


@pytest.mark.parametrize("cell,needle", [("nan", "NaN"), ("", "empty cell"), ("inf", "infinite"),
                                         ("1.2.3", "not a number")])
def test_bad_cell_names_line_and_column(tmp_path, capsys, good_run, cell, needle):
    lines = _lines(good_run)
    cells = lines[120].split(",")
    cells[2] = cell  # column f2, line 121
    lines[120] = ",".join(cells)
    _rewrite(good_run, lines)
    rc, err, report = _run_cli(tmp_path, capsys, good_run)
    _assert_refused(rc, err, report, "run.csv", "line 121", "column f2", needle)


def test_empty_optional_cell(tmp_path, capsys, good_run):
    lines = _lines(good_run)
    cells = lines[9].split(",")
    cells[3] = ""
    lines[9] = ",".join(cells)
    _rewrite(good_run, lines)
    rc, err, report = _run_cli(tmp_path, capsys, good_run)
    _assert_refused(rc, err, report, "run.csv", "line 10", "column beta", "empty cell")


def test_ragged_row(tmp_path, capsys, good_run):
    lines = _lines(good_run)
    lines[30] = lines[30] + ",7"
    _rewrite(good_run, lines)
    rc, err, report = _run_cli(tmp_path, capsys, good_run)
    _assert_refused(rc, err, report, "run.csv", "line 31", "5 cells but the header has 4")


def test_too_short_run(tmp_path, capsys):
    cols = {k: v[: MIN_SAMPLES - 1] for k, v in _good_columns().items()}
    path = tmp_path / "run.csv"
    _write_csv(path, cols)
    rc, err, report = _run_cli(tmp_path, capsys, path)
    _assert_refused(rc, err, report, "run.csv", "too short")


def test_empty_and_missing_files(tmp_path, capsys):
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    rc, err, report = _run_cli(tmp_path, capsys, empty)
    _assert_refused(rc, err, report, "empty.csv", "empty file")
    header_only = tmp_path / "header.csv"
    header_only.write_text("t,f1,f2\n")
    rc, err, report = _run_cli(tmp_path, capsys, header_only)
    _assert_refused(rc, err, report, "header.csv", "no data rows")
    rc, err, report = _run_cli(tmp_path, capsys, tmp_path / "nope.csv")
    _assert_refused(rc, err, report, "nope.csv", "not found")


def _model_file(tmp_path, obj, raw=None):
    path = tmp_path / "model.json"
    path.write_text(raw if raw is not None else json.dumps(obj))
    return path


@pytest.mark.parametrize("change,needle", [
    (lambda m: m.pop("k3"), "missing key(s) k3"),
    (lambda m: m.update(mass=750.0), "unknown key 'mass'"),
    (lambda m: m.update(m3=0.0), "'m3' must be a positive number"),
    (lambda m: m.update(I=-500.0), "'I' must be a positive number"),
    (lambda m: m.update(g="9.81"), "'g' must be a number"),
    (lambda m: m.update(a=True), "'a' must be a number"),
])
def test_bad_model(tmp_path, capsys, good_run, change, needle):
    model = dict(DEFAULT_MODEL)
    change(model)
    path = _model_file(tmp_path, model)
    rc, err, report = _run_cli(tmp_path, capsys, good_run, model=path)
    _assert_refused(rc, err, report, "model.json", needle)


def test_model_not_json(tmp_path, capsys, good_run):
    path = _model_file(tmp_path, None, raw='{"a": 1.0,\n "b": }')
    rc, err, report = _run_cli(tmp_path, capsys, good_run, model=path)
    _assert_refused(rc, err, report, "model.json", "line 2", "invalid JSON")


def test_unknown_key_hint_and_read_model(tmp_path):
    model = dict(DEFAULT_MODEL)
    model["d5"] = model.pop("d4")
    with pytest.raises(InputError, match="unknown key 'd5'.*did you mean 'd"):
        read_model(_model_file(tmp_path, model))
    assert read_model(_model_file(tmp_path, DEFAULT_MODEL)) == DEFAULT_MODEL


def test_sensors_for_vehicle_run_and_bad_output(tmp_path, capsys, good_run):
    rc, err, report = _run_cli(tmp_path, capsys, good_run, extra=["--sensors", str(good_run)])
    _assert_refused(rc, err, report, "--model, not --sensors")
    rc = cli.main(["diagnose", str(good_run), "--json", str(tmp_path / "no" / "r.json")])
    err = capsys.readouterr().err
    assert rc == 2 and "does not exist" in err


def test_write_vehicle_run_roundtrip(tmp_path):
    cols = _good_columns()
    path = tmp_path / "rt.csv"
    write_vehicle_run(path, cols["t"], {k: v for k, v in cols.items() if k != "t"})
    run = read_vehicle_run(path)
    np.testing.assert_array_equal(run["beta"], cols["beta"])
    np.testing.assert_array_equal(run.t, cols["t"])
