"""``--map`` and ``--units``: other column names and other units than the contract's (SI).

``--map f1=Fz_FL,f2=Fz_RL`` reads the contract's column ``f1`` from the file's column ``Fz_FL``.
``--units f1=kN,t=ms,beta=deg`` converts on reading (the names are the contract's, after the map).
Each column has one quantity (time, force, angle, ...) and accepts only units of that quantity.
"""

from __future__ import annotations

import difflib
import re

from ..errors import InputError

__all__ = ["UNITS", "quantity_of", "parse_map", "parse_units", "unit_factor"]

#: quantity -> {unit: factor to SI}
UNITS: dict[str, dict[str, float]] = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0},
    "force": {"N": 1.0, "kN": 1e3, "daN": 10.0, "lbf": 4.4482216152605},
    "angle": {"rad": 1.0, "deg": 0.017453292519943295, "mrad": 1e-3},
    "rate": {"rad/s": 1.0, "deg/s": 0.017453292519943295, "mrad/s": 1e-3},
    "length": {"m": 1.0, "mm": 1e-3, "cm": 1e-2},
    "acceleration": {"m/s^2": 1.0, "m/s2": 1.0, "g": 9.80665, "mm/s^2": 1e-3},
    "ratio": {"1": 1.0, "-": 1.0},
}

_QUANTITY = {
    "t": "time", "f1": "force", "f2": "force", "beta": "angle", "beta_rate": "rate",
    "z3": "length", "s1": "length", "s2": "length", "zeta1": "length", "zeta2": "length",
    "wx": "rate", "wy": "rate", "wz": "rate", "qw": "ratio", "qx": "ratio", "qy": "ratio", "qz": "ratio",
    "roll": "angle", "pitch": "angle", "yaw": "angle",
}
_ACC = re.compile(r"^a\d+[xyz]$")


def quantity_of(name: str) -> str | None:
    if name in _QUANTITY:
        return _QUANTITY[name]
    if _ACC.match(name):
        return "acceleration"
    return None


def _pairs(text: str, option: str) -> list[tuple[str, str]]:
    out = []
    for item in (text or "").split(","):
        item = item.strip()
        if not item:
            continue
        if item.count("=") != 1 or not all(p.strip() for p in item.split("=")):
            raise InputError(f"{option} {text!r}: expected NAME=VALUE pairs separated by commas, got {item!r}")
        a, b = (p.strip() for p in item.split("="))
        out.append((a, b))
    return out


def parse_map(text: str | dict | None, known: tuple[str, ...] | None = None) -> dict[str, str]:
    """``"f1=Fz_FL,f2=Fz_RL"`` -> ``{"f1": "Fz_FL", "f2": "Fz_RL"}`` (contract name -> file name)."""
    if text is None:
        return {}
    pairs = list(text.items()) if isinstance(text, dict) else _pairs(text, "--map")
    out: dict[str, str] = {}
    for a, b in pairs:
        if known is not None and a not in known and quantity_of(a) is None:
            hint = difflib.get_close_matches(a, known, n=1, cutoff=0.6)
            did = f"; did you mean `{hint[0]}`?" if hint else ""
            raise InputError(f"--map {a}={b}: {a!r} is not a column of this kind of run{did} "
                             f"(columns: {', '.join(known)})")
        if a in out:
            raise InputError(f"--map: {a!r} is mapped twice")
        if b in out.values():
            raise InputError(f"--map: file column {b!r} is used twice")
        out[a] = b
    return out


def unit_factor(column: str, unit: str, option: str = "--units") -> float:
    q = quantity_of(column)
    if q is None:
        raise InputError(f"{option} {column}={unit}: {column!r} is not a known column")
    table = UNITS[q]
    if unit in table:
        return table[unit]
    low = {k.lower(): k for k in table}
    if unit.lower() in low:
        return table[low[unit.lower()]]
    raise InputError(f"{option} {column}={unit}: unknown unit for a {q} column "
                     f"(accepted: {', '.join(table)})")


def parse_units(text: str | dict | None) -> dict[str, float]:
    """``"f1=kN,t=ms"`` -> ``{"f1": 1000.0, "t": 0.001}`` (factor to SI per contract name)."""
    if text is None:
        return {}
    pairs = list(text.items()) if isinstance(text, dict) else _pairs(text, "--units")
    out = {}
    for a, b in pairs:
        if a in out:
            raise InputError(f"--units: {a!r} given twice")
        out[a] = unit_factor(a, b)
    return out
