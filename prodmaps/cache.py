"""Explicit, bounded in-memory caches for values derived from a basis.

A :class:`Cache` is a small least-recently-used memo whose keys are tuples that name what the
value depends on, e.g. ``("product_basis", k, order, pairs)``, held by the (frozen) basis objects:

* A :class:`prodmaps.Basis` owns one cache, **shared with every truncation of it**
  (``basis.truncate(k)`` views the same arrays), so values keyed by the column count ``k``
  survive ``truncate()``: ``product_basis(b.truncate(10))`` twice returns the same object and
  reuses its factorisations.
* A :class:`prodmaps.ProductBasis` owns one for its matrix, Gram matrix, eigendecomposition and
  approximation operators.

Bounds: ``max_entries`` entries (least recently used evicted first) and, optionally,
``max_bytes`` of numpy arrays (sizes are estimated from ``nbytes``). Nothing is cached on disk
here; the experiments layer (:mod:`prodmaps.experiments.shared.store`) has the on-disk cache.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Callable, Hashable

import numpy as np

__all__ = ["Cache", "nbytes"]


def nbytes(value) -> int:
    """Approximate memory of a cached value: numpy arrays (also inside tuples, lists, dicts)."""
    if isinstance(value, np.ndarray):
        return int(value.nbytes)
    if isinstance(value, (tuple, list)):
        return sum(nbytes(v) for v in value)
    if isinstance(value, dict):
        return sum(nbytes(v) for v in value.values())
    data = getattr(value, "data", None)  # scipy.sparse matrices
    if isinstance(data, np.ndarray):
        return int(data.nbytes) + sum(int(getattr(value, a).nbytes) for a in ("indices", "indptr")
                                      if isinstance(getattr(value, a, None), np.ndarray))
    return 0


class Cache:
    """A bounded LRU memo: ``cache.get(key, compute)`` returns the cached value or computes it.

    Parameters
    ----------
    max_entries : evict the least recently used entry beyond this many.
    max_bytes : optional bound on the numpy memory held (``None``: no bound). A value larger
        than the bound is returned but not kept.
    """

    def __init__(self, max_entries: int = 64, max_bytes: int | None = None):
        if int(max_entries) < 1:
            raise ValueError(f"max_entries must be >= 1, got {max_entries}")
        self.max_entries = int(max_entries)
        self.max_bytes = None if max_bytes is None else int(max_bytes)
        self._data: OrderedDict = OrderedDict()
        self._sizes: dict = {}

    def get(self, key: Hashable, compute: Callable[[], object]):
        """The value under ``key``; computed with ``compute()`` and stored if absent."""
        if key in self._data:
            self._data.move_to_end(key)
            return self._data[key]
        value = compute()
        self.put(key, value)
        return value

    def put(self, key: Hashable, value) -> None:
        """Store ``value`` under ``key``, evicting least recently used entries (too large a value is not kept)."""
        size = nbytes(value)
        if self.max_bytes is not None and size > self.max_bytes:
            return
        self._data[key] = value
        self._sizes[key] = size
        self._data.move_to_end(key)
        while len(self._data) > self.max_entries or (
                self.max_bytes is not None and sum(self._sizes.values()) > self.max_bytes):
            old, _ = self._data.popitem(last=False)
            del self._sizes[old]

    def __contains__(self, key) -> bool:
        return key in self._data

    def __len__(self) -> int:
        return len(self._data)

    def keys(self) -> list:
        """The keys held, least recently used first."""
        return list(self._data)

    @property
    def bytes(self) -> int:
        """Memory held by the cached numpy arrays (estimate)."""
        return sum(self._sizes.values())

    def clear(self) -> None:
        """Drop every entry."""
        self._data.clear()
        self._sizes.clear()

    def __repr__(self) -> str:
        return f"Cache({len(self)} entries, {self.bytes / 1e6:.1f} MB, max_entries={self.max_entries})"
