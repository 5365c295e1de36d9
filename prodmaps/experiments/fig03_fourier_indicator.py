"""Figure 3: an indicator on the circle reconstructed in the Fourier basis, standard vs products.

Conventions: :func:`prodmaps.fourier_basis` samples ``n`` points of ``[0, 2π)``; ``k`` in the
paper's sense counts the non-constant functions (the basis has ``k + 1`` columns); errors are the
paper's relative L2 errors with the quadrature weights.
"""

from __future__ import annotations

import numpy as np

from ..approx import PAPER_RTOL, approximate
from ..basis import fourier_basis
from ..metrics import relative_error
from ..products import product_basis

__all__ = ["fourier_indicator"]


def fourier_indicator(n_samples: int, k_values, interval, rtol: float = PAPER_RTOL, pairs: str = "ordered") -> dict:
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
