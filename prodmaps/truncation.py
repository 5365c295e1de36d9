"""Choosing Approach B's truncation threshold: diagnostics and data-driven rules.

Background (see ``notebooks/study_truncation.ipynb``)
-----------------------------------------------------
Approach B (Section 4.2) computes ``sqrt(A1) B1 = U Σ Vᵀ`` on the source and keeps the
singular directions with ``σ_i > rtol · σ_max`` (the paper: ``rtol = 1e-3``). A direction
``v_i`` is a combination of products whose function ``B1 v_i`` has area norm ``σ_i``: small
``σ_i`` means the products nearly cancel on the source. The extended map ``C~`` (Lemma 2)
transfers ``v_i`` to ``B2 C~ v_i``; for a map that preserved products exactly (a point map
with complete bases) the image would be ``(B1 v_i) ∘ p2p_21`` and, for a near-isometric map,
have about the same norm ``σ_i``. With truncated bases (``Φ2 C`` is only the projection of the
transferred eigenfunctions on ``k_N + 1`` target eigenfunctions) products are not preserved
exactly, the cancellation is lost on the target and the image is much larger than ``σ_i``.
The **transfer gain** of direction ``i`` is

    ``g_i = ||B2 C~ v_i||_A2 / ||B1 v_i||_A1 = ||B2 C~ v_i||_A2 / σ_i``        (no ground truth)

and the coefficient of a function along ``v_i`` is ``(u_iᵀ sqrt(A1) f) / σ_i``: directions with
``g_i >> 1`` amplify whatever part of ``f`` they carry. Ground-truth maps already have gains
of ~20 at ``rtol = 1e-3`` on the embedded humans (``k_M = 9`` or ``29``), computed maps more.

Rules offered here (none needs the ground truth):

* ``method="gain"`` (uses the map ``C_12`` and both bases, not the function): the smallest
  candidate ``rtol`` for which every kept direction has ``g_i <= max_gain``. A pull-back by a
  near-isometric point map preserves L2 norms up to the area ratio, so gains above a small
  constant (default 2) can only come from the failure of product preservation.
* ``method="cv"`` (source only): hold out a random ``holdout`` fraction of the source
  vertices, fit on the rest with each candidate ``rtol`` and keep the ``rtol`` with the
  smallest held-out relative error (averaged over the functions given).
* ``method="gcv"`` (source only): generalised cross-validation of the truncated least squares,
  ``GCV(r) = n ||(I - H_r) sqrt(A) f||² / (n - r)²`` (each function normalised by ``||sqrt(A) f||²``,
  averaged over the functions).

The paper profile of every notebook keeps ``rtol = 1e-3``; these rules are options: pass the
selected value as ``rtol`` to :func:`prodmaps.transfer` / :func:`prodmaps.approximate`.
"""

from __future__ import annotations

import numpy as np

from .approx import DEFAULT_NORMALIZATION, column_weights, gram_eigenpairs
from .basis import Basis
from .checks import check_basis, check_fmap
from .mapping import extend_fmap
from .products import product_basis

__all__ = ["singular_directions", "transfer_gains", "select_rtol", "DEFAULT_CANDIDATES"]

DEFAULT_CANDIDATES = tuple(float(v) for v in np.logspace(-4, -1, 13))  # 1e-4 ... 1e-1, 4 per decade


def singular_directions(basis_1: Basis, order: int = 2, pairs: str = "ordered", normalization: str | None = None):
    """``(sigma (K_u,), V (K_u, K_u))`` of ``sqrt(A1) B_s D`` (descending), ``B_s`` the solver basis.

    ``B_s`` is the scaled unique-multiset basis of :class:`prodmaps.ProductBasis` (it has exactly
    the singular values of the paper's ordered basis) and ``D`` the column weights of
    ``normalization`` (:func:`prodmaps.approx.column_weights`; default
    :data:`prodmaps.approx.DEFAULT_NORMALIZATION`). Direction ``i`` is the function
    ``B_s D V[:, i]``; ``ext.expand() @ (D V)`` gives the directions as coefficients of ``pairs``'
    basis. Diagonalises the Gram matrix ``D B_sᵀ A B_s D`` once per product basis and
    normalization, shared with Approach B's operator (:func:`prodmaps.approx.gram_eigenpairs`, cached;
    fast for ``n >> K``; squares the
    condition number: ``sigma_i`` has a relative error of about ``1e-16 (sigma_max / sigma_i)²``,
    below ``1e-7`` for the thresholds ``>= 1e-4`` studied here).
    """
    ext = product_basis(basis_1, order, pairs)
    norm = normalization or DEFAULT_NORMALIZATION
    w, V, side = gram_eigenpairs(ext, norm)  # the decomposition Approach B's operator caches and reuses
    if side != "primal":  # K_u > n: the operator diagonalises X Xᵀ; the directions need Xᵀ X
        d = column_weights(ext, norm)
        G = ext.solver_gram()
        w, V = np.linalg.eigh(G if d is None else d[:, None] * G * d)
        w, V = w[::-1], V[:, ::-1]
    return np.sqrt(np.maximum(w, 0.0)), np.array(V)  # a copy: the cached decomposition stays intact


def transfer_gains(C_12, basis_1: Basis, basis_2: Basis, order: int = 2, pairs: str = "ordered",
                   normalization: str | None = None):
    """Transfer gain ``g_i = ||B2 C~ v_i||_A2 / sigma_i`` of every singular direction of the source.

    ``C_12`` is ``(basis_2.k, basis_1.k)`` (maps coefficients on shape 1 to shape 2). Returns a
    dict with ``sigma (K_u,)`` (descending), ``rel = sigma / sigma_max``, ``image_norm (K_u,)``
    and ``gain (K_u,)`` (``inf`` where ``sigma_i = 0``). Uses only the map and the two bases.
    """
    C = check_fmap(C_12, basis_1, basis_2)
    ext1 = product_basis(basis_1, order, pairs)
    ext2 = product_basis(basis_2, order, pairs)
    sigma, V = singular_directions(basis_1, order, pairs, normalization)
    d = column_weights(ext1, normalization or DEFAULT_NORMALIZATION)
    if d is not None:
        V = d[:, None] * V  # directions as solver coefficients
    Ct = extend_fmap(C, basis_1, basis_2, order, pairs)  # (K2, K1)
    img = ext2.evaluate(Ct @ (ext1.expand() @ V))  # (n2, K_u) images of the directions
    m2 = basis_2.lumped_mass
    norms = np.sqrt(np.einsum("ij,ij->j", img, m2[:, None] * img))  # (K_u,)
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.where(sigma > 0, norms / np.where(sigma > 0, sigma, 1.0), np.inf)
    return {"sigma": sigma, "rel": sigma / sigma[0], "image_norm": norms, "gain": gain}


def select_rtol(basis_1: Basis, F=None, *, method: str = "gain", C_12=None, basis_2: Basis | None = None,
                candidates=DEFAULT_CANDIDATES, max_gain: float = 2.0, holdout: float = 0.2, seed: int = 0,
                order: int = 2, pairs: str = "ordered", normalization: str | None = None,
                return_info: bool = False):
    """Pick Approach B's ``rtol`` without ground truth (see the module doc for the rules).

    Parameters
    ----------
    basis_1 : source basis (``k_M + 1`` columns, A-orthonormal, constant first).
    F : ``(n1,)`` or ``(n1, m)`` functions on the source (needed by ``"cv"`` and ``"gcv"``).
    method : ``"gain"`` (needs ``C_12`` and ``basis_2``), ``"cv"`` or ``"gcv"`` (source only).
    C_12 : ``(basis_2.k, basis_1.k)`` functional map, for ``"gain"``.
    candidates : thresholds relative to ``sigma_max`` (default 1e-4 ... 1e-1, 13 values).
    max_gain : ``"gain"``: largest admissible transfer gain of a kept direction.
    holdout, seed : ``"cv"``: held-out fraction of the vertices and the seed of the split.

    Returns the selected ``rtol`` (and a dict with the per-candidate scores if ``return_info``).
    """
    cand = np.sort(np.asarray(candidates, dtype=np.float64))
    if cand.ndim != 1 or cand.size == 0 or np.any(cand <= 0) or np.any(cand >= 1):
        raise ValueError(f"candidates must be a non-empty list of thresholds in (0, 1); got {candidates!r}")
    check_basis(basis_1, "basis_1")
    if method == "gain":
        if C_12 is None or basis_2 is None:
            raise ValueError("method='gain' needs the functional map C_12 and basis_2")
        if not max_gain > 0:
            raise ValueError(f"max_gain must be > 0, got {max_gain}")
        g = transfer_gains(C_12, basis_1, basis_2, order, pairs, normalization)
        worst = np.array([g["gain"][g["rel"] > r].max() for r in cand])  # (n_cand,)
        ok = np.flatnonzero(worst <= max_gain)
        rtol = float(cand[ok[0]] if ok.size else cand[-1])
        info = {"candidates": cand, "max_gain_kept": worst, "gain": g}
    elif method in ("cv", "gcv"):
        if F is None:
            raise ValueError(f"method={method!r} needs the functions F on the source")
        F = np.asarray(F, dtype=np.float64)
        F2 = F[:, None] if F.ndim == 1 else F
        if F2.shape[0] != basis_1.n or not np.all(np.isfinite(F2)):
            raise ValueError(f"F must be finite with {basis_1.n} rows; got shape {F.shape}")
        if not basis_1.mass_is_diagonal:
            raise ValueError("select_rtol needs a lumped (diagonal) mass")
        ext = product_basis(basis_1, order, pairs)
        norm = normalization or DEFAULT_NORMALIZATION

        def scaled_basis():
            B_s, _ = ext.solver_basis()  # (n, K_u)
            d = column_weights(ext, norm)
            # the truncation sees the normalised columns (coefficients are not returned)
            return B_s if d is None else B_s * d

        sq = np.sqrt(basis_1.mass)
        if method == "cv":
            if not 0 < holdout < 1:
                raise ValueError(f"holdout must be in (0, 1), got {holdout}")
            def split_svd():  # the split, its SVD and the test rows depend on the basis only: cached
                B_s = scaled_basis()
                rng = np.random.default_rng(seed)
                test = np.zeros(basis_1.n, dtype=bool)
                test[rng.choice(basis_1.n, size=max(1, int(round(holdout * basis_1.n))), replace=False)] = True
                X = sq[~test, None] * B_s[~test]  # (n_train, K_u)
                return (test,) + tuple(np.linalg.svd(X, full_matrices=False)) + (sq[test, None] * B_s[test],)

            test, U, s, Vt, Bt = ext.cache.get(("select_rtol_cv_svd", float(holdout), int(seed), norm), split_svd)
            beta = U.T @ (sq[~test, None] * F2[~test])  # (K_u, m); Bt (n_test, K_u)
            Ft = sq[test, None] * F2[test]
            den = np.maximum(np.sum(Ft**2, axis=0), 1e-300)
            score = []
            for r in cand:
                keep = s > r * s[0]
                a = Vt[keep].T @ (beta[keep] / s[keep, None])  # (K_u, m)
                score.append(float(np.mean(np.sqrt(np.sum((Bt @ a - Ft) ** 2, axis=0) / den))))
        else:
            U, s = ext.cache.get(("select_rtol_gcv_svd", norm),
                                 lambda: np.linalg.svd(sq[:, None] * scaled_basis(), full_matrices=False)[:2])
            Y = sq[:, None] * F2
            beta = U.T @ Y
            tot = np.sum(Y**2, axis=0)
            n = basis_1.n
            score = []
            for r in cand:
                keep = s > r * s[0]
                res = tot - np.sum(beta[keep] ** 2, axis=0)  # (m,) residual energy
                score.append(float(np.mean(n * np.maximum(res, 0) / (n - keep.sum()) ** 2 / np.maximum(tot, 1e-300))))
        score = np.array(score)
        rtol = float(cand[int(np.argmin(score))])
        info = {"candidates": cand, "score": score}
    else:
        raise ValueError(f"method must be 'gain', 'cv' or 'gcv', got {method!r}")
    return (rtol, info) if return_info else rtol
