"""Our Dormand-Prince 5(4) integrator: adaptive and fixed step, dense output, explicit Euler.

Pure JAX, jit- and vmap-safe. The adaptive controller reproduces scipy's ``RK45`` step for step
(same initial step selection, error norm and step-size factors), so scipy serves as an oracle.
Under ``vmap`` a failure (``max_steps``, step-size underflow) is a per-path result code, never
an exception.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._tableau import DOPRI5, ButcherTableau

__all__ = ["RESULTS", "Result", "Solution", "StepController", "solve_ode"]


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


class Solution(eqx.Module):
    """The values at the requested save times and the solver statistics."""

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
    n_steps = int(np.ceil((t1c - t0c) / dtc * (1 - 1e-12)))
    per_step = _max_saves_per_step(ts_concrete, dtc)
    tab = DOPRI5
    dt = jnp.asarray(dtc, y0.dtype)

    def body(carry, i):
        t_i, y, k0, idx, out = carry
        # Grid times computed from the index (no accumulation of rounding in t).
        t = t0 + i * dt
        t_new = jnp.minimum(t0 + (i + 1) * dt, t1)
        h = t_new - t
        if method == "euler":
            y_new = y + h * k0
            ks = None
        else:
            ks, y_new = _stages(tab, f, t, y, k0, h, args)
        k_new = f(t_new, y_new, args)
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
    tab = DOPRI5
    dtype = y0.dtype
    rtol = jnp.asarray(rtol, dtype)
    atol = jnp.asarray(atol, dtype)
    if dt0 is None:
        h_abs = _select_initial_step(f, t0, y0, f0, t1, args, rtol, atol, tab.error_order)
    else:
        h_abs = jnp.asarray(dt0, dtype)
    err_exp = ctrl.beta1
    e = tab.b_error

    class State(eqx.Module):
        t: jax.Array
        y: jax.Array
        k0: jax.Array
        h_abs: jax.Array
        rejected: jax.Array  # a rejection happened within the current step
        err_prev: jax.Array
        idx: jax.Array
        out: jax.Array
        n_acc: jax.Array
        n_rej: jax.Array
        result: jax.Array

    def cond(s):
        return (s.t < t1) & (s.result == Result.SUCCESS)

    def body(s):
        # scipy: min_step = 10 * spacing(t); the step is first raised to it, then tested.
        min_step = 10 * jnp.abs(jnp.nextafter(s.t, jnp.asarray(jnp.inf, dtype)) - s.t)
        h_abs = jnp.maximum(s.h_abs, min_step)
        underflow = s.h_abs < min_step * (1 - 1e-15)
        # The step of the attempt (clipped to t1).
        t_new = jnp.minimum(s.t + h_abs, t1)
        h = t_new - s.t
        ks, y_new = _stages(tab, f, s.t, s.y, s.k0, h, args)
        k_new = f(t_new, y_new, args)
        ks = ks + [k_new]
        err = h * sum(float(e[i]) * ks[i] for i in range(len(ks)) if e[i] != 0.0)
        scale = atol + jnp.maximum(jnp.abs(s.y), jnp.abs(y_new)) * rtol
        err_norm = _rms(err / scale)
        # A NaN/inf error norm (or state) is a rejected step with the minimum factor.
        finite = jnp.isfinite(err_norm) & jnp.all(jnp.isfinite(y_new))
        accept = finite & (err_norm < 1)
        safe_err = jnp.where(finite & (err_norm > 0), err_norm, 1.0)
        fac = ctrl.safety * safe_err ** (-err_exp)
        if ctrl.beta2:
            fac = fac * jnp.where(s.n_acc > 0, s.err_prev, 1.0) ** ctrl.beta2
        fac_acc = jnp.where(err_norm == 0, ctrl.max_factor, jnp.minimum(ctrl.max_factor, fac))
        fac_acc = jnp.where(s.rejected, jnp.minimum(1.0, fac_acc), fac_acc)
        fac_rej = jnp.where(finite, jnp.maximum(ctrl.min_factor, fac), ctrl.min_factor)
        new_h_abs = h_abs * jnp.where(accept, fac_acc, fac_rej)

        # Under vmap the branch is a select and the save loop runs while any path has a save
        # pending; the dense coefficients are formed inside it, so steps without saves skip them.
        idx, out = jax.lax.cond(
            accept,
            lambda: _save_pending(ts, s.idx, s.out, s.t, t_new, s.y, lambda: _dense_coeffs(tab, ks, h), h, None),
            lambda: (s.idx, s.out),
        )
        n_acc = s.n_acc + accept.astype(jnp.int32)
        n_rej = s.n_rej + (~accept).astype(jnp.int32)
        result = jnp.where(underflow, Result.STEP_UNDERFLOW, Result.SUCCESS)
        result = jnp.where(
            (result == Result.SUCCESS) & (n_acc + n_rej >= max_steps) & ~(accept & (t_new >= t1)),
            Result.MAX_STEPS,
            result,
        ).astype(jnp.int32)
        keep = underflow  # an underflowing step is not taken
        return State(
            t=jnp.where(accept & ~keep, t_new, s.t),
            y=jnp.where(accept & ~keep, y_new, s.y),
            k0=jnp.where(accept & ~keep, k_new, s.k0),
            h_abs=new_h_abs,
            rejected=~accept,
            err_prev=jnp.where(accept, jnp.maximum(err_norm, 1e-4), s.err_prev),
            idx=jnp.where(keep, s.idx, idx),
            out=jnp.where(keep, s.out, out),
            n_acc=jnp.where(keep, s.n_acc, n_acc),
            n_rej=jnp.where(keep, s.n_rej, n_rej),
            result=result,
        )

    z = jnp.asarray(0, jnp.int32)
    s0 = State(
        t=t0,
        y=y0,
        k0=f0,
        h_abs=h_abs.astype(dtype),
        rejected=jnp.asarray(False),
        err_prev=jnp.asarray(1.0, dtype),
        idx=z,
        out=out0,
        n_acc=z,
        n_rej=z,
        result=z,
    )
    s = jax.lax.while_loop(cond, body, s0)
    return Solution(ts=ts, ys=s.out, result=s.result, num_accepted=s.n_acc, num_rejected=s.n_rej)
