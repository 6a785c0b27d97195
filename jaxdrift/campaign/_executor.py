"""Where the campaign's tasks run: a Dask ``LocalCluster`` (one single-threaded worker process per
core by default) or an existing Dask scheduler. jaxdrift writes no scheduler, queue or pool of its
own; this module only starts or joins a Dask cluster and maps tasks over it with a progress bar."""

from __future__ import annotations

import contextlib
import os

from ..errors import UsageError

__all__ = ["dask_client", "map_tasks", "MISSING"]

MISSING = ("jaxdrift campaign runs its tasks on Dask, which is not installed: "
           "pip install 'jaxdrift[campaign]' (or pip install 'dask[distributed]')")


def _distributed():
    try:
        import distributed
    except ImportError:
        raise UsageError(MISSING) from None
    return distributed


@contextlib.contextmanager
def dask_client(*, workers: int | None = None, scheduler: str | None = None):
    """A ``distributed.Client`` and the executor's description for the provenance.

    ``scheduler``: ``tcp://HOST:PORT`` of a running ``dask scheduler`` (its workers do the work);
    otherwise a ``LocalCluster`` of ``workers`` processes (default: all cores), one thread each
    (each task is single-threaded numpy/scipy/JAX work; processes keep the GIL out of the way)."""
    distributed = _distributed()
    if scheduler is not None:
        try:
            client = distributed.Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as e:
            raise UsageError(f"--scheduler {scheduler}: cannot connect ({e})") from None
        try:
            n = len(client.scheduler_info().get("workers", {}))
            yield client, {"kind": "dask", "scheduler": scheduler, "workers": n}
        finally:
            client.close()
        return
    n = int(workers or os.cpu_count() or 1)
    if n < 1:
        raise UsageError(f"--workers must be >= 1, got {n}")
    cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                       dashboard_address=":0", silence_logs=40)  # any free port: no clash, no warning
    try:
        client = distributed.Client(cluster)
        try:
            yield client, {"kind": "dask", "scheduler": "LocalCluster", "workers": n}
        finally:
            client.close()
    finally:
        cluster.close()


def map_tasks(client, fn, items, *, desc: str, progress: bool = True, record_failures: bool = False, **kwargs):
    """``[fn(item, **kwargs) for item in items]`` on the cluster, in order, with a progress bar over
    the tasks as they finish. Tasks are pure (Dask keys from their arguments), so clients of one
    scheduler that submit the same task share one computation. ``record_failures``: a task that
    raises (or whose workers keep dying) gives ``{"status": "failed", "message": ...}`` instead of
    stopping the campaign. ``client=None``: in this process, one task after the other (tests)."""
    from tqdm import tqdm

    if not items:
        return []
    if client is None:
        return [fn(it, **kwargs) for it in items]
    distributed = _distributed()
    futures = [client.submit(fn, it, pure=True, **kwargs) for it in items]
    index = {f.key: i for i, f in enumerate(futures)}
    out = [None] * len(items)
    with tqdm(total=len(items), desc=desc, unit="run", disable=not progress, leave=False) as bar:
        for fut in distributed.as_completed(futures):
            i = index[fut.key]
            try:
                out[i] = fut.result()
            except Exception as e:  # noqa: BLE001 - the task's own error, or KilledWorker
                if not record_failures:
                    raise
                out[i] = {"status": "failed", "message": f"{type(e).__name__}: {e}"}
            bar.update(1)
    return out
