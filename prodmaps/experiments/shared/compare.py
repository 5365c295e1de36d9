"""One rule for every stored "better / worse / tie" between two errors.

Two numbers are compared by their **relative** difference ``d = (a - b) / max(|a|, |b|)``:

* ``|d| <= TIE_REL`` — a **tie**: the two are equal up to floating-point rounding (methods equal
  by construction, the noise of other BLAS kernels, thread counts or LAPACK builds).
* otherwise ``a`` is **better** (lower error) when ``a < b`` and **worse** when ``a > b``.

``TIE_REL = 1e-5`` is ten times the largest drift of a smoke-profile value between OpenBLAS
kernels (``docs/benchmarks.md``), far below what the paper's two-decimal tables resolve.

:data:`ROUNDING_REL` is the wider band within which the claims ledger's plain comparisons
(``lower`` / ``not_higher`` of :mod:`prodmaps.experiments.shared.claims`) are *inconclusive*: a
relative difference between ``TIE_REL`` and ``ROUNDING_REL`` is one rounding could flip, so it is
taken both ways and a verdict that depends on it is "inconclusive".
``ROUNDING_REL = 1e-3`` covers the widest drift between one and two BLAS threads (``docs/benchmarks.md``).

Counts of comparisons (``n_products_better`` in the tables, wins over pairs in the point-map
study, cells in the default-transfer study) are reported as ``{"better": n, "tie": n, "worse": n}``
so that a tie is never counted as a win or a loss.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

__all__ = ["TIE_REL", "ROUNDING_REL", "OUTCOMES", "relative_difference", "outcome", "is_tie", "tie_mask", "lower",
           "not_higher", "count_outcomes"]

TIE_REL = 1e-5
ROUNDING_REL = 1e-3
OUTCOMES = ("better", "tie", "worse")


def relative_difference(a: float, b: float) -> float:
    """``(a - b) / max(|a|, |b|)`` (0 when both are 0); raises ``ValueError`` on NaN or infinity.

    Examples
    --------
    >>> relative_difference(1.0, 2.0)
    -0.5
    >>> relative_difference(0.0, 0.0)
    0.0
    """
    a, b = float(a), float(b)
    if not (math.isfinite(a) and math.isfinite(b)):
        raise ValueError(f"cannot compare non-finite values {a!r} and {b!r}")
    scale = max(abs(a), abs(b))
    return 0.0 if scale == 0.0 else (a - b) / scale


def outcome(a: float, b: float, rel: float = TIE_REL) -> str:
    """``"better"`` / ``"worse"`` if error ``a`` is below / above ``b`` by more than ``rel`` relative, else ``"tie"``.

    Examples
    --------
    >>> outcome(0.10, 0.20)
    'better'
    >>> outcome(0.2, 0.2 * (1 + 1e-12))   # equal up to rounding
    'tie'
    >>> outcome(0.3, 0.2)
    'worse'
    """
    d = relative_difference(a, b)
    if abs(d) <= rel:
        return "tie"
    return "better" if d < 0 else "worse"


def is_tie(a: float, b: float, rel: float = TIE_REL) -> bool:
    """``outcome(a, b, rel) == "tie"``."""
    return outcome(a, b, rel) == "tie"


def tie_mask(a, b, rel: float = TIE_REL) -> np.ndarray:
    """:func:`is_tie` elementwise on arrays of errors, broadcasting like ``a - b``.

    ``|a - b| <= rel * max(|a|, |b|)``, ``True`` where both are 0.

    Examples
    --------
    >>> tie_mask([0.1, 0.2, 0.0], [0.2, 0.2 * (1 + 1e-12), 0.0]).tolist()
    [False, True, True]
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return np.abs(a - b) <= rel * np.maximum(np.abs(a), np.abs(b))


def lower(a: float, b: float, rel: float = TIE_REL) -> bool:
    """``a < b`` by more than a tie: ``outcome(a, b, rel) == "better"``."""
    return outcome(a, b, rel) == "better"


def not_higher(a: float, b: float, rel: float = TIE_REL) -> bool:
    """``a <= b`` up to a tie: ``outcome(a, b, rel) != "worse"``."""
    return outcome(a, b, rel) != "worse"


def count_outcomes(pairs: Iterable[tuple[float, float]], rel: float = TIE_REL) -> dict:
    """``{"better": n, "tie": n, "worse": n}`` over ``(a, b)`` pairs (``a`` the method judged).

    Examples
    --------
    >>> count_outcomes([(1.0, 2.0), (2.0, 2.0), (3.0, 2.0), (0.5, 1.0)])
    {'better': 2, 'tie': 1, 'worse': 1}
    """
    out = dict.fromkeys(OUTCOMES, 0)
    for a, b in pairs:
        out[outcome(a, b, rel)] += 1
    return out
