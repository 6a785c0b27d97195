"""One JAX CPU device per core, so that :func:`jaxdrift.monte_carlo` splits paths over all cores.

XLA's CPU client exposes a single device by default, and one device runs a vmapped batch of paths
on one core (the compiler splits single kernels over threads, but a 1 ms Dormand-Prince step is
hundreds of tiny kernels, so that gains little). With one device per core the runner's
``shard_map`` gives every core its own share of the paths, measured 1.6-1.9x on 2 cores
(``docs/performance.md``). The number of CPU devices is fixed when JAX creates its CPU backend,
i.e. at the first JAX operation, so :func:`use_all_cores` must run before that; the ``jaxdrift``
command calls it before any subcommand touches JAX.
"""

from __future__ import annotations

import os
import re

__all__ = ["use_all_cores", "available_cores"]

#: The XLA flag that lets LLVM use 512-bit vectors in XLA's CPU kernels (XLA's default is 256).
_VECTOR_WIDTH_FLAG = "--xla_cpu_prefer_vector_width"


def _cpu_has_avx512() -> bool:
    """True when /proc/cpuinfo lists ``avx512f`` (False when unknown: not Linux, no file)."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("flags"):
                    return "avx512f" in line.split()
    except OSError:
        pass
    return False


def _prefer_wide_vectors() -> bool:
    """Add ``--xla_cpu_prefer_vector_width=512`` to ``XLA_FLAGS`` on an AVX-512 CPU.

    Only before JAX creates its CPU backend (XLA reads ``XLA_FLAGS`` then), only when the CPU has
    AVX-512 and only when ``XLA_FLAGS`` does not already choose a width (the user's choice stands;
    ``XLA_FLAGS=--xla_cpu_prefer_vector_width=256`` keeps XLA's default). Measured on the half-car
    study (2-core AMD EPYC, ``docs/performance.md``): 1.4x less CPU time per path-step
    for the engine and the fast mode, results bit-identical. Returns whether the flag was added.
    """
    from jax._src import xla_bridge

    flags = os.environ.get("XLA_FLAGS", "")
    if _VECTOR_WIDTH_FLAG in flags or xla_bridge.backends_are_initialized() or not _cpu_has_avx512():
        return False
    os.environ["XLA_FLAGS"] = (flags + f" {_VECTOR_WIDTH_FLAG}=512").strip()
    return True


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity, which honours ``taskset`` and cgroups)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        return os.cpu_count() or 1


def use_all_cores(n: int | None = None) -> int:
    """Ask JAX for ``n`` CPU devices (default: one per available core) and return the count used.

    Call it right after ``import jax`` and before any JAX operation (creating an array, asking for
    ``jax.devices()``): afterwards the CPU backend exists and its device count can no longer
    change, and a different request raises ``RuntimeError``. Nothing is changed, and the current
    count is returned, when the user already chose one: ``XLA_FLAGS`` containing
    ``--xla_force_host_platform_device_count`` or the ``jax_num_cpu_devices`` option set. The
    environment variable ``JAXDRIFT_CPU_DEVICES`` overrides the default count (``1`` keeps JAX's
    single device). Results do not depend on the count: a path's outputs are bit-identical on one
    or several devices (``tests/test_devices.py``).

    On a CPU with AVX-512 it also lets XLA's kernels use 512-bit vectors
    (``--xla_cpu_prefer_vector_width=512`` added to ``XLA_FLAGS`` unless ``XLA_FLAGS`` already sets
    that flag): measured 1.4x less CPU time per path-step on the half-car study, same results.
    """
    import jax
    from jax._src import xla_bridge

    if n is None:
        env = os.environ.get("JAXDRIFT_CPU_DEVICES", "").strip()
        n = int(env) if env else available_cores()
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"n must be a positive int, got {n!r}")
    _prefer_wide_vectors()
    current = int(jax.config.jax_num_cpu_devices)
    flag = re.search(r"--xla_force_host_platform_device_count=(\d+)", os.environ.get("XLA_FLAGS", ""))
    if flag or current >= 1:  # the user's choice stands
        if xla_bridge.backends_are_initialized():
            return len(jax.devices("cpu"))
        return current if current >= 1 else int(flag.group(1))
    if xla_bridge.backends_are_initialized():
        have = len(jax.devices("cpu"))
        if have == n:
            return n
        raise RuntimeError(
            f"use_all_cores({n}) was called after JAX created its CPU backend with {have} device(s): "
            "call it right after `import jax`, before any JAX operation"
        )
    jax.config.update("jax_num_cpu_devices", n)
    return n
