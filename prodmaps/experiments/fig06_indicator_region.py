"""Figure 6: the indicator of a region in the standard and extended bases, thresholded at 0.5.

Conventions: ``k`` in the paper's sense counts the non-constant eigenfunctions (bases of
``k + 1`` columns, cotangent Laplacian, lumped mass); products are approximated with Approach B
(``rtol``, the paper's ``1e-3``); errors are the paper's area-weighted relative L2 errors, and for
coordinates the mean over x, y, z.
"""

from __future__ import annotations

import numpy as np

from ..approx import PAPER_RTOL
from ..basis import eigenbasis
from ..metrics import relative_error
from .shared.reconstruction import extended_reconstruction

__all__ = ["indicator_region"]


def indicator_region(mesh, ks, region_center, region_radius: float, *, threshold: float = 0.5,
                     pairs: str = "ordered", rtol: float = PAPER_RTOL) -> dict:
    """Figure 6: a Euclidean ball's indicator approximated without and with products, and its region.

    The region is recovered by thresholding at ``threshold``.

    Scores: ``rel_l2`` (relative L2 error), ``sym_diff = area(R̂ Δ R) / area(R)``,
    ``iou = area(R̂ ∩ R) / area(R̂ ∪ R)``, ``recovered_area_fraction``. Returns
    ``{"results": ..., "region": (n,) bool, "chi": (n,), "approx": {k: (f_std, f_prod, R̂_std, R̂_prod)}}``.
    """
    X = mesh.vertices
    centre = int(np.argmin(np.linalg.norm(X - np.asarray(region_center), axis=1)))
    region = np.linalg.norm(X - X[centre], axis=1) < region_radius  # (n,) true region R
    chi = region.astype(float)
    full = eigenbasis(mesh, max(ks) + 1)
    mass = full.mass

    def scores(f):
        rec = f > threshold  # recovered region R̂
        union = mass[rec | region].sum()
        return {"rel_l2": relative_error(f, chi, mass),
                "sym_diff": mass[rec ^ region].sum() / mass[region].sum(),
                "iou": mass[rec & region].sum() / union if union > 0 else 0.0,
                "recovered_area_fraction": mass[rec].sum() / mass.sum()}, rec

    errors, approx = {"std": {}, "prod": {}}, {}
    for k in ks:
        basis = full.truncate(k + 1)
        f_std = basis.vecs @ basis.project(chi)
        _, _, f_prod = extended_reconstruction(basis, chi, pairs, rtol)
        (errors["std"][f"k{k}"], r_std), (errors["prod"][f"k{k}"], r_prod) = scores(f_std), scores(f_prod)
        approx[k] = (f_std, f_prod, r_std, r_prod)
    results = {
        "error_definition": {"rel_l2": "sqrt(int (f-chi)^2)/sqrt(int chi^2)", "sym_diff": "area(Rhat xor R)/area(R)",
                             "iou": "area(Rhat and R)/area(Rhat or R)", "threshold": threshold},
        "region": {"centre_vertex": centre, "n_vertices": int(region.sum()),
                   "area_fraction": mass[region].sum() / mass.sum()},
        "errors": errors,
    }
    return {"results": results, "region": region, "chi": chi, "approx": approx}
