"""FAUST_r / TOSCA_r: preparation and sample-based ground truth on small collections built here.

The synthetic collections follow the layout of ``llorz/SGA18_orientation_BCICP_dataset``
(``Dataset/<collection>/vtx_5k/<id>.off``, ``corres/<id>.vts`` one 1-based vertex per sample,
``corres/sampleID.vts`` or ``corres/<class>_sampleID.vts``, ``test_pairs.txt`` one level up) with
the real shape ids but small meshes: every shape is a sphere of its own triangulation (Fibonacci
points, 40..70 of them), stretched per subject/class; sample ``s`` is one direction on the unit
sphere, listed on each shape as its vertex closest to that direction, so vertices listed for two
samples occur as in the real data. Nothing here reads the real data.
"""

import json
import shutil
import subprocess
import sys
import zipfile
import zlib

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import ConvexHull, cKDTree

import prodmaps as pm
import prodmaps.datasets as ds
from prodmaps.geodesics import edge_graph
from prodmaps.prepare import faust, sga18
from prodmaps.prepare.archive import PrepareError

S = 40  # samples per shape (the real collections: 5000, TOSCA non-isometric 900)
RANGE = (20, 200)  # accepted vertex counts for these small shapes
N_TPL = 6890  # the FAUST template's vertex count (faust_r's template indexes it)


def fib_sphere(n, phase=0.0):
    i = np.arange(n) + 0.5
    phi, th = np.arccos(1 - 2 * i / n), np.pi * (1 + 5**0.5) * i + phase
    v = np.column_stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)])
    return v, ConvexHull(v).simplices.astype(np.int64)


def off_text(v, f):
    return (f"OFF\n{len(v)} {len(f)} 0\n" + "".join(f"{a:.9f} {b:.9f} {c:.9f}\n" for a, b, c in v)
            + "".join(f"3 {a} {b} {c}\n" for a, b, c in f))


def vts_text(idx0):
    return "".join(f"{i + 1}\n" for i in idx0)


def stretch(key):
    """Axis scales of a subject or class (a deterministic function of its name)."""
    return 1 + 0.5 * np.random.default_rng(zlib.crc32(key.encode())).random(3)


TPL_V, TPL_F = fib_sphere(N_TPL)  # the "FAUST template": registrations are stretched copies of it
SAMPLE_TPL = np.random.default_rng(7).choice(N_TPL, size=S, replace=False)  # template vertex of each sample
DIRS = TPL_V[SAMPLE_TPL]  # (S, 3) the sample points on the unit sphere


def make_collection(coll, n_samples=S):
    """``{relative path under vtx_5k/: text}``, the shapes ``{id: (V, F)}`` and samples ``{id: (S,) 0-based}``."""
    files, shapes, samples = {}, {}, {}
    dirs = DIRS[:n_samples]
    for k, sid in enumerate(coll.ids):
        v, f = fib_sphere(40 + (k * 7) % 31, phase=0.37 * k)
        v = v * stretch(coll.class_of(sid))
        s = cKDTree(v / np.linalg.norm(v, axis=1, keepdims=True)).query(dirs)[1]
        shapes[sid], samples[sid] = (v, f), s
        files[f"{sid}.off"] = off_text(v, f)
        files[f"corres/{sid}.vts"] = vts_text(s)
        files[f"corres/{sid}.sym.vts"] = vts_text(s[::-1])
    for g in sorted({coll.group_of(s) for s in coll.ids}):
        t = coll.template_file(g)
        if t:
            files[f"corres/{t}"] = vts_text(SAMPLE_TPL[:n_samples])
    return files, shapes, samples


COLLS = {name: make_collection(c, 30 if name == "tosca_r_noniso" else S) for name, c in sga18.COLLECTIONS.items()}


def write_clone(root, names=tuple(COLLS), edit=None):
    """A clone-like folder (``maps/`` missing, as in the snapshot) of the collections ``names``."""
    for name in names:
        coll = sga18.COLLECTIONS[name]
        files = dict(COLLS[name][0])
        if edit:
            edit(name, files)
        base = root / "Dataset" / coll.folder
        for rel, text in files.items():
            p = base / "vtx_5k" / rel
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_text(text) if isinstance(text, str) else p.write_bytes(text)
        ids = coll.ids
        (base / "test_pairs.txt").write_text(f"{ids[0]}\t{ids[1]}\n{ids[2]}\t{ids[0]}\n")
    (root / "README.md").write_text("# Datasets\n")
    return root


def prep(name, src, root, **kw):
    n = 30 if name == "tosca_r_noniso" else S
    return sga18.prepare_collection(name, src, root, n_samples=n, n_vertices=RANGE, verbose=False, **kw)


def nothing_written(root):
    return not root.exists() or list(root.iterdir()) == []


@pytest.fixture(scope="module")
def prepared(tmp_path_factory):
    """All three collections prepared from one clone-like folder, plus 3 FAUST registrations."""
    tmp = tmp_path_factory.mktemp("sga18")
    clone = write_clone(tmp / "SGA18_orientation_BCICP_dataset")
    root = tmp / "data"
    for name in COLLS:
        prep(name, clone, root)
    regs = tmp / "registrations"
    regs.mkdir()
    for sid in ("tr_reg_000", "tr_reg_001", "tr_reg_025"):
        (regs / f"{sid}.off").write_text(off_text(TPL_V * stretch(str(int(sid[-3:]) // 10)), TPL_F))
    faust.prepare_faust(regs, root, verbose=False)
    return root, clone


@pytest.fixture
def use(prepared, monkeypatch):
    monkeypatch.setenv("PRODMAPS_DATA", str(prepared[0]))
    ds.clear_cache()
    yield prepared[0]
    ds.clear_cache()


# ----------------------------------------------------------------------------- prepare
def test_prepare_writes_the_dataset_and_manifest(prepared, use):
    root, _ = prepared
    assert sorted(p.name for p in root.iterdir()) == ["faust", "faust_r", "tosca_r", "tosca_r_noniso"]
    man = json.loads((root / "faust_r" / "manifest.json").read_text())
    assert man["source"]["folder"] == "Dataset/FAUST/vtx_5k/" and man["source"]["sha256"] is None
    assert man["ground_truth"]["kind"] == "samples" and man["n_test_pairs"] == 2
    assert man["groups"] == {"faust": {"n_samples": S, "n_shapes": 100, "template": {
        "file": "samples/faust.template.txt", "dataset": "faust", "n_vertices": N_TPL,
        "source": "corres/sampleID.vts"}}}
    e = man["shapes"][42]
    assert (e["id"], e["class"], e["group"], e["triangulation"]) == ("tr_reg_042", "4", "faust", "tr_reg_042")
    v, f = COLLS["faust_r"][1]["tr_reg_042"]
    assert (e["n_vertices"], e["n_faces"]) == (len(v), len(f))
    assert e["n_sample_vertices"] == np.unique(COLLS["faust_r"][2]["tr_reg_042"]).size
    np.testing.assert_array_equal(np.loadtxt(root / "faust_r" / e["samples"], dtype=int),
                                  COLLS["faust_r"][2]["tr_reg_042"])
    np.testing.assert_array_equal(np.loadtxt(root / "faust_r" / "samples" / "faust.template.txt", dtype=int),
                                  SAMPLE_TPL)
    assert (root / "faust_r" / "test_pairs.txt").read_text() == "tr_reg_000 tr_reg_001\ntr_reg_002 tr_reg_000\n"
    tosca = json.loads((root / "tosca_r" / "manifest.json").read_text())
    assert sorted(tosca["groups"]) == ["cat", "centaur", "david", "dog", "horse", "michael", "victoria", "wolf"]
    assert all("template" not in g for g in tosca["groups"].values())
    assert tosca["classes"]["michael"] == 20 and sum(tosca["classes"].values()) == 76
    noniso = json.loads((root / "tosca_r_noniso" / "manifest.json").read_text())
    assert noniso["groups"] == {"tosca_noniso": {"n_samples": 30, "n_shapes": 24}}
    assert noniso["classes"] == {"gorilla": 5, "man": 7, "woman": 12}
    for name in COLLS:
        assert all(ds.verify_checksums(name).values())
    m = ds.load_shape("faust_r", "tr_reg_042")
    np.testing.assert_allclose(m.vertices, v, atol=1e-6)
    np.testing.assert_array_equal(m.faces, f)


def test_prepare_from_a_github_zip_and_from_the_collection_folder(tmp_path, prepared):
    clone = prepared[1]
    zpath = tmp_path / "SGA18_orientation_BCICP_dataset-master.zip"
    with zipfile.ZipFile(zpath, "w") as z:
        for p in sorted(clone.rglob("*")):
            if p.is_file():
                z.write(p, "SGA18_orientation_BCICP_dataset-master/" + p.relative_to(clone).as_posix())
        z.writestr("SGA18_orientation_BCICP_dataset-master/Dataset/FAUST/vtx_5k/segmentation.zip", b"PK")
        z.writestr("SGA18_orientation_BCICP_dataset-master/Dataset/FAUST/vtx_5k/maps/BIM.zip", b"PK")
    out = prep("faust_r", zpath, tmp_path / "a")
    man = json.loads((out / "manifest.json").read_text())
    assert man["source"]["folder"] == "SGA18_orientation_BCICP_dataset-master/Dataset/FAUST/vtx_5k/"
    assert len(man["source"]["sha256"]) == 64
    ref = prepared[0] / "faust_r"
    for sub in ("shapes/tr_reg_007.ply", "samples/tr_reg_007.txt", "samples/faust.template.txt"):
        assert (out / sub).read_bytes() == (ref / sub).read_bytes()
    out = prep("tosca_r", clone / "Dataset" / "TOSCA_Isometric" / "vtx_5k", tmp_path / "b")
    assert not (out / "test_pairs.txt").exists()  # one level above the folder given
    assert len(json.loads((out / "manifest.json").read_text())["shapes"]) == 76
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == ["tosca_r"]
    with pytest.raises(PrepareError, match="already exists; pass --force"):
        prep("tosca_r", clone, tmp_path / "b")
    prep("tosca_r", clone, tmp_path / "b", force=True)
    assert (tmp_path / "b" / "tosca_r" / "test_pairs.txt").is_file()


def _drop(rel):
    return lambda name, files: files.pop(rel)


def _set(rel, text):
    return lambda name, files: files.__setitem__(rel, text)


def _corrupt_line(rel, line, value):
    def edit(name, files):
        rows = files[rel].splitlines()
        rows[line] = value
        files[rel] = "\n".join(rows) + "\n"
    return edit


_N42 = len(COLLS["faust_r"][1]["tr_reg_042"][0])
_BAD_FACES = np.vstack([COLLS["faust_r"][1]["tr_reg_042"][1], COLLS["faust_r"][1]["tr_reg_042"][1][:1]])


@pytest.mark.parametrize("case, edit, error, message", [
    ("missing corres", _drop("corres/tr_reg_042.vts"), sga18.MissingFileError,
     r"missing: \['corres/tr_reg_042.vts'\].*check it out again"),
    ("missing shape", _drop("tr_reg_099.off"), sga18.MissingFileError, r"missing: \['tr_reg_099.off'\]"),
    ("missing template", _drop("corres/sampleID.vts"), sga18.MissingFileError, r"\['corres/sampleID.vts'\]"),
    ("short file", _corrupt_line("corres/tr_reg_042.vts", -1, ""), sga18.CorrespondenceFileError,
     rf"corres/tr_reg_042.vts: {S - 1} lines; expected {S}"),
    ("index too large", _corrupt_line("corres/tr_reg_042.vts", 3, str(_N42 + 1)), sga18.CorrespondenceFileError,
     rf"tr_reg_042.vts: line 4 holds index {_N42 + 1}, outside \[1, {_N42}\]"),
    ("index zero", _corrupt_line("corres/tr_reg_042.vts", 0, "0"), sga18.CorrespondenceFileError,
     "tr_reg_042.vts: line 1 holds index 0, outside"),
    ("not an integer", _corrupt_line("corres/tr_reg_042.vts", 5, "12.5"), sga18.CorrespondenceFileError,
     "tr_reg_042.vts: line 6 is '12.5', not one non-negative integer"),
    ("template out of range", _corrupt_line("corres/sampleID.vts", 2, str(N_TPL + 1)), sga18.CorrespondenceFileError,
     f"sampleID.vts: line 3 holds index {N_TPL + 1}, outside \\[1, {N_TPL}\\]"),
    ("foreign shape", _set("tr_reg_100.off", off_text(*fib_sphere(50))), sga18.ForeignFileError,
     r"not faust_r's own: \['tr_reg_100.off'\]"),
    ("foreign corres", _set("corres/tr_reg_000 (copy).vts", "1\n"), sga18.ForeignFileError,
     r"\['corres/tr_reg_000 \(copy\).vts'\]"),
    ("foreign file", _set("notes.txt", "x"), sga18.ForeignFileError, r"\['notes.txt'\]"),
    ("invalid mesh", _set("tr_reg_042.off", off_text(COLLS["faust_r"][1]["tr_reg_042"][0], _BAD_FACES)),
     sga18.InvalidShapeError, "tr_reg_042.off: .*duplicate"),
    ("vertex count", _set("tr_reg_042.off", off_text(*fib_sphere(300))), sga18.InvalidShapeError,
     r"tr_reg_042.off: 300 vertices; the shapes of faust_r have 20..200"),
])
def test_prepare_refuses_a_bad_layout_and_writes_nothing(tmp_path, case, edit, error, message):
    clone = write_clone(tmp_path / "clone", ["faust_r"], edit=lambda name, files: edit(name, files))
    root = tmp_path / "data"
    with pytest.raises(error, match=message):
        prep("faust_r", clone, root)
    assert nothing_written(root)
    assert issubclass(error, PrepareError)


def test_prepare_refuses_no_collection_two_copies_and_bad_test_pairs(tmp_path):
    with pytest.raises(sga18.LayoutError, match=r"no shape of tosca_r found .*Dataset/TOSCA_Isometric/vtx_5k/cat0.off"):
        prep("tosca_r", write_clone(tmp_path / "only_faust", ["faust_r"]), tmp_path / "data")
    two = write_clone(tmp_path / "two" / "a", ["tosca_r_noniso"])
    write_clone(tmp_path / "two" / "b", ["tosca_r_noniso"])
    with pytest.raises(sga18.LayoutError, match="2 folders hold tosca_r_noniso shapes"):
        prep("tosca_r_noniso", two.parent, tmp_path / "data")
    bad = write_clone(tmp_path / "pairs", ["faust_r"])
    (bad / "Dataset" / "FAUST" / "test_pairs.txt").write_text("tr_reg_000 tr_reg_100\n")
    with pytest.raises(sga18.ForeignFileError, match=r"test_pairs.txt: lines \[\['tr_reg_000', 'tr_reg_100'\]\]"):
        prep("faust_r", bad, tmp_path / "data")
    assert nothing_written(tmp_path / "data")


def test_prepare_command_line(tmp_path, prepared):
    clone = write_clone(tmp_path / "clone", ["tosca_r_noniso"], edit=_drop("corres/8_man_03.vts"))
    r = subprocess.run([sys.executable, "-m", "prodmaps.prepare", "tosca_r_noniso", "--archive", str(clone),
                        "--data-root", str(tmp_path / "data")], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.startswith("error: clone/Dataset/TOSCA_nonIsometric/vtx_5k/: 1 of"), r.stderr
    assert "corres/8_man_03.vts" in r.stderr and nothing_written(tmp_path / "data")
    r = subprocess.run([sys.executable, "-m", "prodmaps.prepare", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and all(c in r.stdout for c in ("faust_r", "tosca_r", "tosca_r_noniso"))
    r = subprocess.run([sys.executable, "-m", "prodmaps.prepare", "tosca_r", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and "SGA18_orientation_BCICP_dataset" in r.stdout and "maps/" in r.stdout


# ----------------------------------------------------------------------------- the dense rule
def reference_assignment(mesh, samples, distance):
    """The rule written out independently: all distances, then the lowest winning sample among the nearest."""
    first = {}
    for s, v in enumerate(np.asarray(samples).tolist()):
        first.setdefault(v, s)
    verts = np.array(sorted(first))
    win = np.array([first[v] for v in verts])
    if distance == "graph":
        d = dijkstra(edge_graph(mesh), directed=False, indices=verts)  # (u, n)
    else:
        d = np.linalg.norm(mesh.vertices[verts][:, None] - mesh.vertices[None], axis=2)
    nearest = d == d.min(axis=0, keepdims=True)
    return np.where(nearest, win[:, None], np.iinfo(np.int64).max).min(axis=0)


@pytest.mark.parametrize("distance", ["graph", "euclidean"])
def test_sample_assignment_follows_the_stated_rule(distance):
    v, f = fib_sphere(300)
    mesh = pm.Mesh(v * [1.0, 2.0, 0.5], f)
    rng = np.random.default_rng(3)
    samples = rng.choice(300, size=120)  # with repeats: several samples at one vertex
    assert np.unique(samples).size < samples.size
    a = ds.sample_assignment(mesh, samples, distance=distance)
    assert a.shape == (300,) and a.dtype == np.int64
    np.testing.assert_array_equal(a, reference_assignment(mesh, samples, distance))
    for v_ in np.unique(samples):  # at a sample vertex: the first sample listing it
        assert a[v_] == np.flatnonzero(samples == v_)[0]
    grid = pm.Mesh(np.array([[x, y, 0.0] for y in range(3) for x in range(3)]),
                   np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [3, 4, 7], [3, 7, 6], [4, 5, 8], [4, 8, 7]]))
    # vertex 1 is equally near vertex 0 (sample 1) and vertex 2 (sample 0): the lower sample index wins
    assert ds.sample_assignment(grid, [2, 0, 8], distance=distance)[1] == 0
    assert ds.sample_assignment(grid, [0, 2, 8], distance=distance)[1] == 0


def test_graph_rule_does_not_cross_a_gap():
    """Two fingers side by side: the Euclidean rule takes the other finger's sample, the graph rule does not."""
    u = np.linspace(0, 1, 11)
    top = np.column_stack([np.r_[u, u], np.r_[np.zeros(11), np.full(11, 0.1)], np.zeros(22)])  # a thin strip
    strip_f = np.array([[i, i + 1, 11 + i] for i in range(10)] + [[i + 1, 12 + i, 11 + i] for i in range(10)])
    v = np.vstack([top, top + [0, 0.3, 0], [[1.5, 0.0, 0], [1.5, 0.4, 0]]])
    f = np.vstack([strip_f, strip_f + 22, [[10, 44, 21], [21, 44, 45], [21, 45, 32], [32, 45, 43]]])
    mesh = pm.Mesh(v, f)  # a U: the fingers are joined only at x = 1.5
    samples = np.array([0, 22])  # the left end of each finger
    g = ds.sample_assignment(mesh, samples)
    e = ds.sample_assignment(mesh, samples, distance="euclidean")
    assert np.all(g[:22] == 0) and np.all(g[22:44] == 1)
    assert np.all(e[:22] == 0) and e[43] == 1  # Euclidean: fine here, the gap is larger than the distances
    samples = np.array([0, 40])  # finger 2 sampled at its tip only; its root is nearer finger 1's sample in R^3
    assert ds.sample_assignment(mesh, samples)[22] == 1
    assert ds.sample_assignment(mesh, samples, distance="euclidean")[22] == 0


def test_sample_functions_refuse_bad_input():
    v, f = fib_sphere(50)
    mesh = pm.Mesh(v, f)
    with pytest.raises(ValueError, match=r"samples indices out of range: they must be in \[0, 50\)"):
        ds.sample_assignment(mesh, [3, 50])
    with pytest.raises(ValueError, match="non-empty 1-D"):
        ds.sample_assignment(mesh, np.zeros(0, dtype=int))
    with pytest.raises(ValueError, match="distance must be one of"):
        ds.sample_assignment(mesh, [1], distance="geodesic")
    with pytest.raises(TypeError, match="expected a prodmaps.Mesh"):
        ds.sample_assignment(v, [1])
    with pytest.raises(ValueError, match=r"one entry per sample; got shapes \(3,\) and \(2,\)"):
        ds.p2p_from_samples([1, 2, 3], [4, 5], mesh)
    with pytest.raises(ValueError, match="integer vertex indices"):
        ds.p2p_from_samples([1.5, 2.0], [4, 5], mesh)


# ----------------------------------------------------------------------------- the dataset API
def test_ground_truth_is_exact_at_the_samples_and_follows_the_rule(use):
    for name, pairs in (("faust_r", [("tr_reg_004", "tr_reg_071"), ("tr_reg_071", "tr_reg_004")]),
                        ("tosca_r", [("centaur0", "centaur5"), ("michael19", "michael3")]),
                        ("tosca_r_noniso", [("8_gorilla_01", "8_woman_12")])):
        assert ds.ground_truth_kind(name) == "samples"
        for a, b in pairs:
            s1, s2 = COLLS[name][2][a], COLLS[name][2][b]
            np.testing.assert_array_equal(ds.sample_vertices(name, a), s1)
            m2 = ds.load_shape(name, b)
            gt = ds.ground_truth(name, a, b)
            assert gt.shape == (m2.n_vertices,) and gt.dtype == np.int64
            first = {}
            for s, v in enumerate(s2.tolist()):
                first.setdefault(v, s)
            for v, s in first.items():  # exact at every sample vertex (the first sample listing it)
                assert gt[v] == s1[s]
            np.testing.assert_array_equal(gt, s1[reference_assignment(m2, s2, "graph")])
            # geometry (spheres, each stretched): an image lies far nearer the vertex's direction than by chance
            m1 = ds.load_shape(name, a)
            d1 = m1.vertices / np.linalg.norm(m1.vertices, axis=1, keepdims=True)
            d2 = m2.vertices / np.linalg.norm(m2.vertices, axis=1, keepdims=True)
            chance = np.random.default_rng(0).integers(m1.n_vertices, size=m2.n_vertices)
            assert np.sum(d1[gt] * d2, axis=1).mean() > 0.8 > 0.2 > np.sum(d1[chance] * d2, axis=1).mean()
        a = pairs[0][0]
        np.testing.assert_array_equal(ds.ground_truth(name, a, a), np.arange(ds.load_shape(name, a).n_vertices))


def test_samples_are_shared_between_samples_on_a_vertex(use):
    s = COLLS["faust_r"][2]["tr_reg_050"]
    assert np.unique(s).size < s.size  # the synthetic collection has shared vertices, as the real one


def test_pairs_classes_and_groups(use):
    assert ds.shape_ids("faust_r") == [f"tr_reg_{i:03d}" for i in range(100)]
    assert ds.shape_class("faust_r", "tr_reg_057") == "5"
    assert ds.correspondence_group("faust_r", "tr_reg_057") == "faust"
    assert len(list(ds.pairs("faust_r", "intra"))) == 900 and len(list(ds.pairs("faust_r", "inter"))) == 9000
    p = list(ds.pairs("faust_r", "all", n=20, seed=4))
    assert p == list(ds.pairs("faust_r", "all", n=20, seed=4)) != list(ds.pairs("faust_r", "all", n=20, seed=5))
    assert len(set(p)) == 20
    intra = list(ds.pairs("faust_r", "intra", n=20, seed=0))
    assert all(int(a[-3:]) // 10 == int(b[-3:]) // 10 and a != b for a, b in intra)
    inter = list(ds.pairs("faust_r", "inter", n=20, seed=0))
    assert all(int(a[-3:]) // 10 != int(b[-3:]) // 10 for a, b in inter)
    assert intra == sorted(intra)  # kept in enumeration order
    tosca = list(ds.pairs("tosca_r", "intra"))
    sizes = {"cat": 11, "centaur": 6, "david": 7, "dog": 9, "horse": 8, "michael": 20, "victoria": 12, "wolf": 3}
    assert len(tosca) == sum(k * (k - 1) for k in sizes.values())
    assert all(ds.shape_class("tosca_r", a) == ds.shape_class("tosca_r", b) for a, b in tosca)
    assert ds.correspondence_group("tosca_r", "cat3") == "cat"
    assert list(ds.pairs("tosca_r", "inter")) == []
    with pytest.raises(ValueError, match="only 0 exist .no ground truth between classes"):
        ds.pairs("tosca_r", "inter", n=1)
    with pytest.raises(ValueError, match="different correspondence groups .classes 'cat' and 'dog'"):
        ds.ground_truth("tosca_r", "cat0", "dog1")
    noniso_inter = list(ds.pairs("tosca_r_noniso", "inter"))
    assert len(noniso_inter) == 24 * 23 - (5 * 4 + 7 * 6 + 12 * 11)
    assert ds.ground_truth("tosca_r_noniso", *noniso_inter[0]).shape == (
        ds.load_shape("tosca_r_noniso", noniso_inter[0][1]).n_vertices,)
    with pytest.raises(ValueError, match="identity ground truth"):
        ds.sample_vertices("faust", "tr_reg_000")


def test_ground_truth_between_a_registration_and_its_remesh(use):
    reg, rem = ds.load_shape("faust", "tr_reg_025"), ds.load_shape("faust_r", "tr_reg_025")
    s_rem = COLLS["faust_r"][2]["tr_reg_025"]
    p_rf = ds.ground_truth_between(("faust", "tr_reg_025"), ("faust_r", "tr_reg_025"))  # remesh -> registration
    assert p_rf.shape == (rem.n_vertices,) and p_rf.max() < N_TPL
    np.testing.assert_array_equal(p_rf, SAMPLE_TPL[reference_assignment(rem, s_rem, "graph")])
    p_fr = ds.ground_truth_between(("faust_r", "tr_reg_025"), ("faust", "tr_reg_025"))  # registration -> remesh
    assert p_fr.shape == (N_TPL,) and p_fr.max() < rem.n_vertices
    np.testing.assert_array_equal(p_fr[SAMPLE_TPL], s_rem)  # exact at the (distinct) template samples
    np.testing.assert_array_equal(p_fr, ds.p2p_from_samples(s_rem, SAMPLE_TPL, reg))
    # one pose in two triangulations: the images lie on the (same) surface, far nearer than by chance
    chance = np.random.default_rng(0).integers(N_TPL, size=rem.n_vertices)
    assert (np.linalg.norm(reg.vertices[p_rf] - rem.vertices, axis=1).mean()
            < 0.5 * np.linalg.norm(reg.vertices[chance] - rem.vertices, axis=1).mean())
    # any FAUST registration corresponds to any faust_r shape through the template
    other = ds.ground_truth_between(("faust", "tr_reg_001"), ("faust_r", "tr_reg_057"))
    np.testing.assert_array_equal(other, SAMPLE_TPL[ds.sample_assignment(ds.load_shape("faust_r", "tr_reg_057"),
                                                                         COLLS["faust_r"][2]["tr_reg_057"])])
    np.testing.assert_array_equal(ds.ground_truth_between(("faust_r", "tr_reg_003"), ("faust_r", "tr_reg_025")),
                                  ds.ground_truth("faust_r", "tr_reg_003", "tr_reg_025"))
    with pytest.raises(ValueError, match="no ground truth between datasets 'tosca_r' and 'faust_r'"):
        ds.ground_truth_between(("tosca_r", "cat0"), ("faust_r", "tr_reg_000"))
    with pytest.raises(ValueError, match="group 'cat'.*name no 'faust' template"):
        ds.ground_truth_between(("tosca_r", "cat0"), ("faust", "tr_reg_000"))
    with pytest.raises(ValueError, match="unknown shape id 'tr_reg_002' in dataset 'faust'"):
        ds.ground_truth_between(("faust", "tr_reg_002"), ("faust_r", "tr_reg_000"))


def test_a_variant_of_a_remeshed_shape_composes_with_the_samples_rule(use, tmp_path):
    rem = use / "faust_r" / "remeshed"
    rem.mkdir()
    try:
        base = ds.load_shape("faust_r", "tr_reg_010")
        pm.save_mesh(rem / "tr_reg_010_copy.ply", base)
        perm = np.roll(np.arange(base.n_vertices), 3)  # a variant vertex k is base vertex perm[k]: relabelled copy
        np.savetxt(rem / "tr_reg_010_copy.gt_to_family.txt", perm, fmt="%d")
        ds.clear_cache()
        assert ds.variants("faust_r") == ["tr_reg_010_copy"]
        np.testing.assert_array_equal(ds.ground_truth("faust_r", "tr_reg_033", "tr_reg_010_copy"),
                                      ds.ground_truth("faust_r", "tr_reg_033", "tr_reg_010")[perm])
    finally:
        for p in rem.iterdir():
            p.unlink()
        rem.rmdir()
        ds.clear_cache()


def test_unprepared_and_damaged_sample_datasets(tmp_path, monkeypatch, prepared):
    monkeypatch.setenv("PRODMAPS_DATA", str(tmp_path))
    ds.clear_cache()
    with pytest.raises(ds.DatasetNotPreparedError) as e:
        ds.shape_ids("faust_r")
    assert "github.com/llorz/SGA18_orientation_BCICP_dataset" in str(e.value)
    assert "python -m prodmaps.prepare faust_r --archive" in str(e.value) and "licences" in str(e.value)
    shutil.copytree(prepared[0] / "tosca_r", tmp_path / "tosca_r")
    (tmp_path / "tosca_r" / "samples" / "cat4.txt").unlink()
    ds.clear_cache()
    with pytest.raises(ds.DatasetNotPreparedError, match=r"missing \(first \['samples/cat4.txt'\]\)"):
        ds.shape_ids("tosca_r")
    (tmp_path / "tosca_r" / "manifest.json").unlink()
    ds.clear_cache()
    with pytest.raises(ds.DatasetNotPreparedError, match="has no manifest.json"):
        ds.shape_ids("tosca_r")
    ds.clear_cache()
