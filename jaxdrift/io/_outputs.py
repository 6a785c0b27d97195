"""Writing results without losing data: one helper for every writer (JSON, CSV, Parquet, figures,
folders of figures).

- :func:`check_outputs` runs before any computation: an output equal to an input (symlinks
  resolved) or to another output is refused, and every output folder must exist (or be creatable)
  and take a test file.
- :func:`atomic_path` writes through a temporary file in the target's folder and renames it into
  place, so a killed run leaves the old file or the new one, never half of one.
- :func:`atomic_dir` collects a folder's files in a temporary folder beside it and moves them in at
  the end, with ``jaxdrift-manifest.json`` (files, SHA-256, time) written last: a folder without a
  manifest, or with files the manifest does not list, is from an interrupted run.

The renames run under :data:`COMMIT_LOCK`; the interrupt handler of the command line takes that lock
before it exits, so Ctrl-C never lands between two renames, and removes the temporary files
registered in :data:`PENDING`. An ``OSError`` becomes :class:`InputError` naming the path (exit 2).
"""

from __future__ import annotations

import contextlib
import datetime
import hashlib
import json
import math
import re
import os
import shutil
import tempfile
import threading

from ..errors import InputError

__all__ = ["COMMIT_LOCK", "PENDING", "INTERRUPT", "MANIFEST", "in_commit", "park", "check_outputs", "atomic_path", "atomic_dir",
           "write_json", "write_report", "check_report_finite", "nonfinite_in_report", "write_text", "write_table", "sha256_file", "input_bytes", "finite_json", "remove_pending"]

#: held while temporary files are renamed into place
COMMIT_LOCK = threading.RLock()
#: temporary files and folders that exist right now (removed on interrupt)
PENDING: set[str] = set()
#: set by the interrupt handler as soon as a signal arrives
INTERRUPT = threading.Event()
_DEPTH = [0]  # commits in progress in the main thread


def in_commit() -> bool:
    return _DEPTH[0] > 0


def park() -> None:
    """Wait for the interrupt handler's thread to end the process (it exits with os._exit)."""
    import time

    while True:
        time.sleep(1.0)


@contextlib.contextmanager
def _committing():
    """The renames of one output: under COMMIT_LOCK; after them, an interrupt that arrived
    meanwhile ends the process before anything else happens."""
    with COMMIT_LOCK:
        _DEPTH[0] += 1
        try:
            yield
        finally:
            _DEPTH[0] -= 1
    if INTERRUPT.is_set():
        park()
MANIFEST = "jaxdrift-manifest.json"


def _commit_hook(path) -> None:
    """Tests of Ctrl-C while writing: with ``JAXDRIFT_TEST_COMMIT_DELAY_S`` set, say so on stderr
    and wait that long inside the commit (the interrupt handler must wait for it)."""
    delay = os.environ.get("JAXDRIFT_TEST_COMMIT_DELAY_S")
    if delay:
        import sys
        import time

        print(f"jaxdrift: committing {path}", file=sys.stderr, flush=True)
        time.sleep(float(delay))


def _real(p) -> str:
    return os.path.realpath(os.path.abspath(os.fspath(p)))


def _writable_folder(option: str, path: str, folder: str) -> None:
    if not os.path.isdir(folder):
        raise InputError(f"{option} {path}: folder {folder} does not exist")
    try:
        fd, probe = tempfile.mkstemp(prefix=".jaxdrift-probe-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise InputError(f"{option} {path}: folder {folder} is not writable ({e.strerror})") from None


def check_outputs(outputs, inputs=()) -> None:
    """Refuse outputs that would overwrite an input or each other, or that cannot be written.

    ``outputs``: ``(option, path, kind)`` with kind ``"file"`` or ``"dir"``, or ``(option, path,
    "dir", names)`` with the names of the files that will be written into the folder. ``inputs``:
    paths read by the command. Call it before any computation."""
    ins = {_real(p): str(p) for p in inputs if p is not None}
    seen: dict[str, str] = {}
    for item in outputs:
        option, path, kind = item[:3]
        if path is None:
            continue
        names = item[3] if len(item) > 3 else ()
        real = _real(path)
        if real in ins:
            raise InputError(f"{option} {path}: is the input file {ins[real]}; refusing to overwrite it")
        if real in seen:
            raise InputError(f"{option} {path}: the same path as {seen[real]}")
        seen[real] = f"{option} {path}"
        if kind == "file":
            if os.path.isdir(path):
                raise InputError(f"{option} {path}: is a folder, expected a file name")
            _writable_folder(option, path, os.path.dirname(real))
            if os.path.exists(path) and not os.access(path, os.W_OK):
                raise InputError(f"{option} {path}: exists and is not writable")
        else:
            if os.path.exists(path) and not os.path.isdir(path):
                raise InputError(f"{option} {path}: exists and is not a folder")
            folder = real if os.path.isdir(real) else os.path.dirname(real)
            if not os.path.isdir(folder):
                raise InputError(f"{option} {path}: parent folder {folder} does not exist")
            _writable_folder(option, path, folder)
            for nm in names:
                r = _real(os.path.join(path, nm))
                if r in ins:
                    raise InputError(f"{option} {path}: would overwrite the input file {ins[r]} ({nm})")


def remove_pending() -> None:
    """Remove every temporary file and folder still registered (the interrupt handler)."""
    for p in list(PENDING):
        try:
            if os.path.isdir(p):
                shutil.rmtree(p, ignore_errors=True)
            else:
                os.unlink(p)
        except OSError:
            pass
        PENDING.discard(p)


def _umask_mode() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


@contextlib.contextmanager
def atomic_path(path, option: str = "output"):
    """Yield a temporary path beside ``path`` (same extension); rename it to ``path`` on success.

    On an exception the temporary file is removed and nothing at ``path`` changes."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    base, ext = os.path.splitext(os.path.basename(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{base}.", suffix=f".jaxdrift-tmp{ext}", dir=folder)
        os.close(fd)
    except OSError as e:
        raise InputError(f"{option} {path}: cannot write ({e.strerror})") from None
    PENDING.add(tmp)
    try:
        yield tmp
        with _committing():
            _commit_hook(path)
            os.chmod(tmp, _umask_mode())  # mkstemp makes it private; a result is an ordinary file
            os.replace(tmp, path)
            PENDING.discard(tmp)
    except OSError as e:
        raise InputError(f"{option} {path}: cannot write ({e.strerror or e})") from None
    finally:
        if tmp in PENDING:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            PENDING.discard(tmp)


def _files_under(path) -> list[str]:
    """The files of an input: the path itself, or every file under a folder (a ROS 2 bag is a
    folder of metadata.yaml and .db3/.mcap files), in a fixed order."""
    if not os.path.isdir(path):
        return [path]
    out = []
    for dirpath, dirs, files in os.walk(path):
        dirs.sort()
        out += [os.path.join(dirpath, f) for f in sorted(files)]
    return out


def sha256_file(path, block: int = 1 << 20) -> str:
    """SHA-256 of a file; of a folder, over its files' relative names and contents in order."""
    path = os.fspath(path)
    h = hashlib.sha256()
    folder = os.path.isdir(path)
    for f in _files_under(path):
        if folder:
            h.update(os.path.relpath(f, path).replace(os.sep, "/").encode() + b"\0")
        with open(f, "rb") as fh:
            while chunk := fh.read(block):
                h.update(chunk)
    return h.hexdigest()


def input_bytes(path) -> int:
    """Size of a file, or of all files under a folder."""
    return sum(os.path.getsize(f) for f in _files_under(os.fspath(path)))


@contextlib.contextmanager
def atomic_dir(path, option: str = "--out"):
    """Yield a temporary folder; on success move its files into ``path`` (created if missing).

    The old manifest goes first, the files are renamed in one by one, the new manifest last."""
    path = os.fspath(path)
    parent = os.path.dirname(os.path.abspath(path))
    try:
        tmp = tempfile.mkdtemp(prefix=f".{os.path.basename(os.path.abspath(path))}.jaxdrift-tmp-", dir=parent)
    except OSError as e:
        raise InputError(f"{option} {path}: cannot write ({e.strerror})") from None
    PENDING.add(tmp)
    try:
        yield tmp
        names = sorted(n for n in os.listdir(tmp) if n != MANIFEST)
        manifest = {"files": {n: sha256_file(os.path.join(tmp, n)) for n in names if os.path.isfile(os.path.join(tmp, n))},
                    "written_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
        with _committing():
            os.makedirs(path, exist_ok=True)
            with contextlib.suppress(FileNotFoundError):
                os.unlink(os.path.join(path, MANIFEST))
            for i, n in enumerate(names):
                os.replace(os.path.join(tmp, n), os.path.join(path, n))
                if i == 0:
                    _commit_hook(path)
            mtmp = os.path.join(tmp, MANIFEST)
            with open(mtmp, "w") as fh:
                json.dump(manifest, fh, indent=1)
            os.replace(mtmp, os.path.join(path, MANIFEST))
    except OSError as e:
        raise InputError(f"{option} {path}: cannot write ({e.strerror or e})") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        PENDING.discard(tmp)


def finite_json(obj):
    """Replace non-finite floats by None and numpy scalars/arrays by Python values (strict JSON)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): finite_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_json(v) for v in obj]
    if hasattr(obj, "tolist") and callable(obj.tolist):  # numpy scalar or array
        return finite_json(obj.tolist())
    return obj


_NONFINITE_WORD = re.compile(r"(?<![A-Za-z])[-+]?(inf|infinity|nan)(?![A-Za-z])", re.IGNORECASE)


def nonfinite_in_report(obj, where="report") -> list[str]:
    """Where a report holds a number that is not finite (inf, NaN) or a sentence that quotes one
    ("z = inf", "nan rad/s"): a list of ``"report.findings[0].evidence: ..."`` (empty when clean).

    A report is read by people and programs; an infinite z or a NaN estimate is a degenerate fit that
    must be said in words (the diagnoses report such a cause as not determined), never written as a
    number or turned into a null by the JSON writer."""
    out = []
    if isinstance(obj, bool) or obj is None:
        return out
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += nonfinite_in_report(v, f"{where}.{k}")
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            out += nonfinite_in_report(v, f"{where}[{i}]")
    elif isinstance(obj, str):
        if _NONFINITE_WORD.search(obj):
            out.append(f"{where}: {obj!r}")
    elif hasattr(obj, "tolist") and callable(obj.tolist):
        out += nonfinite_in_report(obj.tolist(), where)
    elif isinstance(obj, (int, float)):
        if not math.isfinite(obj):
            out.append(f"{where}: {obj}")
    return out


def check_report_finite(report) -> None:
    """Raise ``ValueError`` naming every place of ``report`` that holds inf or NaN (see
    :func:`nonfinite_in_report`)."""
    bad = nonfinite_in_report(report)
    if bad:
        raise ValueError("report holds non-finite values (a degenerate fit reported as a number): " + "; ".join(bad[:10]))


def write_report(path, report, option: str = "--json") -> None:
    """Write a diagnosis report: refused (``ValueError``, nothing written) when it holds inf or NaN."""
    check_report_finite(report)
    write_json(path, report, option)


def write_text(path, text: str, option: str = "output") -> None:
    with atomic_path(path, option) as tmp:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)


def write_json(path, obj, option: str = "output", indent: int = 2) -> None:
    """Strict JSON (non-finite floats as null), atomically."""
    write_text(path, json.dumps(finite_json(obj), indent=indent, allow_nan=False) + "\n", option)


def write_table(path, columns: dict, option: str = "output") -> None:
    """Columns of equal length as CSV (shortest round-trip decimals) or Parquet (by extension),
    atomically."""
    import pyarrow as pa

    table = pa.table({k: pa.array(v) for k, v in columns.items()})
    with atomic_path(path, option) as tmp:
        if str(path).lower().endswith((".parquet", ".pq")):
            import pyarrow.parquet as pq

            pq.write_table(table, tmp)
        else:
            import pyarrow.csv as pcsv

            with open(tmp, "wb") as fh:  # the header unquoted, as every CSV of the contract
                fh.write((",".join(columns) + "\n").encode())
                pcsv.write_csv(table, fh, pcsv.WriteOptions(include_header=False, quoting_style="none"))
