"""Cross fields acting on functions, and the span Approach B keeps in an extended basis.

The consistency of two fields through a map compares their actions on functions
(:mod:`prodmaps.fields.consistency`). A vector field would act as a derivation, whose Leibniz
extension to the product columns is fixed by its action on the base functions and so adds no
information of its own ([ABCO13]); what the extended basis adds is the **representation** of
high-frequency functions such as the actions below, hence :class:`SpanProjector`: the span
that the library's Approach B keeps, in which those functions are expressed.

Cross fields: the degree-N action
---------------------------------
A cross field has no sign and no preferred branch, so it is not a derivation. We represent an
``N``-direction field by its unit power field ``z`` and its **degree-N action**

    ``Q_z(f) = Re(conj(z) g(f)^N) |g(f)|^(p-N)  =  |∇f|^p cos(N (angle(∇f) - α))``   (per face),

with ``α`` any of its directions. For every ``p`` it is (i) independent of the face frame
(``g`` turns by ``-β`` and ``z`` by ``-Nβ`` under a frame change), (ii) invariant under the
symmetry of the field (``α -> α + 2π/N`` leaves ``z`` unchanged; a 45° turn of a cross flips
its sign), (iii) natural: for an isometry ``T`` and the pushed field,
``Q_{T_* z}(f ∘ T⁻¹) = Q_z(f) ∘ T⁻¹``, and (iv) **linear in z**, so designing a field from its
action is a linear least-squares problem. ``p = N`` is the polynomial form ``Re(conj(z) g^N)``
(a degree-N form in ``f``; for ``N = 1`` exactly the derivation ``D_X f``). ``p = 0``, the
default, keeps the gradient direction only: it is natural under *conformal* maps too, where the
``|∇f|^4`` weight of ``p = 4`` amplifies the metric distortion of the map (``docs/benchmarks.md``).
Either way, the functions the action produces from basis functions are high-frequency (powers of
gradients), which a small standard basis cannot represent and products of basis functions
represent much better. ACBCO17 relate cross fields across shapes through their action on
functions in the same spirit (only real-valued functions cross the map); this particular action
is our choice, see :mod:`prodmaps.fields.consistency`.

[ABCO13] Azencot, Ben-Chen, Chazal, Ovsjanikov. An operator approach to tangent vector field
processing. SGP 2013.
"""

from __future__ import annotations

import numpy as np

from ..approx import PAPER_RTOL, approximation_operator
from ..basis import Basis
from ..products import ProductBasis

__all__ = ["SpanProjector", "span_projector", "powered_gradients", "field_action"]


class SpanProjector:
    """The span Approach B keeps in an extended basis, as an A-orthonormal basis ``Q`` ``(n, r)``.

    A view of the library's Approach B operator (:meth:`prodmaps.ProductBasis.operator`
    ``("svd", rtol=...)``, :mod:`prodmaps.approx`), never a second truncation: the same
    singular values are kept, under the same column normalisation (by default the library's
    ``"euclidean"`` reading, unit-Euclidean factors; free of the mesh's units). With
    ``sqrt(A) B D = U Σ Vᵀ`` truncated at ``rtol · σ_max``: ``Q = B P`` with
    ``P = D V_r Σ_r⁻¹`` (:meth:`~prodmaps.approx.ApproximationOperator.span_factors`),
    ``QᵀAQ = I``; ``coefficients(f) = Qᵀ A f`` are the operator's canonical coefficients of
    ``f``'s Approach-B coefficients; ``basis_coefficients(f)`` are those coefficients (minimum
    norm, the paper's Approach B) and ``from_basis(a) = Σ_r V_rᵀ D⁻¹ a`` the span coordinates of
    ``B a``.

    ``normalization="area"`` truncates A-orthonormal factors with no column weights: it keeps more
    small directions, which make the transported actions of the test functions wrong
    (``docs/benchmarks.md``).
    """

    def __init__(self, operator):
        if getattr(operator, "method", None) != "svd":
            raise ValueError("SpanProjector needs an Approach B operator: basis.operator('svd', rtol=...)")
        basis = operator.basis
        base = basis.base if isinstance(basis, ProductBasis) else basis
        if not base.mass_is_diagonal:
            raise ValueError("SpanProjector needs a lumped (diagonal) mass")
        self.operator = operator
        self.P = operator.span_factors()  # (K, r)
        self.Q = basis.evaluate(self.P) if isinstance(basis, ProductBasis) else basis.vecs @ self.P  # (n, r)
        self.mass = np.asarray(base.mass, dtype=np.float64)
        self.rank = self.P.shape[1]

    def coefficients(self, F: np.ndarray) -> np.ndarray:
        """``Qᵀ A F`` ``(r,)`` or ``(r, m)``: the canonical coefficients of ``F``'s Approach-B fit."""
        return self.operator.canonical(self.operator.coefficients(F))

    def basis_coefficients(self, F: np.ndarray) -> np.ndarray:
        """Approach-B coefficients of ``F`` in ``B`` ``(K,)`` or ``(K, m)`` (the operator's)."""
        return self.operator.coefficients(F)

    def from_basis(self, a: np.ndarray) -> np.ndarray:
        """Span coordinates ``Qᵀ A B a`` of the function ``B a`` (the operator's canonical coefficients)."""
        return self.operator.canonical(a)

    def coefficient_matrix(self) -> np.ndarray:
        """``(K, n)`` matrix of :meth:`basis_coefficients`: ``P Qᵀ A``."""
        return self.P @ (self.Q * self.mass[:, None]).T


def span_projector(basis, rtol: float = PAPER_RTOL, normalization: str | None = None) -> SpanProjector:
    """:class:`SpanProjector` of a :class:`prodmaps.ProductBasis` (or a Basis) at the Approach-B threshold ``rtol``.

    Built through the library's cached operator ``basis.operator("svd", ...)``.

    ``normalization``: the operator's column normalisation (default: the library's,
    :data:`prodmaps.approx.DEFAULT_NORMALIZATION`).
    """
    params = {"rtol": rtol} if normalization is None else {"rtol": rtol, "normalization": normalization}
    if isinstance(basis, ProductBasis):
        return SpanProjector(basis.operator("svd", **params))
    if isinstance(basis, Basis):
        return SpanProjector(approximation_operator(basis, "svd", **params))
    raise TypeError(f"span_projector takes a ProductBasis or a Basis, got {type(basis).__name__}")


def powered_gradients(G: np.ndarray, N: int = 4, power: float | None = None, eps: float = 1e-3) -> np.ndarray:
    """``g^N |g|^(p - N)`` for complex gradients ``G`` ``(m,)`` or ``(m, J)``.

    The ``N``-th power of the gradient direction times the magnitude to the ``p = power`` (default
    ``p = N``: ``g^N``).

    For ``p < N`` the direction of a vanishing gradient is round-off, so the result is faded out
    by ``|g|² / (|g|² + ε²)`` with ``ε = eps`` times the RMS of ``|g|`` over the faces (per column).
    """
    G = np.asarray(G)
    p = N if power is None else float(power)
    if p >= N:
        return G ** N * (np.abs(G) ** (p - N) if p > N else 1.0)
    a = np.abs(G)
    e2 = (eps ** 2) * np.mean(a ** 2, axis=0)
    unit = np.where(a > 0, G / np.where(a > 0, a, 1.0), 0.0)
    return unit ** N * a ** p * (a ** 2 / (a ** 2 + e2 + 1e-300))


def field_action(G: np.ndarray, z: np.ndarray, N: int = 4, power: float | None = None) -> np.ndarray:
    """Degree-N action ``Re(conj(z) g^N) |g|^(p-N)`` ``(m, J)`` of a power field ``z`` ``(m,)``.

    ``G`` ``(m, J)`` are the complex gradients of ``J`` functions (``complex_gradient(fr) @ F``).
    ``power`` ``p`` defaults to ``N`` (the polynomial action ``Re(conj(z) g^N)``); ``p = 0``
    keeps the direction only, ``cos(N (angle(∇f) - α))``. For ``N = 1``, ``p = 1`` this is
    ``<X, ∇f>`` per face.
    """
    G = np.asarray(G)
    z = np.asarray(z)
    if G.ndim == 1:
        G = G[:, None]
    if z.shape != (G.shape[0],):
        raise ValueError(f"z must be (m,) with m = {G.shape[0]}; got {z.shape}")
    return np.real(np.conj(z)[:, None] * powered_gradients(G, N, power))
