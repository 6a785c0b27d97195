"""Noise as a pure function of (key, path index, sample index), and sensor input effects.

Every random number a Monte-Carlo path uses is drawn here, so that a path's result depends only on
``(key, path index, model)``: never on the chunk size, the number of devices, or the order in
which paths run.

Layout of the draw.  Samples are drawn in fixed blocks of ``BLOCK_SIZE`` samples, one channel at a
time.  The key of block ``b`` of channel ``c`` of path ``p`` is::

    fold_in(fold_in(fold_in(key, p), c), b)

and the block holds samples ``b * BLOCK_SIZE ... (b + 1) * BLOCK_SIZE - 1`` of that channel.
Hence sample ``i`` of channel ``c`` depends only on ``(key, p, c, i)`` and the dtype: asking for
more samples, or more channels, never changes the ones already drawn.  Drawing per path in blocks
costs almost nothing next to the integration, whereas drawing one sample per integrator step costs
as much as the integration itself (measured in ``../shared/FIELD-NOTES.md``).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

__all__ = [
    "BLOCK_SIZE",
    "path_normals",
    "white_noise",
    "apply_input_effects",
    "remove_input_effects",
]

#: Number of samples drawn per key (part of the reproducibility contract: changing it changes
#: every noise sample, so it is fixed).
BLOCK_SIZE = 256


def _check_static_int(name: str, value, minimum: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be a Python int (it fixes an array shape), got {value!r}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def _check_path_index(path_index):
    """Check a concrete path index; a traced one is taken as it is (checked by its caller)."""
    if isinstance(path_index, jax.core.Tracer):
        return path_index
    arr = np.asarray(path_index)
    if arr.shape != () or not np.issubdtype(arr.dtype, np.integer):
        raise TypeError(f"path_index must be an integer scalar, got {path_index!r}")
    if arr < 0:
        raise ValueError(f"path_index must be >= 0, got {int(arr)}")
    return path_index


def path_normals(key, path_index, n_samples: int, n_channels: int, dtype=None) -> jax.Array:
    """Standard normal samples of one Monte-Carlo path.

    Args:
        key: a JAX PRNG key (``jax.random.key(seed)`` or ``jax.random.PRNGKey(seed)``), the seed of
            the whole study.
        path_index: integer scalar, the path's index (may be traced, e.g. under ``vmap``).
        n_samples: number of samples (static).
        n_channels: number of independent channels (static).
        dtype: floating dtype; None gives JAX's default float (float64 with x64 enabled).

    Returns:
        ``(n_samples, n_channels)`` i.i.d. standard normals.  Entry ``[i, c]`` is a pure function
        of ``(key, path_index, c, i)`` and the dtype (see the module docstring for the layout), so
        it does not depend on ``n_samples``, ``n_channels``, chunking, devices or path order.
    """
    n_samples = _check_static_int("n_samples", n_samples, 0)
    n_channels = _check_static_int("n_channels", n_channels, 0)
    path_index = _check_path_index(path_index)
    if dtype is None:
        dtype = jnp.zeros(()).dtype  # the default float: float32, or float64 under x64
    if not jnp.issubdtype(dtype, jnp.floating):
        raise TypeError(f"dtype must be a floating dtype, got {dtype}")
    if n_samples == 0 or n_channels == 0:
        return jnp.zeros((n_samples, n_channels), dtype)
    return _path_normals(key, path_index, n_samples, n_channels, jnp.dtype(dtype))


@functools.partial(jax.jit, static_argnums=(2, 3, 4))
def _path_normals(key, path_index, n_samples, n_channels, dtype):
    # jitted so that eager calls compile once per shape instead of dispatching op by op;
    # under an outer jit/vmap it is simply inlined.
    n_blocks = -(-n_samples // BLOCK_SIZE)
    path_key = jax.random.fold_in(key, path_index)

    def channel(c):
        channel_key = jax.random.fold_in(path_key, c)

        def block(b):
            return jax.random.normal(jax.random.fold_in(channel_key, b), (BLOCK_SIZE,), dtype)

        return jax.vmap(block)(jnp.arange(n_blocks, dtype=jnp.uint32)).reshape(-1)

    z = jax.vmap(channel)(jnp.arange(n_channels, dtype=jnp.uint32))  # (n_channels, n_blocks * B)
    return z[:, :n_samples].T


def white_noise(key, path_index, n_samples: int, sigma, dtype=None) -> jax.Array:
    """Gaussian white noise of standard deviation ``sigma[c]`` on channel ``c`` of one path.

    Args:
        key, path_index, n_samples, dtype: as in :func:`path_normals`.
        sigma: ``(n_channels,)`` non-negative standard deviations; a zero gives a noise-free
            channel (exact zeros).  A scalar means one channel.

    Returns:
        ``(n_samples, n_channels)`` samples ``sigma[c] * path_normals(...)[:, c]``.
    """
    sigma = jnp.asarray(sigma)
    if sigma.ndim > 1:
        raise ValueError(f"sigma must be a scalar or 1-D (one value per channel), got shape {sigma.shape}")
    if not isinstance(sigma, jax.core.Tracer):
        s = np.asarray(sigma)
        if not np.all(np.isfinite(s)) or np.any(s < 0):
            raise ValueError(f"sigma must be finite and >= 0, got {s}")
    sigma = jnp.atleast_1d(sigma)
    if dtype is None:
        dtype = jnp.result_type(sigma.dtype, jnp.zeros(()).dtype)
    z = path_normals(key, path_index, n_samples, sigma.shape[0], dtype)
    sigma = sigma.astype(dtype)
    # where(): a noise-free channel is exactly zero (0 * z would give -0.0 for negative z).
    return jnp.where(sigma == 0, jnp.zeros((), dtype), sigma * z)


def _shift_linear(values: jax.Array, shift_samples: jax.Array) -> jax.Array:
    """``out[k, c] = values(k - shift_samples[c], c)`` by linear interpolation between samples,
    holding the first/last sample outside the record."""
    n = values.shape[0]
    if n == 1:
        return values
    k = jnp.arange(n, dtype=values.dtype)[:, None]
    s = jnp.clip(k - shift_samples[None, :], 0.0, n - 1.0)
    i0 = jnp.clip(jnp.floor(s), 0, n - 2).astype(jnp.int32)
    frac = s - i0
    v0 = jnp.take_along_axis(values, i0, axis=0)
    v1 = jnp.take_along_axis(values, i0 + 1, axis=0)
    return v0 + frac * (v1 - v0)


def _prepare_effects(values, dt, offset, scale, delay):
    values = jnp.asarray(values)
    if values.ndim not in (1, 2):
        raise ValueError(f"values must be (n_samples,) or (n_samples, n_channels), got shape {values.shape}")
    if values.shape[0] < 1:
        raise ValueError("values must hold at least one sample")
    one_d = values.ndim == 1
    if one_d:
        values = values[:, None]
    if not jnp.issubdtype(values.dtype, jnp.floating):
        values = values.astype(jnp.zeros(()).dtype)
    n_ch = values.shape[1]
    dtype = values.dtype
    if not isinstance(dt, jax.core.Tracer) and not (np.ndim(dt) == 0 and float(dt) > 0):
        raise ValueError(f"dt must be a positive scalar, got {dt!r}")

    def per_channel(name, x):
        x = jnp.asarray(x, dtype)
        if x.ndim > 1 or (x.ndim == 1 and x.shape[0] not in (1, n_ch)):
            raise ValueError(
                f"{name} must be a scalar or have one value per channel ({n_ch}), got shape {x.shape}"
            )
        return jnp.broadcast_to(x, (n_ch,))

    return (values, one_d, jnp.asarray(dt, dtype), per_channel("offset", offset),
            per_channel("scale", scale), per_channel("delay", delay))


def apply_input_effects(values, dt, offset=0.0, scale=1.0, delay=0.0) -> jax.Array:
    """What a sensor with offset, scale error and delay reports for a sampled true signal.

    Implements the input effects of ``docs/measured-data.md`` per channel::

        measured(t) = scale * true(t - delay) + offset

    on the sample grid ``t_k = t0 + k * dt``.  A delay that is not a whole number of samples is
    applied by linear interpolation between neighbouring samples; outside the record the first
    (last) sample is held.  Positive delay: the channel lags.

    Args:
        values: ``(n_samples, n_channels)`` (or ``(n_samples,)``) true signal.
        dt: sample spacing [s], > 0.
        offset, scale, delay: scalars or one value per channel (delay in seconds, any sign).

    Returns:
        The measured signal, same shape as ``values``.  Pure and jit/vmap safe in all arguments.
    """
    values, one_d, dt, offset, scale, delay = _prepare_effects(values, dt, offset, scale, delay)
    out = scale * _shift_linear(values, delay / dt) + offset
    return out[:, 0] if one_d else out


def remove_input_effects(values, dt, offset=0.0, scale=1.0, delay=0.0) -> jax.Array:
    """Inverse of :func:`apply_input_effects`: ``true(t) = (measured(t + delay) - offset) / scale``.

    This is the correction of ``docs/measured-data.md`` (``extended_model.corrections``).  Exact
    inverse where the delay is a whole number of samples and away from the record's ends; for a
    fractional delay it inverts up to the error of linear interpolation.
    """
    values, one_d, dt, offset, scale, delay = _prepare_effects(values, dt, offset, scale, delay)
    out = (_shift_linear(values, -delay / dt) - offset) / scale
    return out[:, 0] if one_d else out
