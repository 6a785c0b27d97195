"""Outputs never lose data: an output equal to an input is refused, every output is
checked before computing, writes are atomic, an OSError is exit 2 with the path; every report
says what made it (provenance); ``--series``; -q/-v and one-line warnings."""

from __future__ import annotations

import datetime
import hashlib
import json
import os
import warnings

from pathlib import Path

import numpy as np
import pytest

import jaxdrift
from jaxdrift import cli
from jaxdrift.errors import InputError
from jaxdrift.io import atomic_dir, atomic_path, check_outputs, write_json
from jaxdrift.io._outputs import MANIFEST

UNWRITABLE = "/sys"  # refuses new files even to root


def _sha(p):
    with open(p, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


@pytest.fixture(scope="module")
def run_csv(tmp_path_factory):
    """A copy of the committed example run (10 s at 200 Hz, pitch and heave, hidden effects)."""
    import shutil

    path = tmp_path_factory.mktemp("run") / "vehicle_run.csv"
    shutil.copyfile(Path(__file__).resolve().parents[1] / "examples" / "vehicle_run.csv", path)
    return path


@pytest.fixture
def no_compute(monkeypatch):
    """Fail the test if the vehicle diagnosis starts (outputs must be checked before)."""
    import jaxdrift.diagnosis.vehicle as dv

    def must_not_run(*a, **k):
        raise AssertionError("computation started before the outputs were checked")

    monkeypatch.setattr(dv, "diagnose_vehicle_run", must_not_run)


# ------------------------------------------------------------------------------ check_outputs

def test_check_outputs_rules(tmp_path):
    inp = tmp_path / "run.csv"
    inp.write_text("x")
    link = tmp_path / "link.json"
    link.symlink_to(inp)
    with pytest.raises(InputError, match="is the input file"):
        check_outputs([("--json", str(inp), "file")], [str(inp)])
    with pytest.raises(InputError, match="is the input file"):
        check_outputs([("--json", str(link), "file")], [str(inp)])  # symlink resolved
    with pytest.raises(InputError, match="the same path as --json"):
        check_outputs([("--json", str(tmp_path / "a.json"), "file"), ("--series", str(tmp_path / "a.json"), "file")])
    with pytest.raises(InputError, match="folder .* does not exist"):
        check_outputs([("--json", str(tmp_path / "nope" / "r.json"), "file")])
    with pytest.raises(InputError, match="not writable"):
        check_outputs([("--json", f"{UNWRITABLE}/r.json", "file")])
    with pytest.raises(InputError, match="is a folder"):
        check_outputs([("--json", str(tmp_path), "file")])
    with pytest.raises(InputError, match="exists and is not a folder"):
        check_outputs([("--out", str(inp), "dir")])
    with pytest.raises(InputError, match="would overwrite the input file"):
        check_outputs([("--out", str(tmp_path), "dir", ["run.csv"])], [str(inp)])
    check_outputs([("--json", str(tmp_path / "ok.json"), "file"), ("--out", str(tmp_path / "new"), "dir")], [str(inp)])
    assert sorted(os.listdir(tmp_path)) == ["link.json", "run.csv"]  # the probes left nothing


# ------------------------------------------------------------------------------ diagnose

@pytest.mark.parametrize("which", ["--json", "--series", "symlink"])
def test_diagnose_refuses_to_overwrite_its_input(tmp_path, capsys, run_csv, no_compute, which):
    before = _sha(run_csv)
    report = tmp_path / "r.json"
    if which == "--json":
        argv = ["diagnose", str(run_csv), "--json", str(run_csv)]
    elif which == "--series":
        argv = ["diagnose", str(run_csv), "--json", str(report), "--series", str(run_csv)]
    else:
        link = tmp_path / "same.csv"
        link.symlink_to(run_csv)
        argv = ["diagnose", str(run_csv), "--json", str(report), "--series", str(link)]
    rc = cli.main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and "refusing to overwrite" in err and "Traceback" not in err
    assert _sha(run_csv) == before and not report.exists()


@pytest.mark.parametrize("opt", ["--json", "--plots", "--series"])
def test_diagnose_unwritable_output_fails_before_computing(tmp_path, capsys, run_csv, no_compute, opt):
    argv = ["diagnose", str(run_csv), "--json", str(tmp_path / "r.json")]
    bad = f"{UNWRITABLE}/out" + (".csv" if opt == "--series" else ".json" if opt == "--json" else "")
    if opt == "--json":
        argv[-1] = bad
    else:
        argv += [opt, bad]
    rc = cli.main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and f"{opt} {bad}" in err and "not writable" in err
    assert not (tmp_path / "r.json").exists()


def test_oserror_while_writing_is_exit_2_with_the_path(tmp_path, capsys, run_csv, monkeypatch):
    import jaxdrift.diagnosis.vehicle as dv

    monkeypatch.setattr(dv, "diagnose_vehicle_run", lambda run, model, plots, log=None: {"kind": "vehicle"})
    report = tmp_path / "r.json"
    report.write_text('{"old": true}\n')
    real_replace = os.replace

    def full_disk(src, dst):
        if str(dst) == str(report):
            raise OSError(28, "No space left on device")
        return real_replace(src, dst)

    monkeypatch.setattr(os, "replace", full_disk)
    rc = cli.main(["diagnose", str(run_csv), "--json", str(report)])
    err = capsys.readouterr().err
    assert rc == 2 and f"--json {report}: cannot write (No space left on device)" in err
    assert json.loads(report.read_text()) == {"old": True}  # the old report is intact
    assert os.listdir(tmp_path) == ["r.json"]  # no temporary file left


def test_report_provenance_and_series(tmp_path, capsys, run_csv, monkeypatch):
    """The real diagnosis: provenance says what made the report; --series holds the signals, and
    its simulated pitch reproduces the report's pitch error (an independent simulation)."""
    report, series = tmp_path / "r.json", tmp_path / "s.parquet"
    t0 = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0)
    rc = cli.main(["diagnose", str(run_csv), "--json", str(report), "--series", str(series)])
    err = capsys.readouterr().err
    assert rc == 0, err
    rep = json.loads(report.read_text())
    prov = rep["provenance"]
    assert prov["jaxdrift_version"] == jaxdrift.__version__
    assert prov["inputs"][0]["file"] == "vehicle_run.csv" and prov["inputs"][0]["sha256"] == _sha(run_csv)
    assert datetime.datetime.fromisoformat(prov["time_utc"]) >= t0
    assert "seed's table" in prov["model"]["default"] and prov["options"]["series"] == str(series)
    assert prov["reading"]["format"] == "csv" and prov["reading"]["columns"]["f1"] == "f1"
    assert prov["reading"]["rate_hz"] == pytest.approx(200.0) and prov["reading"]["forced"] is False
    assert set(rep) >= {"schema", "kind", "simulation_error", "findings", "extended_model", "gain", "run"}
    import pyarrow.parquet as pq

    s = pq.read_table(series).to_pydict()
    n = rep["run"]["samples"]
    assert all(len(v) == n for v in s.values())
    assert {"t", "f1", "f2", "beta", "z3", "f1_corrected", "sim_beta", "ext_beta", "sim_z3", "ext_z3"} <= set(s)
    data = np.loadtxt(run_csv, delimiter=",", skiprows=1)
    np.testing.assert_array_equal(np.asarray(s["f1"]), data[:, 1])
    for key, entry in (("sim_beta", rep["simulation_error"]["beta"]), ("ext_beta", rep["gain"]["beta_error"]["after"])):
        err_rms = float(np.sqrt(np.mean((np.asarray(s[key]) - np.asarray(s["beta"])) ** 2)))
        assert err_rms == pytest.approx(entry["rms"], rel=1e-3), key
    offset = rep["extended_model"]["corrections"]["f2"]["offset"]
    np.testing.assert_allclose(np.asarray(s["f2_corrected"]), data[:, 2] - offset, rtol=1e-12, atol=1e-9)
    # CSV too, same columns (the diagnosis itself is not repeated: its report is replayed)
    import jaxdrift.diagnosis.vehicle as dv

    replay = {k: v for k, v in rep.items() if k != "provenance"}
    monkeypatch.setattr(dv, "diagnose_vehicle_run", lambda run, model, plots, log=None: dict(replay))
    csv_out = tmp_path / "s.csv"
    assert cli.main(["-q", "diagnose", str(run_csv), "--json", str(tmp_path / "r2.json"), "--series",
                     str(csv_out)]) == 0
    assert capsys.readouterr().err == ""  # -q: no progress, no notes
    header = csv_out.read_text().splitlines()[0].split(",")
    assert header == list(s)


# ------------------------------------------------------------------------------ the other commands

@pytest.mark.parametrize("argv", [
    ["paper", "--quick"], ["pointmass"], ["ins"], ["quaternion-drift"], ["accel-array"],
])
def test_every_writing_command_checks_its_output_first(tmp_path, capsys, argv):
    rc = cli.main([*argv, "--out", f"{UNWRITABLE}/out"])
    err = capsys.readouterr().err
    assert rc == 2 and f"--out {UNWRITABLE}/out" in err and "not writable" in err
    f = tmp_path / "file"
    f.write_text("keep")
    assert cli.main([*argv, "--out", str(f)]) == 2 and f.read_text() == "keep"
    assert "not a folder" in capsys.readouterr().err


def test_paper_refuses_to_overwrite_its_params(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    params = out / "summary.json"
    params.write_text("{}")
    rc = cli.main(["paper", "--quick", "--out", str(out), "--params", str(params)])
    assert rc == 2 and "would overwrite the input file" in capsys.readouterr().err
    assert params.read_text() == "{}"


def test_small_commands_write_provenance_and_manifest(tmp_path, capsys):
    out = tmp_path / "aa"
    assert cli.main(["accel-array", "--out", str(out), "--duration", "6", "--paths", "10"]) == 0
    capsys.readouterr()
    s = json.loads((out / "accel_summary.json").read_text())
    assert s["provenance"]["command"] == "accel-array" and s["provenance"]["options"]["paths"] == 10
    man = json.loads((out / MANIFEST).read_text())
    assert set(man["files"]) == {"accel_reconstruction.png", "accel_noise_growth.png", "accel_highpass.png",
                                 "accel_summary.json"}
    for name, digest in man["files"].items():
        assert _sha(out / name) == digest


# ------------------------------------------------------------------------------ the helpers

def test_atomic_path_keeps_the_old_file_on_failure(tmp_path):
    p = tmp_path / "r.json"
    write_json(p, {"v": 1})
    with pytest.raises(RuntimeError):
        with atomic_path(p) as tmp:
            with open(tmp, "w") as fh:
                fh.write('{"v": 2, "half')
            raise RuntimeError("killed while writing")
    assert json.loads(p.read_text()) == {"v": 1} and os.listdir(tmp_path) == ["r.json"]
    write_json(p, {"v": float("nan")})
    assert json.loads(p.read_text()) == {"v": None}  # strict JSON


def test_atomic_dir_interrupted_commit_is_recognisable(tmp_path, monkeypatch):
    out = tmp_path / "figs"
    with atomic_dir(out) as tmp:
        for n in ("a.png", "b.png"):
            with open(os.path.join(tmp, n), "w") as fh:
                fh.write(n)
    assert json.loads((out / MANIFEST).read_text())["files"].keys() == {"a.png", "b.png"}
    real = os.replace
    calls = []

    def die_on_second(src, dst):
        calls.append(dst)
        if len(calls) == 2:
            raise OSError(5, "Input/output error")
        return real(src, dst)

    monkeypatch.setattr(os, "replace", die_on_second)
    with pytest.raises(InputError, match="cannot write"):
        with atomic_dir(out) as tmp:
            for n in ("a.png", "b.png"):
                with open(os.path.join(tmp, n), "w") as fh:
                    fh.write(n + " new")
    # a half-replaced folder has no manifest: it cannot be taken for a complete run
    assert not (out / MANIFEST).exists() and (out / "a.png").read_text() == "a.png new"
    assert [p for p in os.listdir(tmp_path) if "jaxdrift-tmp" in p] == []


def test_warnings_are_one_line(capsys):
    from jaxdrift.cli import _common

    saved = warnings.showwarning
    try:
        _common.set_verbosity(1, "diagnose")
        _common.route_warnings()
        with warnings.catch_warnings():
            warnings.simplefilter("always")
            with np.errstate(all="warn"):
                np.log(np.zeros(1))
    finally:
        warnings.showwarning = saved
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("jaxdrift diagnose: warning: divide by zero")
    assert "RuntimeWarning" in err


def test_quiet_and_verbose(tmp_path, capsys, run_csv, monkeypatch):
    import jaxdrift.diagnosis.vehicle as dv

    def fake(run, model, plots, log=None):
        log.append("step 1: best force_offset[f2]")
        return {"kind": "vehicle"}

    monkeypatch.setattr(dv, "diagnose_vehicle_run", fake)
    assert cli.main(["-v", "diagnose", str(run_csv), "--json", str(tmp_path / "v.json")]) == 0
    err = capsys.readouterr().err
    assert "read 2001 samples at 200 Hz (csv)" in err and "step 1: best force_offset[f2]" in err
    assert "default model" in err and "report written" in err
    assert cli.main(["-q", "diagnose", str(run_csv), "--json", str(tmp_path / "q.json")]) == 0
    assert capsys.readouterr().err == ""
