"""Per-shape data shared by the notebooks: meshes, eigenbases, descriptors, computed maps.

:class:`ShapeStore` computes each value once per process (in memory) and once per machine (on
disk, exact float64 ``.npz`` under ``<cache_dir()>/experiments/``), so the notebooks of one
``make reproduce`` share eigenbases, SHOT/AWFT descriptors and NO17 maps instead of recomputing
them. The numbers are the same with and without the disk cache (the arrays are stored exactly).

Disk keys name everything a value depends on: the mesh bytes (:func:`prodmaps.geodesics.mesh_key`),
the parameters, and a fingerprint of the source code of the library modules that compute it
(:func:`code_fingerprint`), so editing e.g. the eigensolver never returns a stale basis.
``PRODMAPS_CACHE`` moves the cache (default ``~/.cache/prodmaps``); ``disk_cache=False`` turns
it off.
"""

from __future__ import annotations

import functools
import importlib
import json
from pathlib import Path

import numpy as np

from ... import datasets, descriptors
from ...basis import Basis, eigenbasis
from ...cache import Cache
from ...files import atomic_path, sha256_bytes
from ...geodesics import DistanceRows, cache_dir, mesh_key
from ...mesh import Mesh
from . import families as pfam

__all__ = ["DiskCache", "ShapeStore", "code_fingerprint"]

# library modules whose source decides each stored value (the disk key includes their bytes)
EIGEN_CODE = ("prodmaps.mesh", "prodmaps.operators", "prodmaps.eigensolver", "prodmaps.basis")
DESCRIPTOR_CODE = {
    "shot": ("prodmaps.mesh", "prodmaps.descriptors.histograms"),
    "awft": EIGEN_CODE + ("prodmaps.curvature", "prodmaps.descriptors.windowed_fourier",
                          "prodmaps.descriptors.spectral"),
}
FAMILY_CODE = tuple(dict.fromkeys(EIGEN_CODE + DESCRIPTOR_CODE["shot"] + DESCRIPTOR_CODE["awft"] + (
    "prodmaps.experiments.shared.families", "prodmaps.products", "prodmaps.geodesics")))


@functools.lru_cache(maxsize=None)
def code_fingerprint(*modules: str) -> str:
    """SHA-256 (16 hex digits) of the source bytes of the named modules."""
    return sha256_bytes(b"".join(name.encode() + b"\0" + Path(importlib.import_module(name).__file__).read_bytes()
                                 + b"\0" for name in modules))[:16]


class DiskCache:
    """Arrays stored as ``.npz`` files named by a hash of their key (a JSON-able dict).

    ``get(kind, key, compute)`` returns ``{name: array}`` from disk, or calls ``compute()`` (which
    returns such a dict), stores it atomically and returns it. ``enabled=False`` never touches
    the disk.
    """

    def __init__(self, folder=None, enabled: bool = True):
        self.folder = Path(folder) if folder is not None else cache_dir() / "experiments"
        self.enabled = bool(enabled)

    def path(self, kind: str, key: dict) -> Path:
        """The ``.npz`` file of ``kind`` and ``key`` (named by a hash of the key's JSON)."""
        digest = sha256_bytes(json.dumps(key, sort_keys=True, default=str).encode())[:32]
        return self.folder / f"{kind}_{digest}.npz"

    def get(self, kind: str, key: dict, compute) -> dict:
        """The arrays ``{name: array}`` of ``(kind, key)``: read from disk, or computed and stored."""
        if not self.enabled:
            return compute()
        path = self.path(kind, key)
        if path.is_file():
            with np.load(path, allow_pickle=False) as z:
                return {k: z[k] for k in z.files}
        out = compute()
        with atomic_path(path) as tmp:
            np.savez(tmp, **out)
        return out


class ShapeStore:
    """Meshes, eigenbases and descriptors of one dataset's shapes, computed once and shared.

    Parameters
    ----------
    dataset : a :mod:`prodmaps.datasets` name (``"anny_humans"``, ``"faust"``, ...).
    n_eig : eigenpairs computed per shape, constant included (``k`` of :func:`prodmaps.eigenbasis`);
        :meth:`basis` truncates, and truncations share one cache, so product bases and their
        operators are reused across calls.
    kind : Laplacian (``"cotan"`` | ``"robust"``).
    disk_cache : share the arrays across processes through :class:`DiskCache`.
    """

    def __init__(self, dataset: str, n_eig: int, *, kind: str = "cotan", disk_cache: bool = True,
                 cache_folder=None):
        self.dataset = dataset
        self.n_eig = int(n_eig)
        self.kind = kind
        self.disk = DiskCache(cache_folder, enabled=disk_cache)
        self._mesh: dict[str, Mesh] = {}
        self._basis: dict[str, Basis] = {}
        self._family_cache: dict[str, Cache] = {}
        self._rows = Cache(max_entries=2)  # sid -> DistanceRows of the two most recently used shapes
        self._awft_spectra = Cache(max_entries=2)  # sid -> Cache of AWFT's eigenpairs (about 20 MB a 5k shape)
        self.memo = Cache(max_entries=512)  # per-process values of the experiments (maps, descriptors)

    # ---------------------------------------------------------------- per shape
    def mesh(self, sid: str) -> Mesh:
        """The validated mesh of shape ``sid``."""
        if sid not in self._mesh:
            self._mesh[sid] = datasets.load_shape(self.dataset, sid)
        return self._mesh[sid]

    def distance_rows(self, sid: str) -> DistanceRows:
        """Heat-method distance rows of shape ``sid``, kept across calls (each source solved once).

        :class:`prodmaps.geodesics.DistanceRows`, the same numbers. Rows of the two most recently used
        shapes are kept (memory ``8 n`` bytes a row).
        """
        return self._rows.get(sid, lambda: DistanceRows(self.mesh(sid)))

    def mesh_key(self, sid: str) -> str:
        """The content hash of shape ``sid``'s mesh (:func:`prodmaps.cache.mesh_key`), memoised."""
        return self.memo.get(("mesh_key", sid), lambda: mesh_key(self.mesh(sid)))

    def basis(self, sid: str, k: int | None = None) -> Basis:
        """Eigenbasis of ``sid`` with ``k`` columns (default ``n_eig``), constant included."""
        if sid not in self._basis:
            mesh = self.mesh(sid)
            key = {"mesh": self.mesh_key(sid), "n_eig": self.n_eig, "kind": self.kind,
                   "code": code_fingerprint(*EIGEN_CODE)}

            def compute():
                b = eigenbasis(mesh, self.n_eig, kind=self.kind)
                return {"vecs": b.vecs, "evals": b.evals, "mass": b.mass}

            z = self.disk.get("eig", key, compute)
            self._basis[sid] = Basis(z["vecs"], z["evals"], z["mass"], name=sid)
        full = self._basis[sid]
        if k is None:
            return full
        if k > full.k:
            raise ValueError(f"basis of {sid!r} has {full.k} columns (ShapeStore n_eig={self.n_eig}); asked for {k}")
        return full.truncate(int(k))

    def descriptor(self, sid: str, name: str, **options) -> np.ndarray:
        """The SHOT (``"shot"``) or AWFT (``"awft"``) matrix of ``sid`` (:mod:`prodmaps.descriptors`, ``options``)."""
        if name not in DESCRIPTOR_CODE:
            raise ValueError(f"descriptor must be 'shot' or 'awft', got {name!r}")
        fn = descriptors.shot if name == "shot" else descriptors.awft
        key = {"mesh": self.mesh_key(sid), "code": code_fingerprint(*DESCRIPTOR_CODE[name])}
        if options:  # the defaults keep the key they always had
            key["options"] = repr(pfam.descriptor_key(name, **options))

        def compute():
            # AWFT: the operators' eigenpairs of this shape, kept for its other readings (two shapes at most)
            kw = {"cache": self._awft_spectra.get(sid, lambda: Cache(max_entries=8))} if name == "awft" else {}
            return {"D": fn(self.mesh(sid), **options, **kw)}

        return self.memo.get(("descriptor", sid, name, pfam.descriptor_key(name, **options)),
                             lambda: self.disk.get(name, key, compute)["D"])

    def family_cache(self, sid: str, families=(), options: dict | None = None) -> Cache:
        """The :class:`Cache` for :func:`prodmaps.experiments.shared.families.make_family` on source ``sid``.

        It holds the SHOT/AWFT matrices the requested ``families`` need (computed with ``options``, the
        family's options, when given).
        """
        cache = self._family_cache.setdefault(sid, Cache(max_entries=16))
        for fam, name in (("SHOT", "shot"), ("AWFT", "awft")):
            opts = dict(options or {}) if list(families) == [fam] else {}
            if fam in families and pfam.descriptor_key(name, **opts) not in cache:
                cache.put(pfam.descriptor_key(name, **opts), self.descriptor(sid, name, **opts))
        return cache

    def family_functions(self, sid_1: str, p2p_21, pair_index: int, families, *, k_M: int, seed: int,
                         reading_set: str = "published"):
        """All ``families`` on source ``sid_1`` (columns stacked) and their ground truth.

        ``families`` holds family entries: a family name (its reading in ``reading_set``,
        ``"textbook"`` or ``"published"``) or ``"name:reading"``
        (:data:`prodmaps.experiments.shared.families.READINGS`). Returns ``(F (n1, m), G (n2, m), cols)``
        with ``G = F[p2p_21]`` and ``cols[entry]`` the column slice of each entry. Seeds:
        :func:`prodmaps.experiments.shared.families.family_seed` of the family, so every reading of a
        family draws the same random numbers.
        """
        entries = pfam.sort_entries(families)
        Fs, cols, start = [], {}, 0
        for entry in entries:
            fam, _, options = pfam.resolve_reading(entry, reading_set)
            F1 = self.family(sid_1, fam, k_M=k_M, seed=pfam.family_seed(seed, pair_index, fam), options=options)
            Fs.append(F1)
            cols[entry] = slice(start, start + F1.shape[1])
            start += F1.shape[1]
        F = np.hstack(Fs)  # (n1, m)
        return F, pfam.pull_back(F, p2p_21), cols

    def family(self, sid_1: str, name: str, *, k_M: int, seed: int, options: dict | None = None) -> np.ndarray:
        """The functions ``(n1, m)`` of family ``name`` on ``sid_1``, stored on disk.

        :func:`prodmaps.experiments.shared.families.make_family` with ``options`` (default none); the tables,
        Figure 8 and the studies draw the same families on the same pairs.
        """
        options = dict(options or {})
        key = {"mesh": self.mesh_key(sid_1), "n_eig": self.n_eig, "kind": self.kind, "family": name,
               "k_M": int(k_M), "seed": int(seed), "code": code_fingerprint(*FAMILY_CODE)}
        if options:
            key["options"] = repr(sorted(options.items()))

        def compute():
            cache = self.family_cache(sid_1, [name], options)
            F1, _ = pfam.make_family(name, self.mesh(sid_1), self.basis(sid_1), k_M=k_M, seed=seed, cache=cache,
                                     **options)
            return {"F": F1}

        return self.disk.get("family", key, compute)["F"]

    def __repr__(self) -> str:
        return (f"ShapeStore({self.dataset!r}, n_eig={self.n_eig}, kind={self.kind!r}, "
                f"{len(self._basis)} bases, disk={'on' if self.disk.enabled else 'off'})")
