"""Fast mode: fixed-step Dormand-Prince 5(4) in float32 with a compensated (Kahan) state update.

A Monte-Carlo drift study integrates tens of thousands of paths of a small model over tens of
thousands of steps. On CPU, float32 roughly doubles the SIMD width and makes ``sin``/``cos`` and
divisions much cheaper, but a plain float32 update ``y + h sum(b_i k_i)`` loses the increment's low
bits every step: over 60,000 steps of a state near ``0.05`` m (the static spring deflection) the
rounding walk reaches ``1e-5`` m and, through the free pitch and heave modes, biases the drift
itself. Kahan's compensated summation carries the lost low part ``c`` to the next step::

    d = h sum(b_i k_i) - c;   y_new = y + d;   c = (y_new - y) - d

so that the accumulated state error stays at the level of one rounding of ``y`` instead of growing
with the number of steps (tested in ``tests/test_variance.py``). The stages
``y + h sum(a_ij k_j)`` are evaluated in float32 without compensation: their errors are local.
Time is kept as ``t0 + i dt`` in the default float (float64 with x64 on), so sampled inputs are
interpolated at exact grid positions.

Saves are restricted to the step grid at a constant stride (the usual case: statistics every 0.1 s
with 1 ms steps); the loop is a scan over save intervals around a scan over steps, so no save
bookkeeping runs inside the step. The solver is per path and pure: ``vmap`` it (or hand it to
:func:`jaxdrift.monte_carlo`) for an ensemble. Whether the drift statistics of the fast mode agree
with float64 is measured, not assumed: see ``benchmarks/throughput.py`` and ``docs/performance.md``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jax.custom_batching import custom_vmap

from ._inputs import SampledSignal, _StepSignal, local_to_step
from ._solution import Solution
from ._tableau import DOPRI5

__all__ = ["solve_fixed_fast", "save_grid"]


def _py_float(name, v):
    try:
        out = float(np.asarray(v, dtype=np.float64))
    except (TypeError, jax.errors.ConcretizationTypeError, jax.errors.TracerArrayConversionError):
        raise ValueError(f"{name} must be a concrete number (it fixes the step grid), got a traced value") from None
    if not np.isfinite(out):
        raise ValueError(f"{name} must be finite, got {v}")
    return out


def save_grid(t0, t1, dt, saveat):
    """Check that ``saveat`` lies on the step grid ``t0 + i dt`` at a constant stride.

    Returns ``(n_steps, first, stride)``: the number of steps of ``[t0, t1]``, the step index of
    the first save time and the number of steps between saves. Raises ValueError otherwise.
    """
    t0, t1, dt = _py_float("t0", t0), _py_float("t1", t1), _py_float("dt", dt)
    if not dt > 0:
        raise ValueError(f"dt must be positive, got {dt}")
    if not t1 > t0:
        raise ValueError(f"t1 must be greater than t0, got t0={t0}, t1={t1}")
    n_real = (t1 - t0) / dt
    n_steps = int(round(n_real))
    if n_steps < 1 or abs(n_real - n_steps) > 1e-6 * max(1.0, n_real):
        raise ValueError(f"(t1 - t0) / dt = {n_real} must be a whole number of steps in fast mode")
    try:
        ts = np.asarray(saveat, dtype=np.float64)
    except (TypeError, jax.errors.ConcretizationTypeError, jax.errors.TracerArrayConversionError):
        raise ValueError("saveat must be concrete in fast mode (it fixes the loop structure)") from None
    if ts.ndim != 1 or ts.size == 0:
        raise ValueError(f"saveat must be a non-empty 1-D array, got shape {ts.shape}")
    k_real = (ts - t0) / dt
    k = np.round(k_real).astype(np.int64)
    if np.any(np.abs(k_real - k) > 1e-6 * np.maximum(1.0, np.abs(k_real))):
        bad = int(np.argmax(np.abs(k_real - k)))
        raise ValueError(f"saveat[{bad}] = {ts[bad]} is not on the step grid t0 + i dt (fast mode saves on the grid)")
    if k[0] < 0 or k[-1] > n_steps:
        raise ValueError(f"saveat must lie in [t0, t1] = [{t0}, {t1}]")
    strides = np.diff(k)
    if strides.size and (np.any(strides != strides[0]) or strides[0] <= 0):
        raise ValueError("fast mode needs equally spaced, increasing save times")
    stride = int(strides[0]) if strides.size else 1
    return n_steps, int(k[0]), stride


def solve_fixed_fast(
    f: Callable[[Any, jax.Array, Any], jax.Array],
    y0,
    t0,
    t1,
    *,
    dt,
    saveat,
    args: Any = None,
    inputs=None,
    dtype=jnp.float32,
    compensated: bool = True,
    unroll: int = 1,
) -> Solution:
    """Fixed-step DOPRI5 of ``y' = f(t, y, args)`` in ``dtype`` with an optional Kahan update.

    Same call as the fixed-step mode of :func:`jaxdrift.solve_ode` (``dt`` given), except that the
    save times must lie on the step grid ``t0 + i dt`` at a constant stride (no dense output) and
    ``(t1 - t0) / dt`` must be whole. ``f`` is evaluated on ``dtype`` states; its output is cast to
    ``dtype``. ``args`` (e.g. a :class:`jaxdrift.SampledSignal` of float32 samples) is passed
    through untouched.

    Args:
        inputs: optional ``(n_steps + 1, m)`` input samples on the step grid ``t0 + i dt``. Then the
            vector field is called as ``f(t, y, u, args)`` with ``u`` linear between the samples
            (``u_i + c (u_{i+1} - u_i)`` at the stage ``t_i + c dt``: the values a
            :class:`jaxdrift.SampledSignal` of the same samples gives), and each step reads its two
            samples once instead of interpolating at every stage.
        dtype: state dtype (float32 for the fast mode; float64 gives the plain solver with the
            same loop structure, useful as a reference).
        compensated: Kahan-compensated summation of the state update.
        unroll: steps per iteration of the compiled loop (``lax.scan``'s ``unroll``). Default 1:
            with the step's input samples carried from the previous step (``_CARRY_STEP_ARGS``),
            1 measured 56 against 115 CPU ns per path-step for 5 (half-car, float32, 256 paths,
            ``docs/performance.md``): inside an unrolled iteration XLA fuses the
            counter-dependent input reads back into the vector field's kernels, which then do not
            vectorise. (Before that change 5 was faster than 1.)

    Returns:
        A :class:`jaxdrift.Solution` (``ys`` in ``dtype``; ``result`` always 0).
    """
    n_steps, first, stride = save_grid(t0, t1, dt, saveat)
    t0f, dtf = _py_float("t0", t0), _py_float("dt", dt)
    ts_np = np.asarray(saveat, dtype=np.float64)
    n_save = ts_np.size
    dtype = jnp.dtype(dtype)
    if not jnp.issubdtype(dtype, jnp.floating):
        raise TypeError(f"dtype must be floating, got {dtype}")
    y0 = jnp.asarray(y0).astype(dtype)
    if y0.ndim != 1:
        raise ValueError(f"y0 must be a 1-D state vector, got shape {y0.shape}")
    tdt = jnp.result_type(float)  # the default float: float64 with x64 on
    if inputs is not None:
        inputs = jnp.asarray(inputs).astype(dtype)
        if inputs.ndim != 2 or inputs.shape[0] != n_steps + 1:
            raise ValueError(f"inputs must have shape (n_steps + 1, m) = ({n_steps + 1}, m), got {inputs.shape}")

        def g(t, y, u, a):
            return jnp.asarray(f(t, y, u, a)).astype(dtype)
    else:

        def g(t, y, u, a):
            return jnp.asarray(f(t, y, a)).astype(dtype)

    u_ex = None if inputs is None else inputs[0]
    # The vector field sees the args of one step: grid-aligned signals as their two samples.
    step_args_ex = local_to_step(args, t0f, dtf, jnp.asarray(0, jnp.int32))
    k_ex = jax.eval_shape(g, jnp.asarray(t0f, tdt), y0, u_ex, step_args_ex)
    if k_ex.shape != y0.shape:
        raise ValueError(f"the vector field returned shape {k_ex.shape}, expected {y0.shape}")
    # Closed-over arrays (possibly batch tracers of an enclosing vmap) become explicit arguments,
    # so that the batching rule sees which of them are batched.
    g_conv, consts = jax.closure_convert(g, jnp.asarray(t0f, tdt), y0, u_ex, step_args_ex)
    cfg = _Loop(n_steps=n_steps, first=first, stride=stride, n_save=n_save, t0=t0f, dt=dtf, dtype=dtype,
                tdt=tdt, compensated=compensated, unroll=unroll)
    ys = _solve(g_conv, cfg, y0, inputs, args, tuple(consts))
    zero = jnp.asarray(0, jnp.int32)
    return Solution(
        ts=jnp.asarray(ts_np, tdt),
        ys=ys,
        result=zero,
        num_accepted=jnp.asarray(first + stride * (n_save - 1), jnp.int32),
        num_rejected=zero,
    )


class _Loop(NamedTuple):
    n_steps: int
    first: int
    stride: int
    n_save: int
    t0: float
    dt: float
    dtype: Any
    tdt: Any
    compensated: bool
    unroll: int


#: Carry each step's time and grid-aligned input samples from the previous step (True) instead of
#: computing them from the step counter inside the step (False: the former loop, kept for the A/B benchmark).
#: XLA's CPU backend fuses the counter-dependent slice and interpolation weight into every row of
#: the vector field that reads an input, and loads the counter there without the invariance
#: marking its other operands get; LLVM then left those loops unvectorised (one path at a time).
_CARRY_STEP_ARGS = True

#: Under vmap, run the batched loop on (n, paths) arrays (True) or let vmap batch the per-path
#: loop, paths first (False: the former layout, kept for benchmarks/experiments/engine_layouts.py).
_PATHS_LAST = True


def _solve(g, cfg, y0, inputs, args, consts):
    """The saved states ``(n_save, n)``; paths last and contiguous under ``vmap``.

    Evaluation runs the per-path loop or, under ``vmap``, the batched loop on ``(n, paths)``
    arrays (``custom_vmap``). ``custom_vmap`` has no reverse-mode rule, so derivatives are taken
    through the per-path loop (``custom_jvp``), which ``jax.grad`` can transpose.
    """

    def plain(y0, inputs, args, consts):
        return _loop(lambda t, y, u, a: g(t, y, u, a, *consts), cfg, y0, inputs,
                     lambda i: local_to_step(args, cfg.t0, cfg.dt, i))

    @custom_vmap
    def fast(y0, inputs, args, consts):
        return plain(y0, inputs, args, consts)

    @fast.def_vmap
    def fast_batched(axis_size, in_batched, y0, inputs, args, consts):
        return _batched(g, cfg, axis_size, in_batched, y0, inputs, args, consts), True

    if not _PATHS_LAST:
        return plain(y0, inputs, args, consts)

    @jax.custom_jvp
    def solve(y0, inputs, args, consts):
        return fast(y0, inputs, args, consts)

    @solve.defjvp
    def solve_jvp(primals, tangents):
        return jax.jvp(plain, primals, tangents)

    return solve(y0, inputs, args, consts)


def _loop(F, cfg, y0, inputs, step_args_of):
    """The nested loop (saves around steps) for any state layout: ``y0`` is ``(n,)`` or ``(n, B)``.

    ``F(t, y, u, step_args)`` evaluates the vector field in that layout; ``inputs`` is None or the
    samples with the step index first; ``step_args_of(i)`` gives the ``args`` for step ``i``.
    """
    tab = DOPRI5
    a = [[float(v) for v in row] for row in tab.a]
    b = [float(v) for v in tab.b]
    c = [float(v) for v in tab.c]
    dtype, tdt, t0f, dtf = cfg.dtype, cfg.tdt, cfg.t0, cfg.dt
    h = jnp.asarray(dtf, dtype)
    s = len(c)

    def time_of(i):
        return jnp.asarray(t0f, tdt) + i.astype(tdt) * jnp.asarray(dtf, tdt)

    # With _CARRY_STEP_ARGS the step's time and args (for a grid-aligned signal: its two samples
    # and the interval's left time) are computed at the end of the previous step and carried, so
    # that no kernel of the step reads the step counter (see _CARRY_STEP_ARGS). The array leaves
    # travel in the carry; the others (vmap axes of the batched layout) are static.
    carry_args = _CARRY_STEP_ARGS
    i0 = jnp.asarray(0, jnp.int32)
    sa0 = step_args_of(i0)
    sa_leaves, sa_tree = jax.tree.flatten(sa0)

    def sa_arrays(sa):
        return tuple(x for x in jax.tree.leaves(sa) if isinstance(x, jax.Array))

    def sa_rebuild(arrays):
        it = iter(arrays)
        return jax.tree.unflatten(sa_tree, [next(it) if isinstance(x, jax.Array) else x for x in sa_leaves])

    def step(carry, u1):
        if carry_args:
            i, y, k0, comp, u0, t, arrays = carry
            sargs = sa_rebuild(arrays)
        else:
            i, y, k0, comp, u0 = carry
            t, sargs = time_of(i), step_args_of(i)
        du = None if inputs is None else u1 - u0
        ks = [k0]
        for j in range(1, s):
            dy = sum(a[j][m] * ks[m] for m in range(j) if a[j][m] != 0.0)
            u = None if inputs is None else u0 + jnp.asarray(c[j], dtype) * du
            ks.append(F(t + c[j] * dtf, y + h * dy, u, sargs))
        inc = h * sum(b[m] * ks[m] for m in range(s) if b[m] != 0.0)
        if cfg.compensated:
            d = inc - comp
            y_new = y + d
            comp = (y_new - y) - d
        else:
            y_new = y + inc
        t_new = time_of(i + 1)
        out = (i + 1, y_new, F(t_new, y_new, u1, sargs), comp, u1 if inputs is not None else u0)
        if carry_args:
            out += (t_new, sa_arrays(step_args_of(i + 1)))
        return out, None

    u_init = jnp.zeros((0,), dtype) if inputs is None else inputs[0]
    t_init = jnp.asarray(t0f, tdt)
    k_init = F(t_init, y0, None if inputs is None else u_init, sa0)
    carry = (i0, y0, k_init, jnp.zeros_like(y0), u_init)
    if carry_args:
        carry += (time_of(i0), sa_arrays(sa0))

    def xs_of(lo, n):
        # The "next sample" of each of n steps from step lo (None: no inputs, scan by length).
        return None if inputs is None else inputs[lo + 1 : lo + 1 + n]

    first, stride, n_save = cfg.first, cfg.stride, cfg.n_save
    if first:
        carry, _ = jax.lax.scan(step, carry, xs_of(0, first), length=first)

    def segment(carry, us):
        carry, _ = jax.lax.scan(step, carry, us, length=stride, unroll=min(cfg.unroll, stride))
        return carry, carry[1]

    if n_save == 1:
        return carry[1][None]
    seg_xs = xs_of(first, stride * (n_save - 1))
    if seg_xs is not None:
        seg_xs = seg_xs.reshape((n_save - 1, stride) + seg_xs.shape[1:])
    _, rest = jax.lax.scan(segment, carry, seg_xs, length=n_save - 1)
    return jnp.concatenate([carry[1][None], rest])


def _batched(g, cfg, B, in_batched, y0, inputs, args, consts):
    """The loop over a batch of ``B`` paths with the path axis last: state ``(n, B)``.

    Every stage then works on whole rows of ``B`` contiguous values, and grid-aligned
    :class:`SampledSignal` samples are transposed once to ``(samples, channels, B)`` so a step
    reads two contiguous rows. Returns ``(B, n_save, n)``.
    """
    b_y0, b_inputs, b_args, b_consts = in_batched
    n = y0.shape[-1]
    Y0 = jnp.moveaxis(y0, 0, -1) if b_y0 else jnp.broadcast_to(y0[:, None], (n, B))
    u_ax = None
    if inputs is not None and b_inputs:
        inputs, u_ax = jnp.moveaxis(inputs, 0, -1), 1  # (steps + 1, m, B)
    prepared, aligned = _prepare_signals(args, b_args, cfg)
    c_axes = tuple(0 if bc else None for bc in b_consts)

    def step_args_of(i):
        return _step_signals(args, prepared, aligned, b_args, cfg, i)

    def F(t, y, u, sargs_axes):
        sargs, axes = sargs_axes
        fb = jax.vmap(lambda y_, u_, a_, *c_: g(t, y_, u_, a_, *c_), in_axes=(1, u_ax, axes) + c_axes, out_axes=1)
        return fb(y, u, sargs, *consts)

    ys = _loop(F, cfg, Y0, inputs, step_args_of)  # (n_save, n, B)
    return jnp.moveaxis(ys, -1, 0)


def _is_signal(x):
    return isinstance(x, SampledSignal)


class _Pair:
    """Two results of one tree leaf (not a pytree, so ``args``' own tuples stay containers)."""

    def __init__(self, first, second):
        self.first, self.second = first, second


def _unzip(pairs):
    is_pair = lambda x: isinstance(x, _Pair)  # noqa: E731
    return (jax.tree.map(lambda p: p.first, pairs, is_leaf=is_pair),
            jax.tree.map(lambda p: p.second, pairs, is_leaf=is_pair))


def _prepare_signals(args, b_args, cfg):
    """Transpose the batched samples of grid-aligned signals to ``(samples, channels, B)`` once."""

    def prep(leaf, b):
        k = _aligned_offset(leaf, cfg) if _is_signal(leaf) else None
        if k is None:
            return _Pair(leaf, "off")
        values = jnp.moveaxis(leaf.values, 0, -1) if b.values else leaf.values
        return _Pair(values, k)

    return _unzip(jax.tree.map(prep, args, b_args, is_leaf=_is_signal))


def _aligned_offset(sig, cfg):
    """The sample index of the grid's ``t0`` if ``sig`` is sampled on the step grid, else None."""
    if sig.dt_static is None or sig.t0_static is None or abs(sig.dt_static - cfg.dt) > 1e-12 * cfg.dt:
        return None
    offset = (cfg.t0 - sig.t0_static) / cfg.dt
    return int(round(offset)) if abs(offset - round(offset)) <= 1e-9 else None


def _step_signals(args, prepared, aligned, b_args, cfg, i):
    """(args of step ``i``, their vmap axes): aligned signals become two rows of samples."""

    def conv(leaf, prep, off, b):
        if isinstance(off, str):  # any other leaf (or a signal off the grid): as it is
            return _Pair(leaf, jax.tree.map(lambda bb: 0 if bb else None, b))
        n = leaf.values.shape[-2]  # samples axis of the per-path (or shared) values
        k = jnp.clip(i + off, 0, n - 2)
        lo = jax.lax.dynamic_index_in_dim(prep, k, keepdims=False)
        hi = jax.lax.dynamic_index_in_dim(prep, k + 1, keepdims=False)
        t_left = leaf.t0_static + k.astype(prep.dtype) * cfg.dt
        ax = 1 if b.values else None  # rows (channels, B) or shared (channels,)
        sig = _StepSignal(lo=lo, hi=hi, t_left=t_left, dt=cfg.dt, kind=leaf.kind)
        return _Pair(sig, _StepSignal(lo=ax, hi=ax, t_left=None, dt=cfg.dt, kind=leaf.kind))

    return _unzip(jax.tree.map(conv, args, prepared, aligned, b_args, is_leaf=_is_signal))
