"""The functional maps of the experiments: ground truth and the NO17 demo maps (disk-cached).

Conventions (:mod:`prodmaps.conventions`): ``C_12`` is ``(k2, k1)`` and maps coefficients on the
source (shape 1) to the target (shape 2); ``p2p_21`` ``(n2,)`` gives for each target vertex its
source vertex; ``k1``, ``k2`` count basis columns including the constant.

The computed maps follow pyFM's NO17 demo: descriptors are WKS (100 energies) plus wave-kernel
maps at 5 landmark pairs — farthest-point landmarks on the source and, on the target, the vertex
whose ground-truth image is closest to each (a stand-in for points a user would click) — every
5th column kept, built from ``k_descr`` eigenpairs of each shape; the map minimises the NO17
energy with the default weights (:func:`prodmaps.fmaps.fit_no17`, L-BFGS).
"""

from __future__ import annotations

import numpy as np

from .. import fmaps
from ..files import sha256_bytes
from ..mapping import fmap_from_p2p
from ..sampling import farthest_point_landmarks
from .store import EIGEN_CODE, ShapeStore, code_fingerprint

__all__ = ["landmark_pairs", "no17_demo_map", "functional_map", "MAP_KINDS", "NO17_CODE"]

MAP_KINDS = ("gt", "computed")
NO17_CODE = EIGEN_CODE + ("prodmaps.fmaps.no17", "prodmaps.fmaps.demo", "prodmaps.descriptors.spectral",
                          "prodmaps.sampling", "prodmaps.mapping")


def landmark_pairs(vertices_1: np.ndarray, p2p_21, n: int = 5) -> np.ndarray:
    """``(n, 2)`` landmark pairs ``[source vertex, target vertex]`` from a ground-truth map.

    Source landmarks: ``n`` farthest points of the source (from vertex 0). Target landmark: the
    target vertex whose ground-truth image ``vertices_1[p2p_21]`` is closest to the source one.
    """
    from scipy.spatial import cKDTree

    V1 = np.asarray(vertices_1, dtype=np.float64)
    l1 = farthest_point_landmarks(V1, n)
    _, l2 = cKDTree(V1[np.asarray(p2p_21)]).query(V1[l1])
    return np.column_stack([l1, l2]).astype(np.int64)


def no17_demo_map(store: ShapeStore, sid_1: str, sid_2: str, p2p_21, k1: int, k2: int, *,
                  k_descr: int = 128, n_descr: int = 100, subsample_step: int = 5,
                  n_landmarks: int = 5) -> np.ndarray:
    """NO17 functional map ``C_12`` ``(k2, k1)`` from ``sid_1`` to ``sid_2`` (module doc recipe).

    The descriptors come from the first ``k_descr`` columns of the store's bases; the map is
    cached on disk with every input in its key, so notebooks that ask for the same map share it.
    """
    p2p_21 = np.ascontiguousarray(p2p_21, dtype=np.int64)
    key = {"mesh_1": store.mesh_key(sid_1), "mesh_2": store.mesh_key(sid_2), "p2p_21": sha256_bytes(p2p_21.tobytes()),
           "n_eig": store.n_eig, "kind": store.kind, "k1": int(k1), "k2": int(k2), "k_descr": int(k_descr),
           "n_descr": int(n_descr), "subsample_step": int(subsample_step), "n_landmarks": int(n_landmarks),
           "code": code_fingerprint(*NO17_CODE)}

    def descriptors():
        lm = landmark_pairs(store.mesh(sid_1).vertices, p2p_21, n_landmarks)
        return fmaps.no17_demo_descriptors(store.basis(sid_1), store.basis(sid_2), lm, n_descr=n_descr,
                                           subsample_step=subsample_step, k_descr=k_descr)

    def compute():
        D1, D2 = store.memo.get(("no17_descriptors", sid_1, sid_2, key["p2p_21"], k_descr, n_descr,
                                 subsample_step, n_landmarks), descriptors)
        return {"C": fmaps.fit_no17(store.basis(sid_1, k1), store.basis(sid_2, k2), D1, D2)}

    return store.disk.get("no17", key, compute)["C"]


def functional_map(kind: str, store: ShapeStore, sid_1: str, sid_2: str, p2p_21, k1: int, k2: int,
                   **no17_params) -> np.ndarray:
    """``C_12`` ``(k2, k1)``: the ground truth (``kind="gt"``) or the NO17 demo map (``"computed"``)."""
    if kind == "gt":
        return fmap_from_p2p(p2p_21, store.basis(sid_1, k1), store.basis(sid_2, k2))
    if kind == "computed":
        return no17_demo_map(store, sid_1, sid_2, p2p_21, k1, k2, **no17_params)
    raise ValueError(f"map kind must be one of {MAP_KINDS}, got {kind!r}")
