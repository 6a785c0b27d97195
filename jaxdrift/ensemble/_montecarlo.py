"""The Monte-Carlo runner: chunked, sharded, vmapped paths with streaming ensemble statistics.

A study is ``n_paths`` calls of a user function ``path_fn(key, path_index, model)`` that returns
the path's outputs at the save times, ``ys`` of shape ``(n_save, n_out)``, and an int32 result code
(0 = success).  The runner

- processes the paths in chunks of ``chunk_size`` (a host loop over one jitted, vmapped function,
  compiled once: the last chunk is padded to the chunk size and the padding masked out), so that
  memory is bounded by the chunk, not by ``n_paths``;
- splits each chunk's path axis across the devices of a 1-D mesh with ``jax.shard_map`` (every
  device runs its share of paths on its own, so one device's slow adaptive path does not hold up
  the others; there is no communication inside a chunk);
- reduces every device's share to (count, mean, sum of squared deviations) on the device with a
  two-pass formula and merges those on the host in float64 with Chan et al.'s parallel update,
  which is stable for data with a large mean;
- keeps per path only the result code and the drift-off time, plus the outputs at the save times
  when exact quantiles or the paths themselves are asked for.

Reproducibility: the runner hands ``path_fn`` nothing but ``(key, path_index, model_i)``; a path's
outputs therefore do not depend on chunk size, device count or order, as long as ``path_fn`` draws
its noise from ``(key, path_index)`` (use :func:`jaxdrift.path_normals`).  The merged statistics
depend on the grouping of paths into chunks and devices only through floating-point rounding
(tested to 1e-12 relative).

Multi-host: with ``jax.distributed.initialize()`` called first, ``jax.devices()`` lists the devices
of all processes; the mesh spans them, each process feeds only its own devices, and every process
receives the full result (see ``docs/monte-carlo.md``).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

__all__ = ["MCResult", "monte_carlo", "DEFAULT_MAX_MEMORY_BYTES"]

#: Default device-memory budget per device for one chunk when ``chunk_size`` is None.
DEFAULT_MAX_MEMORY_BYTES = 1 << 30

_AXIS = "paths"
_PROBE_PATHS_PER_DEVICE = 64
# chunk_size=None: at most about 1/_MIN_CHUNKS of the paths per chunk, so the progress bar moves,
# but never fewer than _MIN_PATHS_PER_DEVICE per device (keeps the vmapped batches efficient).
_MIN_CHUNKS = 10
_MIN_PATHS_PER_DEVICE = 512


@dataclasses.dataclass(frozen=True, eq=False)
class MCResult:
    """Ensemble statistics of a Monte-Carlo study (host numpy arrays).

    Statistics at each save time are over the successful paths (``result == 0``); ``count`` says
    how many.  Shapes: ``n_save`` save times, ``n_out`` outputs per path.

    Attributes:
        save_ts: ``(n_save,)`` the save times.
        mean: ``(n_save, n_out)`` ensemble mean (float64).
        var: ``(n_save, n_out)`` unbiased ensemble variance (ddof = 1; NaN for count < 2).
        count: number of successful paths in the statistics.
        quantile_levels: the requested quantile levels (tuple of floats in [0, 1]).
        quantiles: ``(len(quantile_levels), n_save, n_out)`` exact empirical quantiles
            (numpy's default, linear interpolation), or None when none were requested.
        drift_off_time: ``(n_paths,)`` first save time where ``|ys[:, channel] - reference|``
            exceeded the threshold (or was not finite); ``inf`` if never.  None without a
            threshold.
        drift_threshold, drift_channel: the drift-off criterion used (None without a threshold).
        result: ``(n_paths,)`` int32 result code of every path.
        ys: ``(n_paths, n_save, n_out)`` every path's outputs, when ``keep_paths=True``.
        chunk_size: paths per chunk actually used; n_devices: devices the chunk was split over.
    """

    save_ts: np.ndarray
    mean: np.ndarray
    var: np.ndarray
    count: int
    quantile_levels: tuple[float, ...]
    quantiles: np.ndarray | None
    drift_off_time: np.ndarray | None
    drift_threshold: float | None
    drift_channel: int | None
    result: np.ndarray
    ys: np.ndarray | None
    chunk_size: int
    n_devices: int

    @property
    def n_paths(self) -> int:
        return int(self.result.shape[0])

    @property
    def n_failed(self) -> int:
        return int(np.count_nonzero(self.result != 0))

    @property
    def std(self) -> np.ndarray:
        return np.sqrt(self.var)

    def quantile(self, level: float) -> np.ndarray:
        """The ``(n_save, n_out)`` quantile at one of the requested levels."""
        if self.quantiles is None or float(level) not in self.quantile_levels:
            raise KeyError(f"quantile level {level} was not requested (have {self.quantile_levels})")
        return self.quantiles[self.quantile_levels.index(float(level))]

    def drifted_fraction(self) -> np.ndarray:
        """``(n_save,)`` fraction of all paths that have drifted off by each save time."""
        if self.drift_off_time is None:
            raise ValueError("no drift_threshold was given to monte_carlo")
        return np.mean(self.drift_off_time[:, None] <= self.save_ts[None, :], axis=0)


# --- argument checks ---------------------------------------------------------------------------


def _check_positive_int(name, value):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an int, got {value!r}")
    if value <= 0:
        raise ValueError(f"{name} must be > 0, got {value}")
    return int(value)


def _check_save_ts(save_ts):
    ts = np.asarray(save_ts, dtype=np.float64)
    if ts.ndim != 1 or ts.shape[0] < 1:
        raise ValueError(f"save_ts must be a non-empty 1-D array of times, got shape {ts.shape}")
    if not np.all(np.isfinite(ts)):
        raise ValueError("save_ts must be finite")
    if ts.shape[0] > 1 and not np.all(np.diff(ts) > 0):
        bad = int(np.argmax(~(np.diff(ts) > 0)))
        raise ValueError(
            f"save_ts must be strictly increasing: save_ts[{bad}] = {float(ts[bad])} >= "
            f"save_ts[{bad + 1}] = {float(ts[bad + 1])}"
        )
    return ts


def _split_models(models, n_paths):
    """(array part as numpy with leading axis n_paths, static part); checks the batch axis."""
    if models is None:
        return None, None
    dyn, static = eqx.partition(models, eqx.is_array)
    leaves = jax.tree_util.tree_leaves_with_path(dyn)
    if not leaves:
        raise ValueError("models has no array leaves: pass a batch with a leading axis of length n_paths")
    for path, leaf in leaves:
        if leaf.ndim == 0 or leaf.shape[0] != n_paths:
            raise ValueError(
                f"models{jax.tree_util.keystr(path)} has shape {tuple(leaf.shape)}: every array in the "
                f"models batch needs a leading axis of length n_paths = {n_paths}"
            )
    dyn = jax.tree_util.tree_map(np.asarray, dyn)
    return dyn, static


def _split_key(key):
    """Key -> (uint32 key data, impl or None for raw keys) so it can be placed on any mesh."""
    key = jnp.asarray(key) if not isinstance(key, jax.Array) else key
    if jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
        if key.shape != ():
            raise ValueError(f"key must be a single PRNG key, got a key array of shape {key.shape}")
        return np.asarray(jax.random.key_data(key)), jax.random.key_impl(key)
    if key.dtype != jnp.uint32 or key.ndim != 1:
        raise ValueError(f"key must be a PRNG key (jax.random.key(seed)), got {key.dtype}{key.shape}")
    return np.asarray(key), None


# --- host <-> device ---------------------------------------------------------------------------


def _put(x, sharding: NamedSharding) -> jax.Array:
    """A global array from an array that every process holds in full (multi-host safe)."""
    if jax.process_count() == 1:
        return jax.device_put(x, sharding)
    x = np.asarray(x)
    return jax.make_array_from_callback(x.shape, sharding, lambda index: x[index])


def _fetch(x: jax.Array) -> np.ndarray:
    """A (sharded) global array as a host numpy array on every process."""
    if jax.process_count() == 1:
        return np.asarray(x)
    from jax.experimental import multihost_utils

    return np.asarray(multihost_utils.process_allgather(x, tiled=True))


# --- the chunk function ------------------------------------------------------------------------


def _chunk_fn(pf_static, mesh, key_impl, models_static, has_models, channel, want_paths):
    """The jitted chunk function, cached across calls when its static parts are hashable.

    Calling ``monte_carlo`` again with the same path function, models structure, mesh and chunk
    shape then reuses the compiled executable (jax.jit's own cache) instead of compiling anew.
    """
    args = (pf_static, mesh, key_impl, models_static, has_models, channel, want_paths)
    try:
        hash(args)
    except TypeError:
        return _build_chunk_fn(*args)
    return _cached_build_chunk_fn(*args)


def _build_chunk_fn(pf_static, mesh, key_impl, models_static, has_models, channel, want_paths):
    """jit(shard_map(vmap(path_fn))) with per-device statistics; compiled once per chunk shape."""

    def local(pf_dyn, key_data, idx, mask, models_dyn, reference, threshold):
        fn = eqx.combine(pf_dyn, pf_static)
        key = key_data if key_impl is None else jax.random.wrap_key_data(key_data, impl=key_impl)

        def one(i, m):
            model = eqx.combine(m, models_static) if has_models else None
            ys, code = fn(key, i, model)
            return jnp.asarray(ys), jnp.asarray(code, jnp.int32)

        ys, code = jax.vmap(one)(idx, models_dyn)  # (m, n_save, n_out), (m,)
        ok = mask & (code == 0)
        okb = ok[:, None, None]
        n = jnp.sum(ok)
        # Two-pass within the device's share (stable); where() keeps NaNs of failed paths out.
        mean = jnp.sum(jnp.where(okb, ys, 0), axis=0) / jnp.maximum(n, 1).astype(ys.dtype)
        m2 = jnp.sum(jnp.where(okb, jnp.square(ys - mean), 0), axis=0)
        outs = {"n": n[None], "mean": mean[None], "m2": m2[None], "code": code}
        if threshold is not None:
            err = jnp.abs(ys[:, :, channel] - reference[None, :])
            exceeded = ~(err <= threshold)  # NaN / inf counts as drifted off
            first = jnp.argmax(exceeded, axis=1).astype(jnp.int32)
            outs["first"] = jnp.where(jnp.any(exceeded, axis=1), first, -1)
        if want_paths:
            outs["ys"] = ys
        return outs

    sharded = P(_AXIS)
    fn = jax.shard_map(
        local,
        mesh=mesh,
        in_specs=(P(), P(), sharded, sharded, sharded, P(), P()),
        out_specs=sharded,
        # No collectives inside: every device runs its paths on its own.  Without this, a user's
        # scan/while_loop whose initial carry is a constant fails shard_map's varying-axis check.
        check_vma=False,
    )
    return jax.jit(fn)


_cached_build_chunk_fn = functools.lru_cache(maxsize=32)(_build_chunk_fn)


def _chan_merge(acc, n_b, mean_b, m2_b):
    """Chan, Golub & LeVeque's pairwise update of (count, mean, M2) in float64."""
    n_a, mean_a, m2_a = acc
    if n_b == 0:
        return acc
    if n_a == 0:
        return n_b, mean_b, m2_b
    n = n_a + n_b
    delta = mean_b - mean_a
    return n, mean_a + delta * (n_b / n), m2_a + m2_b + np.square(delta) * (n_a * n_b / n)


# --- the runner ---------------------------------------------------------------------------------


def monte_carlo(
    path_fn: Callable[[Any, Any, Any], tuple[Any, Any]],
    n_paths: int,
    *,
    key,
    save_ts,
    models=None,
    chunk_size: int | None = None,
    quantiles: Sequence[float] = (),
    drift_threshold: float | None = None,
    drift_reference=None,
    drift_channel: int = 0,
    keep_paths: bool = False,
    progress: bool = True,
    devices: Sequence[jax.Device] | None = None,
    max_memory_bytes: int = DEFAULT_MAX_MEMORY_BYTES,
) -> MCResult:
    """Run ``n_paths`` Monte-Carlo paths and return their ensemble statistics.

    Args:
        path_fn: ``path_fn(key, path_index, model) -> (ys, result_code)`` with ``ys`` of shape
            ``(len(save_ts), n_out)`` and an int32 scalar result code (0 = success).  Pure and
            vmappable; ``path_index`` is a traced int32 scalar, ``model`` is one model of the batch
            (None without ``models``).  Draw the path's noise with
            ``jaxdrift.path_normals(key, path_index, ...)`` so the path does not depend on how the
            study is chunked.  ``path_fn`` may be a function or an ``eqx.Module``/``eqx.Partial``
            (its arrays are passed to the compiled chunk as arguments, not baked in).
        n_paths: number of paths (> 0).
        key: the study's PRNG key (``jax.random.key(seed)`` or ``jax.random.PRNGKey(seed)``),
            handed to every path unchanged.
        save_ts: ``(n_save,)`` strictly increasing save times (used for shapes and drift-off times;
            ``path_fn`` saves at them itself).
        models: None (every path gets ``model=None``) or a batch of models: a pytree (for example an
            ``eqx.Module`` built with ``eqx.filter_vmap``) whose array leaves all have a leading
            axis of length ``n_paths``; path ``i`` gets the model with every array leaf indexed at
            ``i``.  Shared data belongs in ``path_fn``.
        chunk_size: paths per chunk, rounded up to a multiple of the device count and capped at
            ``n_paths`` (rounded up likewise).  None picks the largest chunk whose compiled memory
            (measured with XLA's memory analysis on a probe compilation) fits
            ``max_memory_bytes`` per device, and at most about a tenth of the paths (but not
            fewer than 512 per device) so that the progress bar moves.
        quantiles: levels in [0, 1] of exact empirical quantiles at every save time.  Exact
            quantiles need every path's outputs on the host: ``n_paths * n_save * n_out`` values.
        drift_threshold: if given, each path's drift-off time is the first save time where
            ``|ys[:, drift_channel] - drift_reference|`` exceeds it (or is not finite).
        drift_reference: ``(n_save,)`` reference for the drift channel, or ``(n_save, n_out)`` (the
            drift channel's column is used); None means zero (the output is itself an error).
        drift_channel: index of the output compared with the reference.
        keep_paths: return every path's outputs (``MCResult.ys``; host memory as for quantiles).
        progress: show a tqdm progress bar (process 0 only).
        devices: devices to split each chunk over; None means all of ``jax.devices()`` (all
            processes' devices under ``jax.distributed``).  The same on every process.
        max_memory_bytes: memory budget per device for one chunk when ``chunk_size`` is None.

    Returns:
        An :class:`MCResult`.  Statistics are over paths with result code 0; a ``RuntimeWarning``
        says how many paths failed.
    """
    n_paths = _check_positive_int("n_paths", n_paths)
    ts = _check_save_ts(save_ts)
    n_save = ts.shape[0]
    key_data, key_impl = _split_key(key)
    models_dyn, models_static = _split_models(models, n_paths)
    has_models = models is not None
    levels, chunk_size, max_memory_bytes = _check_options(quantiles, chunk_size, max_memory_bytes,
                                                         drift_threshold, drift_reference)
    devices = list(jax.devices() if devices is None else devices)
    if not devices:
        raise ValueError("devices is empty")
    n_dev = len(devices)
    mesh = Mesh(np.array(devices), (_AXIS,))

    n_out, dtype = _path_output_shape(path_fn, key_data, key_impl, models_dyn, models_static, has_models,
                                      n_save)
    threshold, reference, channel = _drift_setup(drift_threshold, drift_reference, drift_channel, n_save,
                                                 n_out, dtype)
    want_paths = keep_paths or bool(levels)
    chunk_fn, chunk_args = _sharded_chunk_call(path_fn, mesh, key_data, key_impl, models_dyn,
                                               models_static, has_models, n_paths, channel, want_paths,
                                               reference, threshold)
    max_chunk = n_dev * -(-n_paths // n_dev)
    if chunk_size is None:
        chunk_size, compiled = _chunk_size_from_budget(chunk_fn, chunk_args, n_dev, max_chunk,
                                                       max_memory_bytes)
        if compiled is not None:  # the probe already compiled this chunk size: reuse it
            chunk_fn = compiled
    else:
        chunk_size = min(n_dev * -(-chunk_size // n_dev), max_chunk)

    acc, codes, firsts, paths = _stream_chunks(chunk_fn, chunk_args, chunk_size, n_paths, n_dev,
                                               (n_save, n_out), progress)

    count = acc[0]
    mean, var, result, ys_all, q, drift_off = _ensemble_statistics(acc, codes, firsts, paths, levels, ts,
                                                                    threshold, (n_save, n_out))
    n_failed = int(np.count_nonzero(result != 0))
    if n_failed:
        found = ", ".join(f"{int(c)}: {int(k)}" for c, k in zip(*np.unique(result[result != 0], return_counts=True)))
        warnings.warn(
            f"{n_failed} of {n_paths} Monte-Carlo paths failed (result code: count = {found}); "
            f"the statistics use the {count} successful paths",
            RuntimeWarning,
            stacklevel=2,
        )
    return MCResult(
        save_ts=ts,
        mean=mean,
        var=var,
        count=int(count),
        quantile_levels=levels,
        quantiles=q,
        drift_off_time=drift_off,
        drift_threshold=None if threshold is None else float(threshold),
        drift_channel=channel,
        result=result,
        ys=ys_all if keep_paths else None,
        chunk_size=chunk_size,
        n_devices=n_dev,
    )


def _ensemble_statistics(acc, codes, firsts, paths, levels, ts, threshold, out_shape):
    """From the merged ``acc = (count, mean, m2)`` and the per-chunk lists: mean and variance over the
    successful paths, result codes, the paths' outputs (or None), quantiles (or None) and drift-off
    times (or None)."""
    count, mean, m2 = acc
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, mean, np.nan)
        var = m2 / (count - 1) if count > 1 else np.full(out_shape, np.nan)
    result = np.concatenate(codes).astype(np.int32)
    ys_all = np.concatenate(paths) if paths else None
    q = None
    if levels:
        ok = ys_all[result == 0]
        if ok.shape[0] == 0:
            q = np.full((len(levels), *out_shape), np.nan)
        else:
            q = np.quantile(ok.astype(np.float64), levels, axis=0)
    drift_off = None
    if threshold is not None:
        first = np.concatenate(firsts)
        drift_off = np.where(first >= 0, ts[np.maximum(first, 0)], np.inf)
    return mean, var, result, ys_all, q, drift_off


def _check_options(quantiles, chunk_size, max_memory_bytes, drift_threshold, drift_reference):
    """Validate the scalar options; return the quantile levels, chunk size and memory budget."""
    levels = tuple(float(q) for q in np.atleast_1d(np.asarray(quantiles, dtype=np.float64)))
    if any(not (0.0 <= q <= 1.0) for q in levels):
        raise ValueError(f"quantiles must lie in [0, 1], got {levels}")
    max_memory_bytes = _check_positive_int("max_memory_bytes", max_memory_bytes)
    if chunk_size is not None:
        chunk_size = _check_positive_int("chunk_size", chunk_size)
    if drift_reference is not None and drift_threshold is None:
        raise ValueError("drift_reference was given without drift_threshold")
    return levels, chunk_size, max_memory_bytes


def _path_output_shape(path_fn, key_data, key_impl, models_dyn, models_static, has_models, n_save):
    """Shapes of one path's outputs (``jax.eval_shape``), checked before anything is compiled;
    returns ``(n_out, dtype)``."""
    model0 = None
    if has_models:
        model0 = eqx.combine(jax.tree_util.tree_map(lambda x: x[0], models_dyn), models_static)
    key0 = key_data if key_impl is None else jax.random.wrap_key_data(key_data, impl=key_impl)
    try:
        out_shape = jax.eval_shape(lambda: path_fn(key0, jnp.int32(0), model0))
        ys_shape, code_shape = out_shape
    except (TypeError, ValueError) as err:
        if "cannot unpack" in str(err) or "too many values" in str(err) or "not enough values" in str(err):
            raise TypeError("path_fn must return a pair (ys, result_code)") from err
        raise
    if len(ys_shape.shape) != 2 or ys_shape.shape[0] != n_save:
        raise ValueError(
            f"path_fn returned ys of shape {ys_shape.shape}; expected (n_save, n_out) with "
            f"n_save = len(save_ts) = {n_save}"
        )
    if not jnp.issubdtype(ys_shape.dtype, jnp.floating):
        raise TypeError(f"path_fn must return floating ys, got {ys_shape.dtype}")
    if code_shape.shape != () or not jnp.issubdtype(code_shape.dtype, jnp.integer):
        raise TypeError(
            f"path_fn must return an integer scalar result code, got {code_shape.dtype}{code_shape.shape}"
        )
    return ys_shape.shape[1], ys_shape.dtype


def _drift_setup(drift_threshold, drift_reference, drift_channel, n_save, n_out, dtype):
    """Validate the drift-off options; return ``(threshold, reference, channel)`` (all None without
    a threshold), the threshold and reference in the outputs' dtype."""
    threshold = reference = None
    channel = None
    if drift_threshold is not None:
        threshold = float(drift_threshold)
        if not (math.isfinite(threshold) and threshold >= 0):
            raise ValueError(f"drift_threshold must be finite and >= 0, got {drift_threshold!r}")
        if isinstance(drift_channel, (bool, np.bool_)) or not isinstance(drift_channel, (int, np.integer)):
            raise TypeError(f"drift_channel must be an int, got {drift_channel!r}")
        if not -n_out <= drift_channel < n_out:
            raise ValueError(f"drift_channel {drift_channel} out of range for {n_out} outputs")
        channel = int(drift_channel) % n_out
        ref = np.zeros(n_save) if drift_reference is None else np.asarray(drift_reference, np.float64)
        if ref.shape == (n_save, n_out):
            ref = ref[:, channel]
        if ref.shape != (n_save,):
            raise ValueError(
                f"drift_reference must have shape ({n_save},) or ({n_save}, {n_out}), got {ref.shape}"
            )
        reference = ref.astype(dtype)
        threshold = np.asarray(threshold, dtype)
    return threshold, reference, channel


def _sharded_chunk_call(path_fn, mesh, key_data, key_impl, models_dyn, models_static, has_models, n_paths,
                        channel, want_paths, reference, threshold):
    """The compiled chunk function and ``chunk_args(start, size)``, which places one chunk's
    arguments on the mesh (path indices and models sharded, the rest replicated; the last chunk
    padded with repeats of the last path and masked)."""
    pf_dyn, pf_static = eqx.partition(path_fn, eqx.is_array)
    chunk_fn = _chunk_fn(pf_static, mesh, key_impl, models_static, has_models, channel, want_paths)
    replicated = NamedSharding(mesh, P())
    sharded = NamedSharding(mesh, P(_AXIS))
    rep_args = (
        jax.tree_util.tree_map(lambda x: _put(x, replicated), pf_dyn),
        _put(key_data, replicated),
    )
    tail_args = (
        None if reference is None else _put(reference, replicated),
        None if threshold is None else _put(threshold, replicated),
    )

    def chunk_args(start, size):
        idx = np.arange(start, start + size, dtype=np.int64)
        mask = idx < n_paths
        idx = np.minimum(idx, n_paths - 1).astype(np.int32)  # padding repeats the last path
        mdyn = None
        if has_models:
            mdyn = jax.tree_util.tree_map(lambda x: _put(x[idx], sharded), models_dyn)
        return (*rep_args, _put(idx, sharded), _put(mask, sharded), mdyn, *tail_args)

    return chunk_fn, chunk_args


def _stream_chunks(chunk_fn, chunk_args, chunk_size, n_paths, n_dev, out_shape, progress):
    """Run the chunks (each dispatched before the previous one is collected) and merge their
    statistics on the host in a fixed order; return ``(acc, codes, firsts, paths)`` with
    ``acc = (count, mean, m2)`` and per-chunk lists of result codes, drift-off indices and outputs."""
    acc = (0, np.zeros(out_shape), np.zeros(out_shape))
    codes, firsts, paths = [], [], []

    def collect(out, start):
        nonlocal acc
        out = {k: _fetch(v) for k, v in out.items()}
        real = slice(0, min(chunk_size, n_paths - start))
        for d in range(n_dev):  # fixed merge order: chunk by chunk, device by device
            acc = _chan_merge(acc, int(out["n"][d]), out["mean"][d].astype(np.float64),
                              out["m2"][d].astype(np.float64))
        codes.append(out["code"][real])
        if "first" in out:
            firsts.append(out["first"][real])
        if "ys" in out:
            paths.append(out["ys"][real])
        return real.stop

    from tqdm import tqdm

    bar = tqdm(total=n_paths, unit="path", disable=not progress or jax.process_index() != 0,
               desc="monte_carlo")
    try:
        pending = None
        for start in range(0, n_paths, chunk_size):
            out = chunk_fn(*chunk_args(start, chunk_size))  # dispatched asynchronously
            if pending is not None:
                bar.update(collect(*pending))
            pending = (out, start)
        bar.update(collect(*pending))
    finally:
        bar.close()
    return acc, codes, firsts, paths


def _chunk_size_from_budget(chunk_fn, chunk_args, n_dev, max_chunk, budget):
    """Largest chunk whose per-device memory fits ``budget``, measured on a probe compilation
    (and at most about a tenth of the paths, not below 512 per device).

    The probe compiles the chunk function for ``_PROBE_PATHS_PER_DEVICE`` paths per device and
    reads XLA's memory analysis (arguments + outputs + temporaries per device); memory per path is
    taken as that total over the probe's paths, which over-counts fixed costs (conservative).
    """
    probe = min(_PROBE_PATHS_PER_DEVICE * n_dev, max_chunk)
    compiled = chunk_fn.lower(*chunk_args(0, probe)).compile()
    stats = compiled.memory_analysis()
    if stats is None:  # backend without memory analysis: fall back to the probe size
        return probe, compiled
    per_device = (stats.argument_size_in_bytes + stats.output_size_in_bytes
                  + stats.temp_size_in_bytes)
    per_path = max(per_device / (probe // n_dev), 1.0)
    local = max(1, int(budget // per_path))
    progress_cap = max(_MIN_PATHS_PER_DEVICE, -(-max_chunk // (_MIN_CHUNKS * n_dev))) * n_dev
    size = min(local * n_dev, progress_cap, max_chunk)
    return size, (compiled if size == probe else None)
