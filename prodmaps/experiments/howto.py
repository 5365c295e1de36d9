"""Helpers of the how-to notebook (your own two meshes): demo files and user inputs.

The library calls a user needs are :func:`prodmaps.io.load_mesh_repaired`,
:func:`prodmaps.eigenbasis`, :func:`prodmaps.fmaps.fit_no17` and :func:`prodmaps.transfer`; what
is here builds the demonstration inputs (a mesh that needs cleaning, meshes that cannot be
repaired) and reads the notebook's parameters (landmarks, the function to transfer).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io import file_to_mesh_index, save_mesh
from ..sampling import farthest_point_landmarks

__all__ = ["write_dirty_copy", "write_broken_examples", "user_landmark_pairs", "user_function", "resolve_path"]


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
    studies' landmarks from a ground truth are :func:`prodmaps.experiments.maps.landmark_pairs`
    (chosen on the source).
    """
    if landmarks is None:
        if p2p_21 is None:
            return np.zeros((0, 2), np.int64)
        lm_2 = farthest_point_landmarks(mesh_2.vertices, 6)
        return np.column_stack([p2p_21[lm_2], lm_2])
    lm_file = np.asarray(landmarks, dtype=np.int64).reshape(-1, 2)
    lm = np.column_stack([file_to_mesh_index(kept_1, n_file_1)[lm_file[:, 0]],
                          file_to_mesh_index(kept_2, n_file_2)[lm_file[:, 1]]])
    if np.any(lm < 0):
        raise ValueError("a landmark lies on a vertex that the repair removed")
    return lm


def user_function(spec: str, mesh, kept) -> np.ndarray:
    """The function to transfer: ``"x"``, ``"y"``, ``"z"``, ``"indicator"`` or a file of values.

    ``"indicator"`` is the top 30 % of the height; a ``.txt``/``.npy`` file holds one value per vertex of
    mesh 1's file.
    """
    X = mesh.vertices
    if spec in ("x", "y", "z"):
        return X[:, "xyz".index(spec)].copy()
    if spec == "indicator":
        return (X[:, 2] >= np.quantile(X[:, 2], 0.7)).astype(float)
    vals = np.load(spec) if str(spec).endswith(".npy") else np.loadtxt(spec)
    return np.asarray(vals, dtype=float).reshape(-1)[kept]


def resolve_path(path, dataset: str) -> Path:
    """A user path as given if it exists, else relative to the dataset's folder.

    As given: absolute, or relative to the working directory; the dataset's folder makes the defaults
    point into the embedded data.
    """
    from ..datasets import dataset_dir

    p = Path(path)
    return p if p.exists() else dataset_dir(dataset) / p
