"""Dataset API on the embedded anny_humans data (and the errors for unprepared datasets)."""

import shutil
from pathlib import Path

import numpy as np
import pytest

import prodmaps as pm
import prodmaps.datasets as ds
from prodmaps.datasets import dataset_dir as ds_dir

NAME = "anny_humans"
VARIANT_SIZES = {"anny_000_thin": 13535, "anny_013_remesh_iso": 4154, "anny_025_remesh_nonuniform": 6644}


@pytest.fixture(autouse=True)
def default_root(monkeypatch):
    monkeypatch.delenv("PRODMAPS_DATA", raising=False)
    yield


def test_registry_and_root(monkeypatch, tmp_path):
    assert ds.names() == ["anny_humans", "faust", "tosca", "faust_r", "tosca_r", "tosca_r_noniso"]
    # the embedded data ship inside the installed package, wherever the repository is
    assert ds.dataset_dir(NAME) == Path(pm.__file__).resolve().parent / "data" / NAME
    monkeypatch.setenv("XDG_DATA_HOME", str(tmp_path / "xdg"))
    assert ds.data_root() == tmp_path / "xdg" / "prodmaps"  # prepared datasets, when PRODMAPS_DATA is unset
    monkeypatch.setenv("PRODMAPS_DATA", str(tmp_path))
    assert ds.data_root() == tmp_path.resolve()
    assert ds.dataset_dir("faust") == tmp_path.resolve() / "faust"
    assert ds.dataset_dir(NAME) == ds.embedded_root() / NAME  # not under PRODMAPS_DATA: the embedded copy
    (tmp_path / NAME / "shapes").mkdir(parents=True)
    assert ds.dataset_dir(NAME) == tmp_path.resolve() / NAME  # a copy under PRODMAPS_DATA wins
    with pytest.raises(ValueError, match="unknown dataset 'shrec'"):
        ds.shape_ids("shrec")


def test_every_default_shape_loads_in_one_triangulation():
    ids = ds.shape_ids(NAME)
    assert ids == [f"anny_{i:03d}" for i in range(60)]
    first = ds.load_shape(NAME, ids[0])
    assert (first.n_vertices, first.n_faces) == (5002, 10000)
    for sid in ids:
        m = ds.load_shape(NAME, sid)
        assert isinstance(m, pm.Mesh) and m.name == sid
        np.testing.assert_array_equal(m.faces, first.faces)
    assert ds.load_shape(NAME, "anny_013") is ds.load_shape(NAME, "anny_013")  # cached
    assert not np.array_equal(ds.load_shape(NAME, "anny_013").vertices, first.vertices)


def test_variants_listed_and_loaded():
    assert ds.variants(NAME) == sorted(VARIANT_SIZES)
    assert ds.shape_ids(NAME, include_variants=True)[60:] == sorted(VARIANT_SIZES)
    for vid, n in VARIANT_SIZES.items():
        assert ds.load_shape(NAME, vid).n_vertices == n
        assert ds.base_shape(NAME, vid) == vid[:8]
    assert ds.base_shape(NAME, "anny_007") == "anny_007"
    assert ds.shape_class(NAME, "anny_025_remesh_nonuniform") == "2"
    with pytest.raises(ValueError, match="unknown shape id 'anny_999'"):
        ds.load_shape(NAME, "anny_999")


def test_pair_counts_and_kinds():
    intra = list(ds.pairs(NAME, "intra"))
    inter = list(ds.pairs(NAME, "inter"))
    every = list(ds.pairs(NAME, "all"))
    assert len(intra) == 6 * 10 * 9
    assert len(inter) == 60 * 59 - 540
    assert sorted(every) == sorted(intra + inter)
    assert all(a != b for a, b in every)
    assert all(int(a[-3:]) // 10 == int(b[-3:]) // 10 for a, b in intra)
    assert all(int(a[-3:]) // 10 != int(b[-3:]) // 10 for a, b in inter)
    assert ("anny_000", "anny_013") in inter and ("anny_013", "anny_000") in inter  # ordered pairs


def test_seeded_random_pairs():
    p20 = list(ds.pairs(NAME, "intra", n=20, seed=0))
    assert len(p20) == 20 == len(set(p20))
    assert p20 == list(ds.pairs(NAME, "intra", n=20, seed=0))
    assert p20 != list(ds.pairs(NAME, "intra", n=20, seed=1))
    assert set(p20) <= set(ds.pairs(NAME, "intra"))
    assert len(list(ds.pairs(NAME, "all", n=0))) == 0
    with pytest.raises(ValueError, match="only 540 exist"):
        ds.pairs(NAME, "intra", n=541)
    with pytest.raises(ValueError, match="kind must be one of"):
        ds.pairs(NAME, "cross")


def test_identity_ground_truth_for_all_family_pairs():
    ident = np.arange(5002)
    for a, b in ds.pairs(NAME, "all"):
        gt = ds.ground_truth(NAME, a, b)
        assert gt.shape == (5002,) and gt.dtype == np.int64
        np.testing.assert_array_equal(gt, ident)


@pytest.mark.parametrize("vid", sorted(VARIANT_SIZES))
def test_variants_map_onto_family(vid):
    base = ds.base_shape(NAME, vid)
    var, fam = ds.load_shape(NAME, vid), ds.load_shape(NAME, base)
    text = np.loadtxt(ds_dir(NAME) / "remeshed" / f"{vid}.gt_to_family.txt", dtype=np.int64)
    # family -> variant: p2p_21 (n_variant,) is the variant's gt_to_family, for any family shape
    for other in (base, "anny_042"):
        np.testing.assert_array_equal(ds.ground_truth(NAME, other, vid), text)
    d = np.linalg.norm(var.vertices - fam.vertices[text], axis=1)
    assert d.mean() < 0.01 and d.max() < 0.04  # metres; SOURCE.md: mean 6-8 mm, max < 3.9 cm
    # variant -> family: p2p_21 (5002,) closest variant vertex on the base shape
    back = ds.ground_truth(NAME, vid, base)
    assert back.shape == (5002,) and back.min() >= 0 and back.max() < var.n_vertices
    d_back = np.linalg.norm(fam.vertices - var.vertices[back], axis=1)
    assert d_back.mean() < 0.01 and d_back.max() < 0.04
    if vid == "anny_000_thin":  # the first 5002 vertices are the family vertices
        np.testing.assert_array_equal(text[:5002], np.arange(5002))
        np.testing.assert_array_equal(back, np.arange(5002))
    # variant -> variant: composition, (n2,) into variant 1
    other = "anny_013_remesh_iso" if vid != "anny_013_remesh_iso" else "anny_000_thin"
    vv = ds.ground_truth(NAME, vid, other)
    assert vv.shape == (ds.load_shape(NAME, other).n_vertices,) and vv.max() < var.n_vertices
    np.testing.assert_array_equal(vv, back[ds.ground_truth(NAME, base, other)])


def test_unprepared_datasets_name_the_script(monkeypatch, tmp_path):
    monkeypatch.setenv("PRODMAPS_DATA", str(tmp_path))
    with pytest.raises(ds.DatasetNotPreparedError) as e:
        ds.shape_ids("faust")
    msg = str(e.value)
    assert "prodmaps.prepare faust --archive MPI-FAUST.zip" in msg and "faust.is.tue.mpg.de" in msg
    assert "any subset works" in msg and "--archive FundCG-s1-2018 --archive Laplacian-Mesh" in msg
    with pytest.raises(ds.DatasetNotPreparedError, match="-m prodmaps.prepare tosca --archive toscahires-asci.zip"):
        ds.load_shape("tosca", "cat0")
    monkeypatch.setattr(ds, "embedded_root", lambda: tmp_path / "no_package_data")
    ds.clear_cache()
    with pytest.raises(FileNotFoundError, match="ships inside the package"):
        list(ds.pairs("anny_humans"))
    monkeypatch.undo()
    ds.clear_cache()


def test_checksums(monkeypatch, tmp_path):
    res = ds.verify_checksums(NAME)
    assert len(res) == 67 and all(res.values())
    shutil.copytree(ds_dir(NAME), tmp_path / NAME)
    monkeypatch.setenv("PRODMAPS_DATA", str(tmp_path))
    p = tmp_path / NAME / "shapes" / "anny_007.ply"
    data = bytearray(p.read_bytes())
    data[-1] ^= 1
    p.write_bytes(bytes(data))
    (tmp_path / NAME / "template_vertex_ids.txt").unlink()
    res = ds.verify_checksums(NAME, strict=False)
    assert sorted(k for k, ok in res.items() if not ok) == ["./shapes/anny_007.ply", "./template_vertex_ids.txt"]
    with pytest.raises(ValueError, match="2 of 67 files"):
        ds.verify_checksums(NAME)
