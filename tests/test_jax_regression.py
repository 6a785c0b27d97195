"""Regression test for the jax/jaxlib 0.10.2 CPU miscompilation (jax-ml/jax#39103).

A jitted, vmapped matrix-vector product followed by a reduction returned wrong values on CPU
with 0.10.2 (eager 268435456.0, jit 267911424.0 at n = 16385 in float64). pyproject excludes
that release; this test fails if a broken jax gets installed anyway.
"""

import jax
import jax.numpy as jnp


def _squared_norms(x, matrix):
    return jax.vmap(lambda row: jnp.sum((matrix @ row) ** 2))(x)


def test_vmapped_matvec_reduction_jit_equals_eager():
    n = 16_385
    i = jnp.arange(n, dtype=jnp.float64)
    x = jnp.stack((i, jnp.zeros_like(i), jnp.zeros_like(i)), axis=1)
    matrix = jnp.eye(3, dtype=jnp.float64)
    eager = float(_squared_norms(x, matrix)[-1])
    jitted = float(jax.jit(_squared_norms)(x, matrix)[-1])
    assert eager == float((n - 1) ** 2) == 268435456.0
    assert jitted == eager, f"jax {jax.__version__} miscompiles (jax-ml/jax#39103): {jitted} != {eager}"


def test_installed_jax_is_not_the_broken_release():
    import jaxlib

    assert jax.__version__ != "0.10.2" and jaxlib.__version__ != "0.10.2"
