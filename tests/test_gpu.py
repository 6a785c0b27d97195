"""The engine on a GPU: same paths as on the CPU. Skipped where JAX sees no GPU (every CPU machine).

No GPU was available to the session that wrote this test, so it has not run yet: it is the first
thing to run on a GPU machine (``python -m pytest tests/test_gpu.py -m gpu``).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest


def _gpus():
    try:
        return jax.devices("gpu")
    except RuntimeError:
        return []


pytestmark = [pytest.mark.gpu, pytest.mark.skipif(not _gpus(), reason="no GPU visible to JAX")]


def test_halfcar_paths_on_gpu_equal_cpu():
    from test_devices import halfcar_path

    key = jax.random.key(3)
    fn = jax.jit(jax.vmap(lambda i: halfcar_path(key, i, None)[0]))
    idx = jnp.arange(64, dtype=jnp.int32)
    on_cpu = np.asarray(fn(jax.device_put(idx, jax.devices("cpu")[0])))
    on_gpu = np.asarray(fn(jax.device_put(idx, _gpus()[0])))
    scale = np.max(np.abs(on_cpu), axis=(0, 1))
    # GPU and CPU may contract multiply-adds differently: equal to 1e-12 of the state's scale
    assert np.all(np.abs(on_gpu - on_cpu) <= 1e-12 * scale)
    assert np.std(on_cpu[:, -1, 1]) > 0
