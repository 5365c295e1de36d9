"""Figures 4, 5, 6 and 10: functions on one shape represented with and without products.

Conventions: ``k`` in the paper's sense counts the non-constant eigenfunctions (bases of
``k + 1`` columns, cotangent Laplacian, lumped mass); products are approximated with Approach B
(``rtol``, the paper's ``1e-3``); errors are the paper's area-weighted relative L2 errors, and for
coordinates the mean over x, y, z. A count of basis columns with the constant is a ``*_dim``
(Figure 10's ``mh_dim``, ``global_dim``), or ``n_eig`` (Figure 5).
"""

from __future__ import annotations

import time

import numpy as np

from ..basis import eigenbasis
from ..checks import renamed_keywords
from ..metrics import relative_error
from ..products import product_basis

__all__ = ["coordinate_errors", "coordinate_reconstruction", "higher_order_reconstruction",
           "indicator_region", "lmh_reconstruction"]


COORDINATE_ERROR = "mean over x,y,z of sqrt(int (xhat_c-x_c)^2)/sqrt(int x_c^2), area-weighted"
"""How :func:`coordinate_errors` measures (the results' ``error_definition``)."""


def coordinate_errors(X_rec: np.ndarray, X: np.ndarray, mass: np.ndarray, region=None) -> dict:
    """Relative error of reconstructed coordinates ``(n, 3)``: per axis and their mean.

    With ``region`` (boolean ``(n,)``) also ``region_mean``, the mean error restricted to it.
    """
    e = relative_error(X_rec, X, mass)  # (3,)
    out = {"mean": float(e.mean()), "x": e[0], "y": e[1], "z": e[2]}
    if region is not None:
        out["region_mean"] = float(relative_error(X_rec[region], X[region], mass[region]).mean())
    return out


def _extended_reconstruction(basis, F, pairs: str, rtol: float, order: int = 2):
    ext = product_basis(basis, order=order, pairs=pairs)
    op = ext.operator("svd", rtol=rtol)  # Approach B (cached, reusable)
    return ext, op, ext.evaluate(op.coefficients(F))


def coordinate_reconstruction(mesh, ks, ks_curve=(), *, pairs: str = "ordered", rtol: float = 1e-3,
                              verbose: bool = True) -> dict:
    """Figure 4: the coordinates from ``k + 1`` eigenfunctions, without and with pairwise products.

    Also reports the other pair convention (``"unique"`` if ``pairs="ordered"``). Returns
    ``{"results": {errors, sizes}, "recon": {k: (X_std, X_prod)}, "k_all": [...]}``.
    """
    X = mesh.vertices  # (n, 3) the three coordinate functions
    k_all = sorted(set(ks) | set(ks_curve))
    other = "unique" if pairs == "ordered" else "ordered"
    full = eigenbasis(mesh, max(k_all) + 1)  # k + 1 columns, constant first
    errors = {"std": {}, "prod": {}, f"prod_{other}": {}}
    sizes, recon = {}, {}
    for k in k_all:
        t1 = time.perf_counter()
        basis = full.truncate(k + 1)
        X_std = basis.vecs @ basis.project(X)  # A-orthogonal projection, (n, 3)
        ext, op, X_prod = _extended_reconstruction(basis, X, pairs, rtol)
        ext_o, op_o, X_o = _extended_reconstruction(basis, X, other, rtol)
        key = f"k{k}"
        for name, Xr in (("std", X_std), ("prod", X_prod), (f"prod_{other}", X_o)):
            errors[name][key] = coordinate_errors(Xr, X, full.mass)
        sizes[key] = {"std": basis.k, "extended": ext.K, f"extended_{other}": ext_o.K,
                      "rank_kept": op.rank, f"rank_kept_{other}": op_o.rank}
        if k in ks:
            recon[k] = (X_std, X_prod)
        if verbose:
            print(f"k = {k:2d}: std {errors['std'][key]['mean']:.4f}   prod ({pairs}) {errors['prod'][key]['mean']:.4f}"
                  f"   prod ({other}) {errors[f'prod_{other}'][key]['mean']:.4f}   [{ext.K} columns, rank kept "
                  f"{op.rank}; {time.perf_counter() - t1:.1f} s]")
    return {"results": {"error_definition": COORDINATE_ERROR, "pairs": pairs, "errors": errors, "sizes": sizes},
            "recon": recon, "k_all": k_all}


def higher_order_reconstruction(mesh, n_eig: int, orders, rtols, *, verbose: bool = True) -> dict:
    """Figure 5: the coordinates from ``n_eig`` eigenfunctions and their products, at each Approach B rtol.

    ``n_eig`` counts the constant; products up to each order (multisets, ``pairs="unique"``).

    Returns ``{"results": {errors, sizes}, "recon": {(rtol key, order): X}}``; order 1 is the
    plain projection.
    """
    X = mesh.vertices
    basis = eigenbasis(mesh, n_eig)
    errors, sizes, recon = {}, {}, {}
    for rtol in rtols:
        rk = f"rtol_{rtol:.0e}"  # e.g. "rtol_1e-03"
        errors[rk], sizes[rk] = {}, {}
        for r in orders:
            t1 = time.perf_counter()
            if r == 1:
                Xr = basis.vecs @ basis.project(X)  # A-orthogonal projection
                sizes[rk][f"order{r}"] = {"columns": basis.k, "rank_kept": basis.k}
            else:
                ext, op, Xr = _extended_reconstruction(basis, X, "unique", rtol, order=r)
                sizes[rk][f"order{r}"] = {"columns": ext.K, "rank_kept": op.rank}
            e = coordinate_errors(Xr, X, basis.mass)
            errors[rk][f"order{r}"] = e
            recon[rk, r] = Xr
            if verbose:
                s = sizes[rk][f"order{r}"]
                print(f"rtol {rtol:.0e}, order {r}: {s['columns']:5d} columns (rank kept {s['rank_kept']:4d}): "
                      f"error {e['mean']:.4f}  (x {e['x']:.4f}, y {e['y']:.4f}, z {e['z']:.4f})   "
                      f"[{time.perf_counter() - t1:.1f} s]")
    return {"results": {"error_definition": COORDINATE_ERROR, "pairs": "unique", "errors": errors, "sizes": sizes},
            "recon": recon}


def indicator_region(mesh, ks, region_center, region_radius: float, *, threshold: float = 0.5,
                     pairs: str = "ordered", rtol: float = 1e-3) -> dict:
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
        _, _, f_prod = _extended_reconstruction(basis, chi, pairs, rtol)
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


def lmh_reconstruction(mesh, *, mh_dim: int | None = None, global_dim: int | None = None,
                       local_dim: int | None = None, region_top_fraction: float, mu_region: float, mu_orth: float,
                       pairs: str = "ordered", rtol: float = 1e-3, k_mh: int | None = None,
                       k_global: int | None = None, k_local: int | None = None) -> dict:
    """Figure 10: coordinates in MH and in MH + LMH, each without and with products.

    MH: the first ``mh_dim`` eigenfunctions (constant included); MH + LMH: the first
    ``global_dim`` eigenfunctions (constant included) plus ``local_dim`` localized harmonics of
    the top ``region_top_fraction`` of the height. Errors on the whole surface and in the region.
    ``k_mh``, ``k_global``, ``k_local``: the old names of ``mh_dim``, ``global_dim``,
    ``local_dim`` (deprecated: they warn and give the same numbers).

    Returns ``{"results": ..., "region": (n,) bool, "recon": {"MH"|"LMH": (X_std, X_prod)}}``.
    """
    from .. import lmh

    mh_dim, global_dim, local_dim = renamed_keywords(
        "lmh_reconstruction", {"mh_dim": mh_dim, "global_dim": global_dim, "local_dim": local_dim},
        {"k_mh": k_mh, "k_global": k_global, "k_local": k_local})
    X = mesh.vertices
    z = X[:, 2]
    region = z > z.max() - region_top_fraction * (z.max() - z.min())  # (n,) the head (z is up)
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
        ext, op, X_prod = _extended_reconstruction(basis, X, pairs, rtol)
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
