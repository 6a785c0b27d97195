"""Ctrl-C (SIGINT) on the real command line: exit 130 with one line, no crash, nothing half-written,
at any moment: in the first second (segmentation faults came from interrupting
JAX/XLA compilation), mid-run, and while the results are being written.

Each case starts ``python -m jaxdrift`` in a subprocess and sends SIGINT when the moment is
reached (a line on stderr, or a time). ``JAXDRIFT_TEST_COMMIT_DELAY_S`` makes the commit of the
outputs announce itself and last that long, so "while writing" is hit every time."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _start(args, cwd, extra_env=None):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
               MPLBACKEND="Agg", **(extra_env or {}))
    proc = subprocess.Popen([sys.executable, "-m", "jaxdrift", *args], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    buf = {"err": b"", "out": b""}

    def pump(stream, key):
        for chunk in iter(lambda: stream.read1(4096), b""):
            buf[key] += chunk

    threads = [threading.Thread(target=pump, args=(stream, key), daemon=True)
               for stream, key in ((proc.stderr, "err"), (proc.stdout, "out"))]
    for th in threads:
        th.start()
    buf["threads"] = threads
    return proc, buf


def _close(proc, buf):
    for th in buf["threads"]:
        th.join(timeout=10)
    proc.stdout.close()
    proc.stderr.close()


def _interrupt(args, cwd, *, after_s=None, when=None, extra_env=None, timeout=240, sig=signal.SIGINT):
    """Run, send SIGINT ``after_s`` seconds after the handler is installed (the process's first
    Python code; before it, Python's own start-up is outside jaxdrift's reach), or once ``when``
    appears on stderr."""
    proc, buf = _start(args, cwd, {"JAXDRIFT_TEST_ANNOUNCE": "1", **(extra_env or {})})
    t0 = time.monotonic()
    if after_s is not None:
        while b"interrupt handler ready" not in buf["err"] and proc.poll() is None:
            if time.monotonic() - t0 > timeout:
                break
            time.sleep(0.005)
        t0 = time.monotonic()
    while True:
        if proc.poll() is not None:
            _close(proc, buf)
            pytest.fail(f"finished before the interrupt (rc {proc.returncode}): {buf['err'][-2000:]!r}")
        if after_s is not None and time.monotonic() - t0 >= after_s:
            break
        if when is not None and when.encode() in buf["err"]:
            break
        if time.monotonic() - t0 > timeout:
            proc.kill()
            proc.wait()
            _close(proc, buf)
            pytest.fail(f"never reached {when!r}: {buf['err'][-2000:]!r}")
        time.sleep(0.02)
    proc.send_signal(sig)
    try:
        rc = proc.wait(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        _close(proc, buf)
        pytest.fail("did not exit within 60 s of SIGINT")
    _close(proc, buf)
    err = buf["err"].decode(errors="replace")
    return rc, err


def _assert_clean_exit(rc, err):
    assert rc == 130, (rc, err[-3000:])  # a segfault is rc -11, an unhandled KeyboardInterrupt -2 or 1
    assert "Traceback" not in err and "Segmentation" not in err and "Fatal Python error" not in err, err[-3000:]
    last = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip()][-1]
    assert last.startswith("jaxdrift") and "interrupted" in last, last


def _no_leftovers(folder):
    left = [p for p in os.listdir(folder) if "jaxdrift-tmp" in p]
    assert not left, left


@pytest.fixture(scope="module")
def run_csv(tmp_path_factory):
    """A copy of the committed example run (10 s at 200 Hz, pitch and heave, hidden effects)."""
    import shutil

    path = tmp_path_factory.mktemp("run") / "vehicle_run.csv"
    shutil.copyfile(Path(__file__).resolve().parents[1] / "examples" / "vehicle_run.csv", path)
    return path


@pytest.mark.parametrize("after_s", [0.0, 0.2, 0.4, 0.6, 0.8])
def test_paper_interrupted_in_the_first_second(tmp_path, after_s):
    """Five tries in the first second (four of five used to end in a segmentation fault)."""
    out = tmp_path / "out"
    rc, err = _interrupt(["paper", "--quick", "--out", str(out)], tmp_path, after_s=after_s)
    _assert_clean_exit(rc, err)
    assert not out.exists() or os.listdir(out) == []
    _no_leftovers(tmp_path)


@pytest.mark.slow
def test_paper_interrupted_mid_run(tmp_path):
    out = tmp_path / "out"
    rc, err = _interrupt(["paper", "--quick", "--out", str(out)], tmp_path, when="path/s")
    _assert_clean_exit(rc, err)
    assert not out.exists() or os.listdir(out) == []
    _no_leftovers(tmp_path)


def test_diagnose_interrupted_mid_run(tmp_path, run_csv):
    report, plots = tmp_path / "r.json", tmp_path / "plots"
    rc, err = _interrupt(["diagnose", str(run_csv), "--json", str(report), "--plots", str(plots)], tmp_path,
                         when="1/4")
    _assert_clean_exit(rc, err)
    assert not report.exists() and not plots.exists()
    _no_leftovers(tmp_path)


def test_diagnose_interrupted_while_writing(tmp_path, run_csv):
    """SIGINT during the commit of the figures: the handler waits for the commit, so the folder is
    complete (its manifest lists every file with the right SHA-256); the report is not written."""
    import hashlib

    report, plots = tmp_path / "r.json", tmp_path / "plots"
    rc, err = _interrupt(["diagnose", str(run_csv), "--json", str(report), "--plots", str(plots)], tmp_path,
                         when="jaxdrift: committing", extra_env={"JAXDRIFT_TEST_COMMIT_DELAY_S": "1.5"})
    _assert_clean_exit(rc, err)
    man = json.loads((plots / "jaxdrift-manifest.json").read_text())
    assert len(man["files"]) >= 2
    for name, digest in man["files"].items():
        with open(plots / name, "rb") as fh:
            assert hashlib.sha256(fh.read()).hexdigest() == digest
    assert not report.exists()
    _no_leftovers(tmp_path)


def test_diagnose_terminated_mid_run(tmp_path, run_csv):
    """SIGTERM (a job scheduler ending the run) the same way, with exit code 143."""
    report, series = tmp_path / "r.json", tmp_path / "s.csv"
    rc, err = _interrupt(["diagnose", str(run_csv), "--json", str(report), "--series", str(series)], tmp_path,
                         when="1/4", sig=signal.SIGTERM)
    assert rc == 143 and "terminated" in err.splitlines()[-1] and "Traceback" not in err
    assert not report.exists() and not series.exists()
    _no_leftovers(tmp_path)


@pytest.mark.slow
def test_ins_interrupted_mid_run(tmp_path):
    out = tmp_path / "ins"
    rc, err = _interrupt(["ins", "--out", str(out), "--duration", "20", "--paths", "50"], tmp_path, when="path/s")
    _assert_clean_exit(rc, err)
    assert not out.exists()
    _no_leftovers(tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("rep", range(5))
@pytest.mark.parametrize("cmd", ["diagnose", "paper", "ins", "pointmass", "quaternion-drift", "accel-array"])
@pytest.mark.parametrize("moment", ["first second", "mid-run", "writing"])
def test_every_command_every_moment(tmp_path, run_csv, cmd, moment, rep):
    """The full matrix, 5 repetitions each (slow: about 15 minutes on 2 cores)."""
    out = tmp_path / "out"
    args = {"diagnose": ["diagnose", str(run_csv), "--json", str(tmp_path / "r.json"), "--plots", str(out)],
            "paper": ["paper", "--quick", "--out", str(out)],
            "ins": ["ins", "--out", str(out), "--duration", "20", "--paths", "20"],
            "pointmass": ["pointmass", "--out", str(out), "--paths", "4000"],
            "quaternion-drift": ["quaternion-drift", "--out", str(out), "--paths", "2000"],
            "accel-array": ["accel-array", "--out", str(out), "--paths", "200"]}[cmd]
    kw = {"first second": {"after_s": 0.2 * rep},
          "mid-run": {"after_s": 4.0 + rep},
          "writing": {"when": "jaxdrift: committing", "extra_env": {"JAXDRIFT_TEST_COMMIT_DELAY_S": "1.0"}}}[moment]
    rc, err = _interrupt(args, tmp_path, **kw)
    _assert_clean_exit(rc, err)
    _no_leftovers(tmp_path)
    if out.exists() and os.listdir(out):
        assert "jaxdrift-manifest.json" in os.listdir(out), os.listdir(out)
