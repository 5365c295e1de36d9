"""Package layout: no module shares its name with a function, so every public name is what it says."""

import importlib
import pkgutil
import pydoc
import types

import numpy as np

import prodmaps as pm


def _modules():
    for info in pkgutil.walk_packages(pm.__path__, "prodmaps."):
        if info.name.endswith("__main__"):
            continue
        yield info.name


def test_no_module_is_shadowed_by_or_shares_a_name_with_a_function():
    clashes = []
    for name in _modules():
        mod = importlib.import_module(name)
        parent, _, leaf = name.rpartition(".")
        attr = getattr(importlib.import_module(parent), leaf, None)
        if attr is not mod or callable(attr) or leaf in getattr(mod, "__all__", ()):
            clashes.append(name)
    assert clashes == []


def test_public_names_are_functions_and_classes_not_modules():
    for name in pm.__all__:
        obj = getattr(pm, name)
        assert not isinstance(obj, types.ModuleType), name
        assert callable(obj), name


def test_every_public_name_documents_parameters_returns_raises_and_examples():
    import inspect

    missing = {}
    for name in pm.__all__:
        doc = inspect.getdoc(getattr(pm, name)) or ""
        need = ["Examples", ">>> "] + ([] if inspect.isclass(getattr(pm, name)) else ["Parameters", "Returns"])
        obj = getattr(pm, name)
        need += [] if inspect.isclass(obj) and issubclass(obj, Exception) else ["Raises"]  # errors, warnings
        lacking = [s for s in need if s not in doc]
        if lacking:
            missing[name] = lacking
    assert missing == {}


def test_help_of_transfer_shows_the_function():
    text = pydoc.render_doc(pm.transfer, renderer=pydoc.plaintext)
    assert text.splitlines()[0] == "Python Library Documentation: function transfer in module prodmaps.transfers"
    assert "C_12" in text and "FUNCTIONS" not in text  # the function's page, not a module page


def test_transfer_operator_is_callable_as_named(sphere):
    b = pm.eigenbasis(sphere, 6)
    f = sphere.vertices[:, 2]
    C = np.eye(6)
    g = pm.transfer_operator(C, b, b, "default")(f)
    assert g.shape == f.shape
    np.testing.assert_allclose(g, pm.transfer(f, C, b, b, method="default"))
