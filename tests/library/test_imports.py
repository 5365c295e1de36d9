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
* **Imports at module level**: a prodmaps module imported inside a function is listed in
  ``FUNCTION_LEVEL_IMPORTS`` with its reason (a cycle, or a heavy optional dependency), or moved up.
* **Tests use the public API**: at most ``MAX_PRIVATE_IN_TESTS`` private functions of the library are
  called, imported or monkeypatched by the tests (``tests/**/*.py``).
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


# Every import of a prodmaps module inside a function (or a class body), keyed by (importing module,
# imported module or name), with the one-line reason it cannot be at module level: a cycle it would close
# (name the cycle), or a prodmaps module that loads a heavy optional dependency at import time. Empty:
# every package-internal import is at module level.
FUNCTION_LEVEL_IMPORTS: dict[tuple[str, str], str] = {}


def _module_level_statements(tree) -> set[int]:
    """ids of the statements that run when the module is imported (the body, through if/try/with blocks)."""
    out, todo = set(), list(tree.body)
    while todo:
        node = todo.pop()
        out.add(id(node))
        if isinstance(node, (ast.If, ast.Try, ast.With)):
            todo += node.body + node.orelse if not isinstance(node, ast.With) else node.body
            if isinstance(node, ast.Try):
                todo += node.finalbody + [s for h in node.handlers for s in h.body]
    return out


def _function_level_imports() -> dict[tuple[str, str], list[int]]:
    """``(importing module, imported module or module.name) -> [lines]`` of imports below module level."""
    out: dict[tuple[str, str], list[int]] = {}
    for name, tree in TREES.items():
        top = _module_level_statements(tree)
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in top:
                for mod, what in _targets(name, node):
                    if mod in MODULES:
                        out.setdefault((name, mod if what is None else f"{mod}.{what}"), []).append(node.lineno)
    return out


def test_package_internal_imports_are_at_module_level_unless_listed_with_a_reason():
    found = _function_level_imports()
    new = {f"{m}:{lines} imports {what}" for (m, what), lines in found.items()
           if (m, what) not in FUNCTION_LEVEL_IMPORTS}
    gone = set(FUNCTION_LEVEL_IMPORTS) - set(found)
    print("\n".join(f"{m} imports {what} in a function: {why}" for (m, what), why in FUNCTION_LEVEL_IMPORTS.items()))
    assert not new, f"move to module level, or list with the cycle or heavy dependency: {sorted(new)}"
    assert not gone, f"no longer imported in a function, drop from FUNCTION_LEVEL_IMPORTS: {sorted(gone)}"
    assert all(why.strip() and "\n" not in why for why in FUNCTION_LEVEL_IMPORTS.values())


def test_the_function_level_import_check_finds_local_imports(monkeypatch):
    source = ("from .approx import PAPER_RTOL\n"
              "try:\n    from . import basis\nexcept ImportError:\n    basis = None\n"
              "def f():\n    from .products import product_basis\n    import prodmaps.mesh as m\n    return m\n"
              "class C:\n    def g(self):\n        from . import approx\n        return approx\n")
    monkeypatch.setitem(MODULES, "prodmaps.probe", ROOT / "probe.py")
    monkeypatch.setitem(TREES, "prodmaps.probe", ast.parse(source))
    found = {k: v for k, v in _function_level_imports().items() if k[0] == "prodmaps.probe"}
    assert found == {("prodmaps.probe", "prodmaps.products.product_basis"): [7],
                     ("prodmaps.probe", "prodmaps.mesh"): [8],
                     ("prodmaps.probe", "prodmaps.approx"): [12]}


def _bound_names(tree) -> set[str]:
    """Names a module or test file binds itself: functions, classes, assigned names and attributes, arguments."""
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
    return out


def _private_defined(tree) -> set[str]:
    """Private names a module defines: functions, classes, methods, assigned names and attributes."""
    return {n for n in _bound_names(tree) if n.startswith("_") and not n.startswith("__")}


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


# ----------------------------------------------------------------- the tests' calls of private functions
# Tests exercise the public API: at most MAX_PRIVATE_IN_TESTS private functions of the library (functions,
# methods and classes whose name starts with one underscore) are called, imported, passed around or
# monkeypatched by name anywhere under tests/. Names the library does not define (pytest's and
# monkeypatch's internals, third-party privates such as pyFM's ``model._set_k``) and names a test file
# defines itself are not the library's and do not count; private data (module constants, attributes) is
# not a function and does not count either.
TESTS = ROOT.parent / "tests"
MAX_PRIVATE_IN_TESTS = 5


def _private_callables() -> dict[str, set[str]]:
    """``name -> {qualified name}`` of every private module-level function, class and method of the library.

    A private module-level name bound by assignment counts when its module calls it (``_clock =
    time.perf_counter`` then ``_clock()``): a function by another name.
    """
    out: dict[str, set[str]] = {}
    for name, tree in TREES.items():
        called = {n.func.id for n in ast.walk(tree) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
        for node in tree.body:
            targets = node.targets if isinstance(node, ast.Assign) else [node.target] \
                if isinstance(node, ast.AnnAssign) else []
            for t in targets:
                if isinstance(t, ast.Name) and t.id in called and t.id.startswith("_") and not t.id.startswith("__"):
                    out.setdefault(t.id, set()).add(f"{name}.{t.id}")

    def visit(body, prefix):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                qual = f"{prefix}.{node.name}"
                if node.name.startswith("_") and not node.name.startswith("__"):
                    out.setdefault(node.name, set()).add(qual)
                if isinstance(node, ast.ClassDef):
                    visit(node.body, qual)

    for name, tree in TREES.items():
        visit(tree.body, name)
    return out


PRIVATE_CALLABLES = _private_callables()


def _test_module_aliases(tree) -> dict[str, str]:
    """Local names a test file binds to prodmaps modules by its imports."""
    out = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "prodmaps":
                    out[a.asname or "prodmaps"] = a.name if a.asname else "prodmaps"
        elif isinstance(node, ast.ImportFrom) and not node.level and (node.module or "").split(".")[0] == "prodmaps":
            for a in node.names:
                if f"{node.module}.{a.name}" in MODULES:
                    out[a.asname or a.name] = f"{node.module}.{a.name}"
    return out


def _label(name: str, module: str | None = None) -> str:
    quals = sorted(PRIVATE_CALLABLES[name])
    inside = [q for q in quals if module and q.startswith(module + ".")]
    return " | ".join(inside or quals)


def _private_calls_in(source: str) -> list[tuple[int, str]]:
    """``(line, qualified name)`` of every use of a private library function in one test file's source."""
    tree = ast.parse(source)
    own, aliases = _bound_names(tree), _test_module_aliases(tree)
    found = []

    def private(name) -> bool:
        return (isinstance(name, str) and name.startswith("_") and not name.startswith("__")
                and name in PRIVATE_CALLABLES and name not in own)

    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and not node.level and (node.module or "").split(".")[0] == "prodmaps":
            found += [(node.lineno, _label(a.name, node.module)) for a in node.names
                      if a.name.startswith("_") and not a.name.startswith("__") and a.name in PRIVATE_CALLABLES]
        elif isinstance(node, ast.Attribute) and private(node.attr):  # x._f(...), x._f passed or wrapped
            module = aliases.get(node.value.id) if isinstance(node.value, ast.Name) else None
            found.append((node.lineno, _label(node.attr, module)))
        elif isinstance(node, ast.Call) and node.args:
            func = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", "")
            strings = [a.value for a in node.args if isinstance(a, ast.Constant) and isinstance(a.value, str)]
            if func in ("setattr", "delattr") and len(node.args) >= 2 and private(getattr(node.args[1], "value", None)):
                target = node.args[0]
                module = aliases.get(target.id) if isinstance(target, ast.Name) else None
                found.append((node.lineno, _label(node.args[1].value, module)))  # monkeypatch.setattr(mod, "_f", ...)
            elif func in ("setattr", "delattr", "patch", "object"):  # monkeypatch.setattr("prodmaps.x._f", ...)
                for s in strings:
                    head, _, leaf = s.rpartition(".")
                    if head.split(".")[0] == "prodmaps" and private(leaf):
                        found.append((node.lineno, _label(leaf, head)))
    return sorted(set(found))


def _private_calls_in_tests() -> dict[str, list[str]]:
    """``qualified name -> ["tests/...py:line", ...]`` over every test file."""
    out: dict[str, list[str]] = {}
    for path in sorted(TESTS.rglob("*.py")):
        for line, label in _private_calls_in(path.read_text(encoding="utf-8")):
            out.setdefault(label, []).append(f"{path.relative_to(TESTS.parent)}:{line}")
    return out


def test_tests_call_at_most_five_private_functions_of_the_library():
    found = _private_calls_in_tests()
    listing = "\n".join(f"{label}: {', '.join(where)}" for label, where in sorted(found.items()))
    print(f"{len(found)} private functions of the library used by the tests:\n{listing}")
    assert len(found) <= MAX_PRIVATE_IN_TESTS, listing


@pytest.mark.parametrize("source, expected", [
    ("from prodmaps.approx import _lasso_violation\n", ["prodmaps.approx._lasso_violation"]),
    ("from prodmaps.fields import quadmesh as qm\nqm._close_holes(Q, 8)\n", ["prodmaps.fields.quadmesh._close_holes"]),
    ("def test(ext):\n    assert ext._materialize_solver()\n", ["prodmaps.products.ProductBasis._materialize_solver"]),
    ("from prodmaps import eigensolver\ndef test(monkeypatch):\n"
     "    monkeypatch.setattr(eigensolver, '_cholesky_inverse', None)\n", ["prodmaps.eigensolver._cholesky_inverse"]),
    ("def test(monkeypatch):\n    monkeypatch.setattr('prodmaps.geodesics._HeatSolver', None)\n",
     ["prodmaps.geodesics._HeatSolver"]),
    ("def _close_holes(Q):\n    return Q\n_close_holes(1)\nx._close_holes(2)\n", []),  # the test's own helper
    ("model._set_k(10)\nrequest._pyfuncitem\nmonkeypatch._setattr\n", []),  # not the library's
    ("from prodmaps import transfers\ndef test(monkeypatch):\n"
     "    monkeypatch.setattr(transfers, '_BLOCK_ROWS', 8)\n", []),  # private data, not a function
])
def test_the_private_call_check_finds_private_functions(monkeypatch, source, expected):
    for name, qual in (("_lasso_violation", "prodmaps.approx._lasso_violation"),
                       ("_close_holes", "prodmaps.fields.quadmesh._close_holes"),
                       ("_materialize_solver", "prodmaps.products.ProductBasis._materialize_solver"),
                       ("_cholesky_inverse", "prodmaps.eigensolver._cholesky_inverse"),
                       ("_HeatSolver", "prodmaps.geodesics._HeatSolver")):
        monkeypatch.setitem(PRIVATE_CALLABLES, name, {qual})
    assert [label for _, label in _private_calls_in(source)] == expected
