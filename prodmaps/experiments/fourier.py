"""Figures 2 and 3: the 1D periodic Fourier basis and its products.

Conventions: :func:`prodmaps.fourier_basis` samples ``n`` points of ``[0, 2π)``; ``k`` in the
paper's sense counts the non-constant functions (the basis has ``k + 1`` columns); errors are the
paper's relative L2 errors with the quadrature weights.
"""

from __future__ import annotations

import numpy as np

from ..approx import approximate
from ..basis import fourier_basis
from ..metrics import relative_error
from ..products import product_basis

__all__ = ["fourier_products", "fourier_indicator"]


def fourier_products(n_samples: int, n_functions: int) -> dict:
    """Figure 2: the first ``n_functions`` Fourier functions, their pairwise products and their rank.

    The rank of the extended basis is ``2k + 1``; the caption's dependency is ``φ1⊙φ1 + φ2⊙φ2 + λ φ0 = 0``.

    Returns ``{"results": ..., "x": (n,), "matrix": (n, K), "labels": [...], "k": k}``.
    """
    basis = fourier_basis(n_samples, n_functions)  # (n, 5): 1, cos x, sin x, cos 2x, sin 2x
    ext = product_basis(basis, order=2, pairs="unique")  # products of φ1..φ4, each pair once
    x = np.arange(basis.n) * (2 * np.pi / basis.n)
    k = basis.k - 1  # non-constant functions (the paper's k)
    s = basis.vecs[:, 1] ** 2 + basis.vecs[:, 2] ** 2  # (n,)
    lam = -float(basis.project(s)[0])  # λ by least squares
    residual = float(np.sqrt(np.sum(basis.mass * (s + lam * basis.vecs[:, 0]) ** 2)))
    sv = np.linalg.svd(np.sqrt(basis.mass)[:, None] * ext.matrix, compute_uv=False)
    rank = int(np.sum(sv > 1e-10 * sv[0]))
    spectrum = np.abs(np.fft.rfft(ext.matrix, axis=0))  # (n/2+1, K): products reach higher frequencies
    max_freq = [int(np.flatnonzero(spectrum[:, j] > 1e-8 * spectrum[:, j].max()).max()) for j in range(ext.K)]
    labels = ["φ0"] + [f"φ{i}" for i in range(1, k + 1)] + [f"φ{i}⊙φ{j}" for i, j in ext.index[k + 1:]]
    results = {"k": k, "n_columns_extended": ext.K, "rank_extended": rank, "rank_expected": 2 * k + 1,
               "dependency_lambda": lam, "dependency_residual": residual,
               "max_frequency": dict(zip(labels, max_freq))}
    return {"results": results, "x": x, "matrix": ext.matrix, "labels": labels, "k": k}


def fourier_indicator(n_samples: int, k_values, interval, rtol: float = 1e-3, pairs: str = "ordered") -> dict:
    """Figure 3: an indicator of ``interval`` reconstructed without and with pairwise products.

    ``interval`` is in fractions of the period; the first ``k_M + 1`` Fourier functions, then also their
    pairwise products (Approach B, ``rtol``).

    Returns ``{"results": ..., "x": (n,), "f": (n,), "recon": {k_M: (standard, products)}, "rows": [...]}``.
    """
    n = int(n_samples)
    t = np.arange(n) / n  # position as a fraction of the period
    f = ((t >= interval[0]) & (t < interval[1])).astype(float)  # (n,) the indicator
    rows, recon = [], {}
    for kM in k_values:
        basis = fourier_basis(n, kM + 1)  # k_M + 1 columns, constant first
        ext = product_basis(basis, order=2, pairs=pairs)
        g_std = basis.vecs @ approximate(f, basis, "std")
        g_prod = ext.evaluate(approximate(f, ext, "svd", rtol=rtol))
        e_std, e_prod = relative_error(g_std, f, basis.mass), relative_error(g_prod, f, basis.mass)
        recon[kM] = (g_std, g_prod)
        rows.append({"k_M": kM, "columns_std": basis.k, "columns_extended": ext.K,
                     "rank_kept": ext.operator("svd", rtol=rtol).rank, "error_std": e_std, "error_prod": e_prod})
    results = {"errors": {f"k{r['k_M']}": {"std": r["error_std"], "prod": r["error_prod"]} for r in rows},
               "sizes": {f"k{r['k_M']}": {"std": r["columns_std"], "extended": r["columns_extended"],
                                          "rank_kept": r["rank_kept"]} for r in rows}}
    return {"results": results, "x": 2 * np.pi * t, "f": f, "recon": recon, "rows": rows}
