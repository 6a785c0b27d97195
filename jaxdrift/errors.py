"""Errors every layer may raise; the command line maps them to exit codes.

``UsageError`` and ``InputError`` are bad input from the user (exit code 2, printed without a
traceback). They live here, not in the CLI, so that the library can raise them without importing
the command line.
"""

from __future__ import annotations

__all__ = ["InputError", "UsageError"]


class UsageError(Exception):
    """Bad input from the user: printed without a traceback, exit code 2."""


class InputError(ValueError):
    """Bad user input; the message names file, line or column and the problem."""
