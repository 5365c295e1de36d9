"""Per-shape values computed ahead of the notebooks that need them, on a core they leave idle.

On a cold cache a paper run spends much of its time on values that :class:`ShapeStore` keeps on
disk (eigenbases, SHOT/AWFT descriptors, NO17 maps), while the notebooks before the first user of
a value often run on one core. A prefetcher computes those values on the other core first:

* **Journal.** With ``$PRODMAPS_PREFETCH_JOURNAL`` naming a file, every disk-cache miss of a store
  value appends one JSON line: the request that computes it (dataset, store settings, shape ids,
  map sizes and recipe), never a path or a value. ``prodmaps reproduce`` sets it for its runs,
  so a cold run leaves ``OUT/<profile>/prefetch_journal.jsonl``: the values, in the order the runs
  first needed them.
* **Plan.** A journal kept from a cold run of the same profile (``paper/prefetch/<profile>.jsonl``,
  written by ``python -m prodmaps.experiments.prefetch --keep JOURNAL PLAN``: each request once;
  a journal may hold one twice when two workers needed the same value at once).
* **Prefetcher.** ``python -m prodmaps.experiments.prefetch PLAN`` replays the plan in order at
  the lowest CPU priority (``nice 19``: it takes an idle core, not a busy one) with one BLAS
  thread; a value already on disk is read, not computed. ``reproduce --jobs 1`` starts it beside
  the runs when the plan exists and stops it when they end.

The numbers do not depend on it: a value is the same whichever process computes it first (the
store computes every disk value with one BLAS thread, :meth:`DiskCache.get`), and a notebook that
gets there first computes the value itself. A stale plan (after the notebooks changed) costs
only the idle core's time.
"""

from __future__ import annotations

import json
import os
import sys
import threading
from pathlib import Path

__all__ = ["JOURNAL_ENV", "record", "read_plan", "keep_plan", "replay", "plan_path", "main"]

JOURNAL_ENV = "PRODMAPS_PREFETCH_JOURNAL"


def record(request: dict) -> None:
    """Append ``request`` to the journal named by ``$PRODMAPS_PREFETCH_JOURNAL`` (if set).

    One ``write`` of one short line in append mode: lines from several processes do not interleave.
    """
    path = os.environ.get(JOURNAL_ENV, "").strip()
    if not path:
        return
    line = json.dumps(request, sort_keys=True, separators=(",", ":")) + "\n"
    try:
        with open(path, "a", encoding="utf-8") as fh:
            fh.write(line)
    except OSError:  # a journal is an optimisation: never fail the computation over it
        pass


def read_plan(path) -> list[dict]:
    """The requests of a plan (JSON lines), each once, in their first order; bad lines are skipped."""
    out, seen = [], set()
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        line = line.strip()
        if not line or line in seen:
            continue
        seen.add(line)
        try:
            req = json.loads(line)
        except ValueError:
            continue
        if isinstance(req, dict) and "op" in req:
            out.append(req)
    return out


def keep_plan(journal, plan) -> int:
    """Write ``journal``'s requests, each once in first order, as the plan ``plan``; returns their number."""
    reqs = read_plan(journal)
    Path(plan).parent.mkdir(parents=True, exist_ok=True)
    Path(plan).write_text("".join(json.dumps(r, sort_keys=True, separators=(",", ":")) + "\n" for r in reqs),
                          encoding="utf-8")
    return len(reqs)


def plan_path(root, profile: str) -> Path:
    """Where a profile's plan is kept in the project: ``<root>/paper/prefetch/<profile>.jsonl``."""
    return Path(root) / "paper" / "prefetch" / f"{profile}.jsonl"


def replay(requests, *, cache_folder=None, stop: threading.Event | None = None) -> dict:
    """Compute (or find on disk) every request's value, in order; returns counts per outcome.

    ``cache_folder``: the store's disk cache folder (default: the usual one). A request that
    fails (e.g. a shape the dataset does not have) is counted and skipped.
    """
    from .. import datasets
    from .maps import NO17Recipe, no17_demo_map
    from .store import ShapeStore

    stores: dict = {}
    counts = {"done": 0, "failed": 0}
    for req in requests:
        if stop is not None and stop.is_set():
            break
        try:
            key = (req["dataset"], int(req["n_eig"]), req.get("kind", "cotan"))
            if key not in stores:
                stores[key] = ShapeStore(key[0], key[1], kind=key[2], cache_folder=cache_folder)
            store = stores[key]
            if req["op"] == "basis":
                store.basis(req["sid"])
            elif req["op"] == "descriptor":
                store.descriptor(req["sid"], req["name"])
            elif req["op"] == "no17":
                gt = datasets.ground_truth(store.dataset, req["sid_1"], req["sid_2"])
                no17_demo_map(store, req["sid_1"], req["sid_2"], gt, int(req["k1"]), int(req["k2"]),
                              recipe=NO17Recipe(**req["recipe"]))
            else:
                raise ValueError(f"unknown request {req['op']!r}")
            counts["done"] += 1
        except Exception as exc:  # noqa: BLE001 - the prefetcher must go on with the rest
            counts["failed"] += 1
            print(f"prefetch: skipped {req}: {type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
    return counts


def _exit_with_parent(parent: int) -> None:
    """Stop this process when the process that started it is gone (checked every second)."""
    import time

    while True:
        time.sleep(1.0)
        if os.getppid() != parent:
            os._exit(0)


def main(argv=None) -> int:
    """``python -m prodmaps.experiments.prefetch PLAN``: replay PLAN at the lowest priority.

    ``--keep JOURNAL PLAN`` writes a cold run's journal as a plan instead (e.g.
    ``results/paper/prefetch_journal.jsonl`` to ``paper/prefetch/paper.jsonl``)."""
    args = sys.argv[1:] if argv is None else list(argv)
    if len(args) == 3 and args[0] == "--keep":
        print(f"prefetch: {keep_plan(args[1], args[2])} requests kept in {args[2]}", file=sys.stderr)
        return 0
    if len(args) != 1:
        print("usage: python -m prodmaps.experiments.prefetch PLAN.jsonl\n"
              "       python -m prodmaps.experiments.prefetch --keep JOURNAL.jsonl PLAN.jsonl", file=sys.stderr)
        return 2
    if hasattr(os, "nice"):
        os.nice(19)
    threading.Thread(target=_exit_with_parent, args=(os.getppid(),), daemon=True).start()
    from .parallel import one_blas_thread

    os.environ.pop(JOURNAL_ENV, None)  # its own misses are not the runs' needs
    with one_blas_thread():
        counts = replay(read_plan(args[0]))
    print(f"prefetch: {counts['done']} values ready, {counts['failed']} skipped", file=sys.stderr, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
