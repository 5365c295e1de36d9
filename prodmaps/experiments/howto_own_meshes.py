"""Helpers of the how-to notebook (your own two meshes): demo files and user inputs.

The library calls a user needs are :func:`prodmaps.io.load_mesh_repaired`,
:func:`prodmaps.eigenbasis`, :func:`prodmaps.fmaps.fit_no17` and :func:`prodmaps.transfer`; what
is here builds the demonstration inputs (a mesh that needs cleaning, meshes that cannot be
repaired) and reads the notebook's parameters (landmarks, the function to transfer).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..datasets import dataset_dir
from ..io import file_to_mesh_index, save_mesh
from ..sampling import farthest_point_landmarks

__all__ = ["write_dirty_copy", "write_broken_examples", "user_landmark_pairs", "user_function", "user_ground_truth",
           "resolve_path"]


def write_dirty_copy(mesh, path) -> tuple[int, int]:
    """Write ``mesh`` with real-world defects; returns the file's ``(n_vertices, n_faces)``.

    The defects: a duplicated face, a face repeating a vertex, a small triangle floating beside the body
    and an unreferenced vertex.
    """
    V, F = mesh.vertices, mesh.faces
    far = V.max(0) + 1.0
    V_dirty = np.vstack([V, far, far + [0.01, 0, 0], far + [0, 0.01, 0], V.mean(0)])  # last vertex unreferenced
    F_dirty = np.vstack([F, F[:1], [[F[1, 0], F[1, 1], F[1, 1]]], [[len(V), len(V) + 1, len(V) + 2]]])
    save_mesh(path, V_dirty, F_dirty)
    return len(V_dirty), len(F_dirty)


def write_broken_examples(mesh, folder, valid_file) -> dict:
    """Write files the repairs cannot fix, a non-manifold edge and a truncated copy: ``{name: path}``."""
    folder = Path(folder)
    V, F = mesh.vertices, mesh.faces
    V_nm = np.vstack([V, V[F[0, 0]] + [0.0, 0.0, 0.02]])
    F_nm = np.vstack([F, [[F[0, 0], F[0, 1], len(V)]]])
    save_mesh(folder / "non_manifold.ply", V_nm, F_nm)
    data = Path(valid_file).read_bytes()
    (folder / "truncated.ply").write_bytes(data[: int(0.6 * len(data))])
    return {"non_manifold.ply": folder / "non_manifold.ply", "truncated.ply": folder / "truncated.ply"}


def user_landmark_pairs(landmarks, mesh_2, p2p_21, kept_1, kept_2, n_file_1: int, n_file_2: int) -> np.ndarray:
    """``(q, 2)`` the user's landmark pairs ``[mesh 1 vertex, mesh 2 vertex]`` in the meshes' numbering.

    ``landmarks``: the user's pairs in the files' numbering, translated through the repairs (a
    landmark on a dropped vertex raises). ``landmarks=None``: a stand-in for clicked points — 6
    farthest points of mesh 2 and their ground-truth images (none without a ground truth); the
    studies' landmarks from a ground truth are :func:`prodmaps.experiments.shared.maps.landmark_pairs`
    (chosen on the source).
    """
    if landmarks is None:
        if p2p_21 is None:
            return np.zeros((0, 2), np.int64)
        lm_2 = farthest_point_landmarks(mesh_2.vertices, 6)
        return np.column_stack([p2p_21[lm_2], lm_2])
    lm_file = np.asarray(landmarks, dtype=np.int64).reshape(-1, 2)
    for side, n_file in ((0, n_file_1), (1, n_file_2)):
        bad = (lm_file[:, side] < 0) | (lm_file[:, side] >= n_file)
        if np.any(bad):  # a negative index would silently wrap around to the end of the file
            raise ValueError(f"landmarks on mesh {side + 1} must be vertex indices of its file, in [0, {n_file}); "
                             f"got {lm_file[bad, side].tolist()}")
    lm = np.column_stack([file_to_mesh_index(kept_1, n_file_1)[lm_file[:, 0]],
                          file_to_mesh_index(kept_2, n_file_2)[lm_file[:, 1]]])
    if np.any(lm < 0):
        raise ValueError("a landmark lies on a vertex that the repair removed")
    return lm


def user_function(spec: str, mesh, kept, n_file: int | None = None) -> np.ndarray:
    """The function to transfer: ``"x"``, ``"y"``, ``"z"``, ``"indicator"`` or a file of values.

    ``"indicator"`` is the top 30 % of the height; a ``.txt``/``.npy`` file holds one value per vertex of
    mesh 1's file (``n_file`` of them when given), and anything else (several columns, another count)
    raises ``ValueError``.
    """
    X = mesh.vertices
    if spec in ("x", "y", "z"):
        return X[:, "xyz".index(spec)].copy()
    if spec == "indicator":
        return (X[:, 2] >= np.quantile(X[:, 2], 0.7)).astype(float)
    vals = np.asarray(np.load(spec) if str(spec).endswith(".npy") else np.loadtxt(spec), dtype=float)
    expected = f"{n_file}" if n_file is not None else f"at least {int(np.max(kept)) + 1}"
    if vals.ndim > 1 and vals.shape[1:] != (1,) * (vals.ndim - 1):
        raise ValueError(f"{spec}: one value per vertex of mesh 1's file ({expected}) expected, got an array of "
                         f"shape {vals.shape}; save one function, e.g. np.save(path, values[:, 0])")
    vals = vals.reshape(-1)
    if (n_file is not None and vals.size != n_file) or vals.size <= int(np.max(kept)):
        raise ValueError(f"{spec}: one value per vertex of mesh 1's file ({expected}) expected, got {vals.size}")
    return vals[kept]


def user_ground_truth(path, kept_1, kept_2, n_file_1: int, n_file_2: int) -> np.ndarray:
    """``p2p_21`` ``(n2,)`` in the meshes' numbering from a file in the files' numbering, checked.

    The file holds one vertex of mesh 1's file per vertex of mesh 2's file (``n_file_2`` integers in
    ``[0, n_file_1)``, pyFM's ``p2p_21``); a map of the other direction, indices out of range, or a
    vertex of mesh 2 mapped to a vertex that the repair of mesh 1 dropped raise ``ValueError``.
    """
    gt = np.loadtxt(path, dtype=np.int64, ndmin=1)
    if gt.ndim == 2 and 1 in gt.shape:  # one column, or one row
        gt = gt.reshape(-1)
    if gt.ndim != 1 or gt.size != n_file_2:
        raise ValueError(f"{path}: a ground truth p2p_21 has one vertex of mesh 1 per vertex of mesh 2's file "
                         f"({n_file_2}), got shape {gt.shape}" + (" (the map of the other direction, p2p_12?)"
                                                                  if gt.size == n_file_1 else ""))
    if gt.min() < 0 or gt.max() >= n_file_1:
        raise ValueError(f"{path}: ground-truth values must be vertices of mesh 1's file, in [0, {n_file_1}); "
                         f"got [{gt.min()}, {gt.max()}]")
    p2p_21 = file_to_mesh_index(kept_1, n_file_1)[gt[kept_2]]
    if np.any(p2p_21 < 0):
        raise ValueError(f"{path}: {int(np.sum(p2p_21 < 0))} vertices of mesh 2 map to vertices that the repair "
                         "of mesh 1 removed")
    return p2p_21


def resolve_path(path, dataset: str) -> Path:
    """A user path as given if it exists, else relative to the dataset's folder.

    As given: absolute, or relative to the working directory; the dataset's folder makes the defaults
    point into the embedded data.
    """
    p = Path(path)
    return p if p.exists() else dataset_dir(dataset) / p
