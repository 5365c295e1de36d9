"""Functional bases: Laplace–Beltrami eigenbases of meshes and point clouds, the 1D periodic Fourier basis.

A :class:`Basis` holds ``vecs`` ``(n, k)`` whose columns are functions on the ``n`` points,
``evals`` ``(k,)`` ascending, and the mass (``(n,)`` lumped diagonal, or a sparse ``(n, n)`` FEM
mass). Orthonormality, the constant column 0, what ``k`` counts and the deterministic signs:
:mod:`prodmaps.conventions`. A mesh's basis and a point cloud's are built by the same
eigensolver with the same conventions, so everything downstream takes either.

Saved work: :meth:`Basis.save` writes a checked ``.npz`` (``vecs``, ``evals``, ``mass`` and a
metadata record: ``n``, ``k``, ``kind`` (the operator: ``"cotan"``, ``"robust"``,
``"point_cloud"``, ``"fourier"``, or ``""`` when unknown), ``name``, the library version and a
SHA-256 checksum of the arrays); :func:`load_basis` reads it back bit for bit, after checking it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .cache import Cache
from .eigensolver import smallest_eigenpairs
from .errors import MeshError
from .files import read_checked_npz, write_checked_npz
from .mesh import Mesh, face_components
from .operators import laplacian
from .pointcloud import PointCloud
from .progress import progress_bar

__all__ = ["Basis", "eigenbasis", "eigenbases", "fourier_basis", "fix_signs", "from_arrays", "load_basis",
           "PROGRESS_MIN_WORK", "BASIS_FORMAT"]

PROGRESS_MIN_WORK = 5e6
"""``progress=None``: eigenbases show a bar when ``Σ n·k`` exceeds this (about 10 s of work and more)."""
BASIS_FORMAT = "prodmaps.basis"
"""The ``format`` of a saved basis (:meth:`Basis.save`)."""
FILE_READERS = {"prodmaps.basis": "pm.load_basis(path)", "prodmaps.fmap": "pm.load_map(path)",
                "prodmaps.p2p": "pm.load_map(path)"}
"""What reads each kind of saved file (named in the error for a file of the wrong kind)."""


@dataclass(frozen=True, eq=False)
class Basis:
    """An A-orthonormal functional basis on ``n`` points.

    Usually built with :func:`prodmaps.eigenbasis`, :func:`prodmaps.fourier_basis` or
    :func:`prodmaps.basis.from_arrays` (which checks the conventions).

    Attributes
    ----------
    vecs : (n, k) basis functions as columns, ``vecs[:, 0]`` constant.
    evals : (k,) eigenvalues (ascending; 0 for the constant).
    mass : (n,) lumped area weights, or sparse (n, n) mass matrix.
    name : label for messages.
    cache : a :class:`prodmaps.cache.Cache` of derived values (product bases), shared with
        every truncation of this basis; keys name the column count they depend on.
    kind : the operator the basis diagonalises (``"cotan"``, ``"robust"``, ``"point_cloud"``,
        ``"fourier"``; ``""`` when unknown), recorded by :meth:`save`.

    The basis owns its arrays: ``vecs`` and ``evals`` are made read-only (its caches depend on
    them). :func:`prodmaps.basis.from_arrays` copies the caller's arrays first.

    Raises
    ------
    ValueError
        If the shapes of ``vecs``, ``evals`` and ``mass`` disagree, or a value is not finite.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b = pm.eigenbasis(ellipsoid(2), 6)
    >>> b.k, b.n, b.vecs.shape
    (6, 162, (162, 6))
    >>> bool(np.allclose(b.vecs.T @ (b.mass[:, None] * b.vecs), np.eye(6)))  # A-orthonormal
    True
    >>> b.truncate(4).vecs.shape  # the first 4 columns, constant included
    (162, 4)
    """

    vecs: np.ndarray
    evals: np.ndarray
    mass: np.ndarray | sp.spmatrix
    name: str = ""
    cache: Cache = field(default_factory=Cache, repr=False, compare=False)
    kind: str = ""

    def __post_init__(self):
        vecs = np.asarray(self.vecs, dtype=np.float64)
        evals = np.asarray(self.evals, dtype=np.float64)
        if vecs.ndim != 2:
            raise ValueError(f"vecs must be (n, k); got shape {vecs.shape}")
        if evals.shape != (vecs.shape[1],):
            raise ValueError(f"evals must have shape ({vecs.shape[1]},); got {evals.shape}")
        if not sp.issparse(self.mass):
            mass = np.asarray(self.mass, dtype=np.float64)
            if mass.shape != (vecs.shape[0],):
                raise ValueError(f"mass must be ({vecs.shape[0]},) or sparse (n, n); got {mass.shape}")
            if np.any(mass <= 0) or not np.all(np.isfinite(mass)):
                raise ValueError("mass must be finite and positive")
            object.__setattr__(self, "mass", mass)
        for name, arr in (("vecs", vecs), ("evals", evals)):
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"basis {name} contain non-finite values")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    # ------------------------------------------------------------------ basics
    @property
    def n(self) -> int:
        """Number of points."""
        return self.vecs.shape[0]

    @property
    def k(self) -> int:
        """Number of columns, the constant included (the paper's k_M + 1)."""
        return self.vecs.shape[1]

    @property
    def mass_is_diagonal(self) -> bool:
        """True for a lumped mass held as its diagonal ``(n,)``, False for a sparse matrix."""
        return not sp.issparse(self.mass)

    @property
    def lumped_mass(self) -> np.ndarray:
        """The lumped vertex areas ``(n,)``: the diagonal mass itself, or the row sums of a sparse one."""
        return self.mass if self.mass_is_diagonal else np.asarray(self.mass.sum(axis=1)).ravel()

    @property
    def area(self) -> float:
        """Total area, the sum of the mass ``A``."""
        return float(self.mass.sum())

    @property
    def phi0(self) -> float:
        """Value of the constant basis function, ``1/sqrt(area)``."""
        return float(self.vecs[0, 0])

    def apply_mass(self, f: np.ndarray) -> np.ndarray:
        """``A @ f`` for ``f`` ``(n,)`` or ``(n, m)``."""
        if self.mass_is_diagonal:
            return self.mass[:, None] * f if f.ndim == 2 else self.mass * f
        return self.mass @ f

    def project(self, f: np.ndarray) -> np.ndarray:
        """Coefficients ``Φᵀ A f`` ``(k,)`` or ``(k, m)`` (the A-orthogonal projection)."""
        return self.vecs.T @ self.apply_mass(f)

    def reconstruct(self, coefs: np.ndarray) -> np.ndarray:
        """``Φ @ coefs``."""
        return self.vecs @ coefs

    def scaled(self, s: float) -> "Basis":
        """The same basis on the mesh scaled by ``s``: eigenfunctions ``/ s``, eigenvalues ``/ s²``, mass ``· s²``.

        Still A-orthonormal. ``b.scaled(1 / sqrt(b.area))`` is the unit-area basis that NO17 fits on. Shares
        nothing with this basis' cache (the products of a rescaled basis differ).
        """
        s = float(s)
        if not (np.isfinite(s) and s > 0):
            raise ValueError(f"scale must be a positive number, got {s}")
        return Basis(self.vecs / s, self.evals / s**2, self.mass * s**2, name=self.name, kind=self.kind)

    def truncate(self, k: int) -> "Basis":
        """The first ``k`` columns (constant included), sharing this basis' cache.

        ``self`` when ``k == self.k``. Values cached for a column count (e.g. the product basis
        of the first ``k`` columns) are found again by every truncation to ``k``.
        """
        if not 1 <= k <= self.k:
            raise ValueError(f"k must be in [1, {self.k}], got {k}")
        return self if k == self.k else Basis(self.vecs[:, :k], self.evals[:k], self.mass, name=self.name,
                                              cache=self.cache, kind=self.kind)

    def save(self, path) -> Path:
        """Write the basis to ``path`` (an ``.npz``, exactly that name) with its metadata; returns the path.

        Arrays ``vecs``, ``evals`` and the mass (its diagonal, or the CSR arrays of a sparse mass)
        are stored bit for bit, with ``n``, ``k``, ``kind``, ``name``, the library version and a
        SHA-256 checksum of the arrays (module doc). Read it back with :func:`prodmaps.load_basis`.

        Examples
        --------
        >>> import tempfile, pathlib
        >>> import numpy as np
        >>> import prodmaps as pm
        >>> b = pm.eigenbasis(pm.mesh.ellipsoid(2), 6)
        >>> path = b.save(pathlib.Path(tempfile.mkdtemp()) / "ellipsoid_basis.npz")
        >>> back = pm.load_basis(path)
        >>> bool(np.array_equal(back.vecs, b.vecs)), back.kind, back.name
        (True, 'cotan', 'ellipsoid')
        """
        if self.mass_is_diagonal:
            arrays = {"vecs": self.vecs, "evals": self.evals, "mass": self.mass}
        else:
            M = sp.csr_matrix(self.mass)
            arrays = {"vecs": self.vecs, "evals": self.evals, "mass_data": M.data, "mass_indices": M.indices,
                      "mass_indptr": M.indptr}
        return write_checked_npz(path, BASIS_FORMAT, arrays, {"n": self.n, "k": self.k, "kind": self.kind,
                                                              "name": self.name})

    def __repr__(self) -> str:
        label = f"{self.name!r}, " if self.name else ""
        return f"Basis({label}n={self.n}, k={self.k})"


def load_basis(path) -> Basis:
    """The :class:`Basis` saved by :meth:`Basis.save` at ``path``, checked, bit for bit.

    Parameters
    ----------
    path : str or pathlib.Path
        The ``.npz`` file.

    Returns
    -------
    Basis
        ``vecs``, ``evals``, ``mass``, ``name`` and ``kind`` as saved.

    Raises
    ------
    FileNotFoundError
        For a missing file.
    ValueError
        Naming the path: not a prodmaps archive, a saved map instead of a basis (the error names
        :func:`prodmaps.load_map`), a checksum that does not match the arrays (a changed or damaged
        file), or arrays whose shapes contradict the recorded ``n`` and ``k``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> b = pm.eigenbasis(pm.mesh.ellipsoid(1), 5)
    >>> back = pm.load_basis(b.save(pathlib.Path(tempfile.mkdtemp()) / "b.npz"))
    >>> back.n, back.k, bool(np.array_equal(back.evals, b.evals) and np.array_equal(back.mass, b.mass))
    (42, 5, True)
    """
    arrays, meta = read_checked_npz(path, BASIS_FORMAT, FILE_READERS)
    try:
        n, k = int(meta["n"]), int(meta["k"])
        vecs, evals = arrays["vecs"], arrays["evals"]
        if "mass" in arrays:
            mass = arrays["mass"]
            mass_shape = mass.shape
        else:
            mass = sp.csr_matrix((arrays["mass_data"], arrays["mass_indices"], arrays["mass_indptr"]), shape=(n, n))
            mass_shape = (n,) if arrays["mass_indptr"].shape == (n + 1,) else arrays["mass_indptr"].shape
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{path}: a damaged basis file (missing or malformed {exc})") from None
    if vecs.shape != (n, k) or evals.shape != (k,) or mass_shape != (n,):
        raise ValueError(f"{path}: the arrays contradict the metadata (n={n}, k={k}): vecs {vecs.shape}, "
                         f"evals {evals.shape}, mass {mass_shape}")
    return Basis(vecs, evals, mass, name=str(meta.get("name", "")), kind=str(meta.get("kind", "")))


SIGN_TIE_RTOL = 1e-6
"""Entries within this relative distance of a column's largest magnitude count as tied for it."""


def fix_signs(vecs: np.ndarray, rtol: float = SIGN_TIE_RTOL) -> np.ndarray:
    """Flip columns so the entry of largest magnitude of each column is positive.

    Ties are settled by index, not by rounding: among the entries whose magnitude is within
    ``rtol`` (relative) of the column's largest, the one of **smallest row index** decides.
    Why: on a shape with a reflection symmetry an odd eigenfunction takes ``+m`` and ``-m`` at
    mirrored vertices, and which of the two is larger in floating point (a difference of
    ~1e-15) depends on the BLAS kernel, so a plain ``argmax`` flips the sign from machine to
    machine. Columns without such a tie get the same sign as with a plain ``argmax`` (entries
    near a single extremum share its sign).

    Parameters
    ----------
    vecs : (n, k) ndarray
    rtol : float
        Relative width of the tie band; 1e-6 is far above the solvers' rounding and far below
        the gaps of generic eigenfunctions' extrema.

    Returns
    -------
    (n, k) ndarray
        ``vecs`` with some columns negated.
    """
    a = np.abs(vecs)  # (n, k)
    top = a.max(axis=0)  # (k,)
    tied = a >= (1.0 - rtol) * top  # (n, k), at least one True per column
    idx = np.argmax(tied, axis=0)  # (k,) first (smallest-index) tied row
    s = np.sign(vecs[idx, np.arange(vecs.shape[1])])
    s[s == 0] = 1.0
    return vecs * s


def eigenbasis(mesh, k: int, kind: str | None = None, mass: str = "lumped", *, solver: str = "auto",
               progress: bool | None = None) -> Basis:
    """First ``k`` Laplace–Beltrami eigenpairs of a mesh or a point cloud (constant included).

    Solves ``W φ = λ A φ`` (see :func:`prodmaps.laplacian`) with the package's one eigensolver
    (:func:`prodmaps.eigensolver.smallest_eigenpairs`: shift-invert Lanczos around a small
    negative shift, or dense LAPACK for small meshes). A mesh gets the cotangent Laplacian, or
    with ``kind="robust"`` the intrinsic-Delaunay one, which is also defined on meshes that
    validation refuses (duplicate faces, non-manifold edges: build them with
    ``pm.Mesh(v, f, validate=False)`` or ``pm.load_mesh(path, validate=False)``). A point cloud
    gets the point-cloud Laplacian of ``robust-laplacian`` with its lumped mass. The conventions
    are the same for both (:mod:`prodmaps.conventions`).

    Parameters
    ----------
    mesh : Mesh or PointCloud
        A connected mesh, or a point cloud sampling one connected surface.
    k : int
        Number of columns including the constant; the paper's ``k_M = 9`` is ``k = 10``.
    kind : ``None`` (default: ``"cotan"`` for a mesh, the point-cloud Laplacian for a cloud),
        ``"cotan"`` or ``"robust"``; passed to :func:`prodmaps.laplacian` with ``mass``.
    mass : ``"lumped"`` (default) or ``"full"`` (cotangent only).
    solver : ``"auto"`` (default), ``"superlu"`` or ``"cholesky"``: the sparse factorisation of
        the eigensolver (:func:`prodmaps.eigensolver.smallest_eigenpairs`). ``"auto"`` uses the
        optional sparse Cholesky (``cholespy``) from ``CHOLESKY_MIN_N`` = 100,000 vertices and
        SuperLU below; the two agree to the Lanczos tolerance (eigenvalues 1e-10 relative,
        subspaces 1e-8).
    progress : ``True`` shows a progress bar (operator, eigenpairs), ``False`` never, ``None``
        (default) on large problems (``n·k > PROGRESS_MIN_WORK``) when stderr is a terminal.

    Returns
    -------
    Basis
        ``vecs`` ``(n, k)`` A-orthonormal, column 0 the constant ``1/sqrt(area)``; ``evals``
        ``(k,)`` ascending, the first 0; ``kind`` the operator used (``"cotan"``, ``"robust"`` or
        ``"point_cloud"``).

    Raises
    ------
    TypeError
        If ``mesh`` is not a :class:`prodmaps.Mesh` or :class:`prodmaps.PointCloud`, or ``k`` not
        an integer.
    ValueError
        If ``k`` is not in ``[1, n)``.
    MeshError
        If the mesh has more than one connected component, or a point cloud falls apart into
        several (the constant would not be the only zero mode), or vertices have no area
        (unreferenced by any face).
    NeedsFacesError
        For ``kind="cotan"`` on a point cloud.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> mesh = ellipsoid(2)
    >>> b = pm.eigenbasis(mesh, 6)
    >>> b.vecs.shape, b.evals.shape
    ((162, 6), (6,))
    >>> bool(np.allclose(b.vecs[:, 0], 1 / np.sqrt(mesh.area))), bool(b.evals[0] == 0)
    (True, True)
    >>> c = pm.eigenbasis(pm.PointCloud(mesh.vertices), 6)  # the same points, no faces
    >>> c.kind, bool(np.allclose(c.evals[1:] / b.evals[1:], 1, atol=0.1))
    ('point_cloud', True)
    """
    cloud = isinstance(mesh, PointCloud)
    if not (cloud or isinstance(mesh, Mesh)):
        raise TypeError(f"eigenbasis expects a prodmaps.Mesh or prodmaps.PointCloud, got {type(mesh).__name__}")
    n = mesh.n_vertices
    if not isinstance(k, (int, np.integer)) or isinstance(k, bool):
        raise TypeError(f"k must be an integer, got {type(k).__name__}")
    if not 1 <= k < n:
        raise ValueError(f"k={k} is out of range for a {'point cloud' if cloud else 'mesh'} with {n} "
                         f"{'points' if cloud else 'vertices'}: need 1 <= k < {n} (k counts the constant; the "
                         "paper's k_M = 9 is k = 10)")
    if not cloud:
        lone = np.setdiff1d(np.arange(n), mesh.faces)
        if lone.size:  # a mesh built with validate=False
            raise MeshError(f"eigenbasis: {lone.size} vertices have no area (first {lone[:5].tolist()}): they belong "
                            "to no face; drop them with pm.mesh.remove_unreferenced_vertices(vertices, faces)")
        ncomp, labels = face_components(n, mesh.faces)
        if ncomp > 1:  # a mesh loaded with validate=False: the constant is not the only zero mode
            sizes = sorted(np.bincount(labels).tolist(), reverse=True)[:5]
            raise MeshError(f"eigenbasis needs a connected mesh: {mesh.name or 'this mesh'} has {ncomp} connected "
                            f"components (vertex counts {sizes}); each has its own constant eigenfunction, so the "
                            "conventions (one constant column, A-orthonormal) cannot hold. Keep the largest with "
                            "pm.mesh.largest_component(mesh.vertices, mesh.faces), or load with "
                            "pm.io.load_mesh_repaired(path)")
    label = kind if kind is not None else ("robust" if cloud else "cotan")
    bar = progress_bar(2, f"eigenbasis {mesh.name or ''}".strip(), progress=progress, work=float(n) * k,
                       min_work=PROGRESS_MIN_WORK)
    W, A = laplacian(mesh, kind=kind, mass=mass)
    bar.update(1)
    if not sp.issparse(A) and np.any(A <= 0):
        bad = np.flatnonzero(A <= 0)
        raise MeshError(f"eigenbasis: {bad.size} {'points' if cloud else 'vertices'} have no area (first "
                        f"{bad[:5].tolist()})" + ("" if cloud else "; they belong to no face: drop them with "
                                                   "pm.mesh.remove_unreferenced_vertices(vertices, faces)"))
    evals, vecs = smallest_eigenpairs(W, A, k, solver=solver)  # ascending, A-normalised
    bar.update(1)
    bar.close()
    if cloud and k > 1 and evals[1] <= 1e-8 * max(float(evals[-1]), np.finfo(float).tiny):
        raise MeshError(f"eigenbasis: the point cloud {mesh.name or ''} falls apart into several pieces (a second "
                        f"zero eigenvalue, λ1 = {evals[1]:.2e}): its point-cloud Laplacian joins each point to its "
                        "nearest neighbours only; keep one piece, or sample the surface more densely")
    # fix the constant exactly (round-off only) and the signs
    area = float(A.sum())
    evals = np.maximum(evals, 0.0)
    evals[0] = 0.0
    vecs[:, 0] = 1.0 / np.sqrt(area)
    vecs[:, 1:] = fix_signs(vecs[:, 1:])
    return Basis(vecs, evals, A, name=mesh.name, kind="point_cloud" if cloud else label)


def _eigenbasis_arrays(vertices, faces, name, k, kind, mass, solver="auto"):
    """Worker of :func:`eigenbases`: plain arrays in and out (cheap to send between processes)."""
    shape = PointCloud(vertices, name=name) if faces is None else Mesh(vertices, faces, name=name, validate=False)
    b = eigenbasis(shape, k, kind=kind, mass=mass, solver=solver, progress=False)  # validated by the caller
    return b.vecs, b.evals, b.mass, b.kind


def eigenbases(meshes, k: int, kind: str | None = None, mass: str = "lumped", *, jobs: int | None = None,
               solver: str = "auto", progress: bool | None = None) -> list:
    """:func:`eigenbasis` of several meshes or point clouds, in ``jobs`` worker processes.

    The sparse LU factorisation and the triangular solves of shift-invert Lanczos run on one core,
    so the eigenbases of a pair of large meshes take about the time of one on a 2-core machine
    (``docs/benchmarks.md``). Each basis is what :func:`eigenbasis` returns for that shape (same
    solver, same arrays; the test compares them bit for bit).

    Parameters
    ----------
    meshes : iterable of Mesh or PointCloud
    k, kind, mass, solver : as in :func:`eigenbasis` (the same for every shape).
    jobs : worker processes; default one per shape, at most the number of CPUs; ``1`` runs in
        this process.
    progress : a bar of one step per shape (``True``), none (``False``), or on large problems
        (``Σ n·k > PROGRESS_MIN_WORK``) when stderr is a terminal (``None``, default).

    Returns
    -------
    list of Basis
        In the order of ``meshes``.

    Raises
    ------
    TypeError
        If a shape is neither a mesh nor a point cloud.
    ValueError
        For a bad ``jobs`` or ``k`` (and what :func:`eigenbasis` raises for a shape).

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> from prodmaps.mesh import ellipsoid
    >>> b1, b2 = pm.basis.eigenbases([ellipsoid(2), ellipsoid(2, axes=(1.0, 0.7, 0.5))], 6, jobs=1)
    >>> b1.vecs.shape, b2.evals.shape
    ((162, 6), (6,))
    """
    import os

    meshes = list(meshes)
    for m in meshes:
        if not isinstance(m, (Mesh, PointCloud)):
            raise TypeError(f"eigenbases expects prodmaps.Mesh or prodmaps.PointCloud objects, got {type(m).__name__}")
    if jobs is None:
        jobs = min(len(meshes), os.cpu_count() or 1)
    if not isinstance(jobs, (int, np.integer)) or jobs < 1:
        raise ValueError(f"jobs must be a positive integer, got {jobs!r}")
    work = float(sum(m.n_vertices for m in meshes)) * k
    bar = progress_bar(len(meshes), "eigenbases", progress=progress, work=work, min_work=PROGRESS_MIN_WORK,
                       unit="shape")
    if jobs == 1 or len(meshes) <= 1:
        out = []
        for m in meshes:
            out.append(eigenbasis(m, k, kind=kind, mass=mass, solver=solver, progress=False))
            bar.update(1)
        bar.close()
        return out
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed

    with ProcessPoolExecutor(max_workers=int(jobs), mp_context=mp.get_context("spawn")) as ex:
        futs = [ex.submit(_eigenbasis_arrays, m.vertices, None if isinstance(m, PointCloud) else m.faces, m.name, k,
                          kind, mass, solver) for m in meshes]
        for _ in as_completed(futs):
            bar.update(1)
        out = [f.result() for f in futs]
    bar.close()
    return [Basis(v, e, a, name=m.name, kind=kd) for m, (v, e, a, kd) in zip(meshes, out)]


def fourier_basis(n: int, k: int, period: float = 2 * np.pi) -> Basis:
    """The 1D periodic Fourier basis sampled at ``n`` equispaced points of ``[0, period)``.

    Columns: constant, then ``cos(ωx), sin(ωx), cos(2ωx), sin(2ωx), …`` with
    ``ω = 2π/period``, orthonormal for the quadrature weights ``period/n`` (exact for
    trigonometric polynomials of degree < n/2). Eigenvalues are those of ``-d²/dx²``.
    ``k`` counts all columns, the constant included.

    Parameters
    ----------
    n : int
        Number of samples.
    k : int
        Number of columns, in ``[1, n // 2]``.
    period : float
        Length of the interval (default ``2π``).

    Returns
    -------
    Basis
        ``vecs`` ``(n, k)``, ``evals`` ``(k,)``, ``mass`` ``(n,)`` all equal to ``period / n``.

    Raises
    ------
    ValueError
        If ``k`` is not in ``[1, n // 2]``.

    Examples
    --------
    >>> import prodmaps as pm
    >>> b = pm.fourier_basis(64, 5)
    >>> b.vecs.shape, b.evals.tolist()
    ((64, 5), [0.0, 1.0, 1.0, 4.0, 4.0])
    """
    if not 1 <= k <= n // 2:
        raise ValueError(f"k must be in [1, n//2] = [1, {n // 2}] for n={n} samples, got {k}")
    x = np.arange(n) * (period / n)
    c = np.arange(1, k)  # the non-constant columns: cos, sin of frequency j = 1, 1, 2, 2, ...
    freq = (c + 1) // 2 * (2 * np.pi / period)  # (k - 1,) j ω
    phase = np.outer(x, freq)  # (n, k - 1)
    trig = np.where(c % 2 == 1, np.cos(phase), np.sin(phase)) * np.sqrt(2.0 / period)
    vecs = np.column_stack([np.full(n, 1.0 / np.sqrt(period)), trig])
    return Basis(vecs, np.concatenate([[0.0], freq ** 2]), np.full(n, period / n), name="fourier", kind="fourier")


def diagonal_if_lumped(M) -> np.ndarray | sp.csr_matrix:
    """A sparse mass matrix as its diagonal ``(n,)`` when it has nothing off the diagonal, else as CSR."""
    M = sp.csr_matrix(M)
    return M.diagonal() if (M - sp.diags(M.diagonal())).count_nonzero() == 0 else M


def from_arrays(vecs, evals, mass, *, name: str = "", atol: float = 1e-6) -> Basis:
    """A :class:`Basis` from eigenpairs computed elsewhere (pyFM, geomfum, your own code), checked.

    Parameters
    ----------
    vecs : ``(n, k)`` eigenvectors as columns, the constant first (pyFM:
        ``TriMesh.eigenvectors``; geomfum: ``mesh.basis.full_vecs``).
    evals : ``(k,)`` eigenvalues, ascending (``TriMesh.eigenvalues``).
    mass : the area weights ``(n,)`` (``TriMesh.vertex_areas``) or a sparse ``(n, n)`` mass
        matrix (``TriMesh.A``; a diagonal sparse matrix is turned into its diagonal).
    atol : tolerance of the checks.

    Nothing is recomputed and no sign is changed (a functional map computed with these vectors
    stays valid). Checks, each raising ``ValueError`` that says what to fix: shapes; the first
    column constant (``|φ0 - mean| <= atol·|mean|``); A-orthonormality ``|ΦᵀAΦ - I| <= atol``
    (the inner product every projection here uses); eigenvalues ascending with ``λ0 ≈ 0``.
    """
    # copies: the Basis makes its arrays read-only, the caller's (e.g. pyFM's TriMesh.eigenvectors) stay writeable
    V = np.array(vecs, dtype=np.float64, copy=True)
    ev = np.array(evals, dtype=np.float64, copy=True).ravel()
    if V.ndim != 2:
        raise ValueError(f"vecs must be (n, k) with the eigenvectors as columns; got shape {V.shape}")
    if ev.shape != (V.shape[1],):
        hint = " (vecs transposed? eigenvectors must be the columns)" if ev.size == V.shape[0] else ""
        raise ValueError(f"evals has {ev.size} values but vecs has {V.shape[1]} columns{hint}")
    if sp.issparse(mass):
        M = sp.csr_matrix(mass)
        if M.shape != (V.shape[0],) * 2:
            raise ValueError(f"mass must be ({V.shape[0]}, {V.shape[0]}); got {M.shape}")
        mass = diagonal_if_lumped(M)
    mass_v = mass if sp.issparse(mass) else np.array(mass, dtype=np.float64, copy=True).ravel()  # a copy: as V
    if not sp.issparse(mass_v) and mass_v.shape != (V.shape[0],):
        raise ValueError(f"mass must have one area weight per vertex ({V.shape[0]},); got {mass_v.shape}")
    c = V[:, 0]
    if np.max(np.abs(c - c.mean())) > atol * abs(c.mean()) or c.mean() == 0:
        raise ValueError("the first column of vecs is not constant: prodmaps bases have the constant "
                         "eigenfunction first (sort the eigenpairs by eigenvalue)")
    AV = mass_v @ V if sp.issparse(mass_v) else mass_v[:, None] * V
    G = V.T @ AV  # (k, k)
    dev = float(np.max(np.abs(G - np.eye(V.shape[1]))))
    if dev > atol:
        raise ValueError(f"the eigenvectors are not orthonormal in the area inner product (max |ΦᵀAΦ - I| = "
                         f"{dev:.2e}); pass the mass the eigenproblem was solved with (pyFM: vertex_areas), "
                         "or A-normalise the columns")
    if np.any(np.diff(ev) < -atol * max(abs(ev).max(), 1.0)) or abs(ev[0]) > atol * max(abs(ev).max(), 1.0):
        raise ValueError("evals must be ascending with the constant's eigenvalue 0 first")
    return Basis(V, ev, mass_v, name=name)
