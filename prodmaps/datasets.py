"""Shape datasets: a registry with shape ids, pairs and dense ground-truth point maps.

Datasets
--------
:func:`names`; an unprepared one raises :class:`DatasetNotPreparedError` saying how to get it.

* ``anny_humans``: shipped (CC0), 6 synthetic subjects x 10 poses, 5002 vertices, one triangulation,
  ids ``anny_XXX`` (subject ``XXX // 10``), plus variants of other connectivity;
* ``faust``: MPI-FAUST training registrations ``tr_reg_XXX`` (6890 vertices, one triangulation);
* ``tosca``: TOSCA high-resolution ``<class><i>``, one triangulation per class;
* ``faust_r``: the 100 FAUST shapes each remeshed to ~5k vertices (FAUST_r), subject ``XXX // 10``;
  ``tosca_r``: 76 TOSCA shapes of 8 classes, each remeshed (TOSCA_r); ``tosca_r_noniso``: 24 more
  (gorilla, man, woman); all three from ``llorz/SGA18_orientation_BCICP_dataset``.

Where: ``$PRODMAPS_DATA/<name>`` if set and holding ``shapes/``, else the package's own copy
(``anny_humans``), else ``<data_root()>/<name>`` (default ``~/.local/share/prodmaps``). Layout, written
by ``python -m prodmaps.prepare``: ``shapes/<id>.ply``, ``manifest.json`` (class, triangulation,
correspondence group, sample file of each shape), ``samples/<id>.txt``, ``remeshed/<base>_<recipe>.ply``
with ``.gt_to_family.txt`` (variants), ``SHA256SUMS``.

Ground truth ``ground_truth(name, id_1, id_2)`` is ``p2p_21 (n2,)``: for each vertex of ``id_2`` its vertex
on ``id_1`` (``C_12 = Φ2ᵀ A2 Φ1[p2p_21]``). It exists inside one *correspondence group*, by the
dataset's kind (:func:`ground_truth_kind`):

* ``"identity"`` (anny_humans, faust: one group; tosca: a group per class): a group is one
  triangulation and the map is ``arange(n)``;
* ``"samples"`` (faust_r, tosca_r: a group per class, tosca_r_noniso): line ``s`` of every shape's sample
  file is the same point; ``p2p_21 = samples_1[sample_assignment(mesh_2, samples_2)]`` (exact at the
  samples, nearest sample along the mesh elsewhere: :func:`p2p_from_samples` states the rule);
* variants: family -> variant is the ``gt_to_family`` file, variant -> family the closest variant
  vertex on the base shape, composed with the family map above;
* across datasets (:func:`ground_truth_between`): a group's template (faust_r: the FAUST template
  vertex of each sample) gives every shape of the template's dataset (``faust``) the same samples.

Pairs (:func:`pairs`) are ordered ``(id_1, id_2)``, ``id_1 != id_2``, in one correspondence group:
``"intra"`` same subject/class, ``"inter"`` different ones, ``"all"`` both. A family shape to itself
is the identity. Derivations and measurements: ``docs/guide/datasets.md``.
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
from .geodesics import edge_graph
from .io import load_mesh
from .mesh import Mesh, check_mesh, check_vertex_indices

__all__ = ["DatasetNotPreparedError", "data_root", "dataset_dir", "names", "shape_ids", "variants", "base_shape",
           "shape_class", "correspondence_group", "ground_truth_kind", "coordinate_frame", "sample_vertices",
           "load_shape", "pairs", "ground_truth", "ground_truth_between", "sample_assignment", "p2p_from_samples",
           "verify_checksums", "clear_cache"]


class DatasetNotPreparedError(FileNotFoundError):
    """A registered dataset whose files are not (yet) under the data root."""


@dataclass(frozen=True)
class _Spec:
    name: str
    description: str
    how_to_get: str  # where the user obtains the data and which script prepares it
    class_rule: str  # "div10" (subject = last 3 digits // 10) or "prefix" (class = id without trailing digits)
    shared_triangulation: bool  # without a manifest: the whole family in one triangulation (True) or one per class
    ground_truth: str = "identity"  # "identity": a correspondence group is one triangulation; "samples": sample files
    frame: str = ""  # empty: the shapes keep their source's coordinates; else how they were moved (XYZ values differ)


_SGA18 = ("Clone https://github.com/llorz/SGA18_orientation_BCICP_dataset (or download its zip; the maps/*.zip "
          "and segmentation.zip files are not needed). The licences of FAUST (https://faust.is.tue.mpg.de: "
          "research only, no redistribution) and TOSCA apply to its shapes: use them in place, never "
          "redistribute them. Then run: python -m prodmaps.prepare {cmd} --archive SGA18_orientation_BCICP_dataset "
          "[--data-root DIR] (the repository root, its Dataset/{folder} folder, or the zip)")

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
    _Spec("faust_r", "FAUST_r: the 100 FAUST shapes, each remeshed independently to ~5k vertices and scaled into "
          "a unit box; ground truth through 5000 samples shared by all 100 (subject = XXX // 10)",
          _SGA18.format(cmd="faust_r", folder="FAUST"), "div10", False, "samples",
          "every shape translated and scaled on its own into a unit box (scale 0.54-0.60 of FAUST's metres)"),
    _Spec("tosca_r", "TOSCA_r: 76 TOSCA shapes (cat, centaur, david, dog, horse, michael, victoria, wolf), each "
          "remeshed to ~5k vertices; ground truth through 5000 samples within a class",
          _SGA18.format(cmd="tosca_r", folder="TOSCA_Isometric"), "prefix", False, "samples"),
    _Spec("tosca_r_noniso", "TOSCA_r non-isometric: 24 shapes (gorilla, man, woman) remeshed to ~5k vertices; "
          "ground truth through 900 samples shared by all 24, across classes",
          _SGA18.format(cmd="tosca_r_noniso", folder="TOSCA_nonIsometric"), "prefix", False, "samples"),
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


def coordinate_frame(name: str) -> str:
    """How dataset ``name``'s shapes were moved from their source's coordinates ("" if they were not).

    A relative error of the coordinate functions depends on the frame (an offset lowers it), so XYZ
    values of a moved dataset are not comparable with values measured in the source's frame.

    >>> coordinate_frame("faust"), coordinate_frame("faust_r")[:26]
    ('', 'every shape translated and')
    """
    return _spec(name).frame


def ground_truth_kind(name: str) -> str:
    """How dataset ``name`` gives ground truth: ``"identity"`` or ``"samples"`` (module docstring).

    Parameters
    ----------
    name : str
        A registered dataset (prepared or not).

    Returns
    -------
    str
        ``"identity"``: a correspondence group is one triangulation; ``"samples"``: every shape has a
        sample file and :func:`p2p_from_samples` builds the dense map.

    Raises
    ------
    ValueError
        An unknown dataset.

    Examples
    --------
    >>> ground_truth_kind("faust"), ground_truth_kind("faust_r")
    ('identity', 'samples')
    """
    return _spec(name).ground_truth


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
    tri: dict[str, str]  # triangulation of each shape
    group: dict[str, str]  # correspondence group of each shape (= triangulation for "identity" datasets)
    samples: dict[str, Path] = field(default_factory=dict)  # "samples" datasets: id -> sample file
    n_samples: dict[str, int] = field(default_factory=dict)  # group -> number of samples
    templates: dict[str, dict] = field(default_factory=dict)  # group -> {"file", "dataset", "n_vertices"}
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
        man = json.loads(manifest.read_text())
        entries = man["shapes"]
        ids = [e["id"] for e in entries]
        fmap = {e["id"]: folder / e["file"] for e in entries}
        cls = {e["id"]: str(e["class"]) for e in entries}
        tri = {e["id"]: str(e["triangulation"]) for e in entries}
        group = {e["id"]: str(e.get("group", e["triangulation"])) for e in entries}
        samples = {e["id"]: folder / e["samples"] for e in entries if "samples" in e}
        listed = list(fmap.values()) + list(samples.values())
        missing = [str(p.relative_to(folder)) for p in listed if not p.is_file()]
        if missing:
            raise DatasetNotPreparedError(f"dataset {name!r} under {folder} is incomplete: {len(missing)} files "
                                          f"listed in manifest.json are missing (first {missing[:3]}). "
                                          f"Prepare it again. {spec.how_to_get}")
        groups = man.get("groups", {})
        n_samples = {g: int(info["n_samples"]) for g, info in groups.items() if "n_samples" in info}
        templates = {g: {**info["template"], "file": folder / info["template"]["file"]}
                     for g, info in groups.items() if info.get("template")}
    else:
        if spec.ground_truth != "identity":
            raise DatasetNotPreparedError(f"dataset {name!r} under {folder} has no manifest.json (it names each "
                                          f"shape's sample file). Prepare it again. {spec.how_to_get}")
        ids = [p.stem for p in files]
        fmap = {p.stem: p for p in files}
        cls = {i: _class_of(spec.class_rule, i) for i in ids}
        tri = {i: ("0" if spec.shared_triangulation else cls[i]) for i in ids}
        group, samples, n_samples, templates = dict(tri), {}, {}, {}
    if spec.ground_truth == "samples" and set(samples) != set(ids):
        raise DatasetNotPreparedError(f"dataset {name!r} under {folder}: manifest.json lists no sample file for "
                                      f"{sorted(set(ids) - set(samples))[:3]}. Prepare it again. {spec.how_to_get}")
    index = _Index(folder, ids, fmap, cls, tri, group, samples, n_samples, templates)
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
    for cached in (_index_at, _load_at, _gt_file, _family_to_variant, _samples_at, _assignment_at,
                   _template_at, _template_assignment_at):
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


def correspondence_group(name: str, shape_id: str) -> str:
    """The correspondence group of a shape or variant: ground truth exists between shapes of one group.

    Parameters
    ----------
    name : str
        A prepared dataset.
    shape_id : str
        A family shape or a variant (a variant is in its base shape's group).

    Returns
    -------
    str
        ``"0"`` for anny_humans and faust (one triangulation), the class for tosca and tosca_r, ``"faust"``
        for faust_r, ``"tosca_noniso"`` for tosca_r_noniso.

    Raises
    ------
    ValueError
        An unknown dataset or shape id.
    DatasetNotPreparedError
        The dataset is not prepared.

    Examples
    --------
    >>> correspondence_group("anny_humans", "anny_013"), correspondence_group("anny_humans", "anny_000_thin")
    ('0', '0')
    """
    return _index(name).group[base_shape(name, shape_id)]


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
    correspondence group), ``"all"``. Pairs are enumerated in sorted order; with ``n`` a seeded
    random selection of ``n`` distinct pairs (``numpy.random.default_rng(seed)``, without
    replacement) is returned, kept in that enumeration order. Arguments are checked
    immediately; the result is an iterator. Datasets whose correspondence group is the class
    (tosca, tosca_r) have no ``"inter"`` pairs: the iterator is empty and asking for ``n > 0``
    of them raises ``ValueError``.
    """
    if kind not in _KINDS:
        raise ValueError(f"kind must be one of {_KINDS}; got {kind!r}")
    idx = _index(name)
    ids = np.array(idx.ids)
    cls = np.array([idx.cls[i] for i in idx.ids])
    grp = np.array([idx.group[i] for i in idx.ids])
    ok = (grp[:, None] == grp[None, :]) & ~np.eye(ids.size, dtype=bool)  # (s, s)
    same = cls[:, None] == cls[None, :]
    ok &= {"intra": same, "inter": ~same, "all": True}[kind]
    i1, i2 = np.nonzero(ok)
    total = i1.size
    if n is not None:
        if int(n) != n or n < 0:
            raise ValueError(f"n must be a non-negative integer or None; got {n!r}")
        if n > total:
            why = (" (no ground truth between classes: each class is its own correspondence group; use kind='intra')"
                   if kind == "inter" and total == 0 and np.array_equal(grp, cls) else "")
            raise ValueError(f"asked for n={n} {kind} pairs of {name!r} but only {total} exist{why}")
        sel = np.sort(np.random.default_rng(seed).choice(total, size=int(n), replace=False))
        i1, i2 = i1[sel], i2[sel]
    return iter([(str(ids[a]), str(ids[b])) for a, b in zip(i1.tolist(), i2.tolist())])


# ----------------------------------------------------------------------------- dense maps from samples
_DISTANCES = ("graph", "euclidean")


def sample_assignment(mesh: Mesh, samples, *, distance: str = "graph") -> np.ndarray:
    """For each vertex of ``mesh``, the sample whose correspondence it takes: ``(n,)`` indices into ``samples``.

    The rule of every ``"samples"`` ground truth: a vertex listed in ``samples`` takes the lowest
    sample index ``s`` with ``samples[s] == v`` (the remeshed collections list one vertex for up to
    a few samples; the first line wins, deterministically); any other vertex takes the assignment of
    the sample vertex nearest to it, along the mesh by default.

    Parameters
    ----------
    mesh : Mesh
        The shape the samples lie on.
    samples : (S,) int array
        0-based vertex of each sample (line ``s`` of a collection's sample file, minus one).
    distance : {"graph", "euclidean"}
        ``"graph"`` (default): shortest path along the mesh edges weighted by their lengths (one
        Dijkstra run from every sample vertex at once), so a vertex never takes a sample across a gap
        (between fingers, legs, an arm touching the body). ``"euclidean"``: straight-line distance.
        Equally near sample vertices: the one with the lowest assigned sample index.

    Returns
    -------
    (n,) int64 array
        ``a[v]`` in ``[0, S)``; ``samples[a[samples]]`` equals ``samples``.

    Raises
    ------
    TypeError
        ``mesh`` is not a :class:`Mesh`.
    ValueError
        Empty samples, indices out of range or not integers, an unknown ``distance``.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> path = pm.Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0.1, 0], [0, 1, 0]]),
    ...                np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4]]))
    >>> sample_assignment(path, [2, 0, 2])   # vertex 2: samples 0 and 2, 0 wins; vertex 1: a tie, 0 wins
    array([1, 0, 0, 0, 1])
    >>> sample_assignment(path, [2, 0, 2], distance="euclidean")
    array([1, 0, 0, 0, 1])
    """
    check_mesh(mesh)
    if distance not in _DISTANCES:
        raise ValueError(f"distance must be one of {_DISTANCES}; got {distance!r}")
    s = check_vertex_indices(samples, mesh.n_vertices, "samples")
    if s.ndim != 1 or s.size == 0:
        raise ValueError(f"samples must be a non-empty 1-D array of vertex indices; got shape {s.shape}")
    first = np.full(mesh.n_vertices, -1, dtype=np.int64)
    order = np.arange(s.size - 1, -1, -1)
    first[s[order]] = order  # written last for the lowest index: the first sample at a vertex wins
    sources = np.unique(s)  # (u,)
    if distance == "graph":
        from scipy.sparse.csgraph import dijkstra

        graph = edge_graph(mesh).tocoo()  # both directions of every edge
        dist, _, nearest = dijkstra(graph.tocsr(), directed=False, indices=sources, min_only=True,
                                    return_predecessors=True)  # (n,) (n,) (n,)
        label = first[nearest]
        # equally near sample vertices: the lowest label, carried along the edges that lie on shortest paths
        tight = dist[graph.row] + graph.data == dist[graph.col]  # (2E,) exact: the sums Dijkstra made
        a, b = graph.row[tight], graph.col[tight]
        while True:
            new = label.copy()
            np.minimum.at(new, b, label[a])
            if np.array_equal(new, label):
                return label
            label = new
    from scipy.spatial import cKDTree

    k = min(8, sources.size)
    dd, nn = cKDTree(mesh.vertices[sources]).query(mesh.vertices, k=k)  # (n, k) nearest first
    dd, nn = dd.reshape(mesh.n_vertices, k), nn.reshape(mesh.n_vertices, k)
    cand = np.where(dd == dd[:, :1], first[sources[nn]], np.iinfo(np.int64).max)  # ties with the nearest
    return cand.min(axis=1)


def p2p_from_samples(samples_1, samples_2, mesh_2: Mesh, *, distance: str = "graph") -> np.ndarray:
    """Dense point map ``p2p_21 (n2,)`` from two shapes' corresponding samples.

    ``samples_1[s]`` and ``samples_2[s]`` are the same point on shapes 1 and 2. The map is
    ``samples_1[sample_assignment(mesh_2, samples_2)]``: exact at the samples (sample ``s``'s vertex on
    shape 2 maps to sample ``s``'s vertex on shape 1; where several samples share a vertex of shape 2,
    the lowest index); any other vertex of shape 2 maps where its nearest sample vertex (along the
    mesh, :func:`sample_assignment`) maps. Only shape 2's geometry is used.

    Parameters
    ----------
    samples_1, samples_2 : (S,) int arrays
        0-based vertex of each sample on shape 1 and on shape 2.
    mesh_2 : Mesh
        Shape 2.
    distance : {"graph", "euclidean"}
        Passed to :func:`sample_assignment`.

    Returns
    -------
    (n2,) int64 array
        For each vertex of shape 2 a vertex of shape 1 (pull-back direction: ``C_12 = Φ2ᵀ A2 Φ1[p2p_21]``).

    Raises
    ------
    ValueError
        ``samples_1`` and ``samples_2`` differ in length or are not 1-D integer arrays; see
        :func:`sample_assignment`.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> m2 = pm.Mesh(np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0.1, 0], [0, 1, 0]]),
    ...              np.array([[0, 1, 4], [1, 2, 4], [2, 3, 4]]))
    >>> p2p_from_samples([7, 8, 9], [2, 0, 2], m2)   # samples 0 and 2 share vertex 2 on shape 2: 0 wins
    array([8, 7, 7, 7, 8])
    """
    s1 = np.asarray(samples_1)
    if s1.ndim != 1 or np.shape(samples_2) != s1.shape:
        raise ValueError(f"samples_1 and samples_2 must be 1-D with one entry per sample; got shapes {s1.shape} "
                         f"and {np.shape(samples_2)}")
    s1 = check_vertex_indices(s1, np.iinfo(np.int64).max, "samples_1")
    return s1[sample_assignment(mesh_2, samples_2, distance=distance)]


def _read_indices(path: Path, n_samples: int, n_vertices: int, what: str) -> np.ndarray:
    """0-based vertex indices of a prepared sample or template file, checked."""
    s = np.loadtxt(path, dtype=np.int64, ndmin=1)
    if s.shape != (n_samples,) or s.min() < 0 or s.max() >= n_vertices:
        raise ValueError(f"{path}: expected {n_samples} {what} vertex indices in [0, {n_vertices}); got {s.size} "
                         f"in [{s.min()}, {s.max()}]. Prepare the dataset again")
    s.setflags(write=False)
    return s


@functools.lru_cache(maxsize=512)
def _samples_at(root_str: str, name: str, sid: str) -> np.ndarray:
    idx = _index_at(root_str, name)
    return _read_indices(idx.samples[sid], idx.n_samples[idx.group[sid]], _load_at(root_str, name, sid).n_vertices,
                         "sample")


@functools.lru_cache(maxsize=512)
def _assignment_at(root_str: str, name: str, sid: str) -> np.ndarray:
    out = sample_assignment(_load_at(root_str, name, sid), _samples_at(root_str, name, sid))
    out.setflags(write=False)
    return out


def sample_vertices(name: str, shape_id: str) -> np.ndarray:
    """The sample vertices of a shape of a ``"samples"`` dataset: ``(S,)`` 0-based, read-only.

    Entry ``s`` is the same point on every shape of the shape's correspondence group (a vertex may
    be listed for several samples).

    Parameters
    ----------
    name : str
        A prepared dataset of kind ``"samples"`` (faust_r, tosca_r, tosca_r_noniso).
    shape_id : str
        A family shape.

    Returns
    -------
    (S,) int64 array

    Raises
    ------
    ValueError
        An identity dataset (its ground truth needs no samples), an unknown shape, a damaged file.
    DatasetNotPreparedError
        The dataset is not prepared.

    Examples
    --------
    >>> sample_vertices("anny_humans", "anny_000")
    Traceback (most recent call last):
    ...
    ValueError: dataset 'anny_humans' has identity ground truth (one triangulation per correspondence group): no samples
    """
    if ground_truth_kind(name) != "samples":
        raise ValueError(f"dataset {name!r} has identity ground truth (one triangulation per correspondence "
                         "group): no samples")
    idx = _checked_index(name, shape_id)
    if shape_id not in idx.samples:
        raise ValueError(f"{shape_id!r} is a variant of {name!r}: only family shapes have samples")
    return _samples_at(str(idx.root), name, shape_id)


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


def _family_map(idx: _Index, name: str, b1: str, b2: str) -> np.ndarray:
    """``p2p_21`` between two family shapes of one correspondence group."""
    root = str(idx.root)
    if b1 == b2 or ground_truth_kind(name) == "identity":
        return np.arange(_load_at(root, name, b2).n_vertices, dtype=np.int64)
    return _samples_at(root, name, b1)[_assignment_at(root, name, b2)]


def ground_truth(name: str, id_1: str, id_2: str) -> np.ndarray:
    """Ground-truth point map ``p2p_21`` ``(n2,)``: for each vertex of ``id_2`` its vertex on ``id_1``.

    Parameters
    ----------
    name : str
        A prepared dataset.
    id_1, id_2 : str
        Two shapes (family shapes or variants) of one correspondence group.

    Returns
    -------
    (n2,) int64 array
        The rule of the dataset's :func:`ground_truth_kind` (module docstring): the identity within a
        triangulation, :func:`p2p_from_samples` for ``"samples"`` datasets, composed with a variant's
        map. A family shape to itself is the identity.

    Raises
    ------
    ValueError
        Unknown ids, or shapes of different correspondence groups (two TOSCA classes).
    DatasetNotPreparedError
        The dataset is not prepared.

    Examples
    --------
    >>> ground_truth("anny_humans", "anny_000", "anny_013")[:4]
    array([0, 1, 2, 3])
    """
    idx = _checked_index(name, id_1, id_2)
    root = str(idx.root)
    b1, b2 = base_shape(name, id_1), base_shape(name, id_2)
    if idx.group[b1] != idx.group[b2]:
        what = ("different triangulations" if ground_truth_kind(name) == "identity"
                else "different correspondence groups")
        raise ValueError(f"no ground truth between {id_1!r} and {id_2!r} in {name!r}: {what} "
                         f"(classes {idx.cls[b1]!r} and {idx.cls[b2]!r})")
    fam = _family_map(idx, name, b1, b2)  # (n_b2,) each vertex of b2 -> its vertex on b1
    if id_2 in idx.variant_files:
        fam = fam[_gt_file(root, name, id_2)]  # (n2,) via the variant's vertex on its base
    if id_1 in idx.variant_files:
        return _family_to_variant(root, name, id_1)[fam].copy()
    return np.array(fam, dtype=np.int64)


@functools.lru_cache(maxsize=32)
def _template_at(root_str: str, name: str, group: str) -> np.ndarray:
    idx = _index_at(root_str, name)
    tpl = idx.templates[group]
    return _read_indices(tpl["file"], idx.n_samples[group], int(tpl["n_vertices"]), "template")


@functools.lru_cache(maxsize=128)
def _template_assignment_at(root_str: str, name: str, group: str, t_root: str, t_name: str, sid: str) -> np.ndarray:
    out = sample_assignment(_load_at(t_root, t_name, sid), _template_at(root_str, name, group))
    out.setflags(write=False)
    return out


def _template_side(sample_name: str, sample_id: str, template_name: str, template_id: str):
    """``(samples on the sample-dataset shape, samples on the template-dataset shape, assignment on the latter)``."""
    idx = _checked_index(sample_name, sample_id)
    t_idx = _checked_index(template_name, template_id)
    if sample_id in idx.variant_files or template_id in t_idx.variant_files:
        raise ValueError("ground_truth_between takes family shapes; compose with ground_truth(...) for a variant")
    group = idx.group[sample_id]
    tpl = idx.templates.get(group)
    if tpl is None or tpl.get("dataset") != template_name:
        links = sorted({t["dataset"] for t in idx.templates.values() if t.get("dataset")})
        raise ValueError(f"no ground truth between {sample_name!r} shape {sample_id!r} (group {group!r}) and "
                         f"dataset {template_name!r}: that group's samples name no {template_name!r} template "
                         f"(datasets linked to {sample_name!r}: {links})")
    root, t_root = str(idx.root), str(t_idx.root)
    n_t = _load_at(t_root, template_name, template_id).n_vertices
    if n_t != int(tpl["n_vertices"]):
        raise ValueError(f"{template_name!r} shape {template_id!r} has {n_t} vertices; the {sample_name!r} "
                         f"template indexes a {tpl['n_vertices']}-vertex triangulation")
    return (_samples_at(root, sample_name, sample_id), _template_at(root, sample_name, group),
            _template_assignment_at(root, sample_name, group, t_root, template_name, template_id))


def ground_truth_between(shape_1: tuple[str, str], shape_2: tuple[str, str]) -> np.ndarray:
    """Ground-truth ``p2p_21 (n2,)`` between shapes of two datasets linked by a sample template.

    A ``"samples"`` dataset's group may name a template: the vertex of each sample on the
    triangulation of an ``"identity"`` dataset (faust_r's: the FAUST registrations' 6890-vertex
    template, so ``("faust", "tr_reg_000")`` and ``("faust_r", "tr_reg_000")`` are one pose in two
    triangulations, and any faust shape corresponds to any faust_r shape). Every shape of that
    dataset then has the template as its samples and :func:`p2p_from_samples` gives the map, with
    the rule of :func:`ground_truth` (exact at the samples, nearest sample along shape 2 elsewhere).
    Two shapes of one dataset give :func:`ground_truth`.

    Parameters
    ----------
    shape_1, shape_2 : (dataset name, shape id)
        The source and target shapes (family shapes).

    Returns
    -------
    (n2,) int64 array
        For each vertex of shape 2 a vertex of shape 1.

    Raises
    ------
    ValueError
        Datasets with no template linking them, a variant, a template-dataset shape whose vertex count
        is not the template's.
    DatasetNotPreparedError
        One of the datasets is not prepared.

    Examples
    --------
    >>> ground_truth_between(("anny_humans", "anny_000"), ("anny_humans", "anny_013"))[:3]
    array([0, 1, 2])
    """
    (name_1, id_1), (name_2, id_2) = shape_1, shape_2
    if name_1 == name_2:
        return ground_truth(name_1, id_1, id_2)
    kinds = (ground_truth_kind(name_1), ground_truth_kind(name_2))
    if kinds == ("samples", "identity"):
        s1, _, a2 = _template_side(name_1, id_1, name_2, id_2)
        return s1[a2].astype(np.int64)
    if kinds == ("identity", "samples"):
        _, t1, _ = _template_side(name_2, id_2, name_1, id_1)
        idx = _index(name_2)
        return t1[_assignment_at(str(idx.root), name_2, id_2)].astype(np.int64)
    raise ValueError(f"no ground truth between datasets {name_1!r} and {name_2!r}: only a 'samples' dataset and "
                     "the 'identity' dataset its template names are linked (faust_r and faust)")


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
