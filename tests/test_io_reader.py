"""The one reader: formats, --map/--units/--fs, the printed resolution of t, the
plausibility checks (unit mistakes exit 2 before computing, naming the column), MDF4 and Parquet.

The reference for every conversion is the same run written in SI by ``write_vehicle_run``
(17 significant digits) and read back: a converted file must give the same arrays."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from jaxdrift import cli
from jaxdrift.errors import InputError
from jaxdrift.io import load_run, read_vehicle_run
from jaxdrift.io._attitude_files import read_attitude_run


@pytest.fixture(scope="module")
def real_cols():
    """A physically consistent run: the committed example (road-driven half-car with hidden
    effects, 10 s at 200 Hz; examples/make_vehicle_example.py)."""
    path = Path(__file__).resolve().parents[1] / "examples" / "vehicle_run.csv"
    with open(path) as fh:
        names = fh.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    return {c: data[:, i] for i, c in enumerate(names)}


def _csv(path, cols, fmt="%.17g", names=None):
    names = names or list(cols)
    data = np.column_stack([cols[c] for c in cols])
    with open(path, "w") as fh:
        fh.write(",".join(names) + "\n")
        np.savetxt(fh, data, delimiter=",", fmt=fmt)
    return path


def _cli(tmp_path, capsys, run, *extra):
    report = tmp_path / "report.json"
    rc = cli.main(["diagnose", str(run), "--json", str(report), *extra])
    err = capsys.readouterr().err
    return rc, err, report


# ------------------------------------------------------------------------------- unit mistakes

UNIT_MISTAKES = [
    # name, transform of the SI columns, needles in the message, --units that repairs it
    ("forces in kN", lambda c: {**c, "f1": c["f1"] / 1e3, "f2": c["f2"] / 1e3}, ["f1, f2", "kN?"], "f1=kN,f2=kN"),
    ("time in ms", lambda c: {**c, "t": c["t"] * 1e3}, ["column t", "milliseconds?"], "t=ms"),
    ("pitch in degrees", lambda c: {**c, "beta": np.degrees(c["beta"])}, ["column beta", "degrees?"], None),
    ("all forces zero", lambda c: {**c, "f1": 0 * c["f1"], "f2": 0 * c["f2"]}, ["column f1: constant", "all zero"], None),
    ("dead channel", lambda c: {**c, "z3": np.full_like(c["z3"], 0.25)}, ["column z3: constant", "dead channel"], None),
    ("one sample 1e300", lambda c: {**c, "f2": np.where(np.arange(len(c["t"])) == 321, 1e300, c["f2"])},
     ["line 323, column f2", "1e+300", "glitch"], None),
    ("forces in daN", lambda c: {**c, "f1": c["f1"] / 10, "f2": c["f2"] / 10}, ["f1, f2", "daN?"], "f1=daN,f2=daN"),
]


@pytest.mark.parametrize("case", UNIT_MISTAKES, ids=[c[0] for c in UNIT_MISTAKES])
def test_unit_mistakes_exit_2_before_computing(tmp_path, capsys, monkeypatch, real_cols, case):
    name, change, needles, fix = case
    run = _csv(tmp_path / "run.csv", change(real_cols))
    import jaxdrift.diagnosis.vehicle as dv

    def must_not_run(*a, **k):
        raise AssertionError("computed despite an implausible run")

    monkeypatch.setattr(dv, "diagnose_vehicle_run", must_not_run)
    rc, err, report = _cli(tmp_path, capsys, run)
    assert rc == 2 and not report.exists(), err
    for n in ["run.csv" if "line" in needles[0] else needles[0], *needles]:
        assert n in err, (n, err)
    assert "Traceback" not in err and "--force" in err
    # --force turns the refusal into a warning
    run_f = load_run(run, force=True)
    assert any("--force" in w for w in run_f.warnings)
    if fix:  # the --units the message proposes gives back the SI run
        fixed = load_run(run, units=fix)
        ref = read_vehicle_run(_csv(tmp_path / "si.csv", real_cols))
        for c in ref.channels:
            np.testing.assert_allclose(fixed[c], ref[c], rtol=1e-12, atol=1e-12 * np.max(np.abs(ref[c])))
        np.testing.assert_allclose(fixed.t, ref.t, rtol=1e-12)


def test_degrees_fixed_by_units(tmp_path, real_cols):
    run = _csv(tmp_path / "run.csv", {**real_cols, "beta": np.degrees(real_cols["beta"])})
    r = load_run(run, units="beta=deg")
    np.testing.assert_allclose(r["beta"], real_cols["beta"], rtol=1e-13)


def test_plausible_run_passes_and_names_the_default_model(tmp_path, capsys, real_cols, monkeypatch):
    run = _csv(tmp_path / "run.csv", real_cols)
    r = load_run(run)
    assert r.warnings == () and r.info["rate_hz"] == pytest.approx(200.0)
    import jaxdrift.diagnosis.vehicle as dv

    monkeypatch.setattr(dv, "diagnose_vehicle_run", lambda run, model, plots, log=None: {"kind": "vehicle"})
    rc, err, report = _cli(tmp_path, capsys, run)
    assert rc == 0, err
    assert "default model (the seed's table" in err
    rep = json.loads(report.read_text())
    assert "seed's table" in rep["provenance"]["model"]["default"]


def test_a_wrong_model_is_named(tmp_path, real_cols):
    from jaxdrift.io import DEFAULT_MODEL

    run = _csv(tmp_path / "run.csv", real_cols)
    heavy = {**DEFAULT_MODEL, "m3": 2000.0}
    with pytest.raises(InputError, match=r"the given model weighs .*wrong model"):
        load_run(run, model=heavy)


# ------------------------------------------------------------------------------- time column

@pytest.mark.parametrize("fs,fmt", [(1024.0, "%.9g"), (1024.0, "%.9f"), (300.0, "%.9g"), (300.0, "%.6f")])
def test_time_printed_with_limited_digits_is_uniform(tmp_path, fs, fmt):
    """A 1024 Hz or 300 Hz time column printed with 9 significant digits (or fixed decimals) is a
    uniform run; the grid the run uses is t0 + k/fs to the printed resolution."""
    n = int(3 * fs)
    t = 12.0 + np.arange(n) / fs
    cols = {"t": t, "f1": 3825.0 + np.sin(t), "f2": 3826.0 + np.cos(t)}
    path = tmp_path / "run.csv"
    with open(path, "w") as fh:
        fh.write("t,f1,f2\n")
        for i in range(n):
            fh.write(f"{fmt % t[i]},{float(cols['f1'][i])!r},{float(cols['f2'][i])!r}\n")
    r = load_run(path)
    assert r.dt == pytest.approx(1 / fs, rel=1e-7)
    assert np.max(np.abs(r.t - t)) < 1e-6
    # the old rule (relative jitter 1e-6 on the raw steps) refused these files
    d = np.diff(np.loadtxt(path, delimiter=",", skiprows=1)[:, 0])
    assert np.max(np.abs(d - np.median(d))) / np.median(d) > 1e-6 or fmt == "%.6f" and fs == 1024.0


def test_real_jitter_is_still_refused(tmp_path):
    fs = 1024.0
    t = np.arange(3000) / fs
    t[1500:] += 2e-6  # one step 2 us longer, printed with 9 decimals (resolution 1e-9)
    path = tmp_path / "run.csv"
    with open(path, "w") as fh:
        fh.write("t,f1,f2\n")
        for i in range(len(t)):
            fh.write(f"{t[i]:.9f},{3825 + np.sin(i / 50):.6f},{3826 + np.cos(i / 50):.6f}\n")
    with pytest.raises(InputError, match=r"line 1502, column t: non-uniform"):
        load_run(path, strict_time=True)


def test_fs_makes_the_time_base_and_is_checked(tmp_path, real_cols):
    no_t = {k: v for k, v in real_cols.items() if k != "t"}
    path = _csv(tmp_path / "not.csv", no_t)
    with pytest.raises(InputError, match="missing required column 't'"):
        load_run(path)
    r = load_run(path, fs=200.0)
    np.testing.assert_allclose(r.t, np.arange(len(real_cols["t"])) / 200.0)
    with_t = _csv(tmp_path / "t.csv", real_cols)
    with pytest.raises(InputError, match=r"--fs 250 gives"):
        load_run(with_t, fs=250.0)
    assert load_run(with_t, fs=200.0).n == len(real_cols["t"])


# ------------------------------------------------------------------------------- names

def test_map_reads_other_column_names(tmp_path, real_cols):
    names = ["time_s", "Fz_FL", "Fz_RL", "pitch", "heave"]
    path = _csv(tmp_path / "logger.csv", real_cols, names=names)
    assert list(real_cols) == ["t", "f1", "f2", "beta", "z3"]
    r = load_run(path, map="t=time_s,f1=Fz_FL,f2=Fz_RL,beta=pitch,z3=heave")
    ref = read_vehicle_run(_csv(tmp_path / "si.csv", real_cols))
    for c in ("f1", "f2", "beta", "z3"):
        np.testing.assert_array_equal(r[c], ref[c])
    assert r.info["columns"]["f1"] == "Fz_FL"
    with pytest.raises(InputError, match="has no column 'Fz_FX'; did you mean `Fz_FL`"):
        load_run(path, map="t=time_s,f1=Fz_FX,f2=Fz_RL")
    with pytest.raises(InputError, match="did you mean `beta`"):
        load_run(path, map="t=time_s,f1=Fz_FL,f2=Fz_RL,bta=pitch")
    with pytest.raises(InputError, match="unknown unit for a force column"):
        load_run(path, map="t=time_s,f1=Fz_FL,f2=Fz_RL", units="f1=kg")


def test_semicolon_and_decimal_comma(tmp_path, real_cols):
    path = tmp_path / "de.csv"
    with open(path, "w") as fh:
        fh.write(";".join(real_cols) + "\n")
        for row in np.column_stack(list(real_cols.values())):
            fh.write(";".join(f"{v:.17g}".replace(".", ",") for v in row) + "\n")
    r = load_run(path)
    np.testing.assert_array_equal(r["f1"], real_cols["f1"])


# ------------------------------------------------------------------------------- formats

def test_parquet_in(tmp_path, real_cols):
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = tmp_path / "run.parquet"
    pq.write_table(pa.table(real_cols), path)
    r = load_run(path)
    ref = read_vehicle_run(_csv(tmp_path / "si.csv", real_cols))
    for c in ref.channels:
        np.testing.assert_array_equal(r[c], ref[c])
    assert r.info["format"] == "parquet"
    bad = {**real_cols, "f1": np.where(np.arange(len(real_cols["t"])) == 7, np.nan, real_cols["f1"])}
    pq.write_table(pa.table(bad), tmp_path / "bad.parquet")
    with pytest.raises(InputError, match=r"bad.parquet, row 8, column f1: NaN"):
        load_run(tmp_path / "bad.parquet")


def _write_mf4(path, real_cols, fs_beta=100.0, unit_f="N"):
    from asammdf import MDF, Signal

    t = real_cols["t"]
    tb = np.arange(t[0], t[-1] + 1e-12, 1 / fs_beta)
    mdf = MDF(version="4.10")
    mdf.append([Signal(real_cols["f1"] / (1e3 if unit_f == "kN" else 1), t, name="Fz_FL", unit=unit_f),
                Signal(real_cols["f2"] / (1e3 if unit_f == "kN" else 1), t, name="Fz_RL", unit=unit_f)])
    mdf.append([Signal(np.interp(tb, t, real_cols["beta"]), tb, name="Pitch", unit="rad")])
    mdf.save(path, overwrite=True)
    mdf.close()


def test_mf4_channels_resampled_to_a_stated_rate(tmp_path, real_cols):
    path = tmp_path / "log.mf4"
    _write_mf4(path, real_cols, unit_f="kN")
    r = load_run(path, map="f1=Fz_FL,f2=Fz_RL,beta=Pitch", strict_time=True)
    assert r.info["rate_hz"] == pytest.approx(200.0)
    assert any("resampled (linear) to a common time base of 200 Hz" in n for n in r.info["notes"])
    assert any("stored in kN" in n for n in r.info["notes"])
    n = r.n
    np.testing.assert_allclose(r["f1"], real_cols["f1"][:n], rtol=1e-12)  # kN converted back
    # beta was logged at 100 Hz: linear interpolation of a smooth pitch signal
    assert np.max(np.abs(r["beta"] - real_cols["beta"][:n])) < 0.05 * np.ptp(real_cols["beta"])
    r2 = load_run(path, map="f1=Fz_FL,f2=Fz_RL,beta=Pitch", fs=100.0, strict_time=True)
    assert r2.info["rate_hz"] == pytest.approx(100.0)
    assert any("Fz_FL, Fz_RL decimated" in n and "without an anti-alias filter" in n for n in r2.info["notes"])


def test_mf4_channel_groups_follow_the_time_base_policy(tmp_path, real_cols):
    """Without --strict-time each channel is read on its own times; the grid is f1's rate; a
    faster channel is low-pass filtered before it is carried onto a coarser grid."""
    from scipy.signal import butter, sosfiltfilt

    path = tmp_path / "log.mf4"
    _write_mf4(path, real_cols, unit_f="kN")
    r = load_run(path, map="f1=Fz_FL,f2=Fz_RL,beta=Pitch")
    assert r.time_base["resampled"] and r.time_base["fs"] == pytest.approx(200.0)
    assert r.time_base["channels"]["beta"]["fs"] == pytest.approx(100.0)
    n = r.n
    np.testing.assert_allclose(r["f1"], real_cols["f1"][:n], rtol=1e-10)  # on its own grid: unchanged (kN x 1e3)
    r2 = load_run(path, map="f1=Fz_FL,f2=Fz_RL,beta=Pitch", fs=100.0)
    assert r2.time_base["filtered"] == ["f1", "f2"]
    # the filter is scipy's Butterworth, order 4, zero phase, at 0.8 x the grid's Nyquist frequency
    sos = butter(4, 0.8 * 50.0, fs=200.0, output="sos")
    ref = np.interp(r2.t, real_cols["t"], sosfiltfilt(sos, real_cols["f1"]))
    np.testing.assert_allclose(r2["f1"], ref, rtol=1e-9)


def test_mf4_without_the_extra_says_how_to_install(tmp_path, real_cols, monkeypatch):
    path = tmp_path / "log.mf4"
    _write_mf4(path, real_cols)
    monkeypatch.setitem(sys.modules, "asammdf", None)  # import asammdf -> ImportError
    with pytest.raises(InputError, match=r"pip install 'jaxdrift\[mdf\]'"):
        load_run(path, map="f1=Fz_FL,f2=Fz_RL")


# ------------------------------------------------------------------------------- attitude kind

def test_attitude_runs_follow_the_same_rules(tmp_path):
    rng = np.random.default_rng(1)
    t = np.arange(400) / 100.0
    w = rng.normal(0, 0.01, (400, 3))
    path = tmp_path / "att.csv"
    _csv(path, {"t": t, "wx": w[:, 0], "wy": w[:, 1], "wz": np.degrees(w[:, 2]) * 100})
    run = read_attitude_run(str(path))  # the library reader: format only
    assert run["w"].shape == (400, 3)
    with pytest.raises(InputError, match=r"column wz: .*deg/s\? \(--units wz=deg/s\)"):
        load_run(path, "attitude")
    r = load_run(path, "attitude", units="wz=deg/s")
    np.testing.assert_allclose(r["wz"], w[:, 2] * 100, rtol=1e-12)
    lines = path.read_text().splitlines()
    lines[0] = "t,wx,wy,wzz"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"missing required column 'wz'; did you mean 'wzz'"):
        load_run(path, "attitude")


def test_attitude_rounding_of_the_written_digits(tmp_path):
    """quantisation (rates) and acc_quantisation: RMS rounding error step / sqrt(12) of the cells as
    written; zero cells ("0.0000") count, binary formats are exact."""
    rng = np.random.default_rng(2)
    n = 300
    path = tmp_path / "att.csv"
    acc_cols = [f"a{k}{a}" for k in range(1, 5) for a in "xyz"]
    with open(path, "w") as fh:
        fh.write("t,wx,wy,wz," + ",".join(acc_cols) + "\n")
        for i in range(n):
            w = [0.0 if i % 7 == 0 else v for v in rng.normal(0, 0.01, 3)]
            a = rng.normal(0, 1.0, len(acc_cols))
            fh.write(f"{i / 100:.2f}," + ",".join(f"{v:.4f}" for v in w) + "," + ",".join(f"{v:.2f}" for v in a) + "\n")
    run = read_attitude_run(str(path))
    assert run["quantisation"] == pytest.approx(1e-4 / np.sqrt(12), rel=1e-12)
    assert run["acc_quantisation"] == pytest.approx(1e-2 / np.sqrt(12), rel=1e-12)
    assert run["acc"].shape == (n, 4, 3)


def test_cli_reading_options_reach_the_reader(tmp_path, capsys, real_cols, monkeypatch):
    """--map/--units (CSV) and an MF4 file through `jaxdrift diagnose`: the diagnosis gets the SI
    run, the notes are shown, provenance.reading says how it was read."""
    import jaxdrift.diagnosis.vehicle as dv

    seen = []

    def fake(run, model, plots, log=None):
        seen.append(run)
        return {"kind": "vehicle"}

    monkeypatch.setattr(dv, "diagnose_vehicle_run", fake)
    logger = _csv(tmp_path / "logger.csv", {**real_cols, "f1": real_cols["f1"] / 1e3},
                  names=["time_s", "Fz_FL", "Fz_RL", "pitch", "heave"])
    rc, err, report = _cli(tmp_path, capsys, logger, "--map", "t=time_s,f1=Fz_FL,f2=Fz_RL,beta=pitch,z3=heave",
                           "--units", "f1=kN")
    assert rc == 0, err
    np.testing.assert_allclose(seen[-1]["f1"], real_cols["f1"], rtol=1e-12)
    reading = json.loads(report.read_text())["provenance"]["reading"]
    assert reading["columns"]["f1"] == "Fz_FL" and reading["units_converted"] == {"f1": 1000.0}
    mf4 = tmp_path / "log.mf4"
    _write_mf4(mf4, real_cols)
    rc, err, report = _cli(tmp_path, capsys, mf4, "--map", "f1=Fz_FL,f2=Fz_RL,beta=Pitch")
    assert rc == 0, err
    assert "time base 200 Hz from the median step" in err
    reading = json.loads(report.read_text())["provenance"]["reading"]
    assert reading["format"] == "mf4" and reading["time_base"]["channels"]["beta"]["fs"] == pytest.approx(100.0)
    np.testing.assert_allclose(seen[-1]["f2"], real_cols["f2"][:seen[-1].n], rtol=1e-10)


def test_mf4_slower_motion_channel_kept_at_its_own_times(tmp_path, real_cols):
    path = tmp_path / "log.mf4"
    _write_mf4(path, real_cols)
    r = load_run(path, map="f1=Fz_FL,f2=Fz_RL,beta=Pitch")
    tb_, vb = r.references["beta"]
    tb_ref = np.arange(real_cols["t"][0], real_cols["t"][-1] + 1e-12, 1 / 100.0)
    np.testing.assert_allclose(tb_, tb_ref[(tb_ref >= r.t[0]) & (tb_ref <= r.t[-1])], atol=1e-12)
    np.testing.assert_allclose(vb, np.interp(tb_, real_cols["t"], real_cols["beta"]), atol=1e-12)
    assert "f2" not in r.references  # as fast as the grid: on the grid only
