"""``sin`` and ``cos`` of one angle as elementwise polynomials, for the vector fields' pitch angle.

XLA's CPU backend calls a scalar library routine for every element of ``jnp.sin``/``jnp.cos`` and,
because it fuses the pitch's sine and cosine into every output row that depends on them, a
half-car evaluation computes them four to five times per path (read in the optimised HLO, see
``docs/performance.md``). This routine is made of multiplies, adds and selects only, which the
compiler vectorises and for which a duplicate costs little:

* Cody-Waite reduction ``r = ((x - k p1) - k p2) ...`` with ``k = round(2 x / pi)`` and ``pi/2 =
  p1 + p2 (+ p3)`` split for the dtype, so ``|r| <= pi/4`` (up to rounding);
* Taylor polynomials in ``r^2`` on ``[-pi/4, pi/4]`` (float64: through ``r^17`` / ``r^18``,
  truncation below ``1e-19``; float32: through ``r^11`` / ``r^12``, below ``5e-11``), evaluated by
  Horner's rule;
* the quadrant ``k mod 4`` selects and signs the two polynomials.

Accuracy (``tests/test_trig.py``, against ``numpy.longdouble``): float64 within 2 ulp of the
correctly rounded value for ``|x| <= 1e4`` (absolute error below ``2.3e-16`` for ``|x| <= 1``),
float32 within 3 ulp for ``|x| <= 1e3`` (2.6 measured). The error of the reduction grows with ``|x|`` (``k`` times
the rounding of ``lo``); beyond ``|x| = 2^30`` the quadrant index overflows. A pitch angle lives
far inside both ranges. Derivatives: ``round`` has derivative zero, so the derivative is that of
the polynomials, which approximate ``cos`` and ``-sin`` to the same order.

:func:`plain_trig` (a context manager, for checks) makes :func:`sincos` return ``jnp.sin`` and
``jnp.cos`` instead: results that change by more than rounding between the two depend on the last
bits of the arithmetic (the paper study's headline is checked this way).
"""

from __future__ import annotations

import contextlib
import math

import jax.numpy as jnp
import numpy as np

__all__ = ["sincos", "plain_trig"]

_PLAIN = [False]  # set by plain_trig; read when a function is traced


def _split(bits: int, parts: int, dtype) -> tuple[float, ...]:
    """pi/2 as a sum of ``parts`` numbers of ``bits`` significant bits each (the last one rounded
    to ``dtype``), so that ``k * part`` is exact in ``dtype`` for ``|k| < 2^(p - bits)``."""
    rest = np.longdouble("1.5707963267948966192313216916397514")
    out = []
    for _ in range(parts - 1):
        e = math.frexp(float(rest))[1]
        head = float(np.round(rest * np.longdouble(2.0) ** (bits - e)) * np.longdouble(2.0) ** (e - bits))
        out.append(head)
        rest = rest - np.longdouble(head)
    out.append(float(np.asarray(rest).astype(dtype)))
    return tuple(out)


# pi/2 split for each dtype: float64 as the correctly rounded value plus the rest (Cody-Waite with
# two parts); float32 in three parts of 12 bits, exact products for |k| < 2^12 (|x| < 6400).
_PIO2 = {
    np.dtype(np.float64): (1.5707963267948966, 6.123233995736766e-17),
    np.dtype(np.float32): _split(12, 3, np.float32),
}
# Number of Taylor terms (sin: r, r^3, ...; cos: 1, r^2, ...) per dtype.
_TERMS = {np.dtype(np.float64): (9, 10), np.dtype(np.float32): (6, 7)}


def sincos(x):
    """``(sin(x), cos(x))`` elementwise, as polynomials (accuracy: see the module docstring)."""
    x = jnp.asarray(x)
    if not jnp.issubdtype(x.dtype, jnp.floating):
        x = x.astype(jnp.result_type(float))
    if _PLAIN[0]:
        return jnp.sin(x), jnp.cos(x)
    key = np.dtype(x.dtype) if np.dtype(x.dtype) in _PIO2 else np.dtype(np.float64)
    n_sin, n_cos = _TERMS[key]
    k = jnp.round(x * (2.0 / math.pi))
    r = x
    for part in _PIO2[key]:
        r = r - k * part
    r2 = r * r
    ps = (-1) ** (n_sin - 1) / math.factorial(2 * n_sin - 1)
    for j in range(n_sin - 2, -1, -1):
        ps = (-1) ** j / math.factorial(2 * j + 1) + r2 * ps
    ps = r * ps
    pc = (-1) ** (n_cos - 1) / math.factorial(2 * n_cos - 2)
    for j in range(n_cos - 2, -1, -1):
        pc = (-1) ** j / math.factorial(2 * j) + r2 * pc
    q = k.astype(jnp.int32) & 3
    swap = (q & 1) == 1  # odd quadrants exchange sin and cos
    s = jnp.where(swap, pc, ps)
    c = jnp.where(swap, ps, pc)
    s = jnp.where(q >= 2, -s, s)  # quadrants 2, 3: sin negative
    c = jnp.where((q == 1) | (q == 2), -c, c)  # quadrants 1, 2: cos negative
    return s, c


@contextlib.contextmanager
def plain_trig():
    """Within the block, :func:`sincos` is ``(jnp.sin(x), jnp.cos(x))``.

    JAX's compilation caches are cleared on entry and on exit, so that functions compiled with
    the polynomials are traced again (and those compiled inside are not reused after).
    """
    import jax

    jax.clear_caches()
    _PLAIN[0] = True
    try:
        yield
    finally:
        _PLAIN[0] = False
        jax.clear_caches()
