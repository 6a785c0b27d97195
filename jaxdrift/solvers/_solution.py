"""What a solve returns: the per-path result codes and the :class:`Solution` container.

Kept apart from the loops so that every integrator (``_solve``, ``_fast``, ``_sde``) can return a
``Solution`` without importing another integrator.
"""

from __future__ import annotations

import enum

import equinox as eqx
import jax

__all__ = ["RESULTS", "Result", "Solution"]


class Result(enum.IntEnum):
    """Per-path result codes of :func:`solve_ode` (``RESULTS[code]`` is the message)."""

    SUCCESS = 0
    MAX_STEPS = 1
    STEP_UNDERFLOW = 2


RESULTS = {
    Result.SUCCESS: "successful",
    Result.MAX_STEPS: "the maximum number of solver steps was reached",
    Result.STEP_UNDERFLOW: "the step size fell below the spacing of floating-point numbers "
    "(stiff or non-finite right-hand side)",
}


class Solution(eqx.Module):
    """The values at the requested save times and the solver statistics.

    ``num_accepted``/``num_rejected`` count the steps taken. The fixed-step mode with save times on
    the step grid stops at the last save time (nothing after it is returned), so there it counts
    the steps up to that time, not to ``t1``.
    """

    ts: jax.Array
    ys: jax.Array
    result: jax.Array
    num_accepted: jax.Array
    num_rejected: jax.Array

    @property
    def stats(self) -> dict[str, jax.Array]:
        return {
            "num_accepted": self.num_accepted,
            "num_rejected": self.num_rejected,
            "num_steps": self.num_accepted + self.num_rejected,
        }
