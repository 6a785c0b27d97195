"""Where the notebooks write: a folder the user chooses, by default inside the build area."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["notebook_output_dir"]


def notebook_output_dir(out=None, *, create: bool = True) -> str:
    """The notebooks' output folder.

    ``out`` if given, else ``$JAXDRIFT_NOTEBOOK_OUT``, else ``build/notebooks`` under the
    repository the working folder lies in (the first parent holding ``pyproject.toml``; Jupyter
    starts in ``notebooks/``), else ``build/notebooks`` under the working folder. Never the
    working folder itself."""
    out = out or os.environ.get("JAXDRIFT_NOTEBOOK_OUT")
    if not out:
        here = Path.cwd().resolve()
        root = next((p for p in (here, *here.parents) if (p / "pyproject.toml").is_file()), here)
        out = str(root / "build" / "notebooks")
    if create:
        os.makedirs(out, exist_ok=True)
    return out
