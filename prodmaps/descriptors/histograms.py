"""SHOT point descriptors [TSDS10] on triangle meshes (see :func:`shot` for the exact layout).

References
----------
[TSDS10] Tombari, Salti, Di Stefano. Unique signatures of histograms for local surface
description. ECCV 2010.
"""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh, check_mesh

__all__ = ["SHOT_DIM", "shot"]

SHOT_DIM = 352  # 32 sectors x 11 bins (the default layout)


def _neighbour_pairs(points: np.ndarray, radius: float):
    """All ordered pairs within ``radius`` (self pairs included): ``(i, j, d)``."""
    from scipy.spatial import cKDTree

    tree = cKDTree(points)
    pairs = tree.sparse_distance_matrix(tree, radius, output_type="ndarray")
    return pairs["i"].astype(np.int64), pairs["j"].astype(np.int64), pairs["v"].astype(np.float64)


def _linear_weights(coord: np.ndarray, n_bins: int, circular: bool):
    """Split a continuous bin coordinate between the two nearest bins: ``(lo, hi, w_lo, w_hi)``.

    Bin centres are at integers 0..n_bins-1. Non-circular coordinates are clamped to the end bins (all
    weight to the end bin outside the centre range).
    """
    if circular:
        base = np.floor(coord)
        frac = coord - base
        lo = np.mod(base, n_bins).astype(np.int64)
        hi = np.mod(base + 1, n_bins).astype(np.int64)
    else:
        c = np.clip(coord, 0.0, n_bins - 1.0)
        base = np.minimum(np.floor(c), n_bins - 2) if n_bins > 1 else np.zeros_like(c)
        frac = c - base
        lo = base.astype(np.int64)
        hi = np.minimum(lo + 1, n_bins - 1)
    return lo, hi, 1.0 - frac, frac


def shot(mesh: Mesh, radius: float | None = None, n_bins: int = 11, *, radius_frac: float = 0.1, n_azimuth: int = 8,
         n_elevation: int = 2, n_radial: int = 2, normals: np.ndarray | None = None,
         chunk_pairs: int = 2_000_000) -> np.ndarray:
    """SHOT descriptor [TSDS10] at every vertex, ``(n, n_azimuth·n_elevation·n_radial·n_bins)``.

    352 columns with the defaults; rows of unit Euclidean length.

    What is implemented
    -------------------
    * Support: the vertices within Euclidean distance ``R`` of the feature vertex ``p`` (a
      cKDTree ball query); ``R = radius`` or, if None, ``radius_frac · sqrt(area)`` (so the
      descriptor is scale-invariant).
    * Local reference frame: eigenvectors of ``M = Σ_i (R - d_i)(q_i - p)(q_i - p)ᵀ / Σ_i (R - d_i)``
      (centred at ``p`` itself, weights ``R - d_i``): ``x`` the largest, ``z`` the smallest
      eigenvector, ``y = z × x``. Sign disambiguation as in TSDS10: ``x`` (resp. ``z``) is flipped
      when more neighbours satisfy ``(q_i - p)·x < 0`` than ``>= 0``. Simplification: exact ties
      are broken by the sign of ``Σ_i (R - d_i)(q_i - p)·x`` (TSDS10 break them with the
      median-neighbour subset); both are rotation-invariant.
    * Grid: ``n_azimuth`` (8) azimuth sectors of the LRF xy-plane, ``n_elevation`` (2) hemispheres
      (``z`` sign), ``n_radial`` (2) shells split at ``R/2``; 32 volumes.
    * Histogram in each volume: ``n_bins`` (11) bins of ``cos θ_i = n_i · z`` over ``[-1, 1]``,
      ``n_i`` the vertex normal of neighbour ``q_i`` and ``z`` the LRF normal at ``p`` (as in the
      PCL implementation).
    * Quadrilinear interpolation: each neighbour's unit vote is split linearly between the two
      nearest bins in each of the four coordinates -- cosine, azimuth (circular), elevation angle
      (bin centres at ±45°) and distance (centres at R/4, 3R/4) -- i.e. 16 weighted votes, the
      products of the four 1-D weights (TSDS10 interpolate in the same four dimensions; PCL
      *adds* separate 1-D corrections instead of multiplying them). Coordinates beyond the first
      or last bin centre give their whole weight to the end bin. The vertex ``p`` itself
      (distance 0) does not vote.
    * The full vector is normalised to unit Euclidean length (all-zero rows stay zero).

    Rows are ordered sector-major: column ``((a·n_elevation + e)·n_radial + r)·n_bins + b``.
    Invariant to rigid motions (up to round-off and to neighbours exactly at distance ``R``).
    """
    mesh = check_mesh(mesh, "shot")
    for name, val in (("n_bins", n_bins), ("n_azimuth", n_azimuth), ("n_elevation", n_elevation),
                      ("n_radial", n_radial)):
        if int(val) != val or val < 1:
            raise ValueError(f"{name} must be a positive integer, got {val!r}")
    V = mesh.vertices  # (n, 3)
    n = V.shape[0]
    if radius is None:
        if not np.isfinite(radius_frac) or radius_frac <= 0:
            raise ValueError(f"radius_frac must be > 0, got {radius_frac!r}")
        radius = radius_frac * np.sqrt(mesh.area)
    if not np.isfinite(radius) or radius <= 0:
        raise ValueError(f"radius must be finite and > 0, got {radius!r}")
    N = mesh.vertex_normals() if normals is None else np.asarray(normals, dtype=np.float64)
    if N.shape != (n, 3) or not np.all(np.isfinite(N)):
        raise ValueError(f"normals must be a finite ({n}, 3) array")

    I, J, D = _neighbour_pairs(V, radius)  # pairs (feature I, neighbour J), distance D
    keep = D > 1e-12 * radius
    I, J, D = I[keep], J[keep], D[keep]
    diff = V[J] - V[I]  # (P, 3)
    w = radius - D  # (P,)

    # weighted covariance (6 unique entries) and LRF
    wsum = np.bincount(I, weights=w, minlength=n)
    cov = np.zeros((n, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            cov[:, a, b] = cov[:, b, a] = np.bincount(I, weights=w * diff[:, a] * diff[:, b], minlength=n)
    cov /= np.where(wsum > 0, wsum, 1.0)[:, None, None]
    _, evecs = np.linalg.eigh(cov)  # ascending eigenvalues
    x_ax = evecs[:, :, 2].copy()  # (n, 3)
    z_ax = evecs[:, :, 0].copy()  # (n, 3)
    for ax in (x_ax, z_ax):
        s = np.einsum("ij,ij->i", diff, ax[I])  # (P,)
        pos = np.bincount(I, weights=(s >= 0).astype(float), minlength=n)
        neg = np.bincount(I, weights=(s < 0).astype(float), minlength=n)
        wsgn = np.bincount(I, weights=w * s, minlength=n)  # tie-break: weighted projection
        ax[(neg > pos) | ((neg == pos) & (wsgn < 0))] *= -1.0
    y_ax = np.cross(z_ax, x_ax)  # (n, 3)

    lx, ly, lz = (np.einsum("ij,ij->i", diff, ax[I]) for ax in (x_ax, y_ax, z_ax))
    cos_t = np.clip(np.einsum("ij,ij->i", N[J], z_ax[I]), -1.0, 1.0)

    azim = np.mod(np.arctan2(ly, lx), 2 * np.pi)
    elev = np.arcsin(np.clip(lz / D, -1.0, 1.0))  # [-π/2, π/2]
    coords = [
        (azim / (2 * np.pi / n_azimuth) - 0.5, n_azimuth, True),
        ((elev + np.pi / 2) / (np.pi / n_elevation) - 0.5, n_elevation, False),
        (D / (radius / n_radial) - 0.5, n_radial, False),
        ((cos_t + 1.0) / (2.0 / n_bins) - 0.5, n_bins, False),
    ]
    splits = [_linear_weights(c, nb, circ) for c, nb, circ in coords]
    strides = [n_elevation * n_radial * n_bins, n_radial * n_bins, n_bins, 1]
    dim = n_azimuth * n_elevation * n_radial * n_bins
    desc = np.zeros(n * dim)
    base = I * dim
    for corner in range(16):
        idx = base.copy()
        wt = np.ones_like(D)
        for d_i, (lo, hi, wlo, whi) in enumerate(splits):
            up = (corner >> d_i) & 1  # this corner's bin along coordinate d_i: the upper or the lower
            idx += (hi if up else lo) * strides[d_i]
            wt *= whi if up else wlo
        desc += np.bincount(idx, weights=wt, minlength=n * dim)
    desc = desc.reshape(n, dim)
    norm = np.linalg.norm(desc, axis=1, keepdims=True)
    return desc / np.where(norm > 0, norm, 1.0)
