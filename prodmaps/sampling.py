"""Point sampling on meshes: farthest-point landmarks."""

from __future__ import annotations

import numpy as np

__all__ = ["farthest_point_landmarks"]


def farthest_point_landmarks(vertices: np.ndarray, n: int, start: int = 0) -> np.ndarray:
    """``n`` vertex indices by Euclidean farthest-point sampling from vertex ``start`` (deterministic)."""
    V = np.asarray(vertices, dtype=np.float64)
    idx = [int(start)]
    d = np.linalg.norm(V - V[start], axis=1)
    for _ in range(n - 1):  # n landmarks, a handful of iterations
        j = int(np.argmax(d))
        idx.append(j)
        d = np.minimum(d, np.linalg.norm(V - V[j], axis=1))
    return np.array(idx, dtype=np.int64)
