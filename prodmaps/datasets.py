"""Shape datasets: a small registry with shape ids, pairs and ground-truth point maps.

Datasets
--------
``anny_humans``  shipped with the project (CC0): 6 synthetic subjects x 10 poses, one
                 triangulation (5002 vertices), ids ``anny_XXX`` with ``XXX = 10*subject+pose``,
                 plus variants with different connectivity (see below).
``faust``        MPI-FAUST training registrations, ids ``tr_reg_000 .. tr_reg_099`` (6890 V,
                 one triangulation; subject = XXX // 10). Not redistributable: prepare it from
                 your own download with ``python -m prodmaps.prepare faust --archive MPI-FAUST.zip``.
``tosca``        TOSCA high-resolution, ids ``<class><i>`` (``cat0``, ``david3``, ...), one
                 triangulation per class. Prepare with
                 ``python -m prodmaps.prepare tosca --archive toscahires-asci.zip``.

Where datasets are found (:func:`dataset_dir`): ``$PRODMAPS_DATA/<name>`` if ``PRODMAPS_DATA``
is set and holds the dataset (its ``shapes/`` folder), else, for the embedded ``anny_humans``, the copy shipped inside
the installed package (``prodmaps/data/``, package data: editable or not, the install finds
it), else ``<data_root()>/<name>``. :func:`data_root` is where prepared datasets live:
``$PRODMAPS_DATA`` if set, else ``$XDG_DATA_HOME/prodmaps`` (``~/.local/share/prodmaps``); the
preparation scripts write there by default. Layout read here (written by the preparation
scripts; the shipped ``anny_humans`` has no manifest and is indexed from its file names)::

    <root>/<name>/shapes/<id>.ply                      family shapes
    <root>/<name>/manifest.json                        optional: ids, class, triangulation group
    <root>/<name>/remeshed/<base>_<recipe>.ply         variants (different connectivity)
    <root>/<name>/remeshed/<base>_<recipe>.gt_to_family.txt
    <root>/<name>/SHA256SUMS                           optional checksums (:func:`verify_checksums`)

Ground truth convention (as everywhere in the package): ``ground_truth(name, id_1, id_2)``
returns ``p2p_21`` of shape ``(n2,)``: for each vertex of shape ``id_2`` the index of its
corresponding vertex on shape ``id_1`` (pull-back direction; ``C_12 = Φ2ᵀ A2 Φ1[p2p_21]``).

* two family shapes in the same triangulation: the identity ``arange(n)``;
* family ``id_1`` -> variant ``id_2``: ``p2p_21`` is the variant's ``gt_to_family`` file
  (variant vertex ``k`` <-> family vertex ``gt[k]``, valid for every shape of the family);
* variant ``id_1`` -> family ``id_2``: for each family vertex, the closest variant vertex
  (Euclidean) measured on the variant's base shape (the shape it was made from);
* variant -> variant: composition of the two rules above.

Pairs (:func:`pairs`) are ordered ``(id_1, id_2)`` with ``id_1 != id_2`` between family shapes
with ground truth: ``kind="intra"`` same subject/class, ``"inter"`` different subject/class
(same triangulation), ``"all"`` both.
"""

from __future__ import annotations

import functools
import importlib.resources
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .files import sha256_file
from .io import load_mesh
from .mesh import Mesh

__all__ = ["DatasetNotPreparedError", "data_root", "dataset_dir", "names", "shape_ids", "variants", "base_shape",
           "shape_class", "load_shape", "pairs", "ground_truth", "verify_checksums", "clear_cache"]


class DatasetNotPreparedError(FileNotFoundError):
    """A registered dataset whose files are not (yet) under the data root."""


@dataclass(frozen=True)
class _Spec:
    name: str
    description: str
    how_to_get: str  # where the user obtains the data and which script prepares it
    class_rule: str  # "div10" (subject = last 3 digits // 10) or "prefix" (class = id without trailing digits)
    shared_triangulation: bool  # True: whole family in one triangulation; False: one per class


_REGISTRY = {s.name: s for s in (
    _Spec("anny_humans", "6 synthetic subjects x 10 poses (Anny/MakeHuman, CC0), 5002 vertices, one triangulation",
          "It ships inside the package as prodmaps/data/anny_humans/ (reinstall prodmaps, restore it with "
          "`git checkout -- prodmaps/data/anny_humans`, or point PRODMAPS_DATA at a folder that holds it).",
          "div10", True),
    _Spec("faust", "MPI-FAUST training registrations: 10 subjects x 10 poses, 6890 vertices, one triangulation",
          "Register at https://faust.is.tue.mpg.de, accept the licence (research only, no redistribution), "
          "download MPI-FAUST.zip, then run: python -m prodmaps.prepare faust --archive MPI-FAUST.zip "
          "[--data-root DIR] (any subset works, e.g. the eight public registrations: --archive FundCG-s1-2018 "
          "--archive Laplacian-Mesh, see python -m prodmaps.prepare faust --help)",
          "div10", True),
    _Spec("tosca", "TOSCA high-resolution: 9 classes (cat, centaur, david, dog, gorilla, horse, michael, victoria, "
          "wolf), one triangulation per class",
          "Download toscahires-asci.zip from the TOSCA page (http://tosca.cs.technion.ac.il/book/resources_data.html; "
          "if it is down, an archived copy is on web.archive.org), then run: "
          "python -m prodmaps.prepare tosca --archive toscahires-asci.zip [--data-root DIR]",
          "prefix", False),
)}


def names() -> list[str]:
    """Names of the registered datasets (prepared or not)."""
    return list(_REGISTRY)


EMBEDDED = ("anny_humans",)


def prepared() -> list[str]:
    """Names of the datasets that can be loaded here: the embedded ones and those prepared under the data root.

    A prepared dataset is a folder with shapes in ``shapes/*.ply``.

    Examples
    --------
    >>> "anny_humans" in prepared()
    True
    """
    return [n for n in names() if any((dataset_dir(n) / "shapes").glob("*.ply"))]


def embedded_root() -> Path:
    """The folder of the datasets shipped inside the installed package (``prodmaps/data``)."""
    return Path(str(importlib.resources.files("prodmaps") / "data"))


def data_root() -> Path:
    """Where prepared datasets live: ``$PRODMAPS_DATA`` if set, else ``$XDG_DATA_HOME/prodmaps``.

    That is ``~/.local/share/prodmaps`` by default. The preparation scripts write there by default.
    """
    env = os.environ.get("PRODMAPS_DATA")
    if env:
        return Path(env).expanduser().resolve()
    xdg = os.environ.get("XDG_DATA_HOME")
    return (Path(xdg).expanduser() if xdg else Path.home() / ".local" / "share") / "prodmaps"


def _spec(name: str) -> _Spec:
    if name not in _REGISTRY:
        raise ValueError(f"unknown dataset {name!r}; registered datasets: {names()}")
    return _REGISTRY[name]


def dataset_dir(name: str) -> Path:
    """Folder of dataset ``name`` (see the module doc for the search order; may not exist)."""
    _spec(name)
    if os.environ.get("PRODMAPS_DATA") and (data_root() / name / "shapes").is_dir():
        return data_root() / name  # holds the dataset (a folder without shapes/, e.g. remeshed/ only, does not)
    if name in EMBEDDED and (embedded_root() / name).is_dir():
        return embedded_root() / name
    return data_root() / name


# ----------------------------------------------------------------------------- index
@dataclass
class _Index:
    root: Path  # the dataset's folder
    ids: list[str]
    files: dict[str, Path]
    cls: dict[str, str]
    tri: dict[str, str]
    variant_files: dict[str, tuple[Path, Path, str]] = field(default_factory=dict)  # vid -> (ply, gt, base)


def _class_of(rule: str, shape_id: str) -> str:
    if rule == "div10":
        m = re.search(r"(\d+)$", shape_id)
        return str(int(m.group(1)) // 10) if m else shape_id
    return re.sub(r"\d+$", "", shape_id)


@functools.lru_cache(maxsize=32)
def _index_at(folder_str: str, name: str) -> _Index:
    spec = _spec(name)
    folder = Path(folder_str)  # the dataset folder: the key of the per-folder caches below
    shapes = folder / "shapes"
    files = sorted(shapes.glob("*.ply")) if shapes.is_dir() else []
    if not files:
        raise DatasetNotPreparedError(f"dataset {name!r} is not prepared: no shapes/*.ply under {folder}. "
                                      f"{spec.how_to_get} (prepared datasets are found under $PRODMAPS_DATA if "
                                      "set, else ~/.local/share/prodmaps)")
    manifest = folder / "manifest.json"
    if manifest.is_file():
        entries = json.loads(manifest.read_text())["shapes"]
        ids = [e["id"] for e in entries]
        fmap = {e["id"]: folder / e["file"] for e in entries}
        cls = {e["id"]: str(e["class"]) for e in entries}
        tri = {e["id"]: str(e["triangulation"]) for e in entries}
        missing = [i for i in ids if not fmap[i].is_file()]
        if missing:
            raise DatasetNotPreparedError(f"dataset {name!r} under {folder} is incomplete: {len(missing)} shape "
                                          f"files listed in manifest.json are missing (first {missing[:3]}). "
                                          f"Prepare it again. {spec.how_to_get}")
    else:
        ids = [p.stem for p in files]
        fmap = {p.stem: p for p in files}
        cls = {i: _class_of(spec.class_rule, i) for i in ids}
        tri = {i: ("0" if spec.shared_triangulation else cls[i]) for i in ids}
    index = _Index(folder, ids, fmap, cls, tri)
    rem = folder / "remeshed"
    if rem.is_dir():
        by_len = sorted(ids, key=len, reverse=True)
        for p in sorted(rem.glob("*.ply")):
            gt = p.with_name(p.stem + ".gt_to_family.txt")
            base = next((b for b in by_len if p.stem.startswith(b + "_")), None)
            if gt.is_file() and base is not None and p.stem not in fmap:
                index.variant_files[p.stem] = (p, gt, base)
    return index


def _index(name: str) -> _Index:
    return _index_at(str(dataset_dir(name)), name)  # (dataset_dir refuses an unknown name)


def clear_cache() -> None:
    """Forget cached indexes, meshes and ground-truth maps (e.g. after preparing a dataset)."""
    for cached in (_index_at, _load_at, _gt_file, _family_to_variant):
        cached.cache_clear()


def shape_ids(name: str, *, include_variants: bool = False) -> list[str]:
    """Ids of the family shapes (sorted), optionally followed by the variant ids."""
    idx = _index(name)
    return list(idx.ids) + (sorted(idx.variant_files) if include_variants else [])


def variants(name: str) -> list[str]:
    """Ids of the different-connectivity variants (``remeshed/<base>_<recipe>.ply``)."""
    return sorted(_index(name).variant_files)


def _checked_index(name: str, *shape_ids: str) -> _Index:
    """The index of dataset ``name``, after checking that it holds ``shape_ids``."""
    idx = _index(name)
    for shape_id in shape_ids:
        if shape_id not in idx.files and shape_id not in idx.variant_files:
            close = [i for i in list(idx.files) + list(idx.variant_files) if i.startswith(str(shape_id)[:4])][:5]
            raise ValueError(f"unknown shape id {shape_id!r} in dataset {name!r}; "
                             f"use shape_ids({name!r}, include_variants=True) (similar: {close})")
    return idx


def base_shape(name: str, shape_id: str) -> str:
    """The family shape a variant was made from (a family id maps to itself)."""
    idx = _checked_index(name, shape_id)
    return idx.variant_files[shape_id][2] if shape_id in idx.variant_files else shape_id


def shape_class(name: str, shape_id: str) -> str:
    """Subject (FAUST, anny: ``XXX // 10`` as a string) or class (TOSCA) of a shape or variant."""
    return _index(name).cls[base_shape(name, shape_id)]


@functools.lru_cache(maxsize=256)
def _load_at(folder_str: str, name: str, shape_id: str) -> Mesh:
    idx = _index_at(folder_str, name)
    path = idx.files[shape_id] if shape_id in idx.files else idx.variant_files[shape_id][0]
    return load_mesh(path, name=shape_id)


def load_shape(name: str, shape_id: str) -> Mesh:
    """Load (and cache) a family shape or a variant as a validated, read-only :class:`pm.Mesh`."""
    idx = _checked_index(name, shape_id)
    return _load_at(str(idx.root), name, shape_id)


# ----------------------------------------------------------------------------- pairs
_KINDS = ("intra", "inter", "all")


def pairs(name: str, kind: str = "all", n: int | None = None, seed: int = 0):
    """Iterate ordered pairs ``(id_1, id_2)`` of family shapes with ground truth.

    ``kind``: ``"intra"`` (same subject/class), ``"inter"`` (different subject/class, same
    triangulation), ``"all"``. Pairs are enumerated in sorted order; with ``n`` a seeded
    random selection of ``n`` distinct pairs (``numpy.random.default_rng(seed)``, without
    replacement) is returned, kept in that enumeration order. Arguments are checked
    immediately; the result is an iterator.
    """
    if kind not in _KINDS:
        raise ValueError(f"kind must be one of {_KINDS}; got {kind!r}")
    idx = _index(name)
    ids = np.array(idx.ids)
    cls = np.array([idx.cls[i] for i in idx.ids])
    tri = np.array([idx.tri[i] for i in idx.ids])
    ok = (tri[:, None] == tri[None, :]) & ~np.eye(ids.size, dtype=bool)  # (s, s)
    same = cls[:, None] == cls[None, :]
    ok &= {"intra": same, "inter": ~same, "all": True}[kind]
    i1, i2 = np.nonzero(ok)
    total = i1.size
    if n is not None:
        if int(n) != n or n < 0:
            raise ValueError(f"n must be a non-negative integer or None; got {n!r}")
        if n > total:
            raise ValueError(f"asked for n={n} {kind} pairs of {name!r} but only {total} exist")
        sel = np.sort(np.random.default_rng(seed).choice(total, size=int(n), replace=False))
        i1, i2 = i1[sel], i2[sel]
    return iter([(str(ids[a]), str(ids[b])) for a, b in zip(i1.tolist(), i2.tolist())])


# ----------------------------------------------------------------------------- ground truth
@functools.lru_cache(maxsize=64)
def _gt_file(root_str: str, name: str, vid: str) -> np.ndarray:
    idx = _index_at(root_str, name)
    path = idx.variant_files[vid][1]
    gt = np.loadtxt(path, dtype=np.int64, ndmin=1)
    n_var = _load_at(root_str, name, vid).n_vertices
    n_fam = _load_at(root_str, name, idx.variant_files[vid][2]).n_vertices
    if gt.shape != (n_var,) or gt.min() < 0 or gt.max() >= n_fam:
        raise ValueError(f"{path}: expected {n_var} indices in [0, {n_fam}); got {gt.size} in "
                         f"[{gt.min()}, {gt.max()}]")
    gt.setflags(write=False)
    return gt


@functools.lru_cache(maxsize=64)
def _family_to_variant(root_str: str, name: str, vid: str) -> np.ndarray:
    """For each family vertex, the closest variant vertex, measured on the variant's base shape."""
    from scipy.spatial import cKDTree

    idx = _index_at(root_str, name)
    base = _load_at(root_str, name, idx.variant_files[vid][2])
    var = _load_at(root_str, name, vid)
    _, nearest = cKDTree(var.vertices).query(base.vertices)
    out = np.asarray(nearest, dtype=np.int64)
    out.setflags(write=False)
    return out


def ground_truth(name: str, id_1: str, id_2: str) -> np.ndarray:
    """Ground-truth point map ``p2p_21`` ``(n2,)``: for each vertex of ``id_2`` its vertex on ``id_1``.

    The module docstring gives the rules with variants.

    Raises ``ValueError`` for shapes without a common triangulation (e.g. two TOSCA classes).
    """
    idx = _checked_index(name, id_1, id_2)
    root = str(idx.root)
    b1, b2 = base_shape(name, id_1), base_shape(name, id_2)
    if idx.tri[b1] != idx.tri[b2]:
        raise ValueError(f"no ground truth between {id_1!r} and {id_2!r} in {name!r}: different triangulations "
                         f"(classes {idx.cls[b1]!r} and {idx.cls[b2]!r})")
    # the family vertex of each vertex of 2, then its vertex on 1
    fam = (_gt_file(root, name, id_2) if id_2 in idx.variant_files
           else np.arange(_load_at(root, name, id_2).n_vertices, dtype=np.int64))
    if id_1 in idx.variant_files:
        return _family_to_variant(root, name, id_1)[fam].copy()
    return np.array(fam, dtype=np.int64)


# ----------------------------------------------------------------------------- checksums
def verify_checksums(name: str, *, strict: bool = True) -> dict[str, bool]:
    """Check the files listed in ``<root>/<name>/SHA256SUMS`` (``sha256sum`` format).

    Returns ``{relative path: matches}``. With ``strict`` (default) raises ``ValueError``
    naming the mismatching or missing files. Raises :class:`DatasetNotPreparedError` if the
    dataset has no ``SHA256SUMS``. Listed paths must stay inside the dataset folder.
    """
    folder = dataset_dir(name)
    sums = folder / "SHA256SUMS"
    if not sums.is_file():
        raise DatasetNotPreparedError(f"{sums} does not exist; {_spec(name).how_to_get}")
    base = folder.resolve()
    result: dict[str, bool] = {}
    for line in sums.read_text().splitlines():
        if not line.strip():
            continue
        digest, rel = line.split(maxsplit=1)
        rel = rel.lstrip("*").strip()
        path = (folder / rel).resolve()
        if base not in path.parents:
            raise ValueError(f"{sums}: entry {rel!r} points outside {folder}")
        result[rel] = path.is_file() and sha256_file(path) == digest.lower()
    bad = [k for k, ok in result.items() if not ok]
    if strict and bad:
        raise ValueError(f"{name}: {len(bad)} of {len(result)} files are missing or do not match "
                         f"SHA256SUMS (first {bad[:5]}); restore or re-prepare the dataset")
    return result
