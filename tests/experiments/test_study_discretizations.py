"""The discretizations study: the ground-truth rule, the derived discretizations, a tiny run's numbers."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import prodmaps as pm
from prodmaps.experiments import study_discretizations as sd
from prodmaps.mesh import ellipsoid, face_normals, icosphere

DS = "anny_humans"


def _brute_nearest(queries, points):
    """Nearest point by an explicit distance matrix (the reference of the k-d tree)."""
    return np.argmin(((queries[:, None, :] - points[None, :, :]) ** 2).sum(-1), axis=1)


@pytest.fixture(scope="module")
def shapes(human_0):
    return sd.discretizations(human_0, seed=0)


# ------------------------------------------------------------------ the ground-truth rule
def test_ground_truth_is_the_identity_when_the_target_is_the_source(human_0, shapes):
    for name, s in shapes.items():  # a cloud's surface is the mesh it was sampled from
        assert np.array_equal(sd.ground_truth(s, s, human_0), np.arange(s.n_vertices)), name
    cloud = sd.sample_surface(human_0, 3000, seed=4)
    assert np.array_equal(sd.ground_truth(cloud, cloud, human_0), np.arange(3000))


def test_ground_truth_reads_the_closest_surface_point_at_its_nearest_source_vertex():
    mesh = ellipsoid(2, axes=(1.0, 0.4, 0.2))  # convex: a point pushed out along its face's normal projects back
    V, F = mesh.vertices, mesh.faces
    rng = np.random.default_rng(0)
    face = rng.integers(0, F.shape[0], 400)
    w = rng.dirichlet(np.ones(3), 400)  # (400, 3) barycentric
    on = np.einsum("qc,qcd->qd", w, V[F[face]])  # (400, 3) points on the surface
    off = on + 0.5 * face_normals(V, F)[face]
    p2p = sd.surface_ground_truth(off, V, V, F)
    assert np.array_equal(p2p, _brute_nearest(on, V))
    assert np.any(p2p != _brute_nearest(off, V))  # read at the projection, not at the point itself
    assert np.array_equal(sd.surface_ground_truth(on, V, V, F), _brute_nearest(on, V))


def test_ground_truth_of_a_cloud_source_uses_the_original_surface(human_0):
    cloud = sd.sample_surface(human_0, 2000, seed=1)
    p2p = sd.ground_truth(human_0, cloud, human_0)  # mesh vertices lie on the original surface
    assert p2p.shape == (human_0.n_vertices,) and p2p.dtype == np.int64
    assert np.array_equal(p2p, cKDTree(cloud.points).query(human_0.vertices)[1])


# ------------------------------------------------------------------ the discretizations
def test_sample_surface_is_seeded_on_the_surface_and_uniform_by_area():
    mesh = ellipsoid(3, axes=(1.0, 0.5, 0.25))
    a = sd.sample_surface(mesh, 20000, seed=3)
    assert isinstance(a, pm.PointCloud) and a.points.shape == (20000, 3)
    assert np.allclose(np.linalg.norm(a.normals, axis=1), 1.0)
    assert np.array_equal(a.points, sd.sample_surface(mesh, 20000, seed=3).points)
    assert not np.allclose(a.points[:10], sd.sample_surface(mesh, 20000, seed=4).points[:10])
    assert sd.sample_surface(mesh, 50, normals=False).normals is None
    r = (a.points / np.array([1.0, 0.5, 0.25])) ** 2  # on the ellipsoid's triangles: at most 1, near 1
    assert np.all(r.sum(1) <= 1 + 1e-9) and np.all(r.sum(1) > 0.97)
    with pytest.raises(ValueError, match="at least 4"):
        sd.sample_surface(mesh, 3)


def test_marching_cubes_of_a_sphere_is_a_closed_sphere():
    sphere = icosphere(4)  # radius 1
    mc = sd.marching_cubes_mesh(sphere, 0.03)
    h = 0.03 * np.sqrt(sphere.area)
    r = np.linalg.norm(mc.vertices, axis=1)
    assert np.all(np.abs(r - 1) < h)
    assert pm.mesh.boundary_edges(mc.faces).size == 0
    assert pm.mesh.face_components(mc.n_vertices, mc.faces)[0] == 1
    assert abs(mc.area / (4 * np.pi) - 1) < 0.02
    finer = sd.marching_cubes_mesh(sphere, 0.015)
    assert 3.0 < finer.n_vertices / mc.n_vertices < 5.0  # vertices ~ 1 / spacing²
    with pytest.raises(ValueError, match="spacing"):
        sd.marching_cubes_mesh(sphere, 0.0)


def test_discretizations_of_a_human(human_0, shapes):
    assert list(shapes) == list(sd.DISCRETIZATIONS)
    assert shapes["mesh"] is human_0
    n = human_0.n_vertices
    for name in ("iso", "nonuniform", "mc"):
        m = shapes[name]
        assert isinstance(m, pm.Mesh) and pm.mesh.boundary_edges(m.faces).size == 0
        assert abs(m.area / human_0.area - 1) < 0.06, name
    assert 0.7 * n < shapes["iso"].n_vertices < 0.9 * n  # the recipe's ~0.8x
    v = shapes["nonuniform"].vertices  # one side of the median x much coarser
    cut = np.median(human_0.vertices[:, 0])
    assert np.sum(v[:, 0] >= cut) > 2 * np.sum(v[:, 0] < cut)
    q = pm.mesh.face_radius_ratio(shapes["mc"].vertices, shapes["mc"].faces)
    assert np.mean(q < 0.1) > 0.02  # marching cubes leaves slivers; the remeshes do not
    assert np.mean(pm.mesh.face_radius_ratio(shapes["iso"].vertices, shapes["iso"].faces) < 0.1) < 0.005
    for name in ("cloud", "cloud2"):
        assert isinstance(shapes[name], pm.PointCloud) and shapes[name].n_points == n
    assert not np.allclose(shapes["cloud"].points, shapes["cloud2"].points)
    # uniform by area, not by face: on the non-uniform remesh (one side with far fewer, larger faces)
    # the share of points on the coarse side is that side's share of the area
    m = shapes["nonuniform"]
    areas = pm.mesh.face_areas(m.vertices, m.faces)
    coarse = m.vertices[m.faces].mean(1)[:, 0] < cut  # (faces,)
    pts = sd.sample_surface(m, 20000, seed=2).points
    assert coarse.mean() < 0.35  # the faces: far fewer on the coarse side
    assert abs(np.mean(pts[:, 0] < cut) - areas[coarse].sum() / areas.sum()) < 0.02
    assert sd.discretizations(human_0, ["cloud"], cloud_points=500)["cloud"].n_points == 500
    with pytest.raises(ValueError, match="recipe must be one of"):
        sd.remesh(human_0, "voxels")
    with pytest.raises(ValueError, match="unknown discretizations"):
        sd.discretizations(human_0, ["mesh", "voxels"])


def test_every_discretization_lies_on_the_original_surface(human_0, shapes):
    scale = np.sqrt(human_0.area)
    for name, s in shapes.items():
        gt = sd.ground_truth(s, human_0, human_0)
        d = np.linalg.norm(s.vertices - human_0.vertices[gt], axis=1) / scale
        assert d.max() < 0.03, name  # within about an edge of the original's nearest vertex


# ------------------------------------------------------------------ a tiny run
PAIRS = [("mesh", "mesh"), ("mesh", "cloud"), ("cloud", "mesh")]


@pytest.fixture(scope="module")
def tiny():
    return sd.discretization_study(DS, ["anny_000"], pairs=PAIRS, ks=[5], n_indicators=1, n_heat=1, kernel_eig=20,
                                   n_eval=60, verbose=False)


def test_tiny_run_layout(tiny):
    res = tiny["results"]
    assert res["pairs"] == ["mesh->mesh", "mesh->cloud", "cloud->mesh"] and res["ks"] == [5]
    assert res["function_columns"] == ["X", "Y", "Z", "Indicator 0", "hk 0"]
    assert len(res["cells"]) == 3 * 5
    for p in res["pairs"]:
        e = res["errors"]["k5"][p]
        assert set(e) == set(sd.FUNCTIONS)
        assert all(0 <= e[f][m] < 2 for f in sd.FUNCTIONS for m in sd.METHODS)
        assert set(res["point_maps"]["k5"][p]) == set(sd.CONVERSIONS)
    assert res["errors_per_shape"]["anny_000"] == res["errors"]  # one shape: the mean is that shape
    d = res["discretizations"]["anny_000"]
    assert d["mesh"]["gt_distance_max"] == 0.0 and d["cloud"]["kind"] == "cloud"
    pic = tiny["picture"]
    assert pic["k"] == 5 and pic["truth"].shape == (pic["target"].n_vertices, 5)
    assert pic["std"].shape == pic["truth"].shape


def test_tiny_run_numbers_against_the_library(tiny, human_0):
    """The stored errors are the library's, recomputed here from the ground truth."""
    res, pic = tiny["results"], tiny["picture"]
    cloud = pic["target"]
    b1, b2 = pm.eigenbasis(human_0, 6), pm.eigenbasis(cloud, 6)
    p2p = sd.ground_truth(cloud, human_0, human_0)
    C = pm.fmap_from_p2p(p2p, b1, b2)  # (6, 6)
    f = human_0.vertices  # X, Y, Z
    for m, (method, params) in sd.METHODS.items():
        g = pm.transfer(f, C, b1, b2, method, **params)
        err = pm.relative_error(g, f[p2p], b2.mass)
        for j, name in enumerate("XYZ"):
            assert res["errors"]["k5"]["mesh->cloud"][name][m] == pytest.approx(err[j], rel=1e-9)
            assert sd.find_cell(res, shape="anny_000", k=5, pair="mesh->cloud", function=name)[m] == \
                pytest.approx(err[j], rel=1e-9)
    # mesh -> mesh: the identity map; std is the projection, the point maps are exact
    e = res["errors"]["k5"]["mesh->mesh"]
    proj = b1.vecs @ b1.project(f)
    for j, name in enumerate("XYZ"):
        assert e[name]["std"] == pytest.approx(pm.relative_error(proj[:, j], f[:, j], b1.mass), rel=1e-9)
    assert res["point_maps"]["k5"]["mesh->mesh"] == {"std": 0.0, "extended": 0.0}
    assert 0 < res["point_maps"]["k5"]["mesh->cloud"]["std"] < 0.2
    with pytest.raises(KeyError):
        sd.find_cell(res, shape="anny_000", k=5, pair="cloud->cloud2", function="X")


def test_tiny_run_rejects_a_kernel_smaller_than_the_bases():
    with pytest.raises(ValueError, match="kernel_eig"):
        sd.discretization_study(DS, ["anny_000"], pairs=PAIRS, ks=[20], kernel_eig=10, verbose=False)


# ------------------------------------------------------------------ the finding
def _results(cells):
    """A results dict with these single-function cells, one pair per cell's pair, k = 10."""
    pairs = list(dict.fromkeys(c["pair"] for c in cells))
    errors = {"k10": {p: {f: {m: float(np.mean([c[m] for c in cells if c["pair"] == p])) for m in sd.METHODS}
                          for f in sd.FUNCTIONS} for p in pairs}}
    pmaps = {"k10": {p: {"std": 0.05, "extended": 0.04 if p.startswith("mesh") else 0.06} for p in pairs}}
    return {"cells": cells, "pairs": pairs, "ks": [10], "errors": errors, "point_maps": pmaps,
            "methods": list(sd.METHODS)}


def _cell(pair, std, svd, default, function="X", gain=None):
    """One single-function cell; the gain rule's error is std's unless given."""
    return {"shape": "s", "k": 10, "pair": pair, "function": function, "std": std, "svd": svd, "default": default,
            "gain": std if gain is None else gain}


def test_summary_counts_cells_worse_than_std_by_more_than_the_margin():
    cells = [_cell("mesh->iso", 1.0, 0.8, 0.9), _cell("mesh->cloud", 1.0, 1.02, 1.005),
             _cell("cloud->mesh", 1.0, 1.5, 1.0 + 1e-7, gain=1.2), _cell("mc->mesh", 1.0, 1.009, 0.95, gain=0.9)]
    s = sd.summary(_results(cells))
    assert s["worse"]["svd"]["all"]["worse_by_more_than_margin"] == 2
    assert s["worse"]["svd"]["all"]["worst_ratio"] == pytest.approx(1.5)
    assert s["worse"]["svd"]["all"]["worst_cell"] == "s/k10/cloud->mesh/X"
    assert s["worse"]["svd"]["clean"]["worse_by_more_than_margin"] == 0
    assert s["worse"]["svd"]["to_rough"]["worse_by_more_than_margin"] == 1
    assert s["worse"]["svd"]["from_rough"]["pairs_with_worse_cells"] == ["cloud->mesh"]
    assert s["worse"]["default"]["all"]["worse_by_more_than_margin"] == 0  # 1.005 is within 1 %, 1 + 1e-7 a tie
    assert s["xyz_better"]["k10"]["svd"] == ["mesh->iso"]
    assert s["xyz_better"]["k10"]["default"] == ["mesh->iso", "mc->mesh"]
    assert s["worse"]["gain"]["all"]["worse_by_more_than_margin"] == 1  # std's own value is a tie
    assert s["worse"]["gain"]["all"]["worst_cell"] == "s/k10/cloud->mesh/X"
    assert s["xyz_better"]["k10"]["gain"] == ["mc->mesh"]
    assert s["point_maps_better"]["k10"] == ["mesh->iso", "mesh->cloud"]
    assert [sd.pair_group(p) for p in ("mesh->nonuniform", "iso->cloud2", "mc->iso")] == \
        ["clean", "to_rough", "from_rough"]


def test_finding_and_report_are_computed_from_the_numbers(tiny):
    res = tiny["results"]
    text = sd.finding_text(res)
    w = res["summary"]["worse"]
    assert f"on {w['svd']['all']['worse_by_more_than_margin']} of {w['svd']['all']['cells']} single" in text
    assert f"on {w['default']['all']['worse_by_more_than_margin']} of 15 single functions" in text
    assert f"**Approach B with the gain rule** is worse than the standard transfer by more than 1 % on " \
           f"{w['gain']['all']['worse_by_more_than_margin']} of 15 single functions" in text
    blocks = sd.report_blocks(res, "embedded humans")
    assert blocks[0] == ("h", 2, "Study: transfer and point maps across discretizations")
    tables = [b for b in blocks if b[0] == "table"]
    assert len(tables) == 1 and [r[0] for r in tables[0][2]] == ["`mesh->mesh`", "`mesh->cloud`", "`cloud->mesh`"]
    assert blocks[-1] == ("ul", sd.finding_items(res))
    assert sd.report_blocks(res, "FAUST_r", main=False)[0] == (
        "h", 3, "Study: transfer and point maps across discretizations on FAUST_r")
    assert sd.report_blocks({}, "x") == []


def test_front_axes_and_spread_shapes():
    assert np.array_equal(sd.front_axes(), [[0, 0, 1], [1, 0, 0], [0, 1, 0]] * np.array([[1], [1], [-1]]))
    faust = sd.front_axes("faust")
    assert np.array_equal(faust[0], [0, 1, 0]) and np.array_equal(faust[2], [0, 0, 1])  # up +y, facing +z
    assert sd.spread_shapes(DS, 4) == ["anny_000", "anny_015", "anny_030", "anny_045"]
    with pytest.raises(ValueError, match="n must be"):
        sd.spread_shapes(DS, 0)
