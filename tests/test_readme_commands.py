"""Every shell command in README.md and in docs/how-to/*.md runs, on small inputs shipped in the
repository or made here.

The ```bash blocks are extracted as written. A command runs in a temporary folder that holds the
files it names (``flight.ulg`` is the pyulog project's ``tests/data/ulog/sample.ulg``; ``run.bag``,
``logger.csv``, ``run.mf4``, ``runs/*.csv`` and ``campaign.toml`` are made from short generated
runs); ``pip install`` and ``python3 -m venv`` lines are checked against the project's extras, not
run; the quick start's test command is the one CI runs. The commands that diagnose or simulate take
tens of seconds each and are marked slow (CI runs them: ``pytest -m slow -k readme``); the others
run in the default suite.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = [ROOT / "README.md", *sorted((ROOT / "docs" / "how-to").glob("*.md"))]


def commands(path: Path) -> list[str]:
    """The commands of a file's ```bash blocks: continuations joined, comments dropped."""
    out = []
    for m in re.finditer(r"```bash\n(.*?)```", path.read_text(), re.S):
        for line in m.group(1).replace("\\\n", " ").splitlines():
            line = line.split(" #")[0].strip()
            if line and not line.startswith("#"):
                out.append(line)
    return out


ALL = [(p.relative_to(ROOT).as_posix(), c) for p in SOURCES for c in commands(p)]
SETUP = re.compile(r"^(python3 -m venv \.venv && )?\.venv/bin/pip install -q -e (\.|\"\.\[(\w+)\]\")( && (.*))?$")
FAST = ("topics", "--help", "--version")


def _split(cmd: str) -> tuple[str | None, str | None]:
    """(extra installed, the command after the install) for a ``pip install`` line."""
    m = SETUP.match(cmd)
    if not m:
        return None, cmd
    return (m.group(3) or ""), m.group(5)


def _is_slow(cmd: str) -> bool:
    rest = _split(cmd)[1]
    if rest is None or "pytest" in rest or "mkdocs" in rest:
        return False
    return not any(w in shlex.split(rest) for w in FAST)


def _params(slow: bool):
    return [pytest.param(doc, c, id=f"{doc}: {c[:70]}") for doc, c in ALL if _is_slow(c) == slow]


def test_the_docs_have_commands():
    docs = {doc for doc, _ in ALL}
    assert "README.md" in docs and len(docs) == len(SOURCES), docs
    joined = "\n".join(c for _, c in ALL)
    # the campaign's command line in both forms
    assert "campaign runs/*.csv --model model.json --out campaign/ --workers 2" in joined
    assert "campaign --manifest campaign.toml --out campaign/ --workers 2" in joined


def test_install_lines_name_existing_extras():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    for _, cmd in ALL:
        if "pip install" in cmd:
            extra, _ = _split(cmd)
            assert extra is not None, f"an install line the test does not know: {cmd}"
            assert extra == "" or extra in extras, cmd


# ----------------------------------------------------------------------------------- inputs
def _vehicle_inputs(tmp: Path) -> None:
    """The example run and model, and the same run as a logger writes it (CSV with ';', decimal
    commas, kN, degrees and milliseconds; MDF4 with units)."""
    shutil.copy(ROOT / "examples" / "vehicle_run.csv", tmp / "examples_run.csv")
    shutil.copy(ROOT / "examples" / "vehicle_model.json", tmp / "model.json")
    data = np.genfromtxt(ROOT / "examples" / "vehicle_run.csv", delimiter=",", names=True)
    t, f1, f2, beta = data["t"], data["f1"], data["f2"], data["beta"]
    with open(tmp / "logger.csv", "w") as fh:
        fh.write("pitch;Fz_RL;time_ms;Fz_FL\n")
        for row in zip(np.rad2deg(beta), f2 / 1000, t * 1000, f1 / 1000):
            fh.write(";".join(f"{v:.10g}".replace(".", ",") for v in row) + "\n")
    try:
        from asammdf import MDF, Signal
    except ImportError:
        return
    mdf = MDF(version="4.10")
    mdf.append([Signal(f1 / 1000, t, name="Fz_FL", unit="kN"), Signal(f2 / 1000, t, name="Fz_RL", unit="kN"),
                Signal(np.rad2deg(beta), t, name="pitch", unit="deg")])
    mdf.save(tmp / "run.mf4", overwrite=True)
    mdf.close()


def _ros_bag(tmp: Path) -> None:
    """A ROS 1 bag of 20 s of sensor_msgs/Imu at 200 Hz: a turning body, a small bias, noise."""
    rosbags = pytest.importorskip("rosbags")  # noqa: F841
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    T = store.types
    rng = np.random.default_rng(31)
    t = 100.0 + np.arange(4000) * 0.005
    w = np.stack([0.3 * np.sin(0.7 * t), 0.2 * np.cos(0.5 * t), 0.1 * np.sin(0.3 * t)], 1)
    w += np.array([0.002, -0.001, 0.0]) + 1e-3 * rng.standard_normal(w.shape)
    with Writer(tmp / "run.bag") as wr:
        c = wr.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=store)
        for i, ti in enumerate(t):
            sec = int(ti)
            msg = T["sensor_msgs/msg/Imu"](
                header=T["std_msgs/msg/Header"](seq=i, stamp=T["builtin_interfaces/msg/Time"](
                    sec=sec, nanosec=int(round((ti - sec) * 1e9))), frame_id="imu"),
                orientation=T["geometry_msgs/msg/Quaternion"](w=0.0, x=0.0, y=0.0, z=0.0),
                orientation_covariance=np.array([-1.0] + [0.0] * 8),
                angular_velocity=T["geometry_msgs/msg/Vector3"](x=w[i, 0], y=w[i, 1], z=w[i, 2]),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=9.81),
                linear_acceleration_covariance=np.zeros(9))
            wr.write(c, int(ti * 1e9), store.serialize_ros1(msg, "sensor_msgs/msg/Imu"))


def _drive_mf4(tmp: Path) -> None:
    """60 s of a car's CAN GNSS/IMU in MDF4: rates in deg/s at 100 Hz with a 0.1 deg/s bias on the
    vertical axis, and the GNSS heading in degrees at 10 Hz on its own times."""
    pytest.importorskip("asammdf")
    from asammdf import MDF, Signal
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(33)
    t = np.arange(0.0, 60.0, 0.01)
    w = np.column_stack([0.02 * np.sin(2 * np.pi * 0.8 * t), 0.015 * np.sin(2 * np.pi * 0.6 * t),
                         0.2 * np.sin(2 * np.pi * 0.05 * t)])
    r = Rotation.identity()
    yaw = [0.0]
    for k in range(len(t) - 1):
        r = r * Rotation.from_rotvec(w[k] * 0.01)
        yaw.append(r.as_euler("ZYX")[0])
    meas = np.degrees(w + np.array([0.0, 0.0, np.radians(0.1)]) + 2e-3 * rng.standard_normal(w.shape))
    mdf = MDF(version="4.10")
    mdf.append([Signal(meas[:, i], t, name=f"AngularRate{a}", unit="deg/s") for i, a in enumerate("XYZ")])
    mdf.append([Signal(np.degrees(np.asarray(yaw))[::10], t[::10], name="Heading", unit="deg")])
    mdf.save(tmp / "drive.mf4", overwrite=True)
    mdf.close()


def _campaign_inputs(tmp: Path) -> None:
    """Two 3 s runs of one vehicle (the independent generator), their model and a manifest."""
    from benchmarks.validation import gen_campaign as gc

    d = gc.draw_campaign(2, 6107, n_shared=1, durations=(3.0, 3.0), rates=(200,), params=("m3",),
                         motion_noise_share=0.0)
    gc.write_campaign(d, str(tmp / "gen"), progress=False)
    (tmp / "runs").mkdir()
    for p in sorted((tmp / "gen").glob("run_*.csv")):
        shutil.copy(p, tmp / "runs" / p.name)
    shutil.copy(tmp / "gen" / "model.json", tmp / "model.json")
    man = tomllib.loads((tmp / "gen" / "campaign.toml").read_text())
    lines = ['model = "model.json"']
    for r in man["run"]:
        lines += ["[[run]]", f'file = "runs/{Path(r["file"]).name}"', f'logger = "{r.get("logger", "L")}"',
                  f'repetitions = {r.get("repetitions", 1)}']
    (tmp / "campaign.toml").write_text("\n".join(lines) + "\n")


def _substitute(cmd: str, tmp: Path) -> list[str]:
    """The command as argv, with the files it names made or mapped to small ones."""
    argv = shlex.split(cmd)
    if argv[0] == ".venv/bin/jaxdrift":
        argv = [sys.executable, "-m", "jaxdrift", *argv[1:]]
    elif argv[0] == ".venv/bin/mkdocs":
        argv = [sys.executable, "-m", "mkdocs", *argv[1:]]
    out = []
    for a in argv:
        if a == "flight.ulg":
            shutil.copy(ROOT / "tests" / "data" / "ulog" / "sample.ulg", tmp / "flight.ulg")
        elif a == "run.bag" and not (tmp / "run.bag").exists():
            _ros_bag(tmp)
        elif a == "drive.mf4" and not (tmp / a).exists():
            _drive_mf4(tmp)
        elif a in ("logger.csv", "run.mf4", "model.json") and not (tmp / "logger.csv").exists():
            _vehicle_inputs(tmp)
            if a == "run.mf4" and not (tmp / "run.mf4").exists():
                pytest.skip("asammdf is not installed")
        elif a == "flight.csv" and "diagnose" in argv:  # made by the guide's export command before it
            shutil.copy(ROOT / "tests" / "data" / "ulog" / "sample.ulg", tmp / "flight.ulg")
            subprocess.run([sys.executable, "-m", "jaxdrift", "-q", "topics", "flight.ulg", "--export-csv", a],
                           cwd=tmp, check=True, capture_output=True)
        elif a == "report.json" and "durability" in argv and not (tmp / a).exists():
            shutil.copy(ROOT / "examples" / "vehicle_report.json", tmp / a)  # the guide's diagnose line writes it
        elif a.startswith("examples/"):
            a = str(ROOT / a)
        elif a == "site":
            a = str(tmp / "site")
        elif a in ("runs/*.csv", "campaign.toml") and not (tmp / "campaign.toml").exists():
            _campaign_inputs(tmp)
        if a == "runs/*.csv":
            out += sorted(str(p) for p in (tmp / "runs").glob("*.csv"))
            continue
        if a == "paper":  # the main job, shortened
            out += [a, "--quick"]
            continue
        out.append(a)
    # Monte-Carlo draws: a few, not a hundred
    for i, a in enumerate(out[:-1]):
        if a == "--paths":
            out[i + 1] = "4"
    if "campaign" in out and "--no-figures" not in out:
        out.append("--no-figures")
    return out


def _run(doc: str, cmd: str, tmp: Path) -> subprocess.CompletedProcess:
    extra, rest = _split(cmd)
    if rest is None:  # only an install line: the extra exists (test_install_lines_name_existing_extras)
        pytest.skip("an install line")
    if extra is not None and extra and extra not in ("test", "docs"):
        mod = {"ulog": "pyulog", "ros": "rosbags", "mdf": "asammdf", "campaign": "distributed"}.get(extra)
        if mod:
            pytest.importorskip(mod)
    if "pytest" in rest:  # the quick start's test command is CI's own (tests/test_docs.py checks it)
        assert rest in (ROOT / ".ci" / "run").read_text()
        pytest.skip("the test suite itself")
    argv = _substitute(rest, tmp)
    if argv[:3] == [sys.executable, "-m", "mkdocs"]:
        pytest.importorskip("mkdocs")
        argv += ["--config-file", str(ROOT / "mkdocs.yml")]
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1", DISABLE_MKDOCS_2_WARNING="true",
               PYTHONPATH=str(ROOT))
    return subprocess.run(argv, cwd=tmp, capture_output=True, text=True, env=env, timeout=900)


def _check_outputs(cmd: str, tmp: Path) -> None:
    """What a command says it writes is there, and the schemas the reference documents hold."""
    if " diagnose " in f" {cmd} " and "--json report.json" in cmd:
        rep = json.loads((tmp / "report.json").read_text())
        assert rep["schema"] == "jaxdrift.diagnosis/1" and rep["findings"]
        if "examples/vehicle_run.csv" in cmd:
            shipped = json.loads((ROOT / "examples" / "vehicle_report.json").read_text())
            assert set(shipped) <= set(rep)
            assert [(f["cause"], f.get("channel"), f.get("parameter")) for f in rep["findings"]] == \
                [(f["cause"], f.get("channel"), f.get("parameter")) for f in shipped["findings"]]
            for f in rep["findings"]:
                assert f["interval_level"]["findings"] == len(rep["findings"])
        if "logger.csv" in cmd or "run.mf4" in cmd:  # the logger's file reads as the example run
            assert rep["findings"][0]["cause"] == "parameter_error"
    if " campaign " in f" {cmd} ":
        from benchmarks.doc_tables import key_tree

        doc = json.loads((tmp / "campaign" / "campaign.json").read_text())
        assert doc["schema"] == "jaxdrift.campaign/1"
        assert [r["status"] for r in doc["runs"]] == ["ok", "ok"]
        shipped = json.loads((ROOT / "examples" / "campaign.json").read_text())
        want = {k for k, _ in key_tree(shipped, max_depth=2) if "--durability" in cmd or not k.startswith("durability.")}
        have = {k for k, _ in key_tree(doc, max_depth=2)}
        assert want <= have, sorted(want - have)
    if " durability " in f" {cmd} ":
        d = json.loads((tmp / "durability" / "durability.json").read_text())
        assert d["schema"] == "jaxdrift.durability/1"
        assert (tmp / "durability" / "section_forces.csv").is_file()


@pytest.mark.parametrize("doc,cmd", _params(False))
def test_fast_command_runs(doc, cmd, tmp_path):
    proc = _run(doc, cmd, tmp_path)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    _check_outputs(cmd, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("doc,cmd", _params(True))
def test_slow_command_runs(doc, cmd, tmp_path):
    proc = _run(doc, cmd, tmp_path)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    _check_outputs(cmd, tmp_path)
