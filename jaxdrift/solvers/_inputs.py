"""Sampled input signals (measured data) usable by the adaptive integrator at any time t."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["SampledSignal"]


def _static_float(x) -> float | None:
    if isinstance(x, jax.core.Tracer):
        return None
    try:
        return float(x)
    except (TypeError, jax.errors.ConcretizationTypeError, jax.errors.TracerArrayConversionError):
        return None


class SampledSignal(eqx.Module):
    """Uniformly sampled signal ``values[i] = x(t0 + i dt)`` with ``values`` of shape ``(n, ch)``.

    ``sig(t)`` returns the ``(ch,)`` value at any (traced) ``t`` by linear interpolation
    (``kind="linear"``) or zero-order hold (``kind="zoh"``: the last sample at or before t).
    Outside ``[t0, t0 + (n-1) dt]`` the end values are held. A batch of signals (leading batch
    axis on ``values`` and, optionally, ``t0``/``dt``) vmaps like any pytree.
    """

    values: jax.Array
    t0: jax.Array
    dt: jax.Array
    kind: str = eqx.field(static=True, default="linear")
    # t0 and dt as Python floats when they were given as concrete numbers: lets the fixed-step
    # integrator see that the step grid is aligned with the samples (see ``local_to_step``).
    t0_static: float | None = eqx.field(static=True, default=None)
    dt_static: float | None = eqx.field(static=True, default=None)

    def __init__(self, t0, dt, values, kind: str = "linear"):
        if kind not in ("linear", "zoh"):
            raise ValueError(f"kind must be 'linear' or 'zoh', got {kind!r}")
        values = jnp.asarray(values)
        if values.ndim == 1:
            values = values[:, None]
        if values.ndim != 2:
            raise ValueError(f"values must have shape (n_samples, n_channels), got {values.shape}")
        if values.shape[0] < 2:
            raise ValueError(f"a sampled signal needs at least 2 samples, got {values.shape[0]}")
        try:
            dtc = float(dt)
        except (TypeError, jax.errors.ConcretizationTypeError, jax.errors.TracerArrayConversionError):
            dtc = None
        if dtc is not None and not (np.isfinite(dtc) and dtc > 0):
            raise ValueError(f"dt must be positive and finite, got {dt}")
        self.values = values
        self.t0 = jnp.asarray(t0, values.dtype)
        self.dt = jnp.asarray(dt, values.dtype)
        self.kind = kind
        self.t0_static = _static_float(t0)
        self.dt_static = dtc if _static_float(dt) is not None else None

    @property
    def n_samples(self) -> int:
        return self.values.shape[0]

    @property
    def t1(self):
        return self.t0 + (self.n_samples - 1) * self.dt

    def __call__(self, t):
        n = self.values.shape[0]
        s = (t - self.t0) / self.dt
        if self.kind == "zoh":
            # A small relative tolerance so that t on the grid (up to rounding) selects its sample.
            i = jnp.clip(jnp.floor(s + 1e-9), 0, n - 1).astype(jnp.int32)
            return self.values[i]
        s = jnp.clip(s, 0.0, n - 1.0)
        i = jnp.clip(jnp.floor(s), 0, n - 2).astype(jnp.int32)
        w = (s - i).astype(self.values.dtype)
        lo = jax.lax.dynamic_index_in_dim(self.values, i, keepdims=False)
        hi = jax.lax.dynamic_index_in_dim(self.values, i + 1, keepdims=False)
        return lo + w * (hi - lo)


def _clip01(s):
    """``clip(s, 0, 1)`` written as two selects (same values, NaN stays NaN).

    ``jnp.clip`` lowers to XLA's NaN-propagating ``maximum``/``minimum``, which XLA's CPU backend
    emits as ``llvm.maximum``/``llvm.minimum``; LLVM does not vectorise a loop containing them. The
    interpolation weight of a step is a scalar, but XLA fuses it into the loop over the paths of
    every row of the vector field that reads an input, and that loop then ran one path at a time
    (``docs/performance.md``). With selects the loop vectorises.
    """
    return jnp.where(s < 0.0, jnp.zeros_like(s), jnp.where(s > 1.0, jnp.ones_like(s), s))


class _StepSignal(eqx.Module):
    """A :class:`SampledSignal` restricted to one sample interval ``[t_left, t_left + dt]``.

    The fixed-step integrator substitutes it for the full signal during a step that coincides with
    a sample interval: the two samples are read once per step instead of once per stage (the
    strided gather of per-path samples is a large part of a step under ``vmap``). Values equal the
    full signal's on that interval, end holds included.
    """

    lo: jax.Array
    hi: jax.Array
    t_left: jax.Array
    dt: float = eqx.field(static=True)
    kind: str = eqx.field(static=True)

    def __call__(self, t):
        s = _clip01((t - self.t_left) / self.dt).astype(self.lo.dtype)
        if self.kind == "zoh":
            return jnp.where(s >= 1.0 - 1e-9, self.hi, self.lo)
        return self.lo + s * (self.hi - self.lo)


def local_to_step(args, t0_grid: float, dt: float, step_index):
    """Replace every grid-aligned :class:`SampledSignal` in ``args`` by its :class:`_StepSignal`.

    A signal qualifies when its sampling interval equals the step ``dt`` and its samples fall on
    the step grid ``t0_grid + i dt`` (both known as Python floats at trace time); others are left
    as they are.
    """

    def conv(leaf):
        if not isinstance(leaf, SampledSignal) or leaf.dt_static is None or leaf.t0_static is None:
            return leaf
        if abs(leaf.dt_static - dt) > 1e-12 * dt:
            return leaf
        offset = (t0_grid - leaf.t0_static) / dt
        if abs(offset - round(offset)) > 1e-9:
            return leaf
        n = leaf.values.shape[0]
        k = jnp.clip(step_index + int(round(offset)), 0, n - 2)
        lo = jax.lax.dynamic_index_in_dim(leaf.values, k, keepdims=False)
        hi = jax.lax.dynamic_index_in_dim(leaf.values, k + 1, keepdims=False)
        # Before the first sample the full signal holds values[0]: keep that with t_left's clip.
        t_left = leaf.t0_static + k.astype(leaf.values.dtype) * dt
        return _StepSignal(lo=lo, hi=hi, t_left=t_left, dt=dt, kind=leaf.kind)

    return jax.tree.map(conv, args, is_leaf=lambda x: isinstance(x, SampledSignal))
