"""Independent tasks of the experiments (pairs of shapes) in worker processes.

:func:`map_tasks` runs ``fn(*task)`` for every task and yields the results in the tasks' order,
in ``workers`` processes (``spawn``: nothing of the caller's state is inherited but the
environment), kept for the life of the calling process so that what they hold in memory
serves the next call too. Every task runs with **one BLAS thread**, in the workers and in the serial path
alike, so the numbers do not depend on the number of workers (a BLAS kernel may sum in another
order with another thread count); the workers use the cores instead.

The number of workers is ``workers`` if given, else ``$PRODMAPS_WORKERS``, else the number of
CPUs this process may run on. ``prodmaps reproduce --jobs J`` sets ``PRODMAPS_WORKERS`` to
``max(1, CPUs // J)`` for its notebooks (unless it is set), so ``J`` notebooks at a time do not
start ``J x CPUs`` workers.

Workers are *spawned*, so a plain Python script that runs an experiment needs the usual
``if __name__ == "__main__":`` guard around its work (Python stops a child that would re-run an
unguarded script, and the caller then sees a ``BrokenProcessPool``); notebooks need nothing. Or
set ``PRODMAPS_WORKERS=1``.

Per-shape values are shared through the disk cache of :class:`prodmaps.experiments.shared.store.ShapeStore`
(workers rebuild the store from :func:`store_spec` and keep it for the tasks they run); group the
tasks so that one task holds the pairs that share the expensive per-shape work (e.g. one source
shape), so no two workers compute the same value at the same time.
"""

from __future__ import annotations

import atexit
import os

from .store import ShapeStore

__all__ = ["WORKERS_ENV", "default_workers", "map_by_source", "map_tasks", "one_blas_thread", "shutdown_workers",
           "store_spec", "worker_store"]

WORKERS_ENV = "PRODMAPS_WORKERS"


def default_workers() -> int:
    """``$PRODMAPS_WORKERS`` if set (a positive integer), else the CPUs available to this process."""
    env = os.environ.get(WORKERS_ENV, "").strip()
    if env:
        try:
            n = int(env)
        except ValueError:
            n = 0
        if n < 1:
            raise ValueError(f"{WORKERS_ENV} must be a positive integer, got {env!r}")
        return n
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not on Linux
        return max(1, os.cpu_count() or 1)


def one_blas_thread():
    """Context manager limiting BLAS/LAPACK (and OpenMP) to one thread (``threadpoolctl``)."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1)


def _init_worker():
    one_blas_thread()  # the limit holds from the call on, for the worker's life
    os.environ[WORKERS_ENV] = "1"  # a task that maps tasks itself runs them in its worker


_SLOTS: list = []  # one single-process executor per worker slot, kept for the life of this process
_SLOT_OF: dict = {}  # task key -> slot that ran it last (its worker keeps that key's values in memory)


def _slot(i: int):
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    if i < len(_SLOTS) and getattr(_SLOTS[i], "_broken", False):  # a worker died: start a fresh one
        _SLOTS[i] = None
        for key in [k for k, v in _SLOT_OF.items() if v == i]:
            del _SLOT_OF[key]
    _SLOTS.extend([None] * (i + 1 - len(_SLOTS)))
    if _SLOTS[i] is None:
        _SLOTS[i] = ProcessPoolExecutor(max_workers=1, mp_context=mp.get_context("spawn"),
                                        initializer=_init_worker)
    return _SLOTS[i]


def shutdown_workers() -> None:
    """Stop the worker processes (they are otherwise kept, with their memory, until this process ends)."""
    while _SLOTS:
        ex = _SLOTS.pop()
        if ex is not None:
            ex.shutdown(wait=True, cancel_futures=True)
    _SLOT_OF.clear()


atexit.register(shutdown_workers)


class _Dispatch:
    """Which task a free worker slot runs next (see :func:`map_tasks`)."""

    def __init__(self, keys, workers: int):
        from collections import deque

        self.keys, self.workers = keys, workers
        self.own = [deque() for _ in range(workers)]  # tasks whose key a slot already holds
        self.new = deque()  # the others, in the tasks' order
        for i, key in enumerate(keys):
            s = self._held(key)
            (self.new if s is None else self.own[s]).append(i)

    def _held(self, key):
        s = _SLOT_OF.get(key) if key is not None else None
        return s if s is not None and s < self.workers else None

    def next(self, slot: int):
        """The next task for ``slot`` (None when none is left), in the order :func:`map_tasks` describes."""
        if self.own[slot]:
            return self.own[slot].popleft()
        while self.new:
            i = self.new.popleft()
            key = self.keys[i]
            held = self._held(key)
            if held is not None and held != slot:  # claimed earlier in this call by another slot
                self.own[held].append(i)
                continue
            if key is not None:
                _SLOT_OF[key] = slot
            return i
        donor = max(range(self.workers), key=lambda j: len(self.own[j]))
        if not self.own[donor]:
            return None
        i = self.own[donor].pop()
        if self.keys[i] is not None:
            _SLOT_OF[self.keys[i]] = slot
        return i


def map_tasks(fn, tasks, *, workers: int | None = None, keys=None):
    """Yield ``fn(*task)`` for each task of ``tasks``, in order (see the module doc).

    ``fn`` must be a module-level function and the tasks picklable when ``workers > 1``. Runs
    in this process when ``workers`` is 1 or there is at most one task. The workers are kept
    between calls (:func:`shutdown_workers` stops them); ``keys`` (one hashable per task, e.g.
    the source shape) sends a task to the worker that ran the same key before, so the values it
    keeps in memory (extended-basis operators, descriptors) are computed once per notebook.

    Tasks are handed out one at a time to the worker that is free: a worker runs the tasks of
    the keys it holds, then the new tasks in the given order (it then holds their keys), then
    takes the last waiting task of the busiest worker (whose key moves with it). So the load
    follows the tasks' run times, not their number; which worker runs a task never changes its
    result (one BLAS thread everywhere).
    """
    tasks = [tuple(t) for t in tasks]
    keys = [None] * len(tasks) if keys is None else list(keys)
    if len(keys) != len(tasks):
        raise ValueError(f"keys has {len(keys)} entries for {len(tasks)} tasks")
    workers = default_workers() if workers is None else workers
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 1:
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    if workers == 1 or len(tasks) <= 1:
        for t in tasks:
            with one_blas_thread():
                out = fn(*t)
            yield out
        return
    from concurrent.futures import FIRST_COMPLETED, wait

    plan = _Dispatch(keys, workers)
    running, results, nxt = {}, {}, 0

    def start(slot):
        i = plan.next(slot)
        if i is not None:
            running[_slot(slot).submit(fn, *tasks[i])] = (i, slot)

    try:
        for slot in range(workers):
            start(slot)
        while running:
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for f in done:
                i, slot = running.pop(f)
                results[i] = f.result()
                start(slot)
            while nxt in results:
                yield results.pop(nxt)
                nxt += 1
    finally:
        for f in running:
            f.cancel()


def map_by_source(fn, store, items, *args, workers: int | None = None, **kwargs):
    """Per-pair work grouped by source shape: yield ``(index, fn(...))`` in the order of ``items``.

    ``items`` is ``[(source id, item), ...]``, one per pair; every pair is computed as
    ``fn(store, index, source id, item, *args, **kwargs)`` (``store`` a ShapeStore: this one, or
    in a worker the same store rebuilt from :func:`store_spec` and kept). The pairs of one source
    form one task and a source returns to the worker that had it before.
    """
    groups: dict = {}  # source id -> [(index, item), ...] in the items' order
    for i, (src, item) in enumerate(items):
        groups.setdefault(src, []).append((i, item))
    workers = default_workers() if workers is None else workers
    where = store if workers == 1 or len(groups) <= 1 else store_spec(store)
    # the sources with the most pairs first: the free worker takes the next one, so the last
    # tasks handed out are the short ones
    order = sorted(groups, key=lambda src: -len(groups[src]))
    tasks = [(fn, where, src, groups[src], args, kwargs) for src in order]
    done, nxt = {}, 0
    for records in map_tasks(_source_task, tasks, workers=workers, keys=order):
        done.update(records)
        while nxt in done:  # a source's results wait until the pairs before them are out
            yield nxt, done.pop(nxt)
            nxt += 1


def _source_task(fn, where, src, group, args, kwargs) -> dict:
    """One task of :func:`map_by_source`: ``{index: fn(store, index, src, item, ...)}`` for its group."""
    store = worker_store(where)
    return {i: fn(store, i, src, item, *args, **kwargs) for i, item in group}


def store_spec(store) -> tuple:
    """What a worker needs to rebuild ``store`` (a ShapeStore) with the same disk cache."""
    return (store.dataset, store.n_eig, store.kind, store.disk.enabled, str(store.disk.folder))


_STORES: dict = {}


def worker_store(spec):
    """The ShapeStore of ``spec`` in this process, built once and kept (a ShapeStore is returned as is)."""
    if isinstance(spec, ShapeStore):
        return spec
    if spec not in _STORES:
        dataset, n_eig, kind, enabled, folder = spec
        _STORES[spec] = ShapeStore(dataset, n_eig, kind=kind, disk_cache=enabled, cache_folder=folder)
    return _STORES[spec]
