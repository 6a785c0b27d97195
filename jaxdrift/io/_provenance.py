"""What made a report: jaxdrift version, input files with SHA-256, model, options, time (UTC)."""

from __future__ import annotations

import datetime
import os
import platform
import sys

from ._outputs import input_bytes, sha256_file

__all__ = ["provenance", "jaxdrift_version"]


def jaxdrift_version() -> str:
    """The installed distribution's version (the package's ``__version__`` comes from it too)."""
    from importlib import metadata

    try:
        return metadata.version("jaxdrift")
    except metadata.PackageNotFoundError:
        return "unknown (not installed)"


def provenance(command: str, inputs=(), *, model=None, options=None) -> dict:
    """The ``provenance`` object every report carries.

    ``inputs``: paths read (each gets its name, size and SHA-256). ``model``: a short description
    or the parameters used. ``options``: the command's options (JSON-able values)."""
    files = []
    for p in inputs:
        if p is None:
            continue
        files.append({"file": os.path.basename(str(p)), "path": os.path.abspath(str(p)),
                      "bytes": input_bytes(p), "sha256": sha256_file(p)})
    return {
        "jaxdrift_version": jaxdrift_version(),
        "command": command,
        "inputs": files,
        "model": model,
        "options": {k: v for k, v in (options or {}).items()},
        "time_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "python": sys.version.split()[0],
        "platform": platform.platform(terse=True),
    }
