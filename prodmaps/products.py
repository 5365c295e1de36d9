"""Extended (product) bases: a basis plus pointwise products of its non-constant functions.

Column layout of a :class:`ProductBasis` of order ``r`` built on a basis with columns
``φ0 (constant), φ1, …, φk``:

``[φ0, φ1, …, φk,  degree-2 products,  degree-3 products, …, degree-r products]``

Products never involve the constant ``φ0``. Two index conventions:

* ``pairs="ordered"`` (the paper's, Section 4.2): every ordered tuple
  ``(i1, …, id)`` with ``1 <= i_t <= k``; for order 2 the column of ``φl ⊙ φm`` is
  ``k + 1 + (l-1)·k + (m-1)`` (the paper's ``l·k + m`` with 0-based non-constant indices).
  ``K = 1 + k + k² + … + k^r`` columns; ``(l, m)`` and ``(m, l)`` are the same function.
* ``pairs="unique"``: one column per multiset ``i1 <= … <= id`` (``itertools``'
  ``combinations_with_replacement`` order), ``K = 1 + k + k(k+1)/2 + …``. Same span, far
  fewer columns.

``index`` is a ``(K, r)`` integer array: row ``j`` lists the non-constant factors of column
``j`` (0 pads, so ``[0, …, 0]`` is the constant column and ``[l, 0, …]`` is ``φl``).

Computational note (exact, not an approximation): the ordered basis is ``B_o = B_s S`` where
``B_s`` is the unique-multiset basis with every column scaled by the square root of its number
of distinct orderings, and ``S`` has orthonormal rows (each multiset column spread evenly over
its orderings with weight ``1/sqrt(#orderings)``). Hence ``B_o`` and ``B_s`` share their
singular values and left singular vectors, and ``pinv(B_o) = Sᵀ pinv(B_s)`` for any
singular-value truncation. All solvers therefore work on the (much smaller) scaled unique
basis and map coefficients back with ``Sᵀ``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .approx import approximation_operator, mass_gram, operator_parameters
from .basis import Basis
from .cache import Cache

__all__ = ["ProductBasis", "product_basis", "multi_indices", "n_columns", "n_orderings", "check_pairs",
           "evaluate_products", "unique_solver_gram", "PAIRS"]

PAIRS = ("ordered", "unique")


def check_pairs(pairs: str) -> None:
    """A ``ValueError`` unless ``pairs`` is ``"ordered"`` (the paper's) or ``"unique"``."""
    if pairs not in PAIRS:
        raise ValueError(f"pairs must be 'ordered' (the paper's) or 'unique', got {pairs!r}")


def multi_indices(k: int, order: int, pairs: str) -> np.ndarray:
    """Multi-indices ``(K, order)`` of the extended basis on ``k`` non-constant functions.

    Rows are in column order: the constant ``[0…0]``, the ``k`` singletons, then products
    by increasing degree. Factors are 1-based (``1..k``); 0 pads.
    """
    check_pairs(pairs)
    if order < 1:
        raise ValueError(f"order must be >= 1, got {order}")
    rows = [np.zeros((1, order), dtype=np.int64)]
    for d in range(1, order + 1):
        gen = (itertools.product(range(1, k + 1), repeat=d) if pairs == "ordered" and d > 1
               else itertools.combinations_with_replacement(range(1, k + 1), d))
        block = np.array(list(gen), dtype=np.int64).reshape(-1, d)
        rows.append(np.pad(block, ((0, 0), (0, order - d))))
    return np.concatenate(rows)


def n_columns(k: int, order: int, pairs: str) -> int:
    """Number of columns of the extended basis (``k`` non-constant functions)."""
    check_pairs(pairs)
    if pairs == "ordered":
        return 1 + sum(k**d for d in range(1, order + 1))
    return 1 + sum(math.comb(k + d - 1, d) for d in range(1, order + 1))


def n_orderings(index: np.ndarray) -> np.ndarray:
    """Number of distinct orderings of each multiset row (0 pads ignored)."""
    out = np.empty(index.shape[0], dtype=np.float64)
    for j, row in enumerate(index):  # K rows of small multi-indices; not a per-vertex loop
        r = row[row > 0]
        counts = np.unique(r, return_counts=True)[1]
        out[j] = math.factorial(r.size) / np.prod([math.factorial(c) for c in counts])
    return out


def evaluate_products(vecs: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Columns ``Π_t vecs[:, index[j, t]]`` (0 = no factor), the constant column kept as is.

    Returns an ``(n, K)`` Fortran-ordered array: the products are formed on contiguous rows of
    the transposed basis, which is several times faster than gathering columns.
    """
    n = vecs.shape[0]
    padded_T = np.empty((vecs.shape[1], n))  # (k+1, n), factor 0 -> 1
    padded_T[0] = 1.0
    padded_T[1:] = vecs[:, 1:].T
    out_T = padded_T[index[:, 0]]  # (K, n)
    for t in range(1, index.shape[1]):
        out_T *= padded_T[index[:, t]]
    out_T[0] = vecs[:, 0]  # the constant column is φ0 itself
    return out_T.T


@dataclass(frozen=True, eq=False)
class ProductBasis:
    """A basis extended by pointwise products of its non-constant functions (see module doc).

    Build with :func:`product_basis`. ``matrix`` is materialised lazily and cached;
    ``operator(...)`` returns a cached, reusable approximation operator. Derived values live in
    ``cache`` (a bounded :class:`prodmaps.cache.Cache`), keyed by name and parameters.

    Sizes: ``base.k`` columns of the base (constant included, as everywhere), ``n_factors =
    base.k - 1`` non-constant functions multiplied (the paper's ``k_M``), ``K`` columns of the
    extended basis.

    Raises
    ------
    ValueError
        If ``order`` or ``pairs`` is not supported, or ``index`` does not match them.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 6)
    >>> pb = pm.product_basis(b, order=2)
    >>> pb.n_factors, pb.K, pb.matrix.shape  # 1 + 5 + 5*5 ordered pairs
    (5, 31, (162, 31))
    >>> bool(np.allclose(pb.matrix[:, 6], b.vecs[:, 1] * b.vecs[:, 1]))
    True
    """

    base: Basis
    order: int
    pairs: str
    index: np.ndarray = field(repr=False)
    cache: Cache = field(default_factory=lambda: Cache(max_entries=32), repr=False, compare=False)
    block_bytes: int = field(default=32 << 20, repr=False)  # row blocks of the blocked products
    kept_block: Cache = field(default_factory=lambda: Cache(max_entries=1), repr=False, compare=False)
    """The solver basis ``B_s`` when one block of ``block_bytes`` holds every row (formed once, read-only)."""

    @property
    def n_factors(self) -> int:
        """Number of non-constant base functions that are multiplied (the paper's ``k_M``)."""
        return self.base.k - 1

    @property
    def K(self) -> int:
        """Number of columns of the extended basis."""
        return self.index.shape[0]

    @property
    def n(self) -> int:
        """Number of vertices ``n``."""
        return self.base.n

    @property
    def mass(self):
        """The mass ``A`` of the base basis."""
        return self.base.mass

    @property
    def degree(self) -> np.ndarray:
        """Number of non-constant factors of each column, ``(K,)``."""
        return (self.index > 0).sum(axis=1)

    @property
    def matrix(self) -> np.ndarray:
        """The extended basis ``B`` ``(n, K)`` (materialised once and cached)."""
        return self.cache.get("matrix", lambda: evaluate_products(self.base.vecs, self.index))

    # ----------------------------------------------------------- unique/ordered bridge
    @property
    def unique_index(self) -> np.ndarray:
        """Multi-indices of the unique (multiset) columns spanning the same space."""
        uindex = lambda: multi_indices(self.n_factors, self.order, "unique")
        return self.index if self.pairs == "unique" else self.cache.get("uindex", uindex)

    def solver_basis(self) -> tuple[np.ndarray, np.ndarray]:
        """``(B_s (n, K_u), scale (K_u,))``: the unique basis the solvers work on.

        For ``pairs="unique"`` the scale is 1. For ``"ordered"`` each multiset column is
        scaled by ``sqrt(#orderings)`` so that ``B_o = B_s S`` with orthonormal-row ``S``
        (:meth:`expand`).
        """
        def compute():
            if self.pairs == "unique":
                return self.matrix, np.ones(self.K)
            scale = self.solver_scale()
            return evaluate_products(self.base.vecs, self.unique_index) * scale, scale

        return self.cache.get("solver", compute)

    def expand(self) -> sp.csr_matrix:
        """``Sᵀ`` ``(K, K_u)``: maps solver (scaled-unique) coefficients to this basis' coefficients.

        Identity for ``pairs="unique"``.
        """
        def compute():
            if self.pairs == "unique":
                return sp.identity(self.K, format="csr")
            E = _ordered_to_unique(self.index, self.unique_index).T.tocsr()  # counts -> weights
            # S[u, o] = 1/sqrt(#orderings(u)) for every ordering o of multiset u
            w = 1.0 / np.sqrt(n_orderings(self.unique_index))
            return (E @ sp.diags(w)).tocsr()

        return self.cache.get("expand", compute)

    def fold(self) -> sp.csr_matrix:
        """``(K_u, K)`` sparse map from this basis' coefficients to unique-multiset coefficients.

        ``B @ a == B_unique @ (fold() @ a)``: ordered coefficients of the same multiset are summed.
        """
        return self.cache.get("fold", lambda: sp.identity(self.K, format="csr") if self.pairs == "unique"
                              else _ordered_to_unique(self.index, self.unique_index))

    # ----------------------------------------------------- blocked products with B_s
    # The solvers only need B_sᵀ A B_s, B_sᵀ Y and B_s X. Unless the matrix was asked for
    # (``matrix``, ``solver_basis``), they evaluate the product columns by blocks of rows
    # (``block_bytes``), so the extended basis is never held at once.
    def _materialize_solver(self) -> bool:
        return "solver" in self.cache

    def solver_scale(self) -> np.ndarray | None:
        """``sqrt(#orderings)`` ``(K_u,)`` of the unique columns in the solver basis: ``B_s = B_unique * scale``.

        ``None`` for ``pairs="unique"``, whose solver basis is the basis itself.
        """
        scale = lambda: np.sqrt(n_orderings(self.unique_index))
        return None if self.pairs == "unique" else self.cache.get("scale", scale)

    def _solver_blocks(self):
        """Yield ``(rows slice, B_s[rows])`` blocks of about ``block_bytes``.

        When one block holds every row (at most ``block_bytes``) it is kept (:attr:`kept_block`)
        and the next product reuses it: the same array, so the same numbers.
        """
        uidx = self.unique_index
        scale = self.solver_scale()
        step = max(1, int(self.block_bytes // (8 * uidx.shape[0])))

        def block(rows):
            b = evaluate_products(self.base.vecs[rows], uidx)
            return b if scale is None else b * scale

        if step >= self.n:
            def whole():
                b = block(slice(0, self.n))
                b.setflags(write=False)
                return b

            yield slice(0, self.n), self.kept_block.get("B_s", whole)
            return
        for i0 in range(0, self.n, step):
            rows = slice(i0, min(self.n, i0 + step))
            yield rows, block(rows)

    @property
    def has_gram(self) -> bool:
        """Whether :meth:`solver_gram` has been computed (and is held in :attr:`cache`)."""
        return "gram" in self.cache

    def solver_gram(self) -> np.ndarray:
        """``G_s = B_sᵀ A B_s`` ``(K_u, K_u)`` (cached), blocked for large meshes."""
        def compute():
            if self._materialize_solver() or not self.base.mass_is_diagonal:
                return mass_gram(self.solver_basis()[0], self.base)
            K_u = self.unique_index.shape[0]
            G = np.zeros((K_u, K_u))
            sq = np.sqrt(self.base.mass)
            for rows, Bb in self._solver_blocks():
                X = sq[rows, None] * Bb
                G += X.T @ X
            return 0.5 * (G + G.T)

        return self.cache.get("gram", compute)

    def solver_rmatmul(self, Y: np.ndarray) -> np.ndarray:
        """``B_sᵀ Y`` for ``Y`` ``(n,)`` or ``(n, m)``."""
        if self._materialize_solver():
            return self.solver_basis()[0].T @ Y
        return sum(Bb.T @ Y[rows] for rows, Bb in self._solver_blocks())

    def solver_matmul(self, X: np.ndarray) -> np.ndarray:
        """``B_s X`` for ``X`` ``(K_u,)`` or ``(K_u, m)``."""
        if self._materialize_solver():
            return self.solver_basis()[0] @ X
        out = np.empty((self.n,) + X.shape[1:])
        for rows, Bb in self._solver_blocks():
            out[rows] = Bb @ X
        return out

    def evaluate(self, coefs: np.ndarray) -> np.ndarray:
        """The function(s) ``B @ coefs`` ``(n,)``/``(n, m)``, computed through the unique basis."""
        coefs = np.asarray(coefs, dtype=np.float64)
        if coefs.shape[0] != self.K:
            raise ValueError(f"coefficients have {coefs.shape[0]} rows, the basis has {self.K} columns")
        if self.pairs == "unique":
            return self.solver_matmul(coefs)
        scale = self.solver_scale()
        cu = self.fold() @ coefs  # (K_u,) or (K_u, m)
        return self.solver_matmul(cu / (scale if cu.ndim == 1 else scale[:, None]))

    def operator(self, method: str = "svd", **params):
        """A cached reusable approximation operator (see :func:`prodmaps.approx.approximation_operator`)."""
        # keyed by every parameter, defaults filled in: asking with or without a default value is one operator
        key = ("operator", method, tuple(sorted(operator_parameters(**params).items())))
        return self.cache.get(key, lambda: approximation_operator(self, method=method, **params))

    def __repr__(self) -> str:
        return (f"ProductBasis(order={self.order}, pairs={self.pairs!r}, n_factors={self.n_factors}, "
                f"K={self.K}, n={self.n})")


def _ordered_to_unique(index_o: np.ndarray, index_u: np.ndarray) -> sp.csr_matrix:
    """0/1 matrix ``(K_u, K_o)``: ordered column -> the multiset column it equals."""
    key_u = {tuple(r): i for i, r in enumerate(np.sort(index_u, axis=1)[:, ::-1])}
    sorted_o = np.sort(index_o, axis=1)[:, ::-1]
    rows = np.fromiter((key_u[tuple(r)] for r in sorted_o), dtype=np.int64, count=sorted_o.shape[0])
    cols = np.arange(index_o.shape[0])
    return sp.csr_matrix((np.ones(cols.size), (rows, cols)), shape=(index_u.shape[0], index_o.shape[0]))


def product_basis(basis: Basis, order: int = 2, pairs: str = "ordered") -> ProductBasis:
    """The extended basis of ``basis`` with products up to ``order`` (see module doc).

    Cached in ``basis.cache`` under ``("product_basis", basis.k, order, pairs)``: asking twice,
    also through another truncation of the same basis to the same ``k``, returns the same object
    (and so reuses its operators).

    Parameters
    ----------
    basis : a :class:`prodmaps.Basis` (column 0 constant).
    order : highest product degree, ``>= 2`` (``1`` gives the base basis as a ProductBasis).
    pairs : ``"ordered"`` (the paper's convention, the default for reproduction) or
        ``"unique"`` (multisets; same span, fewer columns).

    Returns
    -------
    ProductBasis
        ``K`` columns: the ``basis.k`` base functions, then the products; for ``order=2``,
        ``K = k + (k-1)²`` ordered or ``k + (k-1)k/2`` unique.

    Raises
    ------
    TypeError
        If ``basis`` is not a :class:`prodmaps.Basis`.
    ValueError
        For ``order < 1`` or an unknown ``pairs``.

    Examples
    --------
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 6)
    >>> pm.product_basis(b).K, pm.product_basis(b, pairs="unique").K
    (31, 21)
    >>> pm.product_basis(b) is pm.product_basis(b)  # cached on the basis
    True
    """
    if not isinstance(basis, Basis):
        raise TypeError(f"product_basis expects a prodmaps.Basis, got {type(basis).__name__}")
    if not isinstance(order, (int, np.integer)) or order < 1:
        raise ValueError(f"order must be an integer >= 1, got {order!r}")
    check_pairs(pairs)
    key = ("product_basis", basis.k, int(order), pairs)
    return basis.cache.get(key, lambda: ProductBasis(basis, int(order), pairs,
                                                     multi_indices(basis.k - 1, int(order), pairs)))


def unique_solver_gram(basis: Basis, order: int = 2) -> np.ndarray:
    """The Gram matrix ``B_uᵀ A B_u`` ``(K_u, K_u)`` of the unique-multiset extended basis of ``basis``.

    It is the unique basis' :meth:`ProductBasis.solver_gram` (cached there), except when only the
    ordered (paper's) extended basis has computed its Gram: then it is recovered from that one,
    exactly up to rounding (the ordered solver basis is the unique one with each column scaled by
    ``sqrt(#orderings)``, :meth:`ProductBasis.solver_scale`), and nothing is formed again.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 5)
    >>> G = unique_solver_gram(b)
    >>> G.shape, bool(np.allclose(G[:5, :5], np.eye(5)))  # A-orthonormal base columns
    ((15, 15), True)
    """
    ext_u = product_basis(basis, order, "unique")
    ext_o = product_basis(basis, order, "ordered")
    if not ext_u.has_gram and ext_o.has_gram:
        s = ext_o.solver_scale()
        return ext_o.solver_gram() / np.outer(s, s)
    return ext_u.solver_gram()
