"""Fixed-step SDE schemes: Euler-Maruyama (Ito) and stochastic Heun (Stratonovich).

``dy = a(t, y) dt + B(t, y) dW`` with ``B`` of shape ``(n, m)`` and the Brownian increments
``dW`` given explicitly (shape ``(n_steps, m)``), so that a path is a pure function of its noise:
draw them with :func:`jaxdrift.path_normals` times ``sqrt(dt)``.

The explicit Euler scheme of the paper's section 2 applied to noisy samples is Euler-Maruyama
(its limit is the Ito SDE (2.4)); stochastic Heun converges to the Stratonovich solution, which
for the quaternion SDE (3.13) keeps the norm where the Ito solution grows like exp(sigma^2 t/8).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ._solution import Solution
from ._solve import _check_args, _concrete, _max_saves_per_step, _save_pending

__all__ = ["solve_sde"]


def solve_sde(drift, diffusion, y0, t0, t1, *, dt, dW, saveat, args=None, scheme="euler_maruyama"):
    """Integrate an SDE on the fixed grid ``t0 + i dt`` with the given Brownian increments.

    Args:
        drift: ``a(t, y, args) -> (n,)``.
        diffusion: ``B(t, y, args) -> (n, m)``.
        dW: Brownian increments, shape ``(n_steps, m)`` with ``n_steps = ceil((t1 - t0)/dt)``;
            each row has variance ``dt`` (the last row: the last, possibly shorter, step).
        saveat: save times in ``[t0, t1]``; between grid points the linear interpolant is saved.
        scheme: ``"euler_maruyama"`` (Ito) or ``"heun"`` (stochastic Heun, Stratonovich).
    """
    if scheme not in ("euler_maruyama", "heun"):
        raise ValueError(f"scheme must be 'euler_maruyama' or 'heun', got {scheme!r}")
    y0 = jnp.asarray(y0)
    _check_args(y0, t0, t1, saveat, 0.0, 1.0, dt, None, 1, "dopri5")
    dtype = y0.dtype
    t0c, t1c, dtc = _concrete(t0), _concrete(t1), _concrete(dt)
    n_steps = int(np.ceil((t1c - t0c) / dtc * (1 - 1e-12)))
    dW = jnp.asarray(dW, dtype)
    b0 = diffusion(t0c, y0, args)
    if b0.ndim != 2 or b0.shape[0] != y0.shape[0]:
        raise ValueError(f"diffusion must return shape ({y0.shape[0]}, m), got {b0.shape}")
    if dW.shape != (n_steps, b0.shape[1]):
        raise ValueError(f"dW must have shape (n_steps, m) = ({n_steps}, {b0.shape[1]}), got {dW.shape}")
    ts = jnp.clip(jnp.asarray(saveat, dtype), t0c, t1c)
    per_step = _max_saves_per_step(_concrete(saveat), dtc)
    t0 = jnp.asarray(t0c, dtype)
    t1 = jnp.asarray(t1c, dtype)
    dt = jnp.asarray(dtc, dtype)

    def body(carry, inp):
        y, idx, out = carry
        i, dw = inp
        t = t0 + i * dt
        t_new = jnp.minimum(t0 + (i + 1) * dt, t1)
        h = t_new - t
        a = drift(t, y, args)
        b = diffusion(t, y, args)
        y_pred = y + a * h + b @ dw
        if scheme == "heun":
            a1 = drift(t_new, y_pred, args)
            b1 = diffusion(t_new, y_pred, args)
            y_new = y + 0.5 * (a + a1) * h + 0.5 * (b + b1) @ dw
        else:
            y_new = y_pred
        t_last = jnp.where(i == n_steps - 1, t1, t_new)
        idx, out = _save_pending(ts, idx, out, t, t_last, y, (y_new - y)[None], h, per_step or 0)
        return (y_new, idx, out), None

    out0 = jnp.zeros((ts.shape[0],) + y0.shape, dtype)
    (_, _, out), _ = jax.lax.scan(body, (y0, jnp.asarray(0, jnp.int32), out0), (jnp.arange(n_steps), dW))
    zero = jnp.asarray(0, jnp.int32)
    return Solution(ts=ts, ys=out, result=zero, num_accepted=jnp.asarray(n_steps, jnp.int32), num_rejected=zero)
