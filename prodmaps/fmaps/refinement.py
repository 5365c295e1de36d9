"""ZoomOut refinement of a functional map (Melzi et al. 2019), see :func:`zoomout`.

Conventions: ``C_12`` ``(k2, k1)`` maps coefficients on shape 1 to shape 2; point maps
``p2p_21`` ``(n2,)`` pull back (see :mod:`prodmaps.conventions`).
"""

from __future__ import annotations

import numpy as np

from ..basis import Basis, check_basis
from ..mapping import check_fmap

__all__ = ["zoomout"]




def zoomout(C_12, basis_1: Basis, basis_2: Basis, k_final, step: int = 1, return_p2p: bool = False):
    """ZoomOut refinement (Melzi et al. 2019, "ZoomOut: spectral upsampling for efficient shape correspondence").

    Starting from ``C_12`` ``(k2, k1)``, repeat: convert the current map to a point map with
    the standard nearest-neighbour rule (:func:`prodmaps.p2p.from_fmap`, ``p2p_21`` ``(n2,)``),
    grow both sizes by ``step`` (each clipped at its target) and set
    ``C_12 = Φ2ᵀ A2 Φ1[p2p_21]`` at the new size. Stops when the size reaches ``k_final``.

    Parameters
    ----------
    k_final : int (both sides) or ``(k2_final, k1_final)`` (the order of ``C.shape``); counts
        the constant; must not exceed the bases' column counts nor be below ``C_12.shape``.
    step : size increase per iteration (>= 1).
    return_p2p : also return the last point map (the one that produced the final ``C``).
    """
    from ..p2p import from_fmap

    check_basis(basis_1, "basis_1")
    check_basis(basis_2, "basis_2")
    C = check_fmap(C_12, basis_1, basis_2, allow_truncation=True)
    k2, k1 = C.shape
    if isinstance(k_final, (int, np.integer)):
        K2, K1 = int(k_final), int(k_final)
    else:
        K2, K1 = (int(v) for v in k_final)
    if K1 > basis_1.k or K2 > basis_2.k:
        raise ValueError(f"k_final (k2, k1) = {(K2, K1)} exceeds the bases ({basis_2.k}, {basis_1.k} columns)")
    if K1 < k1 or K2 < k2:
        raise ValueError(f"k_final (k2, k1) = {(K2, K1)} is smaller than the initial map {C.shape}")
    if int(step) < 1:
        raise ValueError(f"step must be >= 1, got {step}")
    p2p = None
    while True:
        p2p = from_fmap(C, basis_1, basis_2, method="std")
        if k1 == K1 and k2 == K2:
            # one last conversion at the final size so the returned C comes from a point map
            C = basis_2.truncate(K2).project(basis_1.vecs[p2p, :K1])
            break
        k1, k2 = min(k1 + step, K1), min(k2 + step, K2)
        C = basis_2.truncate(k2).project(basis_1.vecs[p2p, :k1])  # (k2, k1)
    return (C, p2p) if return_p2p else C
