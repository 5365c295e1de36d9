"""ZoomOut refinement of a functional map (Melzi et al. 2019), see :func:`zoomout`.

Conventions (``C_12`` ``(k2, k1)``, ``p2p_21`` ``(n2,)``): :mod:`prodmaps.conventions`.
"""

from __future__ import annotations

import numpy as np

from ..basis import Basis
from ..checks import check_fmap
from ..p2p import from_fmap
from ..progress import progress_bar

__all__ = ["zoomout"]

PROGRESS_MIN_WORK = 2e10  # progress=None: a bar when Σ n1·n2·k over the steps exceeds this (long runs)


def zoomout(C_12, basis_1: Basis, basis_2: Basis, k_final, step: int = 1, return_p2p: bool = False,
            progress: bool | None = None):
    """ZoomOut refinement (Melzi et al. 2019, "ZoomOut: spectral upsampling for efficient shape correspondence").

    Starting from ``C_12`` ``(k2, k1)``, repeat: convert the current map to a point map with
    the standard nearest-neighbour rule (:func:`prodmaps.p2p.from_fmap` with ``method="std"``, ``p2p_21``
    ``(n2,)``; ZoomOut is defined on spectral embeddings, so the extended conversion of Section 4.4
    is not used here),
    grow both sizes by ``step`` (each clipped at its target) and set
    ``C_12 = Φ2ᵀ A2 Φ1[p2p_21]`` at the new size. Stops when the size reaches ``k_final``.

    Parameters
    ----------
    k_final : int (both sides) or ``(k2_final, k1_final)`` (the order of ``C.shape``); counts
        the constant; must not exceed the bases' column counts nor be below ``C_12.shape``.
    step : size increase per iteration (>= 1).
    return_p2p : also return the last point map (the one that produced the final ``C``).
    progress : report progress per step on stderr (tqdm bar, or plain lines without tqdm);
        ``None`` (default): only on long runs (more than ``PROGRESS_MIN_WORK`` multiply-adds of
        nearest-neighbour search) and when stderr is a terminal.

    Each step's point map is the exact nearest-neighbour answer of
    :func:`prodmaps.p2p.nearest_neighbors` (ties to the smallest source index). Everything works
    on bases of point clouds as on bases of meshes.

    Returns
    -------
    C_12 : ``(k2_final, k1_final)``, and the last ``p2p_21`` ``(n2,)`` with ``return_p2p``.

    Raises
    ------
    TypeError
        If a basis is not a :class:`prodmaps.Basis`.
    ValueError
        If ``C_12`` does not fit the bases, ``k_final`` is out of range or ``step < 1``.

    Examples
    --------
    A small map (``k = 4``) between two ellipsoids of the same triangulation, corrupted by noise,
    refined to 20 columns: the point map it ends with is the true one (the identity).

    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.fmaps import zoomout
    >>> m1, m2 = pm.mesh.ellipsoid(2), pm.mesh.ellipsoid(2, axes=(1.1, 0.6, 0.35))
    >>> b1, b2 = pm.eigenbasis(m1, 20), pm.eigenbasis(m2, 20)
    >>> truth = pm.fmap_from_p2p(np.arange(m2.n_vertices), b1, b2)  # (20, 20)
    >>> C_small = truth[:4, :4] + 0.1 * np.random.default_rng(0).normal(size=(4, 4))
    >>> C_12, p2p_21 = zoomout(C_small, b1, b2, 20, return_p2p=True)
    >>> C_12.shape, float(np.mean(p2p_21 == np.arange(m2.n_vertices)))
    ((20, 20), 1.0)
    """
    C = check_fmap(C_12, basis_1, basis_2, allow_truncation=True)  # (checks the bases too)
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
    n_steps = 1 + max(-(-(K1 - k1) // int(step)), -(-(K2 - k2) // int(step)))  # conversions done
    work = float(basis_1.n) * basis_2.n * max(K1, K2) * n_steps
    bar = progress_bar(n_steps, "zoomout", progress=progress, work=work, min_work=PROGRESS_MIN_WORK)
    p2p = None
    while True:
        p2p = from_fmap(C, basis_1, basis_2, method="std")
        bar.update(1)
        done = k1 == K1 and k2 == K2  # then one last conversion at the final size: C comes from a point map
        k1, k2 = min(k1 + step, K1), min(k2 + step, K2)
        C = basis_2.truncate(k2).project(basis_1.vecs[p2p, :k1])  # (k2, k1)
        if done:
            break
    bar.close()
    return (C, p2p) if return_p2p else C
