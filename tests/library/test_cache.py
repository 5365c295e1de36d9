"""The explicit, bounded caches (prodmaps.cache) and the callable modules of the layout."""

import subprocess
import sys

import numpy as np
import pytest

from prodmaps.cache import Cache, nbytes


def test_get_computes_once_and_lru_evicts():
    c = Cache(max_entries=2)
    calls = []
    for key in ("a", "b", "a", "c", "b"):
        c.get(key, lambda key=key: calls.append(key) or key.upper())
    # "a" was used again before "c" arrived, so "b" was evicted and recomputed
    assert calls == ["a", "b", "c", "b"]
    assert len(c) == 2 and set(c.keys()) == {"c", "b"}


def test_bytes_bound_and_oversized_values_are_not_kept():
    c = Cache(max_entries=10, max_bytes=1000)
    c.put("x", np.zeros(100))  # 800 bytes
    c.put("y", np.zeros(50))  # 400 bytes: x is evicted to stay under 1000
    assert "x" not in c and "y" in c and c.bytes == 400
    big = c.get("big", lambda: np.zeros(1000))  # 8000 bytes: returned, not kept
    assert big.size == 1000 and "big" not in c
    assert nbytes((np.zeros(2), {"a": np.zeros(3)})) == 40
    with pytest.raises(ValueError):
        Cache(max_entries=0)


def test_operator_modules_import_beside_the_standard_operator():
    code = "import prodmaps.mapping, prodmaps.operators, operator; print(prodmaps.mapping.__file__, operator.add)"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split()[0].endswith("prodmaps/mapping.py")


def test_star_import_shadows_no_standard_module():
    import prodmaps

    names = set(prodmaps.__all__)
    assert not names & set(sys.stdlib_module_names), names & set(sys.stdlib_module_names)
    import pkgutil

    submodules = {m.name for m in pkgutil.iter_modules(prodmaps.__path__)}
    for name in names & submodules:  # a public name that is also a submodule must be that module
        assert getattr(prodmaps, name).__name__ == f"prodmaps.{name}"
