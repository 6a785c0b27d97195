"""Our Dormand-Prince 5(4) integrator: adaptive and fixed step, dense output, explicit Euler.

Pure JAX, jit- and vmap-safe. The adaptive controller reproduces scipy's ``RK45`` step for step
(same initial step selection, error norm and step-size factors), so scipy serves as an oracle.
Under ``vmap`` a failure (``max_steps``, step-size underflow) is a per-path result code, never
an exception.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
from jax.custom_batching import custom_vmap
import jax.numpy as jnp
import numpy as np

from ._fast import save_grid, solve_fixed_fast
from ._inputs import local_to_step
from ._solution import RESULTS, Result, Solution
from ._tableau import DOPRI5, ButcherTableau

__all__ = ["RESULTS", "Result", "Solution", "StepController", "solve_ode"]


class StepController(eqx.Module):
    """PI step-size controller. The defaults are scipy's RK45 constants (a pure I controller).

    factor = safety * err^(-beta1) * err_prev^(beta2), clipped to [min_factor, max_factor];
    after a rejection within the same step the factor is capped at 1 (as scipy does).
    ``StepController.pi()`` gives Hairer's DOPRI5 PI gains (beta1 = 0.17, beta2 = 0.04).
    """

    safety: float = eqx.field(static=True, default=0.9)
    min_factor: float = eqx.field(static=True, default=0.2)
    max_factor: float = eqx.field(static=True, default=10.0)
    beta1: float = eqx.field(static=True, default=0.2)  # 1 / (error order + 1)
    beta2: float = eqx.field(static=True, default=0.0)

    @classmethod
    def pi(cls) -> StepController:
        return cls(beta1=0.17, beta2=0.04)


def _rms(x):
    # scipy's error norm: Euclidean norm / sqrt(n) (the RMS over components).
    return jnp.sqrt(jnp.mean(jnp.square(x)))


def _concrete(x):
    try:
        return np.asarray(x, dtype=np.float64)
    except (jax.errors.TracerArrayConversionError, jax.errors.ConcretizationTypeError, TypeError):
        return None


def _check_args(y0, t0, t1, saveat, rtol, atol, dt, dt0, max_steps, method):
    if y0.ndim != 1:
        raise ValueError(f"y0 must be a 1-D state vector, got shape {y0.shape}")
    if not jnp.issubdtype(y0.dtype, jnp.floating):
        raise TypeError(f"y0 must be floating point, got {y0.dtype}")
    if method not in ("dopri5", "euler"):
        raise ValueError(f"method must be 'dopri5' or 'euler', got {method!r}")
    if method == "euler" and dt is None:
        raise ValueError("method='euler' is a fixed-step scheme: pass dt")
    if not isinstance(max_steps, int) or max_steps <= 0:
        raise ValueError(f"max_steps must be a positive int, got {max_steps!r}")
    t0c, t1c = _concrete(t0), _concrete(t1)
    if t0c is not None and t1c is not None:
        if t0c.ndim or t1c.ndim:
            raise ValueError("t0 and t1 must be scalars")
        if not np.isfinite(t0c) or not np.isfinite(t1c):
            raise ValueError("t0 and t1 must be finite")
        if not t1c > t0c:
            raise ValueError(f"t1 must be greater than t0, got t0={float(t0c)}, t1={float(t1c)}")
    ts = _concrete(saveat)
    if ts is not None:
        if ts.ndim != 1 or ts.size == 0:
            raise ValueError(f"saveat must be a non-empty 1-D array of times, got shape {ts.shape}")
        if np.any(np.diff(ts) < 0):
            raise ValueError("saveat must be non-decreasing")
        if t0c is not None and t1c is not None:
            span = max(abs(t0c), abs(t1c), 1.0) * 1e-12
            if ts[0] < t0c - span or ts[-1] > t1c + span:
                raise ValueError(
                    f"saveat must lie in [t0, t1] = [{float(t0c)}, {float(t1c)}], "
                    f"got [{ts[0]}, {ts[-1]}]"
                )
    for name, v in (("rtol", rtol), ("atol", atol)):
        vc = _concrete(v)
        if vc is not None and (np.any(vc < 0) or not np.all(np.isfinite(vc))):
            raise ValueError(f"{name} must be finite and non-negative, got {v}")
    if _concrete(rtol) is not None and _concrete(atol) is not None:
        if np.all(_concrete(rtol) == 0) and np.all(_concrete(atol) == 0):
            raise ValueError("rtol and atol cannot both be zero")
        if np.ndim(atol) and np.shape(atol) != y0.shape:
            raise ValueError(f"atol must be a scalar or of shape {y0.shape}, got {np.shape(atol)}")
    for name, v in (("dt", dt), ("dt0", dt0)):
        vc = _concrete(v) if v is not None else None
        if vc is not None and (vc.ndim or not vc > 0 or not np.isfinite(vc)):
            raise ValueError(f"{name} must be a positive finite scalar, got {v}")


def _stages(tab: ButcherTableau, f, t, y, k0, h, args):
    """The Runge-Kutta stages k_0..k_{s-1} (k0 given: FSAL) and the new state."""
    ks = [k0]
    for i in range(1, len(tab.c)):
        dy = sum(float(tab.a[i, j]) * ks[j] for j in range(i) if tab.a[i, j] != 0.0)
        ks.append(f(t + float(tab.c[i]) * h, y + h * dy, args))
    y_new = y + h * sum(float(tab.b[j]) * ks[j] for j in range(len(ks)) if tab.b[j] != 0.0)
    return ks, y_new


def _dense_coeffs(tab: ButcherTableau, ks, h):
    """Polynomial coefficients Q (4, n) so that y(t + theta h) = y + sum_j Q_j theta^(j+1)."""
    p = tab.p
    return jnp.stack(
        [h * sum(float(p[i, j]) * ks[i] for i in range(p.shape[0]) if p[i, j] != 0.0) for j in range(p.shape[1])]
    )


def _dense_eval(y, q, theta):
    # Horner in theta for y + q0 theta + q1 theta^2 + q2 theta^3 + q3 theta^4.
    acc = q[-1]
    for j in range(q.shape[0] - 2, -1, -1):
        acc = q[j] + theta * acc
    return y + theta * acc


def _select_initial_step(f, t0, y0, f0, t1, args, rtol, atol, error_order):
    """scipy's ``select_initial_step`` (Hairer, Norsett & Wanner, II.4), traced."""
    interval = t1 - t0
    scale = atol + jnp.abs(y0) * rtol
    d0 = _rms(y0 / scale)
    d1 = _rms(f0 / scale)
    h0 = jnp.where((d0 < 1e-5) | (d1 < 1e-5), 1e-6, 0.01 * d0 / jnp.where(d1 == 0, 1.0, d1))
    h0 = jnp.minimum(h0, interval)
    y1 = y0 + h0 * f0
    f1 = f(t0 + h0, y1, args)
    d2 = _rms((f1 - f0) / scale) / h0
    dmax = jnp.maximum(d1, d2)
    h1 = jnp.where(
        (d1 <= 1e-15) & (d2 <= 1e-15),
        jnp.maximum(1e-6, h0 * 1e-3),
        (0.01 / jnp.where(dmax == 0, 1.0, dmax)) ** (1.0 / (error_order + 1)),
    )
    return jnp.minimum(jnp.minimum(100 * h0, h1), interval)


def _save_pending(ts, idx, out, t, t_new, y, q, h, max_per_step):
    """Write dense output for every save time in (t, t_new] (and t0 on the first step).

    ``q`` is the (n_poly, n) array of dense-output coefficients or a zero-argument callable that
    forms it (so that steps without a save never pay for it).
    """
    n_save = ts.shape[0]

    def save_one(idx, out):
        q_ = q() if callable(q) else q
        tsave = ts[jnp.minimum(idx, n_save - 1)]
        theta = jnp.where(h > 0, (tsave - t) / h, 0.0)
        val = _dense_eval(y, q_, theta)
        take = (idx < n_save) & (tsave <= t_new)
        out = jnp.where(take, out.at[jnp.minimum(idx, n_save - 1)].set(val), out)
        return idx + take.astype(idx.dtype), out

    if max_per_step == 1:
        return save_one(idx, out)

    def cond(carry):
        idx, _ = carry
        return (idx < n_save) & (ts[jnp.minimum(idx, n_save - 1)] <= t_new)

    return jax.lax.while_loop(cond, lambda c: save_one(*c), (idx, out))


def solve_ode(
    f: Callable[[Any, jax.Array, Any], jax.Array],
    y0,
    t0,
    t1,
    *,
    saveat,
    args: Any = None,
    method: str = "dopri5",
    rtol=1e-6,
    atol=1e-8,
    dt=None,
    dt0=None,
    max_steps: int = 1_000_000,
    controller: StepController | None = None,
) -> Solution:
    """Integrate ``y' = f(t, y, args)`` from ``t0`` to ``t1``, returning ``y`` at ``saveat``.

    Args:
        f: vector field ``f(t, y, args) -> dy/dt`` (pure JAX; ``y`` is a 1-D array).
        y0: initial state, 1-D floating array.
        t0, t1: the time span, ``t1 > t0``.
        saveat: 1-D non-decreasing array of save times in ``[t0, t1]``. Values between steps come
            from the method's 4th-order continuous extension (dense output); no full path is kept.
        method: ``"dopri5"`` (Dormand-Prince 5(4)) or ``"euler"`` (explicit Euler, fixed step;
            between grid points the saved value is the linear interpolant).
        rtol, atol: tolerances of the adaptive mode; the error norm is scipy's RMS of
            ``err / (atol + rtol * max(|y|, |y_new|))``. ``atol`` may be per component.
        dt: if given, fixed-step mode with this step (the last step is shortened to hit ``t1``).
        dt0: initial step of the adaptive mode; default: scipy's selection.
        max_steps: bound on the number of steps (accepted + rejected); exceeding it gives
            ``Result.MAX_STEPS`` for that path, not an exception.
        controller: step-size controller; default scipy's constants.

    Returns:
        A :class:`Solution` with ``ts``, ``ys`` (``(len(saveat), len(y0))``), per-path ``result``
        and step statistics.
    """
    y0 = jnp.asarray(y0)
    if not jnp.issubdtype(y0.dtype, jnp.floating):
        y0 = y0.astype(jnp.result_type(float))
    _check_args(y0, t0, t1, saveat, rtol, atol, dt, dt0, max_steps, method)
    dtype = y0.dtype
    t0_concrete, t1_concrete = _concrete(t0), _concrete(t1)
    ts_concrete = _concrete(saveat)
    ts = jnp.asarray(saveat, dtype=dtype)
    t0 = jnp.asarray(t0, dtype=dtype)
    t1 = jnp.asarray(t1, dtype=dtype)
    ts = jnp.clip(ts, t0, t1)  # save times within rounding of the span are pulled onto it
    f0 = f(t0, y0, args)
    if f0.shape != y0.shape:
        raise ValueError(f"the vector field returned shape {f0.shape}, expected {y0.shape}")
    f0 = f0.astype(dtype)
    out0 = jnp.zeros((ts.shape[0],) + y0.shape, dtype)
    if dt is not None:
        return _solve_fixed(f, y0, f0, t0, t1, t0_concrete, t1_concrete, ts, ts_concrete, out0, args, method, dt)
    controller = controller or StepController()
    return _solve_adaptive(f, y0, f0, t0, t1, ts, out0, args, rtol, atol, dt0, max_steps, controller)


def _max_saves_per_step(tsc, stepc):
    """1 if no step of length ``stepc`` can contain two save times ``tsc`` (concrete values or None)."""
    if tsc is None or stepc is None or tsc.size < 2:
        return 1 if (tsc is not None and tsc.size < 2) else None
    return 1 if np.min(np.diff(tsc)) > stepc * (1 + 1e-9) else None


def _solve_fixed(f, y0, f0, t0, t1, t0c, t1c, ts, ts_concrete, out0, args, method, dt):
    dtc = _concrete(dt)
    if dtc is None or t0c is None or t1c is None:
        raise ValueError("fixed-step mode needs concrete t0, t1 and dt (they fix the number of steps)")
    if method == "dopri5" and ts_concrete is not None:
        # The usual Monte-Carlo case: saves on the step grid at a constant stride (statistics
        # every 0.1 s with 1 ms steps). A scan over save intervals around a scan over steps needs
        # no save bookkeeping inside the step and no dense output (measured: docs/performance.md).
        try:
            save_grid(t0c, t1c, dtc, ts_concrete)
        except ValueError:
            pass
        else:
            return solve_fixed_fast(f, y0, t0c, t1c, dt=dtc, saveat=ts_concrete, args=args,
                                    dtype=y0.dtype, compensated=False, unroll=1)
    n_steps = int(np.ceil((t1c - t0c) / dtc * (1 - 1e-12)))
    per_step = _max_saves_per_step(ts_concrete, dtc)
    tab = DOPRI5
    dt = jnp.asarray(dtc, y0.dtype)
    t0c_f, dtc_f = float(t0c), float(dtc)

    def body(carry, i):
        t_i, y, k0, idx, out = carry
        # Grid times computed from the index (no accumulation of rounding in t).
        t = t0 + i * dt
        t_new = jnp.minimum(t0 + (i + 1) * dt, t1)
        h = t_new - t
        # Grid-aligned sampled inputs read their two samples once per step (see local_to_step).
        step_args = local_to_step(args, t0c_f, dtc_f, i)
        if method == "euler":
            y_new = y + h * k0
            ks = None
        else:
            ks, y_new = _stages(tab, f, t, y, k0, h, step_args)
        k_new = f(t_new, y_new, step_args)
        t_last = jnp.where(i == n_steps - 1, t1, t_new)

        def do_save(idx, out):
            q = (h * k0)[None] if method == "euler" else _dense_coeffs(tab, ks + [k_new], h)
            return _save_pending(ts, idx, out, t, t_last, y, q, h, per_step or 0)

        # The grid and the save times are the same for every path, so under vmap this stays a
        # real branch: the dense-output coefficients are only formed on steps that save.
        pending = ts[jnp.minimum(idx, ts.shape[0] - 1)] <= t_last
        idx, out = jax.lax.cond(pending & (idx < ts.shape[0]), do_save, lambda i_, o_: (i_, o_), idx, out)
        return (t_new, y_new, k_new, idx, out), None

    init = (t0, y0, f0, jnp.asarray(0, jnp.int32), out0)
    (_, _, _, _, out), _ = jax.lax.scan(body, init, jnp.arange(n_steps))
    zero = jnp.asarray(0, jnp.int32)
    return Solution(ts=ts, ys=out, result=zero, num_accepted=jnp.asarray(n_steps, jnp.int32), num_rejected=zero)


def _solve_adaptive(f, y0, f0, t0, t1, ts, out0, args, rtol, atol, dt0, max_steps, ctrl):
    dtype = y0.dtype
    rtol = jnp.asarray(rtol, dtype)
    atol = jnp.asarray(atol, dtype)
    if dt0 is None:
        h0 = _select_initial_step(f, t0, y0, f0, t1, args, rtol, atol, DOPRI5.error_order)
    else:
        h0 = jnp.asarray(dt0, dtype)
    h0 = jax.lax.stop_gradient(h0)  # the step sequence is not differentiated (see _adaptive_loop)
    # Closed-over arrays (possibly batch tracers of an enclosing vmap) become explicit arguments,
    # so that the batching rule below sees which inputs are batched.
    f_conv, consts = jax.closure_convert(f, t0, y0, args)
    consts = tuple(consts)

    def plain(y0, f0, t0, t1, ts, args, rtol, atol, h0, consts):
        fb = jax.vmap(lambda t, y: f_conv(t, y, args, *consts))
        sol = _adaptive_loop(fb, y0[None], f0[None], t0[None], t1[None], ts[None], rtol, atol, h0[None],
                             max_steps, ctrl)
        return jax.tree.map(lambda x: x[0], sol)

    core = custom_vmap(plain)

    @core.def_vmap
    def core_batched(axis_size, in_batched, y0, f0, t0, t1, ts, args, rtol, atol, h0, consts):
        # Under vmap, a while_loop with a batched predicate selects its whole carry (including the
        # saved outputs) on every iteration. Here the batch is explicit instead: one loop over all
        # paths, per-path masking of the small state only, saves written by a row scatter.
        b_y0, b_f0, b_t0, b_t1, b_ts, b_args, b_rtol, b_atol, b_h0, b_consts = in_batched

        def bc(x, batched, tail):
            return x if batched else jnp.broadcast_to(x, (axis_size,) + tail)

        in_axes_args = jax.tree.map(lambda b: 0 if b else None, b_args)
        in_axes_consts = tuple(0 if b else None for b in b_consts)
        fb = jax.vmap(lambda t, y, a, *c: f_conv(t, y, a, *c), in_axes=(0, 0, in_axes_args) + in_axes_consts)
        n = y0.shape[-1]
        rt = rtol if b_rtol else jnp.broadcast_to(rtol, (axis_size,) + jnp.shape(rtol))
        at = atol if b_atol else jnp.broadcast_to(atol, (axis_size,) + jnp.shape(atol))
        rt = rt.reshape(axis_size, -1)
        at = at.reshape(axis_size, -1)
        sol = _adaptive_loop(
            lambda t, y: fb(t, y, args, *consts),
            bc(y0, b_y0, (n,)), bc(f0, b_f0, (n,)), bc(t0, b_t0, ()), bc(t1, b_t1, ()),
            bc(ts, b_ts, ts.shape[-1:]), rt, at, bc(h0, b_h0, ()), max_steps, ctrl,
        )
        return sol, jax.tree.map(lambda _: True, sol)

    # custom_vmap has no usable derivative rule here; derivatives (forward mode: the loop is a
    # while_loop) go through the plain loop, which vmap batches with its standard rules.
    @jax.custom_jvp
    def solve(y0, f0, t0, t1, ts, args, rtol, atol, h0, consts):
        return core(y0, f0, t0, t1, ts, args, rtol, atol, h0, consts)

    @solve.defjvp
    def solve_jvp(primals, tangents):
        return jax.jvp(plain, primals, tangents)

    return solve(y0, f0, t0, t1, ts, args, rtol, atol, h0, consts)


def _adaptive_loop(fb, y0, f0, t0, t1, ts, rtol, atol, h0, max_steps, ctrl):
    """The adaptive DOPRI5 loop over an explicit batch: y0 (B, n), t0/t1/h0 (B,), ts (B, n_save).

    ``fb(t (B,), y (B, n)) -> (B, n)``. rtol/atol broadcast against (B, n).
    """
    tab = DOPRI5
    dtype = y0.dtype
    B, n = y0.shape
    n_save = ts.shape[-1]
    e = tab.b_error
    rows = jnp.arange(B)

    def rk_step(t, y, k0, h):
        ks = [k0]
        for i in range(1, len(tab.c)):
            dy = sum(float(tab.a[i, j]) * ks[j] for j in range(i) if tab.a[i, j] != 0.0)
            ks.append(fb(t + float(tab.c[i]) * h, y + h[:, None] * dy))
        y_new = y + h[:, None] * sum(float(tab.b[j]) * ks[j] for j in range(len(ks)) if tab.b[j] != 0.0)
        return ks, y_new

    def cond(c):
        t, y, k0, h_abs, rejected, err_prev, idx, out, n_acc, n_rej, result = c
        return jnp.any((t < t1) & (result == Result.SUCCESS))

    def body(c):
        t, y, k0, h_abs, rejected, err_prev, idx, out, n_acc, n_rej, result = c
        active = (t < t1) & (result == Result.SUCCESS)
        # scipy: min_step = 10 * spacing(t); the step is first raised to it, then tested.
        # nextafter has no derivative rule: the spacing of t is a constant for derivatives.
        t_sg = jax.lax.stop_gradient(t)
        min_step = 10 * jnp.abs(jnp.nextafter(t_sg, jnp.asarray(jnp.inf, dtype)) - t_sg)
        underflow = active & (h_abs < min_step * (1 - 1e-15))
        h_try = jnp.maximum(h_abs, min_step)
        t_new = jnp.minimum(t + h_try, t1)
        h = t_new - t
        ks, y_new = rk_step(t, y, k0, h)
        k_new = fb(t_new, y_new)
        ks = ks + [k_new]
        err = h[:, None] * sum(float(e[i]) * ks[i] for i in range(len(ks)) if e[i] != 0.0)
        scale = atol + jnp.maximum(jnp.abs(y), jnp.abs(y_new)) * rtol
        err_norm = jnp.sqrt(jnp.mean(jnp.square(err / scale), axis=-1))  # scipy's RMS norm
        # Derivatives are those of the solution on the chosen step sequence (the steps do not
        # depend on the parameters; the last step still ends at t1): forward-mode sensitivities
        # then solve the variational equations with the same steps (tests/test_solve_grad.py).
        err_norm = jax.lax.stop_gradient(err_norm)
        # A NaN/inf error norm (or state) is a rejected step with the minimum factor.
        finite = jnp.isfinite(err_norm) & jnp.all(jnp.isfinite(y_new), axis=-1)
        accept = active & ~underflow & finite & (err_norm < 1)
        reject = active & ~underflow & ~accept
        safe_err = jnp.where(finite & (err_norm > 0), err_norm, 1.0)
        fac = ctrl.safety * safe_err ** (-ctrl.beta1)
        if ctrl.beta2:
            fac = fac * jnp.where(n_acc > 0, err_prev, 1.0) ** ctrl.beta2
        fac_acc = jnp.where(err_norm == 0, ctrl.max_factor, jnp.minimum(ctrl.max_factor, fac))
        fac_acc = jnp.where(rejected, jnp.minimum(1.0, fac_acc), fac_acc)
        fac_rej = jnp.where(finite, jnp.maximum(ctrl.min_factor, fac), ctrl.min_factor)
        h_abs = jnp.where(accept, h_try * fac_acc, jnp.where(reject, h_try * fac_rej, h_abs))

        # Saves in (t, t_new] of accepted steps: loop while any path has one pending, forming
        # the dense-output coefficients only then; each pass writes one row per path.
        def pending(idx):
            return accept & (idx < n_save) & (ts[rows, jnp.minimum(idx, n_save - 1)] <= t_new)

        def save_body(carry):
            idx, out = carry
            take = pending(idx)
            q = jnp.moveaxis(_dense_coeffs(tab, ks, h[:, None]), 0, 1)  # (B, 4, n)
            j = jnp.minimum(idx, n_save - 1)
            theta = jnp.where(h > 0, (ts[rows, j] - t) / jnp.where(h > 0, h, 1.0), 0.0)
            acc = q[:, -1]
            for jj in range(q.shape[1] - 2, -1, -1):
                acc = q[:, jj] + theta[:, None] * acc
            val = y + theta[:, None] * acc
            out = out.at[rows, j].set(jnp.where(take[:, None], val, out[rows, j]))
            return idx + take.astype(idx.dtype), out

        idx, out = jax.lax.while_loop(lambda c: jnp.any(pending(c[0])), save_body, (idx, out))
        n_acc = n_acc + accept.astype(jnp.int32)
        n_rej = n_rej + reject.astype(jnp.int32)
        result = jnp.where(underflow, Result.STEP_UNDERFLOW, result)
        done_now = accept & (t_new >= t1)
        result = jnp.where(
            active & (result == Result.SUCCESS) & (n_acc + n_rej >= max_steps) & ~done_now, Result.MAX_STEPS, result
        ).astype(jnp.int32)
        return (
            jnp.where(accept, t_new, t),
            jnp.where(accept[:, None], y_new, y),
            jnp.where(accept[:, None], k_new, k0),
            h_abs,
            jnp.where(active, reject, rejected),
            jnp.where(accept, jnp.maximum(err_norm, 1e-4), err_prev),
            idx,
            out,
            n_acc,
            n_rej,
            result,
        )

    z = jnp.zeros((B,), jnp.int32)
    init = (t0, y0, f0, h0.astype(dtype), jnp.zeros((B,), bool), jnp.ones((B,), dtype), z,
            jnp.zeros((B, n_save, n), dtype), z, z, z)
    t, y, k0, h_abs, rejected, err_prev, idx, out, n_acc, n_rej, result = jax.lax.while_loop(cond, body, init)
    return Solution(ts=ts, ys=out, result=result, num_accepted=n_acc, num_rejected=n_rej)
