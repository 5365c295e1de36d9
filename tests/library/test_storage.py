"""Saved work: bases and maps in checked files (Basis.save / pm.load_basis, pm.save_map / pm.load_map)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.files import write_checked_npz


@pytest.fixture(scope="module")
def two():
    m1, m2 = pm.mesh.ellipsoid(2), pm.mesh.ellipsoid(2, axes=(1.0, 0.7, 0.5))
    return m1, m2, pm.eigenbasis(m1, 8), pm.eigenbasis(m2, 10)


def _same_basis(a, b):
    for name in ("vecs", "evals"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), name  # bit for bit
        assert x.flags.f_contiguous == y.flags.f_contiguous, name  # ... in the same memory order
    if a.mass_is_diagonal:
        assert b.mass_is_diagonal and a.mass.tobytes() == b.mass.tobytes()
    else:
        assert not b.mass_is_diagonal and (a.mass != b.mass).nnz == 0
        assert a.mass.toarray().tobytes() == b.mass.toarray().tobytes()
    assert (a.name, a.kind, a.n, a.k) == (b.name, b.kind, b.n, b.k)


def test_saved_bases_load_bit_for_bit(tmp_path, two):
    m1, _, b1, _ = two
    cloud = pm.PointCloud(m1.vertices, name="points")
    bases = {"cotan": b1, "cloud": pm.eigenbasis(cloud, 6), "robust": pm.eigenbasis(m1, 6, kind="robust"),
             "fem": pm.eigenbasis(m1, 6, mass="full"), "fourier": pm.fourier_basis(64, 5)}
    assert not bases["fem"].mass_is_diagonal
    for label, b in bases.items():
        path = b.save(tmp_path / f"{label}.basis")  # any name: saved as given, no .npz appended
        assert path == tmp_path / f"{label}.basis" and path.is_file()
        back = pm.load_basis(path)
        _same_basis(b, back)
    assert pm.load_basis(tmp_path / "cloud.basis").kind == "point_cloud"
    assert pm.load_basis(tmp_path / "fourier.basis").kind == "fourier"
    # a loaded basis is a basis: the same transfer as the original
    f = m1.vertices
    np.testing.assert_array_equal(pm.load_basis(tmp_path / "cotan.basis").project(f), b1.project(f))


def test_basis_file_records_its_metadata(tmp_path, two):
    _, _, b1, _ = two
    path = b1.save(tmp_path / "b.npz")
    with np.load(path) as z:
        meta = json.loads(str(z["__metadata__"]))
        assert sorted(z.files) == ["__metadata__", "evals", "mass", "vecs"]
    assert (meta["format"], meta["n"], meta["k"], meta["kind"], meta["name"]) == ("prodmaps.basis", 162, 8, "cotan",
                                                                                  "ellipsoid")
    assert meta["prodmaps_version"] == pm.__version__ and len(meta["checksum"]) == 64


def test_damaged_or_wrong_files_are_refused_by_name(tmp_path, two):
    _, _, b1, b2 = two
    good = b1.save(tmp_path / "b.npz")
    with np.load(good) as z:
        arrays = {k: z[k] for k in z.files}
    # a changed array under the old checksum
    arrays_changed = dict(arrays, vecs=arrays["vecs"] * (1 + 1e-12))
    np.savez(tmp_path / "changed.npz", **arrays_changed)
    with pytest.raises(ValueError, match="checksum mismatch"):
        pm.load_basis(tmp_path / "changed.npz")
    # arrays that contradict the metadata (a consistent checksum, a lying n)
    meta = json.loads(str(arrays["__metadata__"]))
    write_checked_npz(tmp_path / "lying.npz", "prodmaps.basis", {k: arrays[k] for k in ("vecs", "evals", "mass")},
                      {**{k: meta[k] for k in ("kind", "name")}, "n": 100, "k": 8})
    with pytest.raises(ValueError, match=r"contradict the metadata \(n=100, k=8\)"):
        pm.load_basis(tmp_path / "lying.npz")
    # not a prodmaps file at all
    np.savez(tmp_path / "plain.npz", vecs=arrays["vecs"])
    (tmp_path / "text.npz").write_text("hello")
    np.save(tmp_path / "array.npy", arrays["vecs"])
    for name, message in (("plain.npz", "without prodmaps metadata"), ("text.npz", "cannot be read as an .npz"),
                          ("array.npy", "not a prodmaps prodmaps.basis file")):
        with pytest.raises(ValueError, match=message) as info:
            pm.load_basis(tmp_path / name)
        assert str(info.value).startswith(str(tmp_path / name))
    with pytest.raises(FileNotFoundError):
        pm.load_basis(tmp_path / "missing.npz")
    # the wrong kind of prodmaps file: each loader names the other
    C = pm.fmap_from_p2p(np.arange(162), b1, b2)
    mpath = pm.save_map(tmp_path / "C.npz", C, b1, b2)
    with pytest.raises(ValueError, match=r"a prodmaps\.fmap file, not a prodmaps\.basis file; read it with "
                                         r"pm\.load_map\(path\)"):
        pm.load_basis(mpath)
    with pytest.raises(ValueError, match=r"a prodmaps\.basis file, not a prodmaps\.fmap file; read it with "
                                         r"pm\.load_basis\(path\)"):
        pm.load_map(good)


def test_functional_maps_are_saved_with_their_bases_sizes_and_checked_on_load(tmp_path, two):
    m1, m2, b1, b2 = two
    C = pm.fmap_from_p2p(np.arange(162), b1, b2)  # (10, 8)
    path = pm.save_map(tmp_path / "C_12.npz", C, b1, b2)
    back = pm.load_map(path, b1, b2)
    assert back.tobytes() == C.tobytes() and back.shape == (10, 8)
    info = pm.storage.map_info(path)
    assert (info["format"], info["k"], info["n"], info["names"]) == ("prodmaps.fmap", [8, 10], [162, 162],
                                                                      ["ellipsoid", "ellipsoid"])
    np.testing.assert_array_equal(pm.load_map(path), C)  # the bases are optional
    np.testing.assert_array_equal(pm.load_map(path, pm.eigenbasis(m1, 12), m2), C)  # more columns: fine
    with pytest.raises(ValueError, match=r"needs at least 10 columns in basis_2, which has 6"):
        pm.load_map(path, b1, b2.truncate(6))
    with pytest.raises(ValueError, match=r"belongs to a shape 1 of 162 vertices, not 42"):
        pm.load_map(path, pm.eigenbasis(pm.mesh.ellipsoid(1), 8), b2)
    with pytest.raises(ValueError, match=r"needs at least 8 columns in basis_1, which has 5"):
        pm.save_map(tmp_path / "x.npz", C, b1.truncate(5), b2)
    with pytest.raises(ValueError, match="neither|expected a functional map"):
        pm.save_map(tmp_path / "x.npz", C.astype(np.float32)[None], b1, b2)


def test_point_maps_are_saved_with_their_vertex_counts_and_checked_on_load(tmp_path, two):
    m1, m2, b1, _ = two
    cloud = pm.PointCloud(m2.vertices[:100], name="part")
    p2p_21 = np.arange(100)[::-1].copy()  # for each cloud point a vertex of mesh 1
    path = pm.save_map(tmp_path / "p2p_21.npz", p2p_21, m1, cloud)
    assert pm.storage.map_info(path)["n"] == [162, 100]
    back = pm.load_map(path, m1, cloud)
    assert back.dtype == np.int64 and back.tobytes() == p2p_21.astype(np.int64).tobytes()
    np.testing.assert_array_equal(pm.load_map(path, b1, 100), p2p_21)  # a basis or a count stands for a shape
    with pytest.raises(ValueError, match="belongs to a shape 2 of 100 vertices, not 162"):
        pm.load_map(path, m1, m2)
    with pytest.raises(ValueError, match=r"needs shape_1"):
        pm.save_map(tmp_path / "x.npz", p2p_21)
    with pytest.raises(ValueError, match=r"has 100 entries but shape 2 has 162 vertices .*p2p_12"):
        pm.save_map(tmp_path / "x.npz", p2p_21, m1, m2)
    with pytest.raises(ValueError, match="points to vertex 161 but shape 1 has 100 vertices"):
        pm.save_map(tmp_path / "x.npz", np.arange(162)[::-1].copy(), 100)
    with pytest.raises(TypeError, match="shape_1 must be"):
        pm.save_map(tmp_path / "x.npz", p2p_21, "mesh.ply")
