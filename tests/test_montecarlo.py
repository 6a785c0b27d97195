"""Tests of jaxdrift.ensemble._montecarlo: statistics against exact values, invariance, sharding, errors.

The toy path is an Ornstein-Uhlenbeck process (exact discretisation, so its mean and variance are
known in closed form) and a scaled random walk, both built from ``path_normals``.
"""

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxdrift import SampledSignal, solve_ode
from jaxdrift.ensemble._montecarlo import monte_carlo
from jaxdrift.ensemble._noise import path_normals

KEY = jax.random.key(7)
DT = 0.01
N_STEPS = 200
SAVE_EVERY = 20
SAVE_TS = DT * SAVE_EVERY * np.arange(1, N_STEPS // SAVE_EVERY + 1)  # 0.2, 0.4, ..., 2.0
REPO = Path(__file__).resolve().parents[1]


class OU(eqx.Module):
    """dx = -theta (x - 0) dt + sigma dW, x(0) = x0."""

    theta: jax.Array
    sigma: jax.Array
    x0: jax.Array


DEFAULT = OU(theta=jnp.asarray(2.0), sigma=jnp.asarray(0.5), x0=jnp.asarray(1.0))


def toy_path(key, path_index, model):
    """Outputs at SAVE_TS: [OU x, random walk W (variance t)], exact discretisation."""
    m = DEFAULT if model is None else model
    z = path_normals(key, path_index, N_STEPS, 2)
    a = jnp.exp(-m.theta * DT)
    s = m.sigma * jnp.sqrt((1 - a**2) / (2 * m.theta))

    def step(x, zk):
        x = a * x + s * zk
        return x, x

    _, x = jax.lax.scan(step, m.x0 * jnp.ones(()), z[:, 0])
    w = jnp.cumsum(z[:, 1]) * jnp.sqrt(DT)
    ys = jnp.stack([x, w], axis=1)[SAVE_EVERY - 1 :: SAVE_EVERY]
    return ys, jnp.int32(0)


def perturbed_models(n, seed=3):
    rng = np.random.default_rng(seed)
    return OU(
        theta=jnp.asarray(rng.uniform(1.0, 3.0, n)),
        sigma=jnp.asarray(rng.uniform(0.3, 0.7, n)),
        x0=jnp.asarray(rng.uniform(-1.0, 1.0, n)),
    )


def run(n_paths, **kw):
    kw.setdefault("progress", False)
    return monte_carlo(toy_path, n_paths, key=KEY, save_ts=SAVE_TS, **kw)


def assert_stats_close(a, b, rel=1e-12):
    """Statistics equal up to reordered floating-point reductions (scale-relative)."""
    scale = np.abs(a.mean) + np.sqrt(np.abs(a.var))
    np.testing.assert_array_less(np.abs(a.mean - b.mean), rel * scale + 1e-300)
    np.testing.assert_array_less(np.abs(a.var - b.var), rel * np.abs(a.var) + 1e-300)
    assert a.count == b.count


# --- statistics against exact values ---------------------------------------------------------------


def test_mean_and_variance_against_exact_values():
    n = 4000
    # chunk_size=None: 1 MiB per device is far less than 4000 paths need, so the memory budget
    # (measured on a probe compilation) must split the run into chunks.
    r = run(n, max_memory_bytes=1 << 20)
    assert len(jax.devices()) <= r.chunk_size < n and r.chunk_size % len(jax.devices()) == 0
    assert r.count == n and r.n_failed == 0 and r.n_devices == len(jax.devices())
    k = np.arange(1, N_STEPS // SAVE_EVERY + 1) * SAVE_EVERY  # steps taken by each save time
    a = np.exp(-2.0 * DT)
    exact_mean = np.stack([1.0 * a**k, np.zeros_like(SAVE_TS)], axis=1)
    exact_var = np.stack([0.25 * (1 - a ** (2 * k)) / (2 * 2.0), SAVE_TS], axis=1)
    # |empirical - exact| < 4.5 standard errors, for 20 (save time, output) pairs each.
    se_mean = np.sqrt(exact_var / n)
    se_var = exact_var * np.sqrt(2 / (n - 1))  # Gaussian data
    assert np.all(np.abs(r.mean - exact_mean) < 4.5 * se_mean)
    assert np.all(np.abs(r.var - exact_var) < 4.5 * se_var)
    # The bound is not vacuous: an 11 % error in a variance (5 % in a standard deviation) and a
    # 0.1-sigma bias in a mean would be caught.
    assert np.all(4.5 * se_var < 0.11 * exact_var)
    assert np.all(4.5 * se_mean < 0.1 * np.sqrt(exact_var))


def test_statistics_match_numpy_on_kept_paths_with_large_mean():
    # Values near 1e8 with O(1) spread: the naive E[x^2] - E[x]^2 loses every digit here.
    big = OU(theta=jnp.full(201, 2.0), sigma=jnp.full(201, 0.5), x0=jnp.full(201, 1e8))

    def shifted(key, i, model):
        ys, code = toy_path(key, i, model)
        return ys.at[:, 1].add(1e8), code

    r = monte_carlo(shifted, 201, key=KEY, save_ts=SAVE_TS, models=big, chunk_size=8,
                    keep_paths=True, progress=False)
    ys = r.ys.astype(np.float64)
    ref_var = np.var(ys, axis=0, ddof=1)  # numpy's two-pass, the oracle
    np.testing.assert_allclose(r.mean, ys.mean(axis=0), rtol=1e-15)
    np.testing.assert_allclose(r.var, ref_var, rtol=1e-6)
    naive = (np.mean(ys**2, axis=0) - ys.mean(axis=0) ** 2) * 201 / 200
    assert np.max(np.abs(naive - ref_var) / ref_var) > 1e-3  # the test can tell stable from naive


def test_quantiles_against_order_statistics():
    n = 101  # odd: the median is the 51st order statistic
    levels = (0.0, 0.1, 0.5, 1.0)
    r = run(n, chunk_size=16, quantiles=levels, keep_paths=True)
    ys = np.sort(r.ys, axis=0)
    np.testing.assert_array_equal(r.quantile(0.0), ys[0])
    np.testing.assert_array_equal(r.quantile(1.0), ys[-1])
    np.testing.assert_array_equal(r.quantile(0.5), ys[50])
    # level 0.1: position 0.1 * (n - 1) = 10 exactly (numpy's default "linear" method)
    np.testing.assert_array_equal(r.quantile(0.1), ys[10])
    np.testing.assert_array_equal(r.quantiles, np.quantile(r.ys, levels, axis=0))
    with pytest.raises(KeyError):
        r.quantile(0.25)


def test_drift_off_times_against_direct_computation():
    n = 64
    reference = np.stack([np.zeros_like(SAVE_TS), 0.1 * SAVE_TS], axis=1)
    r = run(n, chunk_size=16, drift_threshold=0.6, drift_reference=reference, drift_channel=1,
            keep_paths=True, models=perturbed_models(n))
    expected = np.full(n, np.inf)
    for p in range(n):
        for j in range(len(SAVE_TS)):
            if abs(r.ys[p, j, 1] - 0.1 * SAVE_TS[j]) > 0.6:
                expected[p] = SAVE_TS[j]
                break
    assert 0 < np.sum(np.isfinite(expected)) < n  # both cases occur
    np.testing.assert_array_equal(r.drift_off_time, expected)
    frac = r.drifted_fraction()
    np.testing.assert_allclose(frac, [np.mean(expected <= t) for t in SAVE_TS])
    # reference of shape (n_save,) for the channel, and reference None (= zero)
    r1 = run(n, chunk_size=16, drift_threshold=0.6, drift_reference=0.1 * SAVE_TS,
             drift_channel=-1, models=perturbed_models(n), keep_paths=True)
    np.testing.assert_array_equal(r1.drift_off_time, expected)
    r0 = run(n, chunk_size=16, drift_threshold=0.6, drift_channel=1, keep_paths=True,
             models=perturbed_models(n))
    first = [next((t for t, v in zip(SAVE_TS, r0.ys[p, :, 1]) if abs(v) > 0.6), np.inf)
             for p in range(n)]
    np.testing.assert_array_equal(r0.drift_off_time, first)


# --- reproducibility -------------------------------------------------------------------------------


# One configuration shared by the invariance tests (the compiled chunk function is cached).
N_INV = 37


def inv_kw():
    return dict(models=perturbed_models(N_INV), quantiles=(0.25, 0.5), drift_threshold=0.5,
                keep_paths=True)


def test_chunk_size_invariance_and_paths_equal_direct_calls():
    n = N_INV
    models = perturbed_models(n)
    # 16: three chunks, the last one padded; None: a generous memory budget runs all in one.
    results = [run(n, chunk_size=c, **inv_kw()) for c in (16, None)]
    base = results[0]
    n_dev = len(jax.devices())
    assert [r.chunk_size for r in results] == [16 + (-16) % n_dev, n + (-n) % n_dev]
    for r in results[1:]:
        np.testing.assert_array_equal(r.ys, base.ys)  # per-path outputs: bit for bit
        np.testing.assert_array_equal(r.drift_off_time, base.drift_off_time)
        np.testing.assert_array_equal(r.quantiles, base.quantiles)
        np.testing.assert_array_equal(r.result, base.result)
        assert_stats_close(r, base)
    # A path computed on its own gives the same outputs as inside any chunk.
    single = jax.jit(toy_path)
    for p in (0, 4, 5, 36):
        model = jax.tree_util.tree_map(lambda x: x[p], models)
        np.testing.assert_array_equal(single(KEY, jnp.int32(p), model)[0], base.ys[p])


def test_path_order_invariance():
    n = N_INV
    perm = np.random.default_rng(5).permutation(n)
    models = perturbed_models(n)
    r = run(n, chunk_size=16, **inv_kw())
    perm_j = jnp.asarray(perm, jnp.int32)

    def permuted_path(key, j, model):  # slot j runs original path perm[j]
        return toy_path(key, perm_j[j], model)

    rp = monte_carlo(permuted_path, n, key=KEY, save_ts=SAVE_TS, chunk_size=16, progress=False,
                     models=jax.tree_util.tree_map(lambda x: x[perm], models), keep_paths=True,
                     drift_threshold=0.5)
    np.testing.assert_array_equal(rp.ys, r.ys[perm])
    np.testing.assert_array_equal(rp.drift_off_time, r.drift_off_time[perm])
    assert_stats_close(rp, r)


_SUBPROCESS = """
import os, sys, json
import numpy as np
import jax
jax.config.update("jax_enable_x64", True)
sys.path.insert(0, {tests!r})
import test_montecarlo as t
assert len(jax.devices()) == 2, jax.devices()
out = {{}}
for name, devs in (("two", jax.devices()),):
    r = t.run(t.N_INV, chunk_size=16, devices=devs, **t.inv_kw())
    out[name] = dict(n_devices=r.n_devices, chunk_size=r.chunk_size, mean=r.mean.tolist(),
                     var=r.var.tolist(), q=r.quantiles.tolist(), ys=r.ys.tolist(),
                     drift=[float(x) for x in r.drift_off_time], count=r.count)
json.dump(out, open({path!r}, "w"))
"""


def test_two_devices_give_the_same_statistics_as_one(tmp_path):
    path = tmp_path / "out.json"
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2",
               JAX_PLATFORMS="cpu")
    code = _SUBPROCESS.format(tests=str(REPO / "tests"), path=str(path))
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(path.read_text())
    assert out["two"]["n_devices"] == 2
    assert out["two"]["chunk_size"] == 16
    here = run(N_INV, chunk_size=16, devices=jax.devices()[:1], **inv_kw())
    assert here.n_devices == 1
    for other in (out["two"],):
        np.testing.assert_array_equal(np.array(other["ys"]), here.ys)
        np.testing.assert_array_equal(np.array(other["q"]), here.quantiles)
        np.testing.assert_array_equal(np.array(other["drift"]), here.drift_off_time)
        assert other["count"] == here.count
        mean, var = np.array(other["mean"]), np.array(other["var"])
        scale = np.abs(here.mean) + np.sqrt(here.var)
        assert np.all(np.abs(mean - here.mean) <= 1e-12 * scale)
        assert np.all(np.abs(var - here.var) <= 1e-12 * here.var)


_MULTIPROCESS = """
import sys, json
import jax
jax.config.update("jax_enable_x64", True)
jax.config.update("jax_cpu_collectives_implementation", "gloo")
pid = int(sys.argv[1])
jax.distributed.initialize(coordinator_address="127.0.0.1:{port}", num_processes=2, process_id=pid)
sys.path.insert(0, {tests!r})
import test_montecarlo as t
assert jax.process_count() == 2 and len(jax.devices()) == 2 and len(jax.local_devices()) == 1
r = t.run(t.N_INV, chunk_size=16, **t.inv_kw())
json.dump(dict(n_devices=r.n_devices, mean=r.mean.tolist(), var=r.var.tolist(),
               q=r.quantiles.tolist(), ys=r.ys.tolist(), drift=[float(x) for x in r.drift_off_time]),
          open({path!r} + str(pid), "w"))
"""


def test_two_processes_with_jax_distributed(tmp_path):
    """The multi-host path: two processes on this machine joined by jax.distributed give the
    one-process statistics (the one-process run overlaps the two processes' start-up)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    path = str(tmp_path / "mp")
    code = _MULTIPROCESS.format(port=port, tests=str(REPO / "tests"), path=path)
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    env.pop("XLA_FLAGS", None)
    procs = [subprocess.Popen([sys.executable, "-c", code, str(pid)], env=env,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for pid in (0, 1)]
    try:
        here = run(N_INV, chunk_size=16, **inv_kw())
        for p in procs:
            _, err = p.communicate(timeout=300)
            assert p.returncode == 0, err[-3000:]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
    for pid in (0, 1):
        out = json.loads(Path(path + str(pid)).read_text())
        assert out["n_devices"] == 2
        np.testing.assert_array_equal(np.array(out["ys"]), here.ys)
        np.testing.assert_array_equal(np.array(out["q"]), here.quantiles)
        np.testing.assert_array_equal(np.array(out["drift"]), here.drift_off_time)
        scale = np.abs(here.mean) + np.sqrt(here.var)
        assert np.all(np.abs(np.array(out["mean"]) - here.mean) <= 1e-12 * scale)
        assert np.all(np.abs(np.array(out["var"]) - here.var) <= 1e-12 * here.var)


# --- behaviour -------------------------------------------------------------------------------------


def test_failed_paths_are_reported_and_left_out_of_the_statistics():
    def flaky(key, i, model):
        ys, _ = toy_path(key, i, model)
        bad = i % 5 == 0
        return jnp.where(bad, jnp.nan, ys), jnp.where(bad, 1, 0).astype(jnp.int32)

    n = 23
    with pytest.warns(RuntimeWarning, match="5 of 23 Monte-Carlo paths failed"):
        r = monte_carlo(flaky, n, key=KEY, save_ts=SAVE_TS, chunk_size=8, keep_paths=True,
                        quantiles=(0.5,), progress=False)
    ok = np.arange(n) % 5 != 0
    np.testing.assert_array_equal(r.result, np.where(ok, 0, 1))
    assert r.count == ok.sum() and r.n_failed == 5
    good = r.ys[ok]
    np.testing.assert_allclose(r.mean, good.mean(axis=0), rtol=1e-13)
    np.testing.assert_allclose(r.var, good.var(axis=0, ddof=1), rtol=1e-12)
    np.testing.assert_array_equal(r.quantile(0.5), np.median(good, axis=0))


def test_compiles_once_for_all_chunks():
    traces = []

    def counted(key, i, model):
        traces.append(1)
        return toy_path(key, i, model)

    r = monte_carlo(counted, 10, key=KEY, save_ts=SAVE_TS, chunk_size=4, progress=False)
    assert r.count == 10
    # one trace for the shape check (eval_shape), one for the single compiled chunk function,
    # although 3 chunks ran (the last one padded).
    assert len(traces) == 2


def test_progress_bar(capsys):
    # same configuration as the quantile test: the compiled chunk function is reused
    run(20, chunk_size=16, quantiles=(0.5,), progress=True)
    err = capsys.readouterr().err
    assert "monte_carlo" in err and "20/20" in err
    run(20, chunk_size=16, quantiles=(0.5,), progress=False)
    assert capsys.readouterr().err == ""


def test_bad_arguments():
    with pytest.raises(ValueError, match="n_paths"):
        run(0)
    with pytest.raises(TypeError, match="n_paths"):
        run(2.5)
    with pytest.raises(ValueError, match=r"models\.theta.*leading axis of length n_paths = 10"):
        run(10, models=perturbed_models(9))
    with pytest.raises(ValueError, match="save_ts must be a non-empty 1-D"):
        monte_carlo(toy_path, 4, key=KEY, save_ts=SAVE_TS[None, :], progress=False)
    with pytest.raises(ValueError, match=r"strictly increasing: save_ts\[1\] = 0.2 >= save_ts\[2\] = 0.2"):
        monte_carlo(toy_path, 4, key=KEY, save_ts=[0.1, 0.2, 0.2, 0.3], progress=False)
    with pytest.raises(ValueError, match="n_save = len\\(save_ts\\) = 3"):
        monte_carlo(toy_path, 4, key=KEY, save_ts=[0.1, 0.2, 0.3], progress=False)
    with pytest.raises(ValueError, match="chunk_size"):
        run(4, chunk_size=0)
    with pytest.raises(ValueError, match="quantiles"):
        run(4, quantiles=(1.5,))
    with pytest.raises(ValueError, match="drift_channel 2 out of range"):
        run(4, drift_threshold=1.0, drift_channel=2)
    with pytest.raises(ValueError, match="drift_reference must have shape"):
        run(4, drift_threshold=1.0, drift_reference=np.zeros(3))
    with pytest.raises(ValueError, match="without drift_threshold"):
        run(4, drift_reference=np.zeros(10))
    with pytest.raises(TypeError, match="integer scalar result code"):
        monte_carlo(lambda k, i, m: (toy_path(k, i, m)[0], 0.0), 4, key=KEY, save_ts=SAVE_TS,
                    progress=False)
    with pytest.raises(ValueError, match="key must be a single PRNG key"):
        monte_carlo(toy_path, 4, key=jax.random.split(KEY, 2), save_ts=SAVE_TS, progress=False)


# --- a real ODE path: jaxdrift.solve_ode driven by a noisy sampled input -------------------------


class Decay(eqx.Module):
    k: jax.Array
    sigma: jax.Array


H = 0.01  # input sample spacing = fixed DOPRI5 step
N_INPUT = 101  # samples at 0, 0.01, ..., 1.0
ODE_TS = np.linspace(0.1, 1.0, 10)


def input_samples(key, path_index, model):
    return model.sigma * path_normals(key, path_index, N_INPUT, 1)


def ode_path(key, path_index, model):
    """y' = -k y + u(t), y(0) = 0, u the noisy input linearly interpolated between samples."""
    u = SampledSignal(0.0, H, input_samples(key, path_index, model), kind="linear")
    sol = solve_ode(lambda t, y, args: -model.k * y + u(t), jnp.zeros(1), 0.0, 1.0,
                    saveat=jnp.asarray(ODE_TS), dt=H)
    return sol.ys, sol.result


def test_real_ode_paths_against_exact_recursion():
    n = 24
    rng = np.random.default_rng(11)
    models = Decay(k=jnp.asarray(rng.uniform(1.0, 3.0, n)), sigma=jnp.asarray(rng.uniform(0.5, 2.0, n)))
    r = monte_carlo(ode_path, n, key=KEY, save_ts=ODE_TS, models=models, chunk_size=16,
                    keep_paths=True, progress=False)
    assert r.count == n and np.all(r.result == 0)
    u = np.asarray(jax.vmap(input_samples, in_axes=(None, 0, 0))(KEY, jnp.arange(n), models))[..., 0]
    # Exact solution for an input linear between samples:
    # y(t+h) = e^{-kh} y + u0 (1 - e^{-kh}) / k + (u1 - u0) (h/k - (1 - e^{-kh}) / k^2) / h.
    k = np.asarray(models.k)
    e = np.exp(-k * H)
    g0 = (1 - e) / k
    g1 = (H / k - (1 - e) / k**2) / H
    y = np.zeros(n)
    exact = []
    for j in range(N_INPUT - 1):
        y = e * y + u[:, j] * g0 + (u[:, j + 1] - u[:, j]) * g1
        if (j + 1) % 10 == 0:
            exact.append(y.copy())
    exact = np.stack(exact, axis=1)  # (n, 10)
    # DOPRI5 truncation error with h = 0.01, k <= 3, |y| <= 0.25: measured 6.4e-12 at most.
    np.testing.assert_allclose(r.ys[:, :, 0], exact, rtol=0, atol=5e-11)
    np.testing.assert_allclose(r.mean[:, 0], exact.mean(axis=0), rtol=0, atol=5e-11)
    np.testing.assert_allclose(r.var[:, 0], exact.var(axis=0, ddof=1), rtol=1e-9)


def test_automatic_chunk_size_rule():
    """The rule behind chunk_size=None, on a stub compilation with known memory per path."""
    from types import SimpleNamespace

    from jaxdrift.ensemble._montecarlo import _chunk_size_from_budget

    class Stub:
        def __init__(self, per_path_bytes):
            self.per_path = per_path_bytes

        def lower(self, idx_paths):
            per_device = idx_paths // 2  # 2 devices
            stats = SimpleNamespace(argument_size_in_bytes=0, output_size_in_bytes=0,
                                    temp_size_in_bytes=self.per_path * per_device)
            return SimpleNamespace(compile=lambda: SimpleNamespace(memory_analysis=lambda: stats))

    def args(start, size):
        return (size,)

    # 1000 bytes per path, 1 MB per device -> 1000 paths per device
    assert _chunk_size_from_budget(Stub(1000), args, 2, 100_000, 10**6)[0] == 2000
    # a large budget: at most a tenth of the paths per chunk (5000 per device)
    assert _chunk_size_from_budget(Stub(1000), args, 2, 100_000, 10**9)[0] == 10_000
    # ... but never fewer than 512 per device, and never more than all paths
    assert _chunk_size_from_budget(Stub(1000), args, 2, 3000, 10**9)[0] == 1024
    assert _chunk_size_from_budget(Stub(1000), args, 2, 100, 10**9)[0] == 100
    # a budget below one path still runs one path per device
    assert _chunk_size_from_budget(Stub(1000), args, 2, 100_000, 10)[0] == 2
