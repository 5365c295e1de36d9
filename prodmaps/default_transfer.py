"""Deprecated module: the default extended transfer is ``method="default"`` of :mod:`prodmaps.transfers`.

Its names still resolve for one release, each with a ``DeprecationWarning`` naming the new one:
``SafeTransfer`` -> :class:`prodmaps.transfers.DefaultTransfer`, ``safe_operator(C, b1, b2, **rule)``
-> ``pm.transfer_operator(C, b1, b2, "default", **rule)``, ``safe_transfer`` ->
``pm.transfer(..., method="default")``, ``DEFAULTS`` -> :data:`prodmaps.transfers.DEFAULT_RULE`,
``isometry_defect`` -> :func:`prodmaps.transfers.isometry_defect`.
"""

from __future__ import annotations

import warnings

from . import transfers

__all__: list[str] = []


def _safe_operator(C_12, basis_1, basis_2, **params):
    params.pop("pairs", None)  # accepted and unused, as before
    return transfers.transfer_operator(C_12, basis_1, basis_2, "default", **params)


_MOVED = {
    "SafeTransfer": (lambda: transfers.DefaultTransfer, "prodmaps.transfers.DefaultTransfer"),
    "safe_operator": (lambda: _safe_operator, "prodmaps.transfer_operator(C_12, basis_1, basis_2, 'default', ...)"),
    "safe_transfer": (lambda: transfers.safe_transfer, "prodmaps.transfer(..., method='default')"),
    "DEFAULTS": (lambda: transfers.DEFAULT_RULE, "prodmaps.transfers.DEFAULT_RULE"),
    "isometry_defect": (lambda: transfers.isometry_defect, "prodmaps.transfers.isometry_defect"),
}


def __getattr__(name: str):
    if name in _MOVED:
        value, new = _MOVED[name]
        warnings.warn(f"prodmaps.default_transfer.{name} is deprecated: use {new}", DeprecationWarning, stacklevel=2)
        return value()
    raise AttributeError(f"module 'prodmaps.default_transfer' has no attribute {name!r}")
