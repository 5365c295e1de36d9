"""Spectral ICP refinement of a functional map (Ovsjanikov et al. 2012, Section 6.1), see :func:`icp_refine`.

Conventions (``C_12`` ``(k2, k1)``, ``p2p_21`` ``(n2,)``): :mod:`prodmaps.conventions`.
"""

from __future__ import annotations

import numpy as np

from ..basis import Basis
from ..checks import check_fmap
from ..p2p import from_fmap

__all__ = ["icp_refine"]


def icp_refine(C_12, basis_1: Basis, basis_2: Basis, n_iter: int = 5, *, orthogonal: bool = True,
               return_p2p: bool = False):
    r"""Refine ``C_12`` ``(k2, k1)`` by alternating point-map conversion and map re-estimation.

    Each of the ``n_iter`` iterations converts the current map to a point map with the standard
    nearest-neighbour rule (:func:`prodmaps.p2p.from_fmap` with ``method="std"`` [OBCS*12], ``p2p_21``
    ``(n2,)``; the NO17 demo's refinement is defined on spectral embeddings, so the extended
    conversion of Section 4.4 is not used here), sets
    ``W = Φ2ᵀ A2 Φ1[p2p_21]`` (the map that point map induces, at the same size) and, with
    ``orthogonal`` (the refinement of the NO17 authors' demo), replaces ``C_12`` by the closest
    partial isometry ``U I_{k2×k1} Vᵀ`` of ``W = U Σ Vᵀ``; otherwise by ``W`` itself. The size
    never changes (contrast :func:`prodmaps.fmaps.zoomout`, which grows it). The demo estimates
    ``W`` by Euclidean least squares ``Φ2 \ Φ1[p2p_21]``; here it is the ``A2``-orthogonal
    projection, the convention of every map in this package (they agree for a uniform mass).

    Returns ``C_12`` (``(k2, k1)``), and with ``return_p2p`` also the point map of the last
    conversion (the one the final ``C`` was estimated from).
    """
    C = check_fmap(C_12, basis_1, basis_2, allow_truncation=True)  # (checks the bases too)
    k2, k1 = C.shape
    if int(n_iter) != n_iter or n_iter < 0:
        raise ValueError(f"n_iter must be a non-negative integer, got {n_iter!r}")
    b1, b2 = basis_1.truncate(k1), basis_2.truncate(k2)
    p2p = None
    for _ in range(int(n_iter)):
        p2p = from_fmap(C, b1, b2, method="std")
        W = b2.project(b1.vecs[p2p])  # (k2, k1)
        if orthogonal:  # the closest partial isometry
            U, _, Vt = np.linalg.svd(W, full_matrices=False)  # U (k2, r), Vt (r, k1), r = min(k1, k2)
            W = U @ Vt
        C = W
    return (C, p2p) if return_p2p else C
