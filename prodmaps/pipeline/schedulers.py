"""Where runs execute: this process, a local process pool, or a Dask distributed cluster.

The execution function and the result collector are passed in (:mod:`prodmaps.pipeline.execute`),
so a scheduler only decides *where* a task runs. With several notebooks at once, BLAS threads are
capped so they do not oversubscribe the CPUs.
"""

from __future__ import annotations

import os
import time

from ..experiments.shared.parallel import WORKERS_ENV

__all__ = ["thread_env", "run_pool", "run_dask", "SchedulerError"]


class SchedulerError(ValueError):
    """The Dask scheduler cannot be reached (the message names the address and the fix)."""


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    """Fail at once, with the address, when nothing listens at a ``tcp://host:port`` scheduler address.

    Dask's own client retries for its whole connect timeout and then raises a bare traceback.
    """
    import socket
    from urllib.parse import urlsplit

    parts = urlsplit(address if "://" in address else f"tcp://{address}")
    if parts.scheme not in ("tcp", "tls") or not parts.hostname:
        return
    try:
        port = parts.port
    except ValueError as exc:
        raise SchedulerError(f"--scheduler {address!r}: {exc}") from exc
    if port is None:
        raise SchedulerError(f"--scheduler {address!r} names no port (e.g. tcp://host:8786)")
    try:
        socket.create_connection((parts.hostname, port), timeout=timeout).close()
    except OSError as exc:
        raise SchedulerError(f"no Dask scheduler reachable at {address} ({exc.strerror or exc}); start one with "
                             "`dask scheduler` (pip install 'prodmaps[dask]') or drop --scheduler to run "
                             "locally") from exc


def thread_env(jobs: int) -> dict:
    """With several notebooks at once, cap BLAS threads and worker processes so they do not oversubscribe.

    The workers are the experiments' (``PRODMAPS_WORKERS``, :mod:`prodmaps.experiments.shared.parallel`).
    A variable the user set is left out: their choice stays.
    """
    if jobs <= 1:
        return {}
    n = str(max(1, (os.cpu_count() or 1) // jobs))
    names = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", WORKERS_ENV)
    return {k: n for k in names if not os.environ.get(k)}


def run_pool(tasks: list[dict], jobs: int, execute, collect):
    """Run ``execute(task)`` in a spawn-based process pool of ``jobs`` workers; yield results."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed

    with ProcessPoolExecutor(max_workers=min(jobs, len(tasks)), mp_context=mp.get_context("spawn")) as ex:
        futs = {ex.submit(execute, t): t for t in tasks}
        for fut in as_completed(futs):
            yield collect(fut, futs[fut])


def run_dask(tasks: list[dict], scheduler, execute, collect):
    """Submit one task per run to a Dask cluster and yield results as they finish."""
    if not tasks:
        return
    try:
        from dask.distributed import Client, as_completed
    except ModuleNotFoundError as exc:
        raise ModuleNotFoundError("--scheduler needs Dask: pip install 'prodmaps[dask]'") from exc
    own = not hasattr(scheduler, "submit")
    if own:
        _check_reachable(str(scheduler))
        try:
            client = Client(scheduler)
        except (OSError, TimeoutError) as exc:
            raise SchedulerError(f"could not connect to the Dask scheduler at {scheduler}: {exc}") from exc
    else:
        client = scheduler
    try:
        futs = {client.submit(execute, t, key=f"prodmaps-{t['name']}-{t['hash'][:12]}-{time.time_ns()}",
                              pure=False, retries=0): t for t in tasks}
        for f in as_completed(list(futs)):
            yield collect(f, futs[f])
    finally:
        if own:
            client.close()
