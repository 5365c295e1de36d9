"""Prepare the remeshed FAUST and TOSCA collections (FAUST_r, TOSCA_r) from a clone of their public repository.

The collections of Ren, Poulenard, Wonka and Ovsjanikov (SIGGRAPH Asia 2018), used across the
functional-map literature: every shape remeshed on its own (LRVD) to about 5000 vertices, ground truth
through samples. The licences of FAUST (research only, no redistribution) and TOSCA apply: use the
files in place, never redistribute them or anything holding their vertices. Get them with
``git clone https://github.com/llorz/SGA18_orientation_BCICP_dataset`` (or its zip download), then::

    python -m prodmaps.prepare faust_r --archive SGA18_orientation_BCICP_dataset [--data-root DIR] [--force]
    python -m prodmaps.prepare tosca_r --archive SGA18_orientation_BCICP_dataset
    python -m prodmaps.prepare tosca_r_noniso --archive SGA18_orientation_BCICP_dataset

``--archive`` is the repository root, its ``Dataset/`` or ``Dataset/<collection>[/vtx_5k]`` folder, or a
zip of any of them. Only ``vtx_5k/<id>.off`` and ``vtx_5k/corres/`` are read: ``maps/*.zip``,
``segmentation.zip`` and the ``*.sym.vts`` files are not needed (ignored when present).

* ``faust_r`` (``Dataset/FAUST``): ``tr_reg_000..099``, class = subject ``XXX // 10``, one
  correspondence group ``faust`` of 5000 samples; ``corres/sampleID.vts`` (the FAUST template vertex
  of each sample) becomes the group's template, linking faust_r to the ``faust`` registrations.
* ``tosca_r`` (``Dataset/TOSCA_Isometric``): 76 shapes ``<class><i>`` of 8 classes, a group per class
  (5000 samples each, ``corres/<class>_sampleID.vts`` checked).
* ``tosca_r_noniso`` (``Dataset/TOSCA_nonIsometric``): 24 shapes ``8_<class>_NN`` (gorilla, man, woman)
  in ONE group of 900 samples across classes: a dataset of its own, since inside tosca_r it would
  give "inter" pairs to one part only and mix 900- with 5000-sample groups.

Checks, nothing written unless all pass: the folder holds exactly the collection's shapes (a missing
shape or sample file: :class:`MissingFileError`; any other ``.off``/``.vts`` or unknown file there:
:class:`ForeignFileError`); each shape parses, has a vertex count in range and is a valid mesh
(:class:`InvalidShapeError`); each ``corres/<id>.vts`` and template has one integer per line, as many
lines as the group's samples, 1-based indices in range (:class:`CorrespondenceFileError`). Writes
``<data-root>/<dataset>/shapes/<id>.ply``, ``samples/<id>.txt`` (0-based), ``samples/<group>.template.txt``
(faust_r), ``test_pairs.txt`` (the collection's list, when present), ``manifest.json``, ``SHA256SUMS``.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

import numpy as np

from .. import datasets
from ..errors import MeshError
from ..io import save_mesh
from ..mesh import Mesh
from .archive import (
    Archive,
    PrepareError,
    argument_parser,
    parse_mesh_bytes,
    sha256_file,
    staged_folder,
    write_manifest_and_sums,
)

REPOSITORY = "https://github.com/llorz/SGA18_orientation_BCICP_dataset"
N_VERTICES = (4000, 6000)  # "about 5k vertices" (measured: 4344..5004; the wolves keep TOSCA's 4344)


class LayoutError(PrepareError):
    """The folder or zip is not (all of) the collection's layout; the message names the file and the fix."""


class MissingFileError(LayoutError):
    """A shape, its ``corres/<id>.vts`` or a template file the collection must hold is absent."""


class ForeignFileError(LayoutError):
    """A file that is not the collection's own sits among its shapes or correspondence files."""


class CorrespondenceFileError(LayoutError):
    """A ``.vts`` file with the wrong number of lines, a non-integer line or an index out of range."""


class InvalidShapeError(PrepareError):
    """A shape that does not parse, has an unexpected vertex count, or is not a valid mesh."""


@dataclass(frozen=True)
class Collection:
    """One remeshed collection of the repository and the dataset it becomes."""

    dataset: str
    folder: str  # under Dataset/
    ids: tuple[str, ...]
    n_samples: int
    one_group: str | None  # the group of every shape, or None: a group per class
    template_dataset: str | None = None  # the identity dataset the template indexes (faust_r: faust)
    template_n_vertices: int | None = None

    def class_of(self, sid: str) -> str:
        """Subject ``XXX // 10`` (FAUST) or the class name (TOSCA)."""
        m = re.fullmatch(r"tr_reg_(\d{3})", sid)
        if m:
            return str(int(m.group(1)) // 10)
        m = re.fullmatch(r"8_([a-z]+)_\d+", sid)
        return m.group(1) if m else re.sub(r"\d+$", "", sid)

    def group_of(self, sid: str) -> str:
        """The correspondence group of a shape."""
        return self.one_group or self.class_of(sid)

    def template_file(self, group: str) -> str | None:
        """The ``corres/`` file naming each sample's template vertex, if the collection has one."""
        if self.dataset == "faust_r":
            return "sampleID.vts"
        return None if self.one_group else f"{group}_sampleID.vts"


_TOSCA = {"cat": range(11), "centaur": range(6), "david": (0, 1, 6, 10, 11, 12, 13),
          "dog": (0, 1, 2, 3, 5, 6, 7, 8, 10), "horse": (0, 5, 6, 7, 10, 14, 15, 17), "michael": range(20),
          "victoria": (0, 1, 2, 4, 7, 10, 12, 17, 21, 23, 24, 25), "wolf": range(3)}
_NONISO = {"gorilla": 5, "man": 7, "woman": 12}
COLLECTIONS = {c.dataset: c for c in (
    Collection("faust_r", "FAUST", tuple(f"tr_reg_{i:03d}" for i in range(100)), 5000, "faust", "faust", 6890),
    Collection("tosca_r", "TOSCA_Isometric", tuple(f"{c}{i}" for c, r in _TOSCA.items() for i in r), 5000, None),
    Collection("tosca_r_noniso", "TOSCA_nonIsometric",
               tuple(f"8_{c}_{i:02d}" for c, k in _NONISO.items() for i in range(1, k + 1)), 900, "tosca_noniso"),
)}
_ALLOWED_EXTRA = re.compile(r"^(segmentation\.zip|(maps|segmentation)/.+|corres/[^/]+\.sym\.vts)$")


def _find_folder(arc: Archive, coll: Collection, where: str) -> str:
    """The prefix (``''`` or ending in ``/``) of the one folder holding the collection's shapes."""
    wanted = {f"{sid}.off" for sid in coll.ids}
    found: dict[str, int] = {}
    for name in arc.names:
        head, _, tail = name.rpartition("/")
        if tail in wanted:
            prefix = head + "/" if head else ""
            found[prefix] = found.get(prefix, 0) + 1
    if not found:
        raise LayoutError(f"{where}: no shape of {coll.dataset} found (expected Dataset/{coll.folder}/vtx_5k/"
                          f"{coll.ids[0]}.off ... with a corres/ folder). Pass the clone of {REPOSITORY} (its root "
                          f"or Dataset/{coll.folder}) or its zip")
    if len(found) > 1:
        raise LayoutError(f"{where}: {len(found)} folders hold {coll.dataset} shapes ({sorted(found)[:4]}); "
                          "pass one of them with --archive")
    return next(iter(found))


def _read_indices(arc: Archive, member: str, n_lines: int, high: int | None, what: str) -> np.ndarray:
    """0-based indices of a ``.vts`` file: one 1-based integer per line, ``n_lines`` lines, in ``[1, high]``."""
    try:
        text = arc.read(member).decode("ascii")
    except UnicodeDecodeError:
        raise CorrespondenceFileError(f"{member}: not an ASCII text file; restore it from {REPOSITORY}") from None
    rows = text.split("\n")
    while rows and not rows[-1].strip():
        rows.pop()
    fix = f"restore the file from {REPOSITORY} (git checkout, or download the zip again)"
    if len(rows) != n_lines:
        raise CorrespondenceFileError(f"{member}: {len(rows)} lines; expected {n_lines} ({what}: one 1-based vertex "
                                      f"index per sample, every file of the group the same length); {fix}")
    tokens = [r.split() for r in rows]
    bad = next((k for k, t in enumerate(tokens) if len(t) != 1 or not t[0].isdigit()), None)
    if bad is not None:
        raise CorrespondenceFileError(f"{member}: line {bad + 1} is {rows[bad].strip()!r}, not one non-negative "
                                      f"integer; {fix}")
    idx = np.array([t[0] for t in tokens], dtype=np.int64)
    lo, hi = int(idx.min()), int(idx.max())
    if lo < 1 or (high is not None and hi > high):
        k = int(np.argmax(idx < 1)) if lo < 1 else int(np.argmax(idx > high))
        raise CorrespondenceFileError(f"{member}: line {k + 1} holds index {int(idx[k])}, outside [1, {high}] "
                                      f"({what}, 1-based); {fix}")
    return idx - 1


def prepare_collection(dataset: str, archive, data_root=None, *, force: bool = False, n_samples: int | None = None,
                       n_vertices: tuple[int, int] = N_VERTICES, verbose: bool = True) -> Path:
    """Read, verify and write one remeshed collection as dataset ``dataset``; returns the dataset folder.

    Parameters
    ----------
    dataset : {"faust_r", "tosca_r", "tosca_r_noniso"}
        Which collection (module docstring).
    archive : path
        The repository clone (root, ``Dataset/`` or the collection's folder) or a zip of it.
    data_root : path, optional
        Where ``<dataset>/`` is written (default ``$PRODMAPS_DATA``, else ``~/.local/share/prodmaps``).
    force : bool
        Replace an existing ``<dataset>/`` folder.
    n_samples : int, optional
        Lines expected in every ``.vts`` file (default: the collection's, 5000 or 900; tests pass fewer).
    n_vertices : (int, int)
        The accepted vertex count range of a shape.
    verbose : bool
        Print progress.

    Returns
    -------
    Path
        ``<data_root>/<dataset>``.

    Raises
    ------
    LayoutError
        No or several collection folders; :class:`MissingFileError`, :class:`ForeignFileError` and
        :class:`CorrespondenceFileError` are its kinds.
    InvalidShapeError
        A shape that does not parse, has a vertex count outside ``n_vertices`` or is not a valid mesh.
    PrepareError
        Unknown dataset, an existing target without ``force``, an unsafe or damaged archive.
        Nothing is written in any of these cases.

    Examples
    --------
    >>> prepare_collection("shrec_r", "SGA18_orientation_BCICP_dataset", verbose=False)
    Traceback (most recent call last):
    ...
    prodmaps.prepare.archive.PrepareError: unknown collection 'shrec_r'; choose from ['faust_r', 'tosca_r', ...]
    """
    if dataset not in COLLECTIONS:
        raise PrepareError(f"unknown collection {dataset!r}; choose from {sorted(COLLECTIONS)}")
    coll = COLLECTIONS[dataset]
    n_samples = coll.n_samples if n_samples is None else int(n_samples)
    say = print if verbose else (lambda *a, **k: None)
    root = Path(data_root) if data_root is not None else datasets.data_root()
    target = root / dataset
    if target.exists() and not force:
        raise PrepareError(f"{target} already exists; pass --force to replace it")
    src = Path(archive)
    with Archive(src) as arc:
        prefix = _find_folder(arc, coll, str(src))
        where = f"{src.name}/{prefix}" if prefix else f"{src.name}/"
        inside = {n[len(prefix):] for n in arc.names if n.startswith(prefix)}
        shapes = {n[:-4] for n in inside if "/" not in n and n.endswith(".off")}
        groups = sorted({coll.group_of(s) for s in coll.ids})
        templates = {g: coll.template_file(g) for g in groups if coll.template_file(g)}
        expected = ({f"{s}.off" for s in coll.ids} | {f"corres/{s}.vts" for s in coll.ids}
                    | {f"corres/{t}" for t in templates.values()})
        foreign = sorted(n for n in inside if n not in expected and not _ALLOWED_EXTRA.match(n)
                         and (n.count("/") == 0 or n.startswith("corres/")))
        if foreign:
            raise ForeignFileError(f"{where}: {len(foreign)} files that are not {coll.dataset}'s own: {foreign[:5]} "
                                   f"(its folder holds exactly {len(coll.ids)} shapes <id>.off and corres/<id>.vts); "
                                   "remove them or pass an unmodified clone")
        missing = sorted(e for e in expected if e not in inside)
        if missing:
            raise MissingFileError(f"{where}: {len(missing)} of the collection's files are missing: {missing[:5]}"
                                   f"{' ...' if len(missing) > 5 else ''}; the clone is incomplete: check it out "
                                   f"again from {REPOSITORY}")
        say(f"found {len(shapes)} shapes of {dataset} in {where}")
        template_idx = {g: _read_indices(arc, prefix + f"corres/{t}", n_samples, coll.template_n_vertices
                                         if coll.template_dataset else None, "template vertex of each sample")
                        for g, t in templates.items()}
        pairs_member = str(PurePosixPath(prefix).parent / "test_pairs.txt") if prefix.endswith("vtx_5k/") else None
        test_pairs = None
        if pairs_member and pairs_member in arc.names:
            test_pairs = [ln.split() for ln in arc.read(pairs_member).decode("ascii", "replace").splitlines()
                          if ln.strip()]
            bad = [p for p in test_pairs if len(p) != 2 or not set(p) <= set(coll.ids)]
            if bad:
                raise ForeignFileError(f"{src.name}/{pairs_member}: lines {bad[:3]} are not two {dataset} shape ids; "
                                       f"restore it from {REPOSITORY}")
        entries = []
        with staged_folder(target, force=force) as tmp:
            (tmp / "shapes").mkdir()
            (tmp / "samples").mkdir()
            for k, sid in enumerate(coll.ids):
                member = f"{prefix}{sid}.off"
                try:
                    v, f = parse_mesh_bytes(arc.read(member), ".off", tmp)
                    if not n_vertices[0] <= v.shape[0] <= n_vertices[1]:
                        raise InvalidShapeError(f"{src.name}/{member}: {v.shape[0]} vertices; the shapes of "
                                                f"{dataset} have {n_vertices[0]}..{n_vertices[1]} (about 5000)")
                    mesh = Mesh(v, f, name=sid)
                except MeshError as exc:
                    raise InvalidShapeError(f"{src.name}/{member}: {exc}; restore it from {REPOSITORY}") from None
                samples = _read_indices(arc, f"{prefix}corres/{sid}.vts", n_samples, mesh.n_vertices,
                                        f"the vertex of each sample on {sid}.off")
                save_mesh(tmp / "shapes" / f"{sid}.ply", mesh)
                np.savetxt(tmp / "samples" / f"{sid}.txt", samples, fmt="%d")
                extent = mesh.vertices.max(axis=0) - mesh.vertices.min(axis=0)
                entries.append({"id": sid, "file": f"shapes/{sid}.ply", "class": coll.class_of(sid),
                                "triangulation": sid, "group": coll.group_of(sid), "samples": f"samples/{sid}.txt",
                                "n_vertices": mesh.n_vertices, "n_faces": mesh.n_faces,
                                "n_sample_vertices": int(np.unique(samples).size),
                                "n_boundary_edges": int(len(mesh.boundary_edges)),
                                "area": round(float(mesh.area), 6), "extent": [round(float(e), 6) for e in extent]})
                if (k + 1) % 20 == 0 or k + 1 == len(coll.ids):
                    say(f"  verified and converted {k + 1}/{len(coll.ids)}")
            group_info = {}
            for g in groups:
                info = {"n_samples": n_samples, "n_shapes": sum(e["group"] == g for e in entries)}
                if g in templates and coll.template_dataset:
                    np.savetxt(tmp / "samples" / f"{g}.template.txt", template_idx[g], fmt="%d")
                    info["template"] = {"file": f"samples/{g}.template.txt", "dataset": coll.template_dataset,
                                        "n_vertices": coll.template_n_vertices,
                                        "source": f"corres/{templates[g]}"}
                group_info[g] = info
            if test_pairs is not None:
                (tmp / "test_pairs.txt").write_text("".join(f"{a} {b}\n" for a, b in test_pairs))
            write_manifest_and_sums(tmp, {
                "dataset": dataset, "format_version": 2, "prepared_by": f"python -m prodmaps.prepare {dataset}",
                "source": {"archive": src.name, "sha256": sha256_file(src) if src.is_file() else None,
                           "folder": prefix, "repository": REPOSITORY},
                "ground_truth": {"kind": "samples", "rule": "prodmaps.datasets.p2p_from_samples: line s of every "
                                 "sample file is one point; exact at the samples (the lowest sample index at a "
                                 "shared vertex), elsewhere the sample vertex nearest along the mesh edges"},
                "classes": {c: sum(e["class"] == c for e in entries)
                            for c in dict.fromkeys(e["class"] for e in entries)},
                "groups": group_info, "n_test_pairs": None if test_pairs is None else len(test_pairs),
                "shapes": entries})
    say(f"wrote {len(entries)} shapes to {target}")
    return target


def main(argv=None, dataset: str = "faust_r") -> None:
    """Command line of ``python -m prodmaps.prepare faust_r|tosca_r|tosca_r_noniso``."""
    ap = argument_parser(__doc__, f"replace an existing prepared {dataset}/ folder")
    ap.prog = f"python -m prodmaps.prepare {dataset}"
    ap.add_argument("--archive", required=True,
                    help="the clone of SGA18_orientation_BCICP_dataset (root, Dataset/ or Dataset/<collection>) or its "
                         "zip; maps/ and segmentation.zip are not needed")
    args = ap.parse_args(argv)
    prepare_collection(dataset, args.archive, args.data_root, force=args.force)


MAINS = {name: functools.partial(main, dataset=name) for name in COLLECTIONS}  # python -m prodmaps.prepare <name>
