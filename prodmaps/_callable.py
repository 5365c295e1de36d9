"""Modules that can be called like their main function: ``pm.transfer(...)``, ``pm.laplacian(...)``.

``prodmaps.transfer`` and ``prodmaps.laplacian`` are modules (``import prodmaps.transfer`` gives
the module, so nothing shadows it) whose main function shares the module's name. Calling the
module calls that function: ``pm.transfer(f, C_12, b1, b2)`` is
``prodmaps.transfer.transfer(f, C_12, b1, b2)``.
"""

from __future__ import annotations

import inspect
import sys
import types

__all__ = ["make_callable"]


class CallableModule(types.ModuleType):
    """A module whose call forwards to its function ``__call_target__``."""

    def __call__(self, *args, **kwargs):
        return getattr(self, self.__call_target__)(*args, **kwargs)


def make_callable(module_name: str, function_name: str | None = None) -> None:
    """Make ``sys.modules[module_name]`` callable as its function ``function_name``
    (default: the module's own last name)."""
    mod = sys.modules[module_name]
    target = function_name or module_name.rsplit(".", 1)[-1]
    mod.__call_target__ = target
    mod.__signature__ = inspect.signature(getattr(mod, target))
    mod.__class__ = CallableModule
