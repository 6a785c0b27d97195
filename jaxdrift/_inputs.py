"""Sampled input signals (measured data) usable by the adaptive integrator at any time t."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

__all__ = ["SampledSignal"]


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
