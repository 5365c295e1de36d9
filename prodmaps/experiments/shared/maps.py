"""The functional maps of the experiments: ground truth and the computed NO17 maps (disk-cached).

Conventions (``C_12`` ``(k2, k1)`` from the source, shape 1, to the target; ``p2p_21``): :mod:`prodmaps.conventions`.

A computed map follows a :class:`NO17Recipe` (descriptors, energy, solver, refinement);
:data:`RECIPES` names the ones the study ``study_no17`` compares and :data:`DEFAULT_RECIPE` is the
one every paper run uses (its docstring says which and why). Landmark pairs stand in for points a
user would click: farthest-point landmarks on the source and, on the target, the vertex whose
ground-truth image is closest to each (:func:`landmark_pairs`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from ... import fmaps
from ...files import sha256_bytes
from ...p2p import fmap_from_p2p
from ...sampling import farthest_point_landmarks
from .store import EIGEN_CODE, ShapeStore, code_fingerprint

__all__ = ["landmark_pairs", "NO17Recipe", "RECIPES", "DEFAULT_RECIPE", "recipe", "no17_fit",
           "no17_demo_map", "functional_map", "MAP_KINDS", "NO17_CODE"]

MAP_KINDS = ("gt", "computed")
NO17_CODE = EIGEN_CODE + ("prodmaps.fmaps.no17", "prodmaps.fmaps.demo", "prodmaps.fmaps.icp",
                          "prodmaps.fmaps.refinement", "prodmaps.descriptors.spectral", "prodmaps.sampling",
                          "prodmaps.mapping", "prodmaps.p2p", "prodmaps.experiments.shared.maps")
REFINEMENTS = ("none", "icp", "zoomout")


@dataclass(frozen=True)
class NO17Recipe:
    """How a computed NO17 map is made: descriptors, energy, solver and refinement.

    Descriptors (:func:`prodmaps.fmaps.no17_demo_descriptors`): WKS at ``n_descr`` automatic
    energies plus wave-kernel maps at ``n_landmarks`` landmark pairs (:func:`landmark_pairs`),
    every ``subsample_step``-th column, from the first ``k_descr`` eigenpairs of each shape
    (``None``: each shape's map size, ``k1`` on the source and ``k2`` on the target), WKS filter
    ``scaled_wks`` or not. Energy (:func:`prodmaps.fmaps.fit_no17`): weights ``w_descr``,
    ``w_lap``, ``w_dcomm``, Laplacian term ``lap``, term normalisation ``normalize``, descriptor
    normalisation ``normalize_descr``; ``solver`` ``"direct"`` (exact minimiser) or ``"lbfgs"``.
    Refinement at the map's size: ``"icp"`` (:func:`prodmaps.fmaps.icp_refine`, ``refine_iter``
    iterations, orthogonal), ``"zoomout"`` (:func:`prodmaps.fmaps.zoomout` from the map's size up
    to ``zoomout_to`` columns on both shapes, then truncated back to ``(k2, k1)``) or ``"none"``.
    """

    k_descr: int | None = 128
    n_descr: int = 100
    subsample_step: int = 5
    n_landmarks: int = 5
    scaled_wks: bool = True
    normalize_descr: bool | str = True
    w_descr: float = 1.0
    w_lap: float = 1e-2
    w_dcomm: float = 1e-1
    lap: str = "resolvent"
    normalize: str | None = "expected"
    solver: str = "lbfgs"
    refine: str = "none"
    refine_iter: int = 5
    zoomout_to: int = 0

    def __post_init__(self):
        if self.refine not in REFINEMENTS:
            raise ValueError(f"refine must be one of {REFINEMENTS}, got {self.refine!r}")
        if self.refine == "zoomout" and self.zoomout_to < 1:
            raise ValueError("refine='zoomout' needs zoomout_to (the final size, >= the map's)")
        if self.solver not in ("lbfgs", "direct"):
            raise ValueError(f"solver must be 'lbfgs' or 'direct', got {self.solver!r}")


_AUTHORS = NO17Recipe(k_descr=None, n_descr=200, subsample_step=10, n_landmarks=6, scaled_wks=False,
                      normalize_descr="source", w_descr=0.1, w_lap=1e-3, w_dcomm=1.0, lap="eigdiff",
                      normalize="frobenius", solver="direct", refine="icp", refine_iter=5)

#: The candidate recipes of the study ``study_no17`` (``notebooks/study_no17.ipynb``):
#:
#: * ``pyfm``: pyFM's NO17 demo (WKS 100 energies + 5 landmarks' wave-kernel maps from 128
#:   eigenpairs, every 5th column; weights 1 / 1e-2 / 1e-1 with pyFM's "canonical" term
#:   normalisation and the resolvent Laplacian term; L-BFGS; no refinement);
#: * ``pyfm_icp``: the same followed by 5 orthogonal ICP iterations;
#: * ``authors_noicp``: the NO17 authors' basic MATLAB demo (``Commute_Fmap_basic_demo``, also
#:   ``build_funmap.m`` of the authors' group's OFP code, which calls it for a 30 x 40 FAUST map):
#:   WKS 200 energies + wave-kernel maps at 6 landmarks from each shape's map-size eigenpairs
#:   (unscaled filter), every 10th column, both shapes' columns divided by the source norms;
#:   descriptor 0.1, descriptor commutativity 1, Laplacian 1e-3 with the ``(λ - μ)²`` mask divided
#:   by its squared Frobenius norm; exact minimiser; no refinement;
#: * ``authors``: the same with the demo's 5 orthogonal ICP iterations (the full demo);
#: * ``authors_200``: the authors' recipe with the descriptors from 200 eigenpairs on both shapes
#:   and 10 landmarks (their ``build_funmap_largedesc.m``): :data:`DEFAULT_RECIPE`.
RECIPES = {
    "pyfm": NO17Recipe(),
    "pyfm_icp": NO17Recipe(refine="icp"),
    "authors_noicp": replace(_AUTHORS, refine="none"),
    "authors": _AUTHORS,
    "authors_200": replace(_AUTHORS, k_descr=200, n_landmarks=10),
}

DEFAULT_RECIPE = "authors_200"
"""The recipe of every computed map in the paper profiles (Tables 2 and 4, Figures 8 and 13, the studies).

Which and why: the NO17 authors' MATLAB recipe (the ``authors`` entry of :data:`RECIPES`: WKS
200 energies + wave-kernel maps, every 10th column, source norms, weights 0.1 / 1e-3 / 1 with the
Frobenius-normalised ``(λ - μ)²`` mask, exact minimiser, 5 orthogonal ICP iterations) with its
descriptors built from 200 eigenpairs and 10 landmarks, as the authors' group's
``build_funmap_largedesc.m``: of :data:`RECIPES`, the one closest to Table 2's standard transfer
column on the eight public FAUST registrations (``study_no17``, whose results give the numbers).

What the paper leaves open (and this choice fixes): the WKS energies and their number, the
landmarks (the authors' NO17 experiments used segment correspondences; here farthest points and
their ground-truth images, as :func:`landmark_pairs`), the three weights, the Laplacian term's form,
the refinement (ICP here) and the symmetric flip (handled by the landmarks' wave-kernel maps, no
orientation term). The authors' demo fits in the meshes' own units; our fits run on unit-area
shapes, which moves the balance of its descriptor and commutativity terms by FAUST's area
(about 1.7 m²); the demo's Laplacian mask is misaligned with the map when ``k1 != k2`` (see
``notebooks/study_no17.ipynb``), ours is aligned.
"""


def recipe(name_or_recipe) -> NO17Recipe:
    """The :class:`NO17Recipe` of a name in :data:`RECIPES` (a recipe is returned as is)."""
    if isinstance(name_or_recipe, NO17Recipe):
        return name_or_recipe
    if name_or_recipe not in RECIPES:
        raise ValueError(f"unknown NO17 recipe {name_or_recipe!r}; choose from {sorted(RECIPES)}")
    return RECIPES[name_or_recipe]


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


def no17_fit(full_1, full_2, landmarks, k1: int, k2: int, rec: NO17Recipe | str) -> np.ndarray:
    """``C_12`` ``(k2, k1)`` made by recipe ``rec`` (no caching; see :func:`no17_demo_map`).

    ``full_1``, ``full_2``: the shapes' bases with at least ``max(k1, k_descr)`` (and, for
    ZoomOut, ``zoomout_to``) columns; descriptors use their first ``k_descr`` columns, the map
    their first ``k1``, ``k2``. ``landmarks``: ``(q, 2)`` pairs ``[source vertex, target vertex]``.
    """
    rec = recipe(rec)
    kd = (k1, k2) if rec.k_descr is None else rec.k_descr
    D1, D2 = fmaps.no17_demo_descriptors(full_1, full_2, landmarks, n_descr=rec.n_descr,
                                         subsample_step=rec.subsample_step, k_descr=kd, scaled=rec.scaled_wks)
    b1, b2 = full_1.truncate(k1), full_2.truncate(k2)
    C = fmaps.fit_no17(b1, b2, D1, D2, w_descr=rec.w_descr, w_lap=rec.w_lap, w_dcomm=rec.w_dcomm, lap=rec.lap,
                       normalize=rec.normalize, normalize_descr=rec.normalize_descr, solver=rec.solver)
    if rec.refine == "icp":
        C = fmaps.icp_refine(C, b1, b2, rec.refine_iter)
    elif rec.refine == "zoomout":
        K = max(min(rec.zoomout_to, full_1.k, full_2.k), k1, k2)
        C = fmaps.zoomout(C, full_1, full_2, K)[:k2, :k1]
    return C


def no17_demo_map(store: ShapeStore, sid_1: str, sid_2: str, p2p_21, k1: int, k2: int, *,
                  recipe: NO17Recipe | str | None = None, k_descr: int | None = None) -> np.ndarray:
    """Computed NO17 map ``C_12`` ``(k2, k1)`` from ``sid_1`` to ``sid_2`` (:func:`no17_fit`).

    ``recipe``: a name in :data:`RECIPES` or a :class:`NO17Recipe`; None: :data:`DEFAULT_RECIPE`.
    ``k_descr`` (optional) replaces the recipe's eigenpair count for the descriptors when the
    recipe uses a fixed count (the ``pyfm`` ones); recipes built on each shape's map size (the
    authors' ones, ``k_descr=None``) ignore it. ``p2p_21`` (the ground truth) only places the
    target landmarks (:func:`landmark_pairs`). The map is cached on disk with every input in its
    key, so notebooks that ask for the same map share it.
    """
    rec = _recipe_of(recipe)
    if k_descr is not None and rec.k_descr is not None:
        rec = replace(rec, k_descr=int(k_descr))
    p2p_21 = np.ascontiguousarray(p2p_21, dtype=np.int64)
    key = {"mesh_1": store.mesh_key(sid_1), "mesh_2": store.mesh_key(sid_2), "p2p_21": sha256_bytes(p2p_21.tobytes()),
           "n_eig": store.n_eig, "kind": store.kind, "k1": int(k1), "k2": int(k2), "recipe": asdict(rec),
           "code": code_fingerprint(*NO17_CODE)}

    def compute():
        lm = landmark_pairs(store.mesh(sid_1).vertices, p2p_21, rec.n_landmarks)
        return {"C": no17_fit(store.basis(sid_1), store.basis(sid_2), lm, int(k1), int(k2), rec)}

    return store.disk.get("no17", key, compute)["C"]


def _recipe_of(rec) -> NO17Recipe:
    return recipe(DEFAULT_RECIPE if rec is None else rec)


def functional_map(kind: str, store: ShapeStore, sid_1: str, sid_2: str, p2p_21, k1: int, k2: int,
                   **no17_params) -> np.ndarray:
    """``C_12`` ``(k2, k1)``: the ground truth (``kind="gt"``) or a computed NO17 map (``"computed"``)."""
    if kind == "gt":
        return fmap_from_p2p(p2p_21, store.basis(sid_1, k1), store.basis(sid_2, k2))
    if kind == "computed":
        return no17_demo_map(store, sid_1, sid_2, p2p_21, k1, k2, **no17_params)
    raise ValueError(f"map kind must be one of {MAP_KINDS}, got {kind!r}")
