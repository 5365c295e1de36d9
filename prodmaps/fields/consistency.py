"""Consistency of direction fields across two shapes through a functional map.

Holds :func:`consistency_problem` (a :class:`ConsistencyProblem`: the energy of a pair of fields
through ``C`` or ``C~``), its pieces (:func:`images_of_tests`, :func:`scaled_actions`,
:func:`comparison_span`), and the designs :func:`design_consistent_field` (the target field for a
fixed source field) and :func:`design_joint` (both fields at once, ACBCO17's setting).

Only real-valued functions cross the map; no point map is used (except by the ``"p2p"`` oracle,
for evaluation). Conventions (:mod:`prodmaps.conventions`): bases A-orthonormal, constant first;
``C_12`` ``(k2, k1)`` maps coefficients on shape 1 to shape 2, ``k1 - 1`` the paper's k; fields
are unit ``N``-power fields per face (``N = 4``: a cross field, :mod:`prodmaps.fields.crossfield`),
acting on functions by the degree-N action ``Q_z(f) = Re(conj(z) g(f)^N) |g|^(p-N)``
(:func:`prodmaps.fields.operators.field_action`). Consistency asks the action to commute with the
map, ``T(Q_{z1}(f_j)) ≈ Q_{z2}(T f_j)`` for every test function ``f_j``, compared in an
A-orthonormal basis of a span of shape 2 (area inner product). ``kind`` (:data:`KINDS`) says how
``T`` carries functions: ``"std"`` (``C``, the basis), ``"ext"`` (the paper's change: the
registry's ``"svd"`` transfer, ``C~`` on the extended basis), ``"default"`` (the library's default
transfer; not in the paper), ``"p2p"`` (the oracle). The energy is normalised: ``E = 1`` for
``z2 = 0``, ``E = 0`` for perfect consistency. Designs are linear least-squares problems (a
smoothness weight ``μ``, dimensionless) solved by preconditioned conjugate gradients.

The test functions, each ``kind``'s comparison span and energy, the scaling, the design energy and
its solver, and the references ([ABCO13], [ACBCO17]): ``docs/guide/fields.md``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..approx import PAPER_RTOL
from ..basis import Basis
from ..checks import check_fmap, check_p2p, check_symmetry_order
from ..products import product_basis
from ..transfers import transfer_operator
from .crossfield import aligned_field, connection_laplacian, normalize_field
from .frames import Frames, as_frames, complex_gradient, face_to_vertex
from .operators import SpanProjector, powered_gradients, span_projector

__all__ = ["ConsistencyProblem", "consistency_problem", "images_of_tests", "scaled_actions", "comparison_span",
           "design_consistent_field", "design_joint",
           "KINDS", "TESTS"]

KINDS = ("std", "ext", "default", "p2p")
TESTS = ("base", "pairs", "products")


def _test_functions(k: int, pairs: bool) -> np.ndarray:
    """``(k1, J)`` coefficient matrix of the test functions in the base basis (row 0 = constant)."""
    cols = [np.eye(k + 1)[:, 1:]]
    if pairs:
        a, b = np.triu_indices(k, 1)
        P, j = np.zeros((k + 1, a.size)), np.arange(a.size)
        P[a + 1, j] = P[b + 1, j] = 1 / np.sqrt(2)
        cols.append(P)
    return np.concatenate(cols, axis=1)


@dataclass(eq=False)
class ConsistencyProblem:
    """The linear consistency model between two shapes (build with :func:`consistency_problem`).

    Each side ``s`` has ``W_s`` ``(m_s, r)`` and ``H_s`` ``(m_s, J)`` such that the coordinates of
    its (transported) action in the comparison span are ``W_sᵀ Re(conj(z_s) H_s)`` ``(r, J)``.
    """

    kind: str
    N: int
    fr_1: Frames
    fr_2: Frames
    W_1: np.ndarray  # (m1, r)
    H_1: np.ndarray  # (m1, J) complex, scaled g(f_j)^N on shape 1
    W_2: np.ndarray  # (m2, r)
    H_2: np.ndarray  # (m2, J) complex, scaled g(T f_j)^N on shape 2
    lam_2: float  # first non-zero Laplace-Beltrami eigenvalue of shape 2 (smoothness scale)
    lam_1: float
    info: dict = field(default_factory=dict)
    _cache: dict = field(default_factory=dict, repr=False)

    # ------------------------------------------------------------------ linear maps
    def _parts(self, side: int):
        if ("parts", side) not in self._cache:
            W, H = (self.W_1, self.H_1) if side == 1 else (self.W_2, self.H_2)
            self._cache[("parts", side)] = (W, np.ascontiguousarray(H.real), np.ascontiguousarray(H.imag))
        return self._cache[("parts", side)]

    def _apply(self, side: int, z):
        W, Hr, Hi = self._parts(side)
        z = np.asarray(z)
        return W.T @ (z.real[:, None] * Hr + z.imag[:, None] * Hi)  # (r, J) = Wᵀ Re(conj(z) H)

    def _adjoint(self, side: int, Y):
        # gradient of <Y, Wᵀ Re(conj(z) H)> with respect to (Re z, Im z), as a complex vector
        W, Hr, Hi = self._parts(side)
        WY = W @ Y  # (m, J)
        return np.einsum("ij,ij->i", Hr, WY) + 1j * np.einsum("ij,ij->i", Hi, WY)  # (m,)

    def data(self, z1: np.ndarray) -> np.ndarray:
        """Coordinates ``(r, J)`` of the transported source action ``T(Q_{z1}(f_j))``."""
        return self._apply(1, z1)

    def model(self, z2: np.ndarray) -> np.ndarray:
        """Coordinates ``(r, J)`` of the target action ``Q_{z2}(T f_j)``."""
        return self._apply(2, z2)

    def energy(self, z1: np.ndarray, z2: np.ndarray) -> float:
        """Relative consistency energy ``||data(z1) - model(z2)||² / ||data(z1)||²``."""
        c = self.data(z1)
        return float(np.sum((c - self.model(z2)) ** 2) / max(np.sum(c ** 2), 1e-300))

    # ------------------------------------------------------------------ pieces for solvers
    def laplacian(self, side: int):
        """The connection Laplacian of ``N``-power fields on shape ``side`` (1 or 2), cached."""
        if ("L", side) not in self._cache:
            self._cache[("L", side)] = connection_laplacian(self.fr_1 if side == 1 else self.fr_2, self.N)[0]
        return self._cache[("L", side)]

    def data_diagonal(self, side: int) -> np.ndarray:
        """Diagonal of the data term's normal matrix (per face, averaged over Re/Im)."""
        W, H = (self.W_1, self.H_1) if side == 1 else (self.W_2, self.H_2)
        return 0.5 * np.sum(np.abs(H) ** 2, axis=1) * np.sum(W ** 2, axis=1)


def _checked_inputs(basis_1: Basis, basis_2: Basis, fr_1: Frames, fr_2: Frames, C_12, kind: str, tests,
                    p2p_21, span_k):
    """Checked inputs of :func:`consistency_problem`: ``(C or None, truncated b1, b2, tests or default, p2p_21)``."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {KINDS}, got {kind!r}")
    if kind == "p2p":
        if p2p_21 is None:
            raise ValueError("kind='p2p' needs p2p_21 (n2,)")
        p2p_21 = check_p2p(p2p_21, basis_1.n, basis_2.n)
    C = None
    if C_12 is None:
        if kind != "p2p":
            raise ValueError(f"kind={kind!r} needs C_12 (k2, k1)")
        k1 = k2 = span_k or basis_1.k
    else:
        C = check_fmap(C_12, basis_1, basis_2, allow_truncation=True)
        k2, k1 = C.shape
    b1, b2 = basis_1.truncate(k1), basis_2.truncate(k2)
    if b1.n != fr_1.n_vertices or b2.n != fr_2.n_vertices:
        raise ValueError("bases and frames describe different meshes")
    if not (b1.mass_is_diagonal and b2.mass_is_diagonal):
        raise ValueError("fields need lumped (diagonal) masses")
    if tests is None:
        tests = "base" if kind in ("std", "default") else "products"
    if tests not in TESTS:
        raise ValueError(f"tests must be one of {TESTS}, got {tests!r}")
    if tests == "products" and kind in ("std", "default"):
        raise ValueError("tests='products' needs the extended basis (kind='ext' or 'p2p'): a (k2, k1) "
                         "map does not transfer products")
    if k1 < 2:
        raise ValueError("need at least one non-constant basis function (k1 >= 2)")
    return C, b1, b2, tests, p2p_21


def images_of_tests(b1: Basis, b2: Basis, C, tests: str, p2p_21=None, *, op=None):
    """The test functions on shape 1 and their images on shape 2: ``(F1 (n1, J), F2 (n2, J))``.

    Through ``C`` ``(k2, k1)`` (``Φ2 C`` of the coefficients; for ``tests="products"`` the exact
    products ``B2 C~``, by ``op``: the registry's ``"svd"`` transfer on the unique pairs, built
    here when not given), or, with ``C`` None, pulled back through ``p2p_21``. ``tests`` as in
    :func:`consistency_problem`.
    """
    if tests == "products":
        F1 = product_basis(b1, 2, "unique").matrix[:, 1:]  # (n1, K1-1)
        if C is None:
            return F1, F1[p2p_21]
        op = transfer_operator(C, b1, b2, "svd", pairs="unique") if op is None else op
        return F1, op.transfer_coefficients(np.eye(op.extended_basis_1.K)[:, 1:])  # (n2, K1-1) exact products
    Tc = _test_functions(b1.k - 1, tests == "pairs")  # (k1, J)
    F1 = b1.vecs @ Tc  # (n1, J)
    return F1, (F1[p2p_21] if C is None else b2.vecs @ (C @ Tc))  # (n2, J)


def scaled_actions(fr_1: Frames, fr_2: Frames, F1, F2, mass_1, N: int, power):
    """The degree-N actions' factors ``(H1 (m1, J), H2 (m2, J))`` of the tests ``F1`` and their images ``F2``.

    ``g^N |g|^(p-N)`` of their complex gradients, each test scaled to unit A-norm of its vertex-averaged
    ``|∇f|^p`` on shape 1 (``p = N`` when ``power`` is None).
    """
    g1 = complex_gradient(fr_1) @ F1  # (m1, J)
    g2 = complex_gradient(fr_2) @ F2
    p = N if power is None else float(power)
    mag = face_to_vertex(fr_1) @ (np.abs(g1) ** p)  # (n1, J)
    scale = 1.0 / np.sqrt(np.sum(mass_1[:, None] * mag ** 2, axis=0))  # (J,)
    return powered_gradients(g1, N, p) * scale, powered_gradients(g2, N, p) * scale


def _ext_transfer(op, ext2, proj2: SpanProjector):
    """``"ext"``: ``Tr = canonical(C~ a(h))``, ``a(h)`` Approach B's coefficients, and the kept directions' gain."""
    ext1 = op.extended_basis_1
    proj1 = SpanProjector(op.approximation)  # Approach B's operator on the source (the transfer's own)
    P1 = proj1.coefficient_matrix()  # (K1, n1)
    Tr = proj2.from_basis(op.extended_map @ P1)  # (r, n1)
    # transfer gain of the kept source directions (A-norm of B2 C~ q for unit q, no ground
    # truth): ~1 when C~ preserves products there; large when C is far from orthogonal
    gain = np.sqrt(np.max(op.basis_2.mass @ op.transfer_coefficients(proj1.P) ** 2))
    return Tr, {"K1": ext1.K, "K2": ext2.K, "rank_1": proj1.rank, "rank_2": proj2.rank, "gain_max": float(gain)}


def _default_transfer(C, b1: Basis, b2: Basis, Q2):
    """``"default"``: ``Tr = Q2ᵀ A2 S(h)``, ``S`` the default transfer (linear in ``h``), on blocks of the identity."""
    op = transfer_operator(C, b1, b2, "default")
    M2 = (Q2 * b2.mass[:, None]).T  # (r, n2)
    Tr = np.empty((Q2.shape[1], b1.n))
    step = 512
    for s0 in range(0, b1.n, step):  # the operator applied to blocks of the identity
        Tr[:, s0:s0 + step] = M2 @ op(np.eye(b1.n, min(step, b1.n - s0), k=-s0))
    return Tr, {"kept_products": op.rank}


def comparison_span(kind: str, C, b1: Basis, b2: Basis, *, rtol: float, normalization=None, p2p_21=None, op=None):
    """The span on shape 2 in which the actions are compared, and the transfer of source functions into it.

    Returns ``(Q2 (n2, r), Tr (r, n1), info)``. ``op``: the registry's ``"svd"`` transfer of ``C``
    on the unique pairs at ``rtol`` and ``normalization`` (built here for ``"ext"`` when not given).

    ``"std"``: ``Q2 = Φ2``, ``Tr = C Φ1ᵀ A1``; every other kind compares in the span the library's
    Approach B operator keeps in the target's extended basis (one truncation, its normalisation):
    ``"ext"`` through ``C~``, ``"default"`` through the default transfer of ``C``, ``"p2p"``
    through the point map (``Q2ᵀ A2 (h ∘ p2p)``).
    """
    A1, A2 = b1.mass, b2.mass
    if kind == "std":
        return b2.vecs, (C @ (b1.vecs.T * A1[None, :])), {}  # (n2, k2), (k2, n1) = C Φ1ᵀ A1
    ext2 = product_basis(b2, 2, "unique") if b2.k > 1 else None
    proj2: SpanProjector = span_projector(ext2 if ext2 else b2, rtol, normalization)
    Q2 = proj2.Q  # (n2, r)
    if kind == "ext":
        if op is None:
            op = transfer_operator(C, b1, b2, "svd", pairs="unique", rtol=rtol, normalization=normalization)
        return (Q2, *_ext_transfer(op, ext2, proj2))
    if kind == "default":
        Tr, info = _default_transfer(C, b1, b2, Q2)
        return Q2, Tr, {"rank_2": proj2.rank, **info}
    w = Q2 * A2[:, None]  # (n2, r)
    Tr = np.zeros((Q2.shape[1], b1.n))
    np.add.at(Tr.T, p2p_21, w)
    return Q2, Tr, {"rank_2": proj2.rank}


def consistency_problem(fr_1: Frames, basis_1: Basis, fr_2: Frames, basis_2: Basis, C_12=None, *,
                        kind: str = "ext", N: int = 4, tests: str | None = None, rtol: float = PAPER_RTOL,
                        p2p_21=None, span_k: int | None = None, power: float | None = 0.0,
                        normalization: str | None = None) -> ConsistencyProblem:
    """Build the consistency model of a pair of shapes.

    Parameters
    ----------
    fr_1, fr_2 : face frames of the shapes (:func:`prodmaps.fields.frames.mesh_frames`) or the meshes.
    basis_1, basis_2 : A-orthonormal bases (constant first). ``C_12`` ``(k2, k1)`` uses their
        first ``k1``/``k2`` columns; ``k1 - 1`` is the paper's k (non-constant functions).
    C_12 : functional map from shape 1 to shape 2 (``T f ≈ Φ2 C Φ1ᵀ A1 f``). For
        ``kind="p2p"`` it may be None (then the images of the test functions are pulled back
        through ``p2p_21`` too and ``span_k`` sets the comparison span).
    kind : ``"std"`` (basis, ``C``), ``"ext"`` (extended basis, ``C~``, pairs="unique"),
        ``"default"`` (the default extended transfer of ``C``, :mod:`prodmaps.transfers`) or
        ``"p2p"`` (oracle through the point map ``p2p_21``, evaluation only).
    N : symmetry order of the fields (4 for cross fields, 1 for vector fields).
    tests : test functions: ``"base"`` (the ``k`` non-constant base functions), ``"pairs"``
        (plus their pairwise sums ``(φ_a + φ_b)/√2``) or ``"products"`` (every non-constant
        column of the extended basis: the base functions and their products ``φ_a φ_b``, whose
        images are the exact products of the images, ``B2 C~``). Default: ``"base"`` for
        ``"std"``, ``"products"`` for ``"ext"`` and ``"p2p"`` (the extended basis replaces the
        basis everywhere); ``"base"`` for ``"default"``. Comparing kinds, pass the same
        ``tests`` to all of them (``"pairs"`` is available to every kind).
    rtol : SVD threshold of the extended bases (Approach B, the paper's 1e-3), applied by the
        library's operator (``ProductBasis.operator("svd", rtol=rtol)``): the same truncation as
        :func:`prodmaps.approximate` and the ``"svd"`` transfer.
    normalization : that operator's column normalisation (default: the library's
        ``"euclidean"``; ``"area"``, A-orthonormal factors without column weights, is kept to
        measure it).
    p2p_21 : ``(n2,)`` point map, only for ``kind="p2p"``; ``span_k`` its basis size if ``C_12`` is None.
    power : magnitude exponent ``p`` of the action (:func:`~prodmaps.fields.operators.field_action`):
        0 (default) direction only; ``None`` for ``p = N``, the polynomial ``Re(conj(z) g^N)``.

    The steps: the inputs checked, :func:`images_of_tests`, :func:`scaled_actions`,
    :func:`comparison_span`; the problem's ``W_s`` push the comparison to the faces.
    """
    N = check_symmetry_order(N)
    fr_1, fr_2 = as_frames(fr_1), as_frames(fr_2)
    C, b1, b2, tests, p2p_21 = _checked_inputs(basis_1, basis_2, fr_1, fr_2, C_12, kind, tests, p2p_21, span_k)
    op = None  # the registry's Approach B transfer (unique pairs), shared by the tests' images and the "ext" span
    if C is not None and (tests == "products" or kind == "ext"):
        op = transfer_operator(C, b1, b2, "svd", pairs="unique", rtol=rtol, normalization=normalization)
    F1, F2 = images_of_tests(b1, b2, C, tests, p2p_21, op=op)
    H1, H2 = scaled_actions(fr_1, fr_2, F1, F2, b1.mass, N, power)
    Q2, Tr, extra = comparison_span(kind, C, b1, b2, rtol=rtol, normalization=normalization, p2p_21=p2p_21, op=op)
    info = {"k": b1.k - 1, "J": F1.shape[1], "tests": tests, **extra, "r": Q2.shape[1]}
    W1 = face_to_vertex(fr_1).T @ Tr.T  # (m1, r): W1ᵀ h_face = Tr (S1 h_face)
    W2 = face_to_vertex(fr_2).T @ (Q2 * b2.mass[:, None])  # (m2, r): W2ᵀ h_face = Q2ᵀ A2 S2 h_face
    lam1 = float(b1.evals[1]) if b1.k > 1 else 1.0 / fr_1.area.sum()
    lam2 = float(b2.evals[1]) if b2.k > 1 else 1.0 / fr_2.area.sum()
    return ConsistencyProblem(kind, N, fr_1, fr_2, np.ascontiguousarray(W1), H1, np.ascontiguousarray(W2), H2,
                              lam2, lam1, info)


# ----------------------------------------------------------------------------- solvers
def _cg(apply, rhs_c: np.ndarray, precond, tol: float, maxiter: int):
    """CG on the real form of a real-linear SPD operator given on complex vectors."""
    m = rhs_c.size
    to_c = lambda x: x[:m] + 1j * x[m:]
    to_r = lambda z: np.concatenate([z.real, z.imag])
    A = spla.LinearOperator((2 * m, 2 * m), matvec=lambda x: to_r(apply(to_c(x))), dtype=np.float64)
    Mop = spla.LinearOperator((2 * m, 2 * m), matvec=lambda x: to_r(precond(to_c(x))), dtype=np.float64)
    it = []  # one entry per iteration
    x, flag = spla.cg(A, to_r(rhs_c), rtol=tol, maxiter=maxiter, M=Mop, callback=lambda _: it.append(1))
    return to_c(x), {"cg_iterations": len(it), "cg_flag": int(flag)}


def design_consistent_field(problem: ConsistencyProblem, z1: np.ndarray, *, smoothness: float = 1e-3,
                            align: float = 0.0, guide: np.ndarray | None = None, tol: float = 1e-6,
                            maxiter: int = 500, normalize: bool = True):
    """The target field consistent with a fixed source field ``z1`` (the energy: ``docs/guide/fields.md``).

    Parameters
    ----------
    z1 : unit ``N``-power field on shape 1 ``(m1,)``.
    smoothness : ``μ``, weight of the connection-Laplacian smoothness (dimensionless).
    align, guide : optional alignment of the target to its own guide ``q`` ``(m2,)`` (e.g.
        :func:`prodmaps.fields.crossfield.curvature_guide`, whose weights are ``|q|``).

    Returns ``(z2 (m2,), info)``: ``z2`` unit (``normalize``) or raw, ``info`` with the energy terms.
    """
    P = problem
    z1 = np.asarray(z1, dtype=np.complex128)
    if z1.shape != (P.fr_1.n_faces,):
        raise ValueError(f"z1 must be (m1,) = ({P.fr_1.n_faces},); got {z1.shape}")
    c = P.data(z1)  # (r, J)
    nc = max(float(np.sum(c ** 2)), 1e-300)
    L = P.laplacian(2)
    area = P.fr_2.area
    mu = smoothness / (P.lam_2 * area.sum())
    wq = np.zeros_like(area) if guide is None or align == 0 else align * area * np.abs(guide) / area.sum()
    q = np.zeros(area.size, np.complex128) if guide is None else normalize_field(guide)

    apply = lambda z: mu * (L @ z) + P._adjoint(2, P.model(z)) / nc + wq * z
    rhs = P._adjoint(2, c) / nc + wq * q
    pre = spla.splu((mu * L + sp.diags(P.data_diagonal(2) / nc + wq + 1e-12 * mu * P.lam_2 * area)).tocsc())
    z2, info = _cg(apply, rhs, pre.solve, tol, maxiter)
    info.update(consistency=P.energy(z1, z2), smooth=float(np.real(np.vdot(z2, L @ z2)) / (P.lam_2 * area.sum())),
                kind=P.kind, **P.info)
    return (normalize_field(z2) if normalize else z2), info


def design_joint(problem: ConsistencyProblem, guide_1: np.ndarray, guide_2: np.ndarray, *,
                 smoothness: float = 1e-3, align: float = 1.0, consistency: float = 1.0,
                 tol: float = 1e-6, maxiter: int = 1000, normalize: bool = True):
    """Design both fields at once (ACBCO17's joint setting), one linear least-squares problem.

    Minimises over ``(z1, z2)``: ``Σ_s μ z_sᴴ L_s z_s/(λ_s area_s) + α Σ_f A_f w_f |z_s - q̂_s|²/area_s``
    ``+ β ||data(z1) - model(z2)||² / ν`` with ``q̂ = q/|q|``, ``w = |q|`` from the guides and
    ``ν`` the squared norm of ``data`` for the aligned source field alone (so ``β`` is
    dimensionless). Returns ``(z1, z2, info)``.
    """
    P = problem
    m1 = P.fr_1.n_faces
    L1, L2 = P.laplacian(1), P.laplacian(2)
    a1, a2 = P.fr_1.area, P.fr_2.area
    mu1, mu2 = smoothness / (P.lam_1 * a1.sum()), smoothness / (P.lam_2 * a2.sum())
    w1, w2 = align * a1 * np.abs(guide_1) / a1.sum(), align * a2 * np.abs(guide_2) / a2.sum()
    q1, q2 = normalize_field(guide_1), normalize_field(guide_2)
    z_ref = aligned_field(P.fr_1, guide_1, P.N, L=L1)
    nu = max(float(np.sum(P.data(z_ref) ** 2)), 1e-300)
    beta = consistency / nu

    def apply(z):
        u1, u2 = z[:m1], z[m1:]
        r = P.data(u1) - P.model(u2)
        g1 = mu1 * (L1 @ u1) + w1 * u1 + beta * P._adjoint(1, r)
        g2 = mu2 * (L2 @ u2) + w2 * u2 - beta * P._adjoint(2, r)
        return np.concatenate([g1, g2])

    rhs = np.concatenate([w1 * q1, w2 * q2])
    pre1 = spla.splu((mu1 * L1 + sp.diags(beta * P.data_diagonal(1) + w1 + 1e-12 * mu1 * P.lam_1 * a1)).tocsc())
    pre2 = spla.splu((mu2 * L2 + sp.diags(beta * P.data_diagonal(2) + w2 + 1e-12 * mu2 * P.lam_2 * a2)).tocsc())
    precond = lambda z: np.concatenate([pre1.solve(z[:m1]), pre2.solve(z[m1:])])
    z, info = _cg(apply, rhs, precond, tol, maxiter)
    z1, z2 = z[:m1], z[m1:]
    info.update(consistency=P.energy(z1, z2), kind=P.kind, **P.info)
    if normalize:
        z1, z2 = normalize_field(z1), normalize_field(z2)
    return z1, z2, info
