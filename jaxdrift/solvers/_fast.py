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
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from ._inputs import local_to_step
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
    unroll: int = 5,
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
        unroll: steps per iteration of the compiled loop (``lax.scan``'s ``unroll``). The default 5
            measured 188-198 against 231-240 ns per path-step for 1 (half-car, float32, 256 paths);
            float64 gained nothing (338-340 for 1, 2 and 5), so the engine's fixed-step mode uses 1.

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
    tab = DOPRI5
    a = [[float(v) for v in row] for row in tab.a]
    b = [float(v) for v in tab.b]
    c = [float(v) for v in tab.c]
    h = jnp.asarray(dtf, dtype)
    s = len(c)

    if inputs is not None:
        inputs = jnp.asarray(inputs).astype(dtype)
        if inputs.ndim != 2 or inputs.shape[0] != n_steps + 1:
            raise ValueError(f"inputs must have shape (n_steps + 1, m) = ({n_steps + 1}, m), got {inputs.shape}")

        def rhs(t, y, u, a=args):
            return jnp.asarray(f(t, y, u, a)).astype(dtype)

        u_init = inputs[0]
    else:

        def rhs(t, y, u, a=args):
            return jnp.asarray(f(t, y, a)).astype(dtype)

        u_init = jnp.zeros((0,), dtype)

    def step(carry, u1):
        i, y, k0, comp, u0 = carry
        t = jnp.asarray(t0f, tdt) + i.astype(tdt) * jnp.asarray(dtf, tdt)
        # grid-aligned SampledSignals in args: read their two samples once per step
        step_args = local_to_step(args, t0f, dtf, i)
        du = None if inputs is None else u1 - u0
        ks = [k0]
        for j in range(1, s):
            dy = sum(a[j][m] * ks[m] for m in range(j) if a[j][m] != 0.0)
            u = None if inputs is None else u0 + jnp.asarray(c[j], dtype) * du
            ks.append(rhs(t + c[j] * dtf, y + h * dy, u, step_args))
        inc = h * sum(b[m] * ks[m] for m in range(s) if b[m] != 0.0)
        if compensated:
            d = inc - comp
            y_new = y + d
            comp = (y_new - y) - d
        else:
            y_new = y + inc
        t_new = jnp.asarray(t0f, tdt) + (i + 1).astype(tdt) * jnp.asarray(dtf, tdt)
        return (i + 1, y_new, rhs(t_new, y_new, u1, step_args), comp, u1 if inputs is not None else u0), None

    k_init = rhs(jnp.asarray(t0f, tdt), y0, u_init if inputs is not None else None)
    if k_init.shape != y0.shape:
        raise ValueError(f"the vector field returned shape {k_init.shape}, expected {y0.shape}")
    carry = (jnp.asarray(0, jnp.int32), y0, k_init, jnp.zeros_like(y0), u_init)

    def xs_of(lo, n):
        # The "next sample" of each of n steps from step lo (None: no inputs, scan by length).
        return None if inputs is None else inputs[lo + 1 : lo + 1 + n]

    if first:
        carry, _ = jax.lax.scan(step, carry, xs_of(0, first), length=first)

    def segment(carry, us):
        carry, _ = jax.lax.scan(step, carry, us, length=stride, unroll=min(unroll, stride))
        return carry, carry[1]

    if n_save > 1:
        seg_xs = xs_of(first, stride * (n_save - 1))
        if seg_xs is not None:
            seg_xs = seg_xs.reshape((n_save - 1, stride) + seg_xs.shape[1:])
        _, rest = jax.lax.scan(segment, carry, seg_xs, length=n_save - 1)
        ys = jnp.concatenate([carry[1][None], rest])
    else:
        ys = carry[1][None]
    zero = jnp.asarray(0, jnp.int32)
    return Solution(
        ts=jnp.asarray(ts_np, tdt),
        ys=ys,
        result=zero,
        num_accepted=jnp.asarray(first + stride * (n_save - 1), jnp.int32),
        num_rejected=zero,
    )

