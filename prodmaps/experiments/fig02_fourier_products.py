"""Figure 2: the first 1D Fourier functions and their pairwise products (with the linear dependency).

Conventions: :func:`prodmaps.fourier_basis` samples ``n`` points of ``[0, 2π)``; ``k`` in the
paper's sense counts the non-constant functions (the basis has ``k + 1`` columns); errors are the
paper's relative L2 errors with the quadrature weights.
"""

from __future__ import annotations

import numpy as np

from ..basis import fourier_basis
from ..products import product_basis

__all__ = ["fourier_products"]


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
