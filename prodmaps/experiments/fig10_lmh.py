"""Figure 10: coordinates and a localized region in the LMH basis, with and without products.

Conventions: ``k`` in the paper's sense counts the non-constant eigenfunctions (bases of
``k + 1`` columns, cotangent Laplacian, lumped mass); products are approximated with Approach B
(``rtol``, the paper's ``1e-3``); errors are the paper's area-weighted relative L2 errors, and for
coordinates the mean over x, y, z.
"""

from __future__ import annotations

import numpy as np

from .. import lmh
from ..approx import PAPER_RTOL
from ..basis import eigenbasis
from .shared.anatomy import body_coordinates
from .shared.reconstruction import COORDINATE_ERROR, coordinate_errors, extended_reconstruction

__all__ = ["lmh_reconstruction"]


def lmh_reconstruction(mesh, *, mh_dim: int, global_dim: int, local_dim: int, region_top_fraction: float,
                       mu_region: float, mu_orth: float, pairs: str = "ordered", rtol: float = PAPER_RTOL,
                       frame=None) -> dict:
    """Figure 10: coordinates in MH and in MH + LMH, each without and with products.

    MH: the first ``mh_dim`` eigenfunctions (constant included); MH + LMH: the first
    ``global_dim`` eigenfunctions (constant included) plus ``local_dim`` localized harmonics of
    the top ``region_top_fraction`` of the height (``up`` of the body frame ``frame``,
    :func:`prodmaps.experiments.shared.anatomy.body_coordinates`: the mesh's own z by default).
    Errors on the whole surface and in the region.

    Returns ``{"results": ..., "region": (n,) bool, "recon": {"MH"|"LMH": (X_std, X_prod)}}``.
    """
    X = mesh.vertices
    z = body_coordinates(X, frame)[:, 2]  # up
    region = z > z.max() - region_top_fraction * (z.max() - z.min())  # (n,) the head
    mh = eigenbasis(mesh, max(mh_dim, global_dim))
    lmh_basis = lmh.lmh_basis(mesh, region, local_dim, global_basis=mh.truncate(global_dim),
                              mu_region=mu_region, mu_orth=mu_orth)
    mh = mh.truncate(mh_dim)
    mass = mh.mass
    loc = lmh_basis.vecs[:, global_dim:]
    inside = np.einsum("i,ij->j", mass * region, loc**2)  # L2 mass of each localized function in the region
    errors, sizes, recon = {}, {}, {}
    for name, basis in (("MH", mh), ("LMH", lmh_basis)):
        X_std = basis.vecs @ basis.project(X)  # A-orthonormal basis: projection
        ext, op, X_prod = extended_reconstruction(basis, X, pairs, rtol)
        errors[name] = {"std": coordinate_errors(X_std, X, mass, region),
                        "prod": coordinate_errors(X_prod, X, mass, region)}
        sizes[name] = {"std": basis.k, "extended": ext.K, "rank_kept": op.rank}
        recon[name] = (X_std, X_prod)
    results = {
        "error_definition": COORDINATE_ERROR + "; region_mean: same on the region",
        "region": {"n_vertices": int(region.sum()), "area_fraction": mass[region].sum() / mass.sum(),
                   "lmh_mass_inside_min": inside.min()},
        "errors": errors, "sizes": sizes,
    }
    return {"results": results, "region": region, "recon": recon, "mass_inside": inside}
