"""The runs of a campaign: from the command line or a TOML manifest, with per-run reading options,
logger ids and repetitions, and the cache key of each run's result."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os

from ..errors import UsageError
from ..io._outputs import sha256_file
from ..io._provenance import jaxdrift_version

__all__ = ["RunSpec", "read_manifest", "run_specs", "cache_key"]

_RUN_KEYS = {"file", "map", "units", "fs", "force", "strict_time", "logger", "repetitions"}


@dataclasses.dataclass(frozen=True)
class RunSpec:
    """One run of a campaign: the file, how to read it, its logger and how often the test
    schedule repeats it. ``logger``: runs with the same id share their sensor effects (default:
    each run its own)."""

    path: str
    map: str | None = None
    units: str | None = None
    fs: float | None = None
    force: bool = False
    strict_time: bool = False
    logger: str | None = None
    repetitions: float = 1.0

    @property
    def name(self) -> str:
        return os.path.splitext(os.path.basename(self.path))[0]

    @property
    def logger_id(self) -> str:
        return self.logger if self.logger is not None else f"run:{self.path}"

    def reading(self) -> dict:
        return {"map": self.map, "units": self.units, "fs": self.fs, "force": self.force,
                "strict_time": self.strict_time}


def _check_run(i: int, where: str, d: dict, base: str) -> RunSpec:
    bad = sorted(set(d) - _RUN_KEYS)
    if bad:
        raise UsageError(f"{where}, run {i + 1}: unknown key {bad[0]!r} (known: {', '.join(sorted(_RUN_KEYS))})")
    if "file" not in d or not isinstance(d["file"], str):
        raise UsageError(f"{where}, run {i + 1}: needs file = \"RUN.csv\"")
    rep = d.get("repetitions", 1)
    if isinstance(rep, bool) or not isinstance(rep, (int, float)) or not rep >= 0:
        raise UsageError(f"{where}, run {i + 1} ({d['file']}): repetitions must be a number >= 0, got {rep!r}")
    for k in ("map", "units", "logger"):
        if k in d and not isinstance(d[k], str):
            raise UsageError(f"{where}, run {i + 1} ({d['file']}): {k} must be a string, got {d[k]!r}")
    for k in ("force", "strict_time"):
        if k in d and not isinstance(d[k], bool):
            raise UsageError(f"{where}, run {i + 1} ({d['file']}): {k} must be true or false, got {d[k]!r}")
    fs = d.get("fs")
    if fs is not None and (isinstance(fs, bool) or not isinstance(fs, (int, float)) or not fs > 0):
        raise UsageError(f"{where}, run {i + 1} ({d['file']}): fs must be a number > 0, got {fs!r}")
    path = d["file"] if os.path.isabs(d["file"]) else os.path.join(base, d["file"])
    return RunSpec(path=os.path.normpath(path), map=d.get("map"), units=d.get("units"),
                   fs=None if fs is None else float(fs), force=bool(d.get("force", False)),
                   strict_time=bool(d.get("strict_time", False)), logger=d.get("logger"), repetitions=float(rep))


def read_manifest(path) -> tuple[list[RunSpec], str | None]:
    """``(runs, model path or None)`` from a TOML manifest::

        model = "model.json"          # optional; relative paths are relative to the manifest
        [[run]]
        file = "day1/run_001.csv"
        logger = "DAQ-7"              # optional: runs with one logger share their sensor effects
        repetitions = 120             # optional (default 1): the test schedule's count
        map = "f1=Fz_FL,f2=Fz_RL"     # optional: as --map, --units, --fs, --force, --strict-time
    """
    import tomllib

    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except OSError as e:
        raise UsageError(f"--manifest {path}: cannot read: {e.strerror}") from None
    except tomllib.TOMLDecodeError as e:
        raise UsageError(f"--manifest {path}: invalid TOML: {e}") from None
    bad = sorted(set(doc) - {"model", "run"})
    if bad:
        raise UsageError(f"--manifest {path}: unknown key {bad[0]!r} (known: model, [[run]])")
    runs = doc.get("run")
    if not isinstance(runs, list) or not runs:
        raise UsageError(f"--manifest {path}: lists no runs (one [[run]] table per run, each with file = ...)")
    base = os.path.dirname(os.path.abspath(path))
    specs = [_check_run(i, f"--manifest {path}", d, base) for i, d in enumerate(runs)]
    model = doc.get("model")
    if model is not None and not isinstance(model, str):
        raise UsageError(f"--manifest {path}: model must be a path string, got {model!r}")
    if model is not None and not os.path.isabs(model):
        model = os.path.join(base, model)
    _check_unique(specs, f"--manifest {path}")
    return specs, model


def _check_unique(specs, where: str) -> None:
    seen = {}
    for s in specs:
        key = os.path.realpath(s.path)
        if key in seen:
            raise UsageError(f"{where}: {s.path} is listed twice")
        seen[key] = s


def run_specs(paths, *, map=None, units=None, fs=None, force=False, strict_time=False,
              repetitions=1.0) -> list[RunSpec]:
    """Specs of runs given on the command line (one set of reading options for all: the keys of
    ``jaxdrift.cli._common.run_options``, which are those of :meth:`RunSpec.reading`)."""
    specs = [RunSpec(path=os.path.normpath(str(p)), map=map, units=units, fs=fs, force=force,
                     strict_time=bool(strict_time), repetitions=float(repetitions)) for p in paths]
    _check_unique(specs, "RUN")
    return specs


#: the campaign modules a run's diagnosis never runs (the joint fit, the outputs, the campaign
#: damage; ``_tasks.diagnose_task`` imports none of them): the diagnose stage's code digest leaves
#: them out, so that a change to the joint model reruns the joint stage on the cached diagnoses
AFTER_DIAGNOSIS = ("_joint.py", "_outputs.py", "_damage.py", "_nonlinear.py", "_campaign.py")

_CODE: dict = {}


def code_digest(stage: str | None = None, root: str | None = None) -> str:
    """SHA-256 of jaxdrift's own source files (those under ``root``, default the installed
    package): a development checkout changes its code without changing its version number, and a
    cached result must not outlive the code that made it. ``stage="diagnose"``: without the
    campaign modules in :data:`AFTER_DIAGNOSIS`."""
    key = (stage == "diagnose", root)
    if key not in _CODE:
        top = root or os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        skip = {os.path.join(top, "campaign", f) for f in AFTER_DIAGNOSIS} if stage == "diagnose" else set()
        h = hashlib.sha256()
        for dirpath, dirs, files in sorted(os.walk(top)):
            dirs.sort()
            for f in sorted(files):
                if f.endswith(".py") and os.path.join(dirpath, f) not in skip:
                    with open(os.path.join(dirpath, f), "rb") as fh:
                        h.update(f.encode() + fh.read())
        _CODE[key] = h.hexdigest()
    return _CODE[key]


def cache_key(spec: RunSpec, model: dict, options: dict, stage: str) -> str:
    """SHA-256 of the run's bytes, its reading options, the model, the stage's options, the
    jaxdrift version and its source (:func:`code_digest` of the stage): a result cached under this
    key is the result a new computation would give."""
    h = hashlib.sha256()
    try:
        h.update(sha256_file(spec.path).encode())
    except OSError as e:
        h.update(f"unreadable:{e.strerror}".encode())  # the diagnosis reports the reading error
    h.update(json.dumps({"stage": stage, "reading": spec.reading(), "model": model, "options": options,
                         "version": jaxdrift_version(), "code": code_digest(stage)}, sort_keys=True,
                        default=str).encode())
    return h.hexdigest()
