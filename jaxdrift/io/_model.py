"""Vehicle model files (JSON): the seed's parameter table, read and validated (numpy-free)."""

from __future__ import annotations

import difflib
import json
import math
from typing import Mapping

from ..errors import InputError
from ._table import file_label as _name

__all__ = ["MODEL_KEYS", "DEFAULT_MODEL", "DEFAULT_MODEL_LABEL", "read_model", "validate_model"]

#: The seed's parameter names, in the seed's order.
MODEL_KEYS: tuple[str, ...] = (
    "a", "b", "m1", "m2", "m3", "I", "k1", "k2", "k3", "k4", "d1", "d2", "d3", "d4", "g",
)
#: The seed's parameter table (the default model).
DEFAULT_MODEL: dict[str, float] = {
    "a": 1.0, "b": 1.0, "m1": 15.0, "m2": 15.0, "m3": 750.0, "I": 500.0,
    "k1": 2.0e5, "k2": 2.0e5, "k3": 1.0e5, "k4": 1.0e5,
    "d1": 2.0e2, "d2": 2.0e2, "d3": 1.0e4, "d4": 1.0e4, "g": 9.81,
}

#: how reports and messages name the default model
DEFAULT_MODEL_LABEL = "the default model (the seed's table: m1 = m2 = 15 kg, m3 = 750 kg, I = 500 kg m^2, a = b = 1 m)"


def read_model(path) -> dict[str, float]:
    """Read and validate a vehicle model JSON: exactly the seed's keys, all positive numbers."""
    fname = _name(path)
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
    except FileNotFoundError:
        raise InputError(f"{path}: file not found") from None
    except (IsADirectoryError, UnicodeDecodeError, OSError) as e:
        raise InputError(f"{path}: cannot read ({e})") from None
    try:
        obj = json.loads(text)
    except json.JSONDecodeError as e:
        raise InputError(f"{fname}, line {e.lineno}, column {e.colno}: invalid JSON ({e.msg})") from None
    return validate_model(obj, fname)


def validate_model(obj, fname: str = "model") -> dict[str, float]:
    if not isinstance(obj, Mapping):
        raise InputError(f"{fname}: expected a JSON object with keys {', '.join(MODEL_KEYS)}")
    unknown = [k for k in obj if k not in MODEL_KEYS]
    if unknown:
        missing = [k for k in MODEL_KEYS if k not in obj]
        hint = difflib.get_close_matches(unknown[0], missing or MODEL_KEYS, n=1, cutoff=0.5)
        did = f" (did you mean {hint[0]!r}?)" if hint else ""
        raise InputError(f"{fname}: unknown key {unknown[0]!r}{did}; keys are {', '.join(MODEL_KEYS)}")
    missing = [k for k in MODEL_KEYS if k not in obj]
    if missing:
        raise InputError(f"{fname}: missing key(s) {', '.join(missing)} (all of {', '.join(MODEL_KEYS)} are required)")
    out = {}
    for k in MODEL_KEYS:
        v = obj[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(f"{fname}: key {k!r} must be a number, got {v!r}")
        v = float(v)
        if not math.isfinite(v) or v <= 0:
            raise InputError(f"{fname}: key {k!r} must be a positive number, got {v!r}")
        out[k] = v
    return out
