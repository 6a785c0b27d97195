"""The point mass of the seed's section 2, equation (2.1): ``x' = v``, ``v' = f/m - eta v``."""

from __future__ import annotations

import jax.numpy as jnp

from ._params import PointMassParams

__all__ = ["pointmass_rhs"]


def pointmass_rhs(t, y, params: PointMassParams, f):
    """Right-hand side of (2.1): ``y = [x, v]``, force ``f`` at time ``t``."""
    return jnp.stack([y[1], f / params.m - params.eta * y[1]])
