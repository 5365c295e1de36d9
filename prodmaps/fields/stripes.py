"""Quad layouts from cross fields: two coupled stripe patterns and their quad texture [KCPS15].

Stripe patterns
---------------
For a unit direction field ``X`` and a frequency ``ν = 2π / period``, a stripe pattern is a
per-vertex complex function ``ψ`` whose phase ``θ = arg ψ`` grows like ``ν <X, ·>``: it minimises
``∫ |∇ψ - i ν X♭ ψ|²`` over unit-``L²`` functions, discretised on edges as
``Σ_ij w_ij |ψ_j - exp(i ω_ij) ψ_i|²`` with ``ω_ij = ν <X̄_ij, x_j - x_i>`` (``X̄`` the direction
at the edge) and the cotangent weights ``w_ij`` (negative ones clipped to 0, and multiplied by
``min(|zv_i|, |zv_j|)²``, the squared magnitude of the vertex-averaged unit power field, which is
small at singular vertices: there the per-edge mismatch is a near tie that would otherwise flip
the whole pattern under round-off). The minimiser is the smallest eigenvector of the generalised
problem with the lumped mass (Knöppel, Crane, Pinkall, Schröder 2015, in its simplest
"connection Laplacian" form, without their per-triangle interpolation; geometry-central's
``stripe_patterns`` is the full version).
We compute it by inverse iteration from the start ``ψ1 = ψ2 = 1``, which is invariant under
every relabelling ``S_m`` below, hence defined intrinsically by the field: on the humans the low
spectrum is clustered (body parts decouple through the singular regions) and an eigen-solver
picks an arbitrary member of the cluster, different on two shapes; the inverse iteration picks
the component of the same intrinsic start vector, deterministic and comparable across shapes.

A cross field gives one pattern per cross direction, ``ψ1`` along ``d1`` and ``ψ2`` along
``d2 = n x d1``. A cross has no global labelling: across an edge the representative ``d1_j`` is
the transported ``d1_i`` turned by ``m_ij`` quarter turns (the *mismatch*, chosen per edge by
best alignment), and the two patterns swap and conjugate accordingly. In ``i``'s labelling the
values at ``j`` are ``S_m(ψ1_j, ψ2_j)``:

    ``m = 0: (ψ1, ψ2)    m = 1: (conj ψ2, ψ1)    m = 2: (conj ψ1, conj ψ2)    m = 3: (ψ2, conj ψ1)``

(turning the frame by 90° maps direction 1 to direction 2 and direction 2 to minus direction
1, and a pattern along ``-X`` is the conjugate of the pattern along ``X``). The coupled energy
``Σ w_ij (|S_m(ψ_j)_1 - e^{iω1} ψ1_i|² + |S_m(ψ_j)_2 - e^{iω2} ψ2_i|²)`` is real-linear in
``(ψ1, ψ2)``, so it is solved as a real symmetric ``4n x 4n`` eigenproblem. ``|ψ|`` vanishes at
the field's singularities.

Quad texture
------------
``q = cos θ1 · cos θ2`` is invariant under every relabelling of the cross (swap, sign flips),
so it is a well defined function on the surface: its sign is the checkerboard colouring of the
quad cells (cell side = half a period), its zero set the grid lines.

Layout consistency (evaluation only)
------------------------------------
:func:`layout_consistency` transports the source texture through the ground-truth point map
``p2p_21`` and compares it with the target's own texture: the fraction of target area where
the checkerboard colours agree, maximised over the global colour swap (a half-period shift of
one pattern, a symmetry of the quad grid), and the area-weighted correlation ``|<q_s, q_t>|``.
Two unrelated layouts agree on about half of the area; identical ones on all of it.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..mesh import edges
from ..operators import cotan_weights, lumped_mass
from .crossfield import vertex_power_field
from .frames import Frames, as_frames

__all__ = ["vertex_directions", "stripe_patterns", "quad_texture", "layout_consistency", "mean_edge_length"]

# S_m: j-labelled (Re ψ1, Im ψ1, Re ψ2, Im ψ2) -> i-labelled, for the mismatch m (quarter turns)
_S = np.array([
    np.eye(4),
    [[0, 0, 1, 0], [0, 0, 0, -1], [1, 0, 0, 0], [0, 1, 0, 0]],
    np.diag([1.0, -1.0, 1.0, -1.0]),
    [[0, 0, 1, 0], [0, 0, 0, 1], [1, 0, 0, 0], [0, -1, 0, 0]],
], dtype=np.float64)


def mean_edge_length(V: np.ndarray, F: np.ndarray) -> float:
    """Mean length of the unique edges."""
    e, _ = edges(np.asarray(F))
    return float(np.linalg.norm(V[e[:, 1]] - V[e[:, 0]], axis=1).mean())


def vertex_directions(fr: Frames, z: np.ndarray, N: int = 4):
    """Per-vertex representative direction ``d1`` ``(n, 3)`` (unit, tangent), normals ``(n, 3)``
    and the field magnitude ``|zv|`` ``(n,)`` (small near singularities); see
    :func:`prodmaps.fields.crossfield.vertex_power_field`."""
    fr = as_frames(fr)
    zv, nv, t, b = vertex_power_field(fr, z, N)
    a = np.angle(zv) / N
    d1 = np.cos(a)[:, None] * t + np.sin(a)[:, None] * b
    return d1, nv, np.abs(zv)


def _rot(a):
    c, s = np.cos(a), np.sin(a)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)  # (E, 2, 2)


def stripe_patterns(fr: Frames, z: np.ndarray, *, period: float | None = None, N: int = 4,
                    iterations: int = 30, return_info: bool = False):
    """Two coupled stripe patterns along a cross field (see the module doc).

    Parameters
    ----------
    fr : face frames of the mesh; ``z`` ``(m,)`` a 4-power field (cross field).
    period : stripe period in the mesh's length unit; default 16 mean edge lengths.
    iterations : inverse-iteration steps (converged after about 20 on the 5k humans).

    Returns ``psi`` ``(n, 2)`` complex (``psi[:, 0]`` along the vertex representative ``d1``,
    ``psi[:, 1]`` along ``n x d1``), unit ``L²`` norm; with ``return_info`` also a dict with
    the edge list ``edges`` ``(E, 2)``, the mismatch ``(E,)``, the expected phase increments
    ``omega`` ``(E, 2)`` (in the labelling of the first vertex), the energy (Rayleigh quotient).
    """
    fr = as_frames(fr)
    if N != 4:
        raise ValueError("stripe_patterns couples two orthogonal patterns: it needs a cross field (N = 4)")
    V, F = fr.vertices, fr.faces
    n = V.shape[0]
    if period is None:
        period = 16.0 * mean_edge_length(V, F)
    if not period > 0:
        raise ValueError(f"period must be positive, got {period}")
    nu = 2 * np.pi / period
    d1, nv, mag = vertex_directions(fr, z, N)
    E, _ = edges(F)  # (E, 2), i < j
    i, j = E[:, 0], E[:, 1]
    W = cotan_weights(V, F)
    w = np.maximum(-np.asarray(W[i, j]).ravel(), 0.0)  # (E,)
    # edges at singular vertices carry no reliable direction (the mismatch is a near tie there):
    # weaken them by the squared vertex field magnitude |zv| in [0, 1]
    w = w * np.minimum(mag[i], mag[j]) ** 2
    # mismatch: d1_i ≈ R^{-m} d1_j, R = rotation by +90° about n_j
    dj = d1[j]
    rj = np.cross(nv[j], dj)  # R d1_j
    cand = np.stack([dj, -rj, -dj, rj], axis=1)  # (E, 4, 3): R^{-m} d1_j for m = 0..3
    mm = np.argmax(np.einsum("ed,emd->em", d1[i], cand), axis=1)  # (E,)
    e1 = d1[i] + cand[np.arange(E.shape[0]), mm]
    e1 /= np.maximum(np.linalg.norm(e1, axis=1, keepdims=True), 1e-300)
    nbar = nv[i] + nv[j]
    nbar /= np.linalg.norm(nbar, axis=1, keepdims=True)
    e2 = np.cross(nbar, e1)
    x = V[j] - V[i]
    om1 = nu * np.einsum("ij,ij->i", e1, x)
    om2 = nu * np.einsum("ij,ij->i", e2, x)
    R = np.zeros((E.shape[0], 4, 4))
    R[:, :2, :2] = _rot(om1)
    R[:, 2:, 2:] = _rot(om2)
    Bji = -w[:, None, None] * np.einsum("eba,ebc->eac", _S[mm], R)  # (E, 4, 4) = -w S_mᵀ R, block (j, i)
    r4 = np.arange(4)
    rows_ji = (4 * j[:, None, None] + r4[None, :, None]) + 0 * r4[None, None, :]
    cols_ji = (4 * i[:, None, None] + r4[None, None, :]) + 0 * r4[None, :, None]
    deg = np.bincount(i, weights=w, minlength=n) + np.bincount(j, weights=w, minlength=n)
    rows = np.concatenate([rows_ji.ravel(), cols_ji.ravel(), np.arange(4 * n)])
    cols = np.concatenate([cols_ji.ravel(), rows_ji.ravel(), np.arange(4 * n)])
    vals = np.concatenate([Bji.ravel(), Bji.ravel(), np.repeat(deg, 4)])
    L = sp.csr_matrix((vals, (rows, cols)), shape=(4 * n, 4 * n))
    mass = np.repeat(lumped_mass(V, F), 4)
    # inverse iteration from the labelling-invariant start ψ1 = ψ2 = 1 (see the module doc)
    x = np.tile([1.0, 0.0, 1.0, 0.0], n)
    shift = 1e-8 * float(L.diagonal().mean() / mass.mean())
    lu = spla.splu((L + sp.diags(shift * mass)).tocsc())
    for _ in range(iterations):
        x = lu.solve(mass * x)
        x /= np.sqrt(np.sum(mass * x ** 2))
    lam = np.array([float(x @ (L @ x))])
    x4 = x.reshape(n, 4)
    psi = np.stack([x4[:, 0] + 1j * x4[:, 1], x4[:, 2] + 1j * x4[:, 3]], axis=1)
    if return_info:
        return psi, {"mismatch": mm, "edges": E, "omega": np.stack([om1, om2], axis=1),
                     "energy": float(lam[0]), "period": period, "field_magnitude": mag}
    return psi


def quad_texture(psi: np.ndarray) -> np.ndarray:
    """``q = cos θ1 cos θ2`` ``(n,)`` from two stripe patterns ``psi`` ``(n, 2)`` (see the module doc)."""
    psi = np.asarray(psi)
    if psi.ndim != 2 or psi.shape[1] != 2:
        raise ValueError(f"psi must be (n, 2) complex; got {psi.shape}")
    a = np.abs(psi)
    c = np.where(a > 0, psi.real / np.where(a > 0, a, 1.0), 0.0)
    return c[:, 0] * c[:, 1]


def layout_consistency(q_1: np.ndarray, q_2: np.ndarray, p2p_21: np.ndarray, mass_2: np.ndarray) -> dict:
    """Consistency of two quad textures given the ground-truth point map (evaluation only).

    ``q_1`` ``(n1,)`` on the source, ``q_2`` ``(n2,)`` on the target, ``p2p_21`` ``(n2,)``,
    ``mass_2`` ``(n2,)`` target vertex areas. Returns ``agreement`` (fraction of target area
    whose checkerboard colour agrees, up to the global colour swap; 0.5 = unrelated, 1 =
    identical) and ``correlation`` (``|<q_1∘p, q_2>_A| / (||q_1∘p||_A ||q_2||_A)``).
    """
    q_1 = np.asarray(q_1, dtype=np.float64)
    q_2 = np.asarray(q_2, dtype=np.float64)
    p = np.asarray(p2p_21, dtype=np.int64)
    A = np.asarray(mass_2, dtype=np.float64)
    if q_2.shape != A.shape or p.shape != q_2.shape:
        raise ValueError(f"q_2, p2p_21 and mass_2 must all be (n2,); got {q_2.shape}, {p.shape}, {A.shape}")
    qs = q_1[p]
    same = float(np.sum(A * (np.sign(qs) == np.sign(q_2))) / A.sum())
    corr = float(abs(np.sum(A * qs * q_2)) / np.sqrt(np.sum(A * qs ** 2) * np.sum(A * q_2 ** 2)))
    return {"agreement": max(same, 1.0 - same), "correlation": corr}
