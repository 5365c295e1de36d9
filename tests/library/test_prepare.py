"""Preparation scripts on small archives built here in the FAUST and TOSCA layouts.

The fake FAUST uses the real counts (6890 vertices, 13776 triangles: a closed genus-0 mesh
has F = 2V - 4, so the convex hull of 6890 points on a sphere has exactly FAUST's counts);
the refusal tests use 12 shapes instead of 100 (``n_shapes`` parameter) to stay fast.
"""

import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import ConvexHull

import prodmaps.datasets as ds
from prodmaps.datasets import dataset_dir as ds_dir
from prodmaps.prepare import faust, tosca
from prodmaps.prepare import variants as variants
from prodmaps.prepare.archive import PrepareError

SCRIPTS = Path(__file__).resolve().parents[2] / "data_scripts"  # the thin command-line wrappers


def fib_sphere(n):
    i = np.arange(n) + 0.5
    phi, th = np.arccos(1 - 2 * i / n), np.pi * (1 + 5**0.5) * i
    v = np.column_stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)])
    return v, ConvexHull(v).simplices.astype(np.int64)


def ply_bytes(v, f, ascii=False):
    head = (f"ply\nformat {'ascii' if ascii else 'binary_little_endian'} 1.0\nelement vertex {len(v)}\n"
            "property float x\nproperty float y\nproperty float z\n"
            f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n").encode()
    if ascii:
        body = "".join(f"{a:.6f} {b:.6f} {c:.6f}\n" for a, b, c in v) + "".join(f"3 {a} {b} {c}\n" for a, b, c in f)
        return head + body.encode()
    rec = np.zeros(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rec["n"], rec["i"] = 3, f
    return head + np.asarray(v, "<f4").tobytes() + rec.tobytes()


def write_zip(path, members, extra=()):
    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as z:
        for name, data in members.items():
            z.writestr(name, data)
        for info, data in extra:
            z.writestr(info, data)
    return path


def nothing_written(root):
    """No dataset folder, no temporary leftovers."""
    return not root.exists() or list(root.iterdir()) == []


# --------------------------------------------------------------------------------- FAUST
FAUST_DIR = "MPI-FAUST/training/registrations/"


@pytest.fixture(scope="module")
def faust_shapes():
    v, f = fib_sphere(6890)
    assert f.shape == (13776, 3)
    rng = np.random.default_rng(0)
    shapes = {i: (v * rng.uniform(0.5, 1.5, size=3), f) for i in range(100)}
    members = {f"{FAUST_DIR}tr_reg_{i:03d}.ply": ply_bytes(*shapes[i], ascii=i < 2) for i in range(100)}
    members["MPI-FAUST/training/scans/tr_scan_000.ply"] = b"not needed"
    members["MPI-FAUST/README.txt"] = b"readme"
    return shapes, members


def small(members, n=12):
    return {k: d for k, d in members.items() if "tr_reg_" not in k or int(k[-7:-4]) < n}


def test_faust_prepare_and_dataset_api(tmp_path, faust_shapes, monkeypatch, capsys):
    shapes, members = faust_shapes
    archive = write_zip(tmp_path / "MPI-FAUST.zip", members)
    root = tmp_path / "data"
    out = faust.prepare_faust(archive, root)
    assert out == root / "faust"
    assert "wrote 100 shapes" in capsys.readouterr().out
    assert sorted(p.name for p in root.iterdir()) == ["faust"]  # no temporary leftovers
    man = json.loads((out / "manifest.json").read_text())
    assert len(man["shapes"]) == 100 and man["n_vertices"] == 6890 and len(man["source"][0]["sha256"]) == 64
    assert man["subset"] is False
    monkeypatch.setenv("PRODMAPS_DATA", str(root))
    assert ds.shape_ids("faust") == [f"tr_reg_{i:03d}" for i in range(100)]
    assert len(list(ds.pairs("faust", "intra"))) == 900
    assert len(list(ds.pairs("faust", "inter"))) == 9000
    m = ds.load_shape("faust", "tr_reg_042")
    np.testing.assert_allclose(m.vertices, shapes[42][0].astype(np.float32), rtol=0, atol=0)
    np.testing.assert_array_equal(m.faces, shapes[42][1])
    np.testing.assert_allclose(ds.load_shape("faust", "tr_reg_001").vertices, shapes[1][0], atol=1e-6)  # ASCII
    np.testing.assert_array_equal(ds.ground_truth("faust", "tr_reg_003", "tr_reg_071"), np.arange(6890))
    assert all(ds.verify_checksums("faust").values())
    with pytest.raises(PrepareError, match="already exists; pass --force"):
        faust.prepare_faust(archive, root)


def test_faust_from_unpacked_folder_and_force(tmp_path, faust_shapes):
    folder = tmp_path / "unpacked"
    for name, data in small(faust_shapes[1]).items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(data)
    root = tmp_path / "data"
    faust.prepare_faust(folder, root, n_shapes=12, verbose=False)
    old = (root / "faust" / "SHA256SUMS").read_text()
    faust.prepare_faust(folder, root, n_shapes=12, verbose=False, force=True)
    assert (root / "faust" / "SHA256SUMS").read_text() == old
    assert sorted(p.name for p in root.iterdir()) == ["faust"]


@pytest.mark.parametrize("evil", ["MPI-FAUST/../../evil.ply", "/tmp/evil.ply", "C:/evil.ply", "a\\..\\evil.ply"])
def test_faust_refuses_escaping_member(tmp_path, faust_shapes, evil):
    archive = write_zip(tmp_path / "a.zip", small(faust_shapes[1]), [(zipfile.ZipInfo(evil), b"boom")])
    root = tmp_path / "data"
    with pytest.raises(PrepareError, match="refusing archive: member"):
        faust.prepare_faust(archive, root, n_shapes=12)
    assert nothing_written(root) and not (tmp_path / "evil.ply").exists()


def test_faust_refuses_symlink_member(tmp_path, faust_shapes):
    info = zipfile.ZipInfo(FAUST_DIR + "link.ply")
    info.external_attr = (0o120777 << 16)
    archive = write_zip(tmp_path / "a.zip", small(faust_shapes[1]), [(info, "/etc/passwd")])
    with pytest.raises(PrepareError, match="symbolic link"):
        faust.prepare_faust(archive, tmp_path / "data", n_shapes=12)
    assert nothing_written(tmp_path / "data")


def test_faust_refuses_truncated_member_without_partial_output(tmp_path, faust_shapes):
    members = small(faust_shapes[1])
    key = FAUST_DIR + "tr_reg_007.ply"
    members[key] = members[key][: len(members[key]) // 2]  # stored intact in the zip, cut in the PLY body
    root = tmp_path / "data"
    with pytest.raises(PrepareError, match=r"tr_reg_007\.ply.*truncated"):
        faust.prepare_faust(write_zip(tmp_path / "a.zip", members), root, n_shapes=12)
    assert nothing_written(root)  # the 7 shapes already converted were removed with the staging folder


def test_faust_refuses_truncated_archive(tmp_path, faust_shapes):
    good = write_zip(tmp_path / "good.zip", small(faust_shapes[1]))
    cut = tmp_path / "cut.zip"
    cut.write_bytes(good.read_bytes()[: int(good.stat().st_size * 0.6)])
    with pytest.raises(PrepareError, match="truncated"):
        faust.prepare_faust(cut, tmp_path / "data", n_shapes=12)
    assert nothing_written(tmp_path / "data")


def test_faust_refuses_wrong_counts_and_triangulations(tmp_path, faust_shapes):
    root = tmp_path / "data"
    members = small(faust_shapes[1])
    members[FAUST_DIR + "tr_reg_009.ply"] = ply_bytes(*fib_sphere(6000))
    with pytest.raises(PrepareError, match="tr_reg_009.ply: 6000 vertices and 11996 faces; FAUST registrations "
                                           "have 6890 and 13776"):
        faust.prepare_faust(write_zip(tmp_path / "a.zip", members), root, n_shapes=12)
    assert nothing_written(root)
    members = small(faust_shapes[1])
    v, f = faust_shapes[0][3]
    members[FAUST_DIR + "tr_reg_003.ply"] = ply_bytes(v, np.roll(f, 1, axis=0))
    with pytest.raises(PrepareError, match="tr_reg_003.ply: triangulation differs"):
        faust.prepare_faust(write_zip(tmp_path / "b.zip", members), root, n_shapes=12)
    members = small(faust_shapes[1])
    members[FAUST_DIR + "tr_reg_012.ply"] = members[FAUST_DIR + "tr_reg_004.ply"]
    with pytest.raises(PrepareError, match=r"unexpected \['012'\]"):
        faust.prepare_faust(write_zip(tmp_path / "c.zip", members), root, n_shapes=12)
    with pytest.raises(PrepareError, match="no tr_reg_XXX.ply or .off found"):
        faust.prepare_faust(write_zip(tmp_path / "d.zip", {"x.txt": b"x"}), root)
    assert nothing_written(root)


def test_faust_cli_reports_refusal(tmp_path, faust_shapes):
    archive = write_zip(tmp_path / "a.zip", small(faust_shapes[1]), [(zipfile.ZipInfo("../evil.ply"), b"x")])
    r = subprocess.run([sys.executable, str(SCRIPTS / "prepare_faust.py"), "--archive", str(archive),
                        "--data-root", str(tmp_path / "data")], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2
    assert r.stderr.startswith("error: refusing archive: member '../evil.ply'")
    assert nothing_written(tmp_path / "data")


# --------------------------------------------------------------------------------- TOSCA
TOSCA_N = {"cat": 60, "centaur": 64, "david": 70, "dog": 56, "gorilla": 50, "horse": 58, "michael": 70,
           "victoria": 66, "wolf": 4344}


def vert_bytes(v):
    return "".join(f"{a:.6f} {b:.6f} {c:.6f}\n" for a, b, c in v).encode()


def tri_bytes(f):
    return "".join(f"{a + 1} {b + 1} {c + 1}\n" for a, b, c in f).encode()


@pytest.fixture(scope="module")
def tosca_members():
    rng = np.random.default_rng(1)
    members, shapes = {}, {}
    for c, n in TOSCA_N.items():
        v, f = fib_sphere(n)
        for i in range(2 if c != "wolf" else 3):
            vi = v * rng.uniform(0.5, 1.5, size=3)
            shapes[f"{c}{i}"] = (vi, f)
            members[f"toscahires-asci/{c}{i}.vert"] = vert_bytes(vi)
            members[f"toscahires-asci/{c}{i}.tri"] = tri_bytes(f)
    members["toscahires-asci/lion0.vert"] = vert_bytes(np.eye(3))
    return members, shapes


def test_tosca_prepare_and_dataset_api(tmp_path, tosca_members, monkeypatch):
    members, shapes = tosca_members
    root = tmp_path / "data"
    tosca.prepare_tosca(write_zip(tmp_path / "toscahires-asci.zip", members), root, verbose=False)
    assert sorted(p.name for p in root.iterdir()) == ["tosca"]
    man = json.loads((root / "tosca" / "manifest.json").read_text())
    assert man["classes"]["wolf"] == {"n_shapes": 3, "n_vertices": 4344, "n_faces": 8684,
                                      "original_n_vertices": 4344, "repaired": False}
    monkeypatch.setenv("PRODMAPS_DATA", str(root))
    ids = ds.shape_ids("tosca")
    assert len(ids) == 19 and "lion0" not in ids
    intra = list(ds.pairs("tosca", "intra"))
    assert len(intra) == 8 * 2 + 6 and all(ds.shape_class("tosca", a) == ds.shape_class("tosca", b) for a, b in intra)
    assert list(ds.pairs("tosca", "inter")) == []
    np.testing.assert_array_equal(ds.ground_truth("tosca", "wolf2", "wolf0"), np.arange(4344))
    with pytest.raises(ValueError, match="different triangulations"):
        ds.ground_truth("tosca", "cat0", "dog1")
    m = ds.load_shape("tosca", "centaur1")
    np.testing.assert_allclose(m.vertices, shapes["centaur1"][0], atol=1e-6)
    np.testing.assert_array_equal(m.faces, shapes["centaur1"][1])  # 1-based on disk, 0-based here
    assert all(ds.verify_checksums("tosca").values())


@pytest.mark.parametrize("case, message", [
    ("evil", "refusing archive: member '../../evil.tri' would be written outside"),
    ("truncated_line", r"cat1.vert: line 60 has 2 numbers, expected 3 \(truncated"),
    ("truncated_rows", r"cat1.tri: index 60 but .*cat1.vert has only 59 vertices \(truncated or mismatched"),
    ("wolf_count", "wolf0.vert: 4000 vertices; TOSCA wolf shapes have 4344"),
    ("class_mismatch", r"dog1: 57 vertices .* triangulation differs from dog0 \(56 vertices\)"),
    ("zero_based", "TOSCA triangles are 1-based"),
    ("missing_tri", r"\.vert but no \.tri.*\['horse1'\]"),
])
def test_tosca_refusals_leave_nothing(tmp_path, tosca_members, case, message):
    members = dict(tosca_members[0])
    extra = []
    d = "toscahires-asci/"
    if case == "evil":
        extra = [(zipfile.ZipInfo("../../evil.tri"), b"1 2 3\n")]
    elif case == "truncated_line":
        members[d + "cat1.vert"] = members[d + "cat1.vert"][:-12]
    elif case == "truncated_rows":
        members[d + "cat1.vert"] = b"".join(members[d + "cat1.vert"].splitlines(keepends=True)[:-1])
    elif case == "wolf_count":
        v, f = fib_sphere(4000)
        members[d + "wolf0.vert"], members[d + "wolf0.tri"] = vert_bytes(v), tri_bytes(f)
    elif case == "class_mismatch":
        v, f = fib_sphere(57)
        members[d + "dog1.vert"], members[d + "dog1.tri"] = vert_bytes(v), tri_bytes(f)
    elif case == "zero_based":
        members[d + "gorilla0.tri"] = tri_bytes(fib_sphere(50)[1] - 1)
    elif case == "missing_tri":
        del members[d + "horse1.tri"]
    root = tmp_path / "data"
    with pytest.raises(PrepareError, match=message):
        tosca.prepare_tosca(write_zip(tmp_path / "t.zip", members, extra), root, verbose=False)
    assert nothing_written(root)


def test_tosca_class_repair(tmp_path, tosca_members, monkeypatch):
    members = dict(tosca_members[0])
    d = "toscahires-asci/"
    for i in (0, 1):  # an isolated extra vertex in both dogs: unreferenced -> refused unless --repair
        members[d + f"dog{i}.vert"] += b"5.0 5.0 5.0\n"
    archive = write_zip(tmp_path / "t.zip", members)
    root = tmp_path / "data"
    with pytest.raises(PrepareError, match="dog0: invalid mesh: unreferenced vertices.*--repair"):
        tosca.prepare_tosca(archive, root, verbose=False)
    assert nothing_written(root)
    tosca.prepare_tosca(archive, root, verbose=False, repair=True)
    info = json.loads((root / "tosca" / "manifest.json").read_text())["classes"]["dog"]
    assert info["repaired"] and info["n_vertices"] == 56 and info["original_n_vertices"] == 57
    np.testing.assert_array_equal(np.loadtxt(root / "tosca" / "shapes" / "dog.kept_vertices.txt"), np.arange(56))
    monkeypatch.setenv("PRODMAPS_DATA", str(root))
    assert ds.load_shape("tosca", "dog1").n_vertices == 56


# --------------------------------------------------------------------------------- variants
def test_make_variants_ground_truth(tmp_path, monkeypatch):
    root = tmp_path / "data"
    (root / "anny_humans" / "shapes").mkdir(parents=True)
    src = ds_dir("anny_humans") / "shapes"
    for sid in ("anny_000", "anny_001"):
        (root / "anny_humans" / "shapes" / f"{sid}.ply").write_bytes((src / f"{sid}.ply").read_bytes())
    written = variants.make_variants("anny_humans", ["anny_000"], data_root=root, verbose=False)
    assert [p.name for p in written] == [f"anny_000_{r}.ply" for r in variants.RECIPES]
    monkeypatch.setenv("PRODMAPS_DATA", str(root))
    ds.clear_cache()
    assert ds.variants("anny_humans") == sorted(f"anny_000_{r}" for r in variants.RECIPES)
    fam = ds.load_shape("anny_humans", "anny_000")
    for r in variants.RECIPES:
        vid = f"anny_000_{r}"
        var = ds.load_shape("anny_humans", vid)
        gt = ds.ground_truth("anny_humans", "anny_001", vid)  # (n_variant,) into the family
        assert gt.shape == (var.n_vertices,)
        d = np.linalg.norm(var.vertices - fam.vertices[gt], axis=1)
        assert d.mean() < 0.012 and d.max() < 0.05  # metres, family mean edge 2.1 cm
        meta = json.loads((root / "anny_humans" / "remeshed" / f"{vid}.json").read_text())
        assert abs(meta["area_ratio"] - 1) < 0.02
        assert var.faces.shape[0] != fam.faces.shape[0]
    thin = json.loads((root / "anny_humans" / "remeshed" / "anny_000_thin.json").read_text())
    assert thin["thin_fraction_q_lt_0.1"] > 0.55 and thin["n_vertices"] > 13000
    nonu = json.loads((root / "anny_humans" / "remeshed" / "anny_000_remesh_nonuniform.json").read_text())
    assert nonu["n_vertices_coarse_side"] < 0.4 * nonu["n_vertices_fine_side"]
    np.testing.assert_array_equal(ds.ground_truth("anny_humans", "anny_001", "anny_000_thin")[:5002], np.arange(5002))
    with pytest.raises(PrepareError, match="exists; pass --force"):
        variants.make_variants("anny_humans", ["anny_000"], ["thin"], data_root=root, verbose=False)


def test_make_variants_refuses_what_it_cannot_write_where_it_is_read(tmp_path, monkeypatch):
    # anny_humans without a copy under the data root is read from the package: variants written under the
    # root would never be read, and the folder they made used to hide the embedded dataset under PRODMAPS_DATA
    root = tmp_path / "data"
    with pytest.raises(PrepareError, match="never be read"):
        variants.make_variants("anny_humans", ["anny_000"], ["thin"], data_root=root, verbose=False)
    assert not (root / "anny_humans").exists()
    with pytest.raises(PrepareError, match="'faust' is not prepared"):  # was a DatasetNotPreparedError traceback
        variants.make_variants("faust", ["tr_reg_000"], ["thin"], data_root=root, verbose=False)
    r = subprocess.run([sys.executable, "-m", "prodmaps.prepare", "variants", "--dataset", "faust", "--shapes",
                        "tr_reg_000", "--recipes", "thin", "--data-root", str(root)], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.startswith("error: dataset 'faust' is not prepared"), r.stderr
    (root / "anny_humans" / "remeshed").mkdir(parents=True)  # a stray folder without shapes/
    monkeypatch.setenv("PRODMAPS_DATA", str(root))
    ds.clear_cache()
    assert ds.dataset_dir("anny_humans") == ds.embedded_root() / "anny_humans"
    assert "anny_humans" in ds.prepared() and ds.load_shape("anny_humans", "anny_000").n_vertices == 5002


def test_prepare_help_lists_the_commands_and_exits_0():
    r = subprocess.run([sys.executable, "-m", "prodmaps.prepare", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and "faust" in r.stdout and "variants" in r.stdout


def test_faust_subset_from_several_sources_in_ply_and_off(tmp_path, faust_shapes, capsys, monkeypatch):
    """Any subset, in several folders/archives, as PLY or OFF, anywhere below the sources (the
    layout of the eight public registrations); a shape found twice must be the same mesh."""
    shapes = faust_shapes[0]
    a, b = tmp_path / "repo_a" / "lesson" / "code", tmp_path / "repo_b"
    a.mkdir(parents=True)
    b.mkdir()
    for i in (0, 3, 10):
        v, f = shapes[i]
        (a / f"tr_reg_{i:03d}.off").write_text(
            f"OFF\n{len(v)} {len(f)} 0\n" + "".join(f"{x:.9f} {y:.9f} {z:.9f}\n" for x, y, z in v)
            + "".join(f"3 {p} {q} {r}\n" for p, q, r in f))
    for i in (3, 25):
        (b / f"tr_reg_{i:03d}.ply").write_bytes(ply_bytes(*shapes[i]))
    root = tmp_path / "data"
    faust.prepare_faust([tmp_path / "repo_a", b], root)
    out = capsys.readouterr().out
    assert "found 4 of the 100 registrations" in out and "a subset (000, 003, 010, 025)" in out
    man = json.loads((root / "faust" / "manifest.json").read_text())
    assert man["subset"] is True and man["n_shapes_full"] == 100
    assert [s["id"] for s in man["shapes"]] == ["tr_reg_000", "tr_reg_003", "tr_reg_010", "tr_reg_025"]
    assert [s["archive"] for s in man["source"]] == ["repo_a", "repo_b"]
    monkeypatch.setenv("PRODMAPS_DATA", str(root))
    assert ds.shape_ids("faust") == ["tr_reg_000", "tr_reg_003", "tr_reg_010", "tr_reg_025"]
    np.testing.assert_allclose(ds.load_shape("faust", "tr_reg_010").vertices, shapes[10][0], atol=1e-6)
    # the same id twice with different vertices is refused, nothing written
    v, f = shapes[25]
    (a / "tr_reg_025.off").write_text(f"OFF\n{len(v)} {len(f)} 0\n" + "".join(f"{x + 0.01} {y} {z}\n" for x, y, z in v)
                                      + "".join(f"3 {p} {q} {r}\n" for p, q, r in f))
    with pytest.raises(PrepareError, match="two different meshes named tr_reg_025"):
        faust.prepare_faust([tmp_path / "repo_a", b], tmp_path / "data2", verbose=False)
    assert nothing_written(tmp_path / "data2")


def test_faust_cli_takes_several_archives(tmp_path, faust_shapes):
    from prodmaps.prepare.__main__ import main

    for i, d in ((1, "x"), (2, "y")):
        (tmp_path / d).mkdir()
        (tmp_path / d / f"tr_reg_{i:03d}.ply").write_bytes(ply_bytes(*faust_shapes[0][i]))
    rc = main(["faust", "--archive", str(tmp_path / "x"), "--archive", str(tmp_path / "y"),
               "--data-root", str(tmp_path / "data")])
    assert rc == 0 and sorted(p.name for p in (tmp_path / "data" / "faust" / "shapes").iterdir()) == [
        "tr_reg_001.ply", "tr_reg_002.ply"]
    assert main(["faust", "--archive", str(tmp_path / "nowhere"), "--data-root", str(tmp_path / "d2")]) == 2
