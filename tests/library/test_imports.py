"""Imports only go down: no cycle among prodmaps modules, no upward import, no private reach-in.

Every module of ``prodmaps/`` is parsed with :mod:`ast` (nothing is imported). Layers, from the
bottom: the math library (every module outside the two subpackages below), then
``prodmaps.experiments`` (what the notebooks share), then ``prodmaps.pipeline`` (runs the
notebooks); ``prodmaps.__main__`` is the command line, on top of everything.

* **Cycles**: module-level imports *and* imports inside functions count. A function-level import
  only delays the cycle to the first call (the module order of a cold import then decides what
  is half-initialised), so it is no way out of one; lazy imports stay for heavy third-party
  packages, never to hide a cycle among our own modules. A package's ``__init__`` counts as a
  module: ``prodmaps/__init__.py`` imports the math library, so ``import prodmaps`` inside a
  math module closes a cycle.
* **Upward imports**: the math library never imports ``prodmaps.experiments`` or
  ``prodmaps.pipeline``; the experiments never import ``prodmaps.pipeline``.
* **Private reach-ins**: ``from prodmaps.x import _name`` or ``x._name`` (``x`` a prodmaps module
  bound by an import), and ``obj._name`` where ``_name`` is not defined in the module using it
  but is a private function, method or attribute of another prodmaps module.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2] / "prodmaps"


def _module_names() -> dict[str, Path]:
    out = {}
    for p in sorted(ROOT.rglob("*.py")):
        parts = ("prodmaps",) + p.relative_to(ROOT).with_suffix("").parts
        out[".".join(parts[:-1]) if parts[-1] == "__init__" else ".".join(parts)] = p
    return out


MODULES = _module_names()
TREES = {name: ast.parse(path.read_text(encoding="utf-8"), filename=str(path)) for name, path in MODULES.items()}


def _package(name: str) -> str:
    return name if MODULES[name].name == "__init__.py" else name.rpartition(".")[0]


def _targets(name: str, node) -> list[tuple[str, str | None]]:
    """``(module, imported name or None)`` of an import statement, prodmaps modules only."""
    out = []
    if isinstance(node, ast.Import):
        for a in node.names:
            if a.name.split(".")[0] == "prodmaps":
                out.append((a.name, None))
        return out
    if node.level:
        base = _package(name).split(".")
        base = base[: len(base) - node.level + 1]
        mod = ".".join(base + ([node.module] if node.module else []))
    else:
        mod = node.module or ""
    if mod.split(".")[0] != "prodmaps":
        return out
    for a in node.names:
        sub = f"{mod}.{a.name}"
        out.append((sub, None) if sub in MODULES else (mod, a.name))
    return out


def _imports(name: str):
    """``(target module, imported name, line, at module level)`` for every import of a prodmaps module."""
    tree = TREES[name]
    top = {id(n) for n in tree.body}
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            for mod, what in _targets(name, node):
                if mod in MODULES:
                    yield mod, what, node.lineno, id(node) in top


def _layer(name: str) -> int:
    if name == "prodmaps.__main__":
        return 3
    if name == "prodmaps.pipeline" or name.startswith("prodmaps.pipeline."):
        return 2
    if name == "prodmaps.experiments" or name.startswith("prodmaps.experiments."):
        return 1
    return 0


def _graph() -> dict[str, set[str]]:
    graph = {name: set() for name in MODULES}
    for name in MODULES:
        for mod, _, _, _ in _imports(name):
            if mod != name:
                graph[name].add(mod)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index, low, on, stack, comps, counter = {}, {}, set(), [], [], [0]
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter[0]
        counter[0] += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        comps.append(sorted(comp))
    return comps


def test_no_import_cycle_among_prodmaps_modules():
    assert _cycles(_graph()) == []


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_imports_only_go_down_the_layers():
    upward = [f"{name}:{line} imports {mod}" for name in MODULES for mod, _, line, _ in _imports(name)
              if _layer(mod) > _layer(name)]
    assert upward == []


def _private_defined(tree) -> set[str]:
    """Private names a module defines: functions, classes, methods, assigned names and attributes."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(node.name)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            out.add(node.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            out.add(node.attr)
        elif isinstance(node, ast.arg):
            out.add(node.arg)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            out.add(node.target.id)
    return {n for n in out if n.startswith("_") and not n.startswith("__")}


PRIVATE = {name: _private_defined(tree) for name, tree in TREES.items()}


def _module_aliases(name: str) -> dict[str, str]:
    """Local names bound to prodmaps modules by the imports of ``name``."""
    out = {}
    for node in ast.walk(TREES[name]):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "prodmaps":
                    out[a.asname or a.name.split(".")[0]] = a.name if a.asname else "prodmaps"
        elif isinstance(node, ast.ImportFrom):
            for mod, what in _targets(name, node):
                if what is None:
                    a = next(x for x in node.names if mod.endswith("." + x.name))
                    out[a.asname or a.name] = mod
    return out


def _private_uses(name: str) -> list[str]:
    found = []
    for mod, what, line, _ in _imports(name):
        if what and what.startswith("_") and not what.startswith("__") and mod != name:
            found.append(f"{name}:{line} imports {what} from {mod}")
    aliases = _module_aliases(name)
    others = set().union(*(PRIVATE[m] for m in MODULES if m != name)) - PRIVATE[name]
    for node in ast.walk(TREES[name]):
        if not isinstance(node, ast.Attribute) or not node.attr.startswith("_") or node.attr.startswith("__"):
            continue
        if isinstance(node.value, ast.Name) and node.value.id in aliases:
            found.append(f"{name}:{node.lineno} uses {aliases[node.value.id]}.{node.attr}")
        elif node.attr in others:
            found.append(f"{name}:{node.lineno} uses .{node.attr} of another module")
    return found


def test_no_module_reaches_into_another_modules_private_names():
    found = [s for name in MODULES for s in _private_uses(name)]
    assert found == []


@pytest.mark.parametrize("source, expected", [
    ("from prodmaps.approx import _gram_eig\n", ["imports _gram_eig"]),
    ("from prodmaps import approx\napprox._gram_eig(1)\n", ["uses prodmaps.approx._gram_eig"]),
    ("def f(ext):\n    return ext._solver_scale()\n", ["uses ._solver_scale"]),
    ("def _mine(x):\n    return x._mine\n", []),
])
def test_the_private_check_finds_reach_ins(monkeypatch, source, expected):
    monkeypatch.setitem(MODULES, "prodmaps.probe", ROOT / "probe.py")
    monkeypatch.setitem(TREES, "prodmaps.probe", ast.parse(source))
    monkeypatch.setitem(PRIVATE, "prodmaps.probe", _private_defined(TREES["prodmaps.probe"]))
    monkeypatch.setitem(MODULES, "prodmaps.other", ROOT / "other.py")
    monkeypatch.setitem(PRIVATE, "prodmaps.other", {"_gram_eig", "_solver_scale"})
    found = _private_uses("prodmaps.probe")
    assert len(found) == len(expected) and all(e in f for e, f in zip(expected, found))
