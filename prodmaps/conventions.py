"""The conventions of prodmaps, stated once (every module refers here); they hold for every function and notebook.

Bases
-----
* A basis ``Φ`` (:class:`prodmaps.Basis`) has shape ``(n, k)``: ``n`` points, ``k`` functions as
  columns. Column 0 is the constant function ``φ0 = 1/sqrt(total area)``.
* Bases are orthonormal in the **area inner product**: ``Φᵀ A Φ = I``, ``A`` the lumped (barycentric,
  a third of each incident triangle's area) mass matrix unless stated; every projection ``Φᵀ A f`` uses it.
* ``W`` is the positive semi-definite cotangent stiffness; eigenpairs solve ``W φ = λ A φ``,
  ascending, ``λ0 = 0``. Signs are deterministic: the entry of largest magnitude of every
  non-constant column is positive (the rule for ties: :func:`prodmaps.basis.fix_signs`).

What ``k`` counts
-----------------
* In the library, ``k`` (``Basis.k``, ``eigenbasis(mesh, k)``, ``ProductBasis.base.k``) counts
  **all** columns, the constant included.
* In the paper and in the notebooks' parameters, ``k_M`` / ``k_N`` count the **non-constant**
  functions: the paper's ``k_M = 9`` is ``eigenbasis(mesh, 10)``.
* A product basis has ``ProductBasis.n_factors = base.k - 1`` non-constant functions that are
  multiplied (the paper's ``k_M``) and ``ProductBasis.K`` columns.

Maps
----
* A functional map ``C_12`` ``(k2, k1)`` maps coefficients on shape 1 to shape 2: ``T f ≈ Φ2 C_12 Φ1ᵀ A1 f``.
* A point map ``p2p_21`` has shape ``(n2,)``: for every vertex of shape 2, a vertex of shape 1 —
  the pull-back direction, ``(T f)(y) = f(p2p_21[y])``. The ground-truth functional map of a
  point map is ``C_12 = Φ2ᵀ A2 Φ1[p2p_21]``.
* The extended map ``C~_12`` (:func:`prodmaps.extend_fmap`) has shape ``(K2, K1)`` between the
  extended bases of the two shapes (same ``order`` and ``pairs``: ``"ordered"``, the paper's, keeps
  both ``(l, m)`` and ``(m, l)``; ``"unique"`` one column per multiset, the same span).

Functions and errors
--------------------
* A function is an array ``(n,)``; several functions are the columns of an ``(n, m)`` array.
* Errors are the paper's relative error ``sqrt(∫(f-g)²) / sqrt(∫g²)``, area-weighted
  (:func:`prodmaps.relative_error`).

The same conventions with their reasons and the rule for tied signs: ``docs/guide/conventions.md``.
"""

__all__: list[str] = []
