"""Tests of jaxdrift.ensemble._noise: reproducibility contract, distribution, input effects."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.stats

from jaxdrift.ensemble._noise import (
    BLOCK_SIZE,
    apply_input_effects,
    path_normals,
    remove_input_effects,
    white_noise,
)

KEY = jax.random.key(20261122)
# Each distinct (n_samples, n_channels, dtype) compiles the threefry draw once (about 1 s of CPU):
# the tests reuse a few shapes.
SHORT = (BLOCK_SIZE + 1, 2)
LONG = (3 * BLOCK_SIZE + 5, 3)


# --- reproducibility contract -------------------------------------------------------------------


def test_sample_does_not_depend_on_n_samples_or_channels():
    long = np.asarray(path_normals(KEY, 7, *LONG))
    short = np.asarray(path_normals(KEY, 7, *SHORT))
    assert long.shape == LONG
    np.testing.assert_array_equal(long[: SHORT[0], :2], short)
    one = np.asarray(path_normals(KEY, 7, 1, 1))
    np.testing.assert_array_equal(one, long[:1, :1])


def test_pure_function_of_key_and_path_index():
    a = path_normals(KEY, 3, *SHORT)
    np.testing.assert_array_equal(a, path_normals(KEY, 3, *SHORT))
    assert not np.any(np.asarray(a) == np.asarray(path_normals(KEY, 4, *SHORT)))
    other = jax.random.key(1)
    assert not np.any(np.asarray(a) == np.asarray(path_normals(other, 3, *SHORT)))
    # raw uint32 keys are accepted as well
    raw = path_normals(jax.random.PRNGKey(0), 3, *SHORT)
    assert raw.shape == SHORT


def test_jit_vmap_and_path_order_invariance():
    idx = jnp.array([5, 0, 17, 3, 2**20])
    f = jax.jit(jax.vmap(lambda p: path_normals(KEY, p, *SHORT)))
    batched = f(idx)
    for row, p in zip(np.asarray(batched), np.asarray(idx)):
        np.testing.assert_array_equal(row, path_normals(KEY, int(p), *SHORT))
    perm = np.array([3, 1, 4, 0, 2])
    permuted = f(idx[perm])
    np.testing.assert_array_equal(np.asarray(permuted), np.asarray(batched)[perm])


def test_dtype():
    assert path_normals(KEY, 0, *SHORT).dtype == jnp.float64  # tests run with x64
    z32 = path_normals(KEY, 0, *SHORT, dtype=jnp.float32)
    assert z32.dtype == jnp.float32
    with pytest.raises(TypeError, match="floating"):
        path_normals(KEY, 0, 10, 2, dtype=jnp.int32)


def test_bad_arguments():
    with pytest.raises(TypeError, match="n_samples"):
        path_normals(KEY, 0, 10.0, 2)
    with pytest.raises(ValueError, match="n_channels"):
        path_normals(KEY, 0, 10, -1)
    with pytest.raises(ValueError, match="path_index"):
        path_normals(KEY, -1, 10, 1)
    with pytest.raises(TypeError, match="path_index"):
        path_normals(KEY, 1.5, 10, 1)
    assert path_normals(KEY, 0, 0, 2).shape == (0, 2)


# --- distribution ---------------------------------------------------------------------------------


def test_standard_normal_statistics():
    # 100 paths x 773 samples x 3 channels = 231900 draws (one compiled shape, called per path).
    z = np.stack([np.asarray(path_normals(KEY, p, *LONG)) for p in range(100)])
    flat = z.reshape(-1)
    n = flat.size
    # Mean, variance within 5 standard errors (exact: 0, 1; se(var) = sqrt(2 / n)).
    assert abs(flat.mean()) < 5 / np.sqrt(n)
    assert abs(flat.var() - 1) < 5 * np.sqrt(2 / n)
    # Kolmogorov-Smirnov against N(0, 1) (scipy as the oracle); fixed key, so deterministic.
    assert scipy.stats.kstest(flat, "norm").pvalue > 1e-3
    # Independence: correlations between channels, neighbouring samples (including across a
    # block boundary) and neighbouring paths, each within 5 standard errors (se = 1/sqrt(m)).
    def corr(a, b):
        return np.corrcoef(a.reshape(-1), b.reshape(-1))[0, 1]

    m = z[..., 0].size
    assert abs(corr(z[..., 0], z[..., 1])) < 5 / np.sqrt(m)
    assert abs(corr(z[:, :-1, 0], z[:, 1:, 0])) < 5 / np.sqrt(m)
    assert abs(corr(z[:-1], z[1:])) < 5 / np.sqrt(m)
    # No two blocks share a key: across all paths, channels and blocks the (B,)-blocks differ
    # (a collision, e.g. block b + 1 of path p equal to block b of path p + 1, would show here).
    blocks = z[:, : 3 * BLOCK_SIZE, :].transpose(0, 2, 1).reshape(-1, BLOCK_SIZE)  # 900 blocks
    assert len({blk.tobytes() for blk in blocks}) == blocks.shape[0]


def test_white_noise_sigma_and_noise_free_channel():
    sigma = np.array([2.5, 0.0, 0.1])
    w = np.asarray(white_noise(KEY, 11, LONG[0], sigma))
    z = np.asarray(path_normals(KEY, 11, *LONG))
    np.testing.assert_array_equal(w[:, 1], 0.0)
    assert not np.any(np.signbit(w[:, 1]))
    np.testing.assert_allclose(w[:, 0], 2.5 * z[:, 0], rtol=0, atol=0)
    np.testing.assert_allclose(w[:, 2], 0.1 * z[:, 2], rtol=1e-15)
    # Scalar sigma -> one channel.  (Under jit/vmap it is path_normals times sigma: see above.)
    assert white_noise(KEY, 0, 1, 1.0).shape == (1, 1)
    with pytest.raises(ValueError, match="sigma"):
        white_noise(KEY, 0, 5, [-1.0])
    with pytest.raises(ValueError, match="sigma"):
        white_noise(KEY, 0, 5, [[1.0]])


# --- input effects (docs/measured-data.md) ---------------------------------------------------------


def test_offset_scale_exact():
    x = np.random.default_rng(0).normal(size=(50, 2))
    out = np.asarray(apply_input_effects(x, 0.01, offset=[52.0, -3.0], scale=[1.0, 0.9]))
    np.testing.assert_allclose(out[:, 0], x[:, 0] + 52.0, rtol=1e-15)
    np.testing.assert_allclose(out[:, 1], 0.9 * x[:, 1] - 3.0, rtol=1e-15)
    np.testing.assert_allclose(remove_input_effects(out, 0.01, [52.0, -3.0], [1.0, 0.9]), x,
                               rtol=1e-13, atol=1e-13)


def test_whole_sample_delay_is_a_shift_with_hold():
    x = np.random.default_rng(1).normal(size=(40, 2))
    dt = 0.001
    out = np.asarray(apply_input_effects(x, dt, delay=[3 * dt, -2 * dt]))
    # lag by 3 samples: out[k] = x[k - 3], first sample held before the record
    np.testing.assert_allclose(out[3:, 0], x[:-3, 0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out[:3, 0], x[0, 0], rtol=1e-12)
    # lead by 2 samples: out[k] = x[k + 2], last sample held after the record
    np.testing.assert_allclose(out[:-2, 1], x[2:, 1], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out[-2:, 1], x[-1, 1], rtol=1e-12)
    back = np.asarray(remove_input_effects(out, dt, delay=[3 * dt, -2 * dt]))
    np.testing.assert_allclose(back[:-3, 0], x[:-3, 0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(back[2:, 1], x[2:, 1], rtol=1e-12, atol=1e-12)


def test_fractional_delay_against_analytic_signal():
    dt = 1e-3
    t = np.arange(2000) * dt
    omega = 2 * np.pi * 5.0
    x = np.sin(omega * t)
    delay = 3.37e-3  # 3.37 samples
    out = np.asarray(apply_input_effects(x, dt, offset=1.5, scale=1.1, delay=delay))
    exact = 1.1 * np.sin(omega * (t - delay)) + 1.5
    interior = t >= 4 * dt
    # linear interpolation error bound: scale * h^2/8 * max|f''| = 1.1 * dt^2 omega^2 / 8
    bound = 1.1 * dt**2 * omega**2 / 8
    err = np.abs(out[interior] - exact[interior])
    assert err.max() <= bound
    assert err.max() > 0.1 * bound  # the bound is tight: the test can fail
    # A ramp is reproduced exactly by linear interpolation.
    ramp = 2.0 * t
    out = np.asarray(apply_input_effects(ramp, dt, delay=delay))
    np.testing.assert_allclose(out[interior], 2.0 * (t[interior] - delay), rtol=0, atol=1e-13)


def test_input_effects_jit_and_vmap_over_delay():
    x = jnp.asarray(np.random.default_rng(2).normal(size=(30, 1)))
    delays = jnp.array([0.0, 0.5e-3, 2e-3])
    f = jax.jit(jax.vmap(lambda d: apply_input_effects(x, 1e-3, delay=d)))
    out = np.asarray(f(delays))
    for row, d in zip(out, np.asarray(delays)):
        np.testing.assert_allclose(row, apply_input_effects(x, 1e-3, delay=float(d)), rtol=1e-15)
    np.testing.assert_array_equal(out[0], np.asarray(x))


def test_input_effects_bad_arguments():
    x = np.zeros((10, 2))
    with pytest.raises(ValueError, match="offset"):
        apply_input_effects(x, 0.1, offset=[1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="dt"):
        apply_input_effects(x, -0.1)
    with pytest.raises(ValueError, match="values"):
        apply_input_effects(np.zeros((2, 2, 2)), 0.1)
