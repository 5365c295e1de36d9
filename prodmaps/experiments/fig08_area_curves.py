"""Figure 8: the fraction of the surface area with error below a threshold, standard vs products.

The functions, pairs, maps and solvers of the tables (:mod:`prodmaps.experiments.shared.protocol`),
with a collector (:class:`AreaCurves`) computing :func:`area_curves` for every pair; curves are
averaged over a family's functions, then the pairs. Figure 8's columns (:func:`columns`) keep
the short labels of its results (``"std"``, ``"l2"``, ``"B"``, ``"B_gain"``, ``"default"``),
each a transfer of the registry (:data:`prodmaps.transfers.REGISTRY`) with its parameters.
"""

from __future__ import annotations

import numpy as np

from ..metrics import area_fraction_curve
from .shared.protocol import STAGES

__all__ = ["columns", "area_curves", "AreaCurves", "AREA_CRITERIA", "COLUMN_NAMES"]

COLUMN_NAMES = {"std": "std", "l2": "ours A (p=2)", "B": "ours B", "B_gain": "ours B, gain-rule rtol",
                "default": "library default"}
"""Figure 8's column labels and their names in the figure."""


def columns(methods, *, rtol: float, eps_ridge: float, max_gain: float) -> dict:
    """Figure 8's columns ``{label: (registry method, parameters)}`` for the labels ``methods``.

    ``"std"`` the standard transfer, ``"l2"`` Approach A (ridge, ``eps_ridge``), ``"B"`` Approach B
    (``rtol``), ``"B_gain"`` Approach B at the gain rule's threshold (``max_gain``), ``"default"``
    the library's default extended transfer.

    >>> columns(["std", "B"], rtol=1e-3, eps_ridge=1e-6, max_gain=2.0)["B"]
    ('svd', {'rtol': 0.001})
    """
    specs = {"std": ("std", {}), "l2": ("ridge", {"eps": eps_ridge}), "B": ("svd", {"rtol": rtol}),
             "B_gain": ("svd_gain", {"max_gain": max_gain}), "default": ("default", {})}
    unknown = [m for m in methods if m not in specs]
    if unknown:
        raise ValueError(f"Figure 8's methods are among {list(specs)}, got {unknown}")
    return {m: specs[m] for m in methods}


AREA_CRITERIA = ("paper", "scale_free")


def area_curves(f: np.ndarray, g: np.ndarray, mass: np.ndarray, gamma: np.ndarray) -> dict:
    """Figure 8's area fractions ``(len(gamma), m)`` under both criteria.

    ``"paper"``: area where ``(f-g)² < γ·sqrt(∫g²)`` (:func:`prodmaps.area_fraction_curve`);
    ``"scale_free"``: area where ``(f-g)² < γ·∫g²/area`` (squared error relative to the mean square
    of ``g``; the paper's criterion depends on the units of ``f`` and of the shape).
    """
    paper = area_fraction_curve(f, g, mass, gamma)
    ms = np.einsum("i,ij->j", mass, g**2) / mass.sum()  # mean square of g, (m,)
    e = (f - g) ** 2 / ms[None, :]  # scale-free pointwise error
    sf = np.einsum("i,tij->tj", mass, (e[None] < gamma[:, None, None]).astype(float)) / mass.sum()
    return {"paper": paper, "scale_free": sf}


class AreaCurves:
    """Figure 8's accumulator: pass it as ``collect=`` to :func:`run_protocol`.

    For every pair it stores, per criterion, stage (approximation on the source, transfer to the
    target), method and family, the area-fraction curve averaged over the family's functions;
    :meth:`mean` averages over pairs and :meth:`auc` integrates over ``gamma`` (trapezoid);
    :meth:`auc_per_pair` integrates each pair's curve.
    """

    def __init__(self, gamma, families, methods):
        self.gamma = np.asarray(gamma, float)  # (n_gamma,)
        self.families, self.methods = list(families), list(methods)
        self._curves = {c: {st: {m: [] for m in self.methods} for st in STAGES} for c in AREA_CRITERIA}

    def measure(self, ip, size, F, G, cols, b1, b2, outputs) -> dict:
        """One pair and size: ``{(criterion, stage, method): {family: (n_gamma,) curve}}`` (pure)."""
        out = {}
        for m, (fa, ft) in outputs.items():
            for st, f, g, mass in (("approx", fa, F, b1.mass), ("transfer", ft, G, b2.mass)):
                cv = area_curves(f, g, mass, self.gamma)
                for c in AREA_CRITERIA:
                    out[(c, st, m)] = {fam: cv[c][:, cols[fam]].mean(axis=1) for fam in self.families}
        return out

    def add(self, ip, size, record: dict) -> None:
        """Keep :meth:`measure`'s record (pairs in order)."""
        for (c, st, m), by_family in record.items():
            self._curves[c][st][m].append(by_family)

    def __call__(self, ip, size, F, G, cols, b1, b2, outputs):
        """Measure one pair and size and keep the record (:meth:`measure` then :meth:`add`)."""
        self.add(ip, size, self.measure(ip, size, F, G, cols, b1, b2, outputs))

    def __getstate__(self):  # a worker gets the settings; the curves stay with the caller
        return {"gamma": self.gamma, "families": self.families, "methods": self.methods}

    def __setstate__(self, state):
        self.__init__(state["gamma"], state["families"], state["methods"])

    def mean(self) -> dict:
        """``{criterion: {stage: {method: {family: (n_gamma,) curve}}}}`` averaged over pairs."""
        return {c: {st: {m: {f: np.mean([d[f] for d in per_pair], axis=0) for f in self.families}
                         for m, per_pair in by_m.items()} for st, by_m in by_st.items()}
                for c, by_st in self._curves.items()}

    def auc_per_pair(self) -> dict:
        """Each pair's area under its curve, ``{criterion: {stage: {method: {family: [auc per pair]}}}}``.

        Their mean is :meth:`auc` (the integral is linear); the claims ledger compares them pair by pair.
        """
        return {c: {st: {m: {f: [float(np.trapezoid(d[f], self.gamma)) for d in per_pair] for f in self.families}
                         for m, per_pair in by_m.items()} for st, by_m in by_st.items()}
                for c, by_st in self._curves.items()}

    def auc(self) -> dict:
        """Area under each mean curve over ``gamma``, same nesting as :meth:`mean`."""
        def integrate(by_f):
            return {f: float(np.trapezoid(v, self.gamma)) for f, v in by_f.items()}

        return {c: {st: {m: integrate(by_f) for m, by_f in by_m.items()} for st, by_m in by_st.items()}
                for c, by_st in self.mean().items()}
