"""The Figure 14 experiment (prodmaps.experiments.fig14_quad_transfer.crossfields) and its figures."""

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.experiments.fig14_quad_transfer import crossfields as cf
from prodmaps.mesh import ellipsoid, icosphere


def test_match_singularities():
    m = icosphere(2)
    v = np.array([0, 5, 9])
    r = cf.match_singularities(m, v, np.array([0.25, 0.25, -0.25]), v, np.array([0.25, 0.25, -0.25]))
    assert r["n_matched"] == 3 and r["mean_dist"] == 0.0 and r["recall"] == 1.0
    r = cf.match_singularities(m, v, np.array([0.25, 0.25, 0.25]), v, np.array([-0.25, -0.25, -0.25]))
    assert r["n_matched"] == 0 and r["recall"] == 0.0


# ----------------------------------------------------------------------------- joint design (main)
@pytest.fixture(scope="module")
def small_joint():
    m1 = ellipsoid(2)
    m2 = pm.Mesh(m1.vertices * [1.0, 1.1, 1.3], m1.faces)
    gt = {"p2p_21": np.arange(m1.n_vertices), "p2p_12": np.arange(m1.n_vertices), "same_triangulation": True,
          "face_21": None, "bary_21": None}
    return m1, m2, cf.figure14_joint_pair(m1, m2, gt, (3, 4), keep_fields=True)


def test_plots(small_joint):
    import matplotlib

    matplotlib.use("Agg")
    from prodmaps.experiments.fig14_quad_transfer.plots import joint_figure, plot_cross_field

    m1, m2, r = small_joint
    z1, _ = r["fields"]["independent"]
    ax = plot_cross_field(m1.vertices, m1.faces, z1, n_glyphs=50)
    assert len(ax.collections) >= 2 and len(ax.collections[1].get_segments()) == 100
    fig = joint_figure(m1, m2, r["fields"], ("independent", "pushforward", "absent"))
    assert len(fig.axes) == 4


def test_figure14_joint_pair_outputs(small_joint):
    m1, m2, r = small_joint
    assert set(r) == {"k3", "k4", "baselines", "quads", "seconds", "fields", "map_only", "map"}
    q = r["quads"]
    assert set(q) == {"size", "k3", "k4", "baselines"} and q["size"] == cf.JOINT_DEFAULTS["quad_size"]
    assert set(q["k3"]) == {"std", "ext", "default", "p2p"} and set(q["baselines"]) == {"independent", "pushforward"}
    for grp, n in (("k3", "std"), ("k4", "ext"), ("baselines", "independent"), ("baselines", "pushforward")):
        st = q[grp][n]
        for side in ("source", "target"):
            assert st[side]["n_quads"] > 0 and st[side]["n_boundary_edges"] == 0  # watertight
            assert st[side]["n_nonmanifold_edges"] == 0
        assert 0 <= st["irregular_matched"] <= min(st["irregular_matched_of"], st["irregular_target"])
        assert st["irregular_matched_of"] == st["source"]["n_irregular"]
        V, Q, polys, irr = r["fields"]["quad_meshes"][(grp, n)][1]
        assert Q.shape == (st["target"]["n_quads"], 4) and Q.max() < V.shape[0]
        assert len(polys) == st["target"]["n_polygons"] and len(irr) == st["target"]["n_irregular"]
    # the push-forward baseline: the same field on both (identity map, one triangulation): the two
    # quad meshes' irregular vertices correspond one to one
    pfq = q["baselines"]["pushforward"]
    assert pfq["irregular_match_fraction"] > 0.9
    assert set(r["k3"]) == set(cf.JOINT_KINDS) | {"no_map"} and set(r["baselines"]) == set(cf.BASELINES)
    assert r["baselines"]["pushforward"]["angle_mean_deg"] < 1e-9
    pf_ = r["baselines"]["pushforward"]
    assert pf_["sing_recall"] in (None, 1.0) or pf_["n_sing_low_1"] == 0
    for k in ("k3", "k4"):
        for kd in cf.JOINT_KINDS:
            m = r[k][kd]
            assert 0 <= m["angle_mean_deg"] <= m["angle_p90_deg"] <= 45
            assert 0 <= m["align_1_deg"] <= 45 and 0 <= m["align_2_deg"] <= 45
            assert 0 <= m["consistency_energy"] < 1
            z1, z2 = r["fields"][(int(k[1:]), kd)]
            np.testing.assert_allclose(np.abs(z2), 1.0)
    # the baselines share the independent source field
    b = r["baselines"]
    assert b["copy"]["align_1_deg"] == b["independent"]["align_1_deg"] == b["pushforward"]["align_1_deg"]
    np.testing.assert_array_equal(r["fields"]["copy"][1], r["fields"]["independent"][0])


def test_map_only_setting_carries_the_fixed_source_field(small_joint):
    m1, m2, r = small_joint
    mo = r["map_only"]
    assert set(mo) == {"k3", "k4", "baselines"} and mo["baselines"]["independent"] == r["baselines"]["independent"]
    z_ind = r["fields"]["independent"][0]
    for k in ("k3", "k4"):
        assert set(mo[k]) == set(cf.JOINT_KINDS) | {"no_map"}
        assert mo[k]["no_map"] == r[k]["no_map"] == r["baselines"]["independent"]  # one no-map baseline
        for kd in cf.JOINT_KINDS:
            z1, z2 = r["fields"][(int(k[1:]), "map_only", kd)]
            np.testing.assert_array_equal(z1, z_ind)  # the source field is fixed: the no-map design's
            assert mo[k][kd]["align_1_deg"] == r["baselines"]["independent"]["align_1_deg"]
            np.testing.assert_allclose(np.abs(z2), 1.0)
            assert 0 <= mo[k][kd]["consistency_energy"] < 1
        # the extended kind reports the library operator's ranks and its transfer gain
        assert mo[k]["ext"]["rank_1"] == r[k]["ext"]["rank_1"] > int(k[1:]) + 1
        assert mo[k]["ext"]["gain_max"] == pytest.approx(r[k]["ext"]["gain_max"]) and mo[k]["ext"]["gain_max"] > 0
        # identity map between a shape and its stretched copy: C is close to orthogonal
        assert 0.5 < r["map"][k]["C_sigma_min"] <= r["map"][k]["C_sigma_max"] < 1.5
    # the map carries a stretched ellipsoid's field: the oracle (exact transfer) within a few degrees
    assert mo["k4"]["p2p"]["angle_mean_deg"] < 10.0


def test_verdict_table_counts_per_setting_and_k():
    def cell(v):
        return {"angle_regular_deg": v, "angle_mean_deg": v + 1, "sing_recall": 0.5}

    def row(s, e, d, o, n):
        return {"std": cell(s), "ext": cell(e), "default": cell(d), "p2p": cell(o), "no_map": cell(n)}

    per = {"a": {"k5": row(2, 1, 3, 1, 4), "map_only": {"k5": row(3, 2, 4, 2.5, 1)}},
           "b": {"k5": row(2, 3, 1, 3, 1), "map_only": {"k5": row(3, 4, 2, 2.0, 1)}}}
    kinds = cf.JOINT_KINDS + ("no_map",)
    study = {"pairs": per, "kinds": list(cf.JOINT_KINDS),
             "summary": {m: cf.summarize_pairs(per, [5], kinds, measure=m)
                         for m in ("angle_regular_deg", "angle_mean_deg")}}
    mo = {n: p["map_only"] for n, p in per.items()}
    study["summary"]["map_only"] = {m: cf.summarize_pairs(mo, [5], kinds, measure=m)
                                    for m in ("angle_regular_deg", "angle_mean_deg")}
    rows = {(x["setting"], x["measure"]): x for x in cf.verdict_table(study, [5])}
    j, m = rows[("joint", "angle_regular_deg")], rows[("map_only", "angle_regular_deg")]
    assert (j["ext_beats_std"], j["p2p_beats_std"], j["no_map_beats_std"], j["default_beats_std"]) == (1, 1, 1, 1)
    assert (m["ext_beats_std"], m["p2p_beats_std"], m["no_map_beats_std"]) == (1, 2, 2) and m["n_pairs"] == 2
    assert m["no_map_mean"] == 1.0 and m["p2p_mean"] == 2.25


def test_summarize_pairs_counts_and_pools():
    def cell(v):
        return {"angle_regular_deg": v}

    per = {"a": {"k5": {"std": cell(2.0), "ext": cell(1.0), "default": cell(3.0), "p2p": cell(0.5)}},
           "b": {"k5": {"std": cell(2.0), "ext": cell(2.5), "default": cell(1.0), "p2p": cell(0.5)}},
           "c": {"k5": {"std": cell(4.0), "ext": cell(3.0), "default": cell(4.0), "p2p": cell(0.5)}}}
    s = cf.summarize_pairs(per, [5])
    assert s["k5"]["ext"]["n_better"] == 2 and s["k5"]["default"]["n_better"] == 1 and s["k5"]["ext"]["n_pairs"] == 3
    assert s["k5"]["std"]["mean"] == pytest.approx(8 / 3) and s["k5"]["ext"]["max"] == 3.0
    assert s["cells"]["ext"] == {"a|k5": 1.0, "b|k5": 2.5, "c|k5": 3.0}
    assert s["pooled"]["default"]["n_cells"] == 3 and s["pooled"]["p2p"]["std"] == 0.0


def test_summarize_quads_counts_and_pools():
    def cell(f, n=100):
        side = {"n_quads": n, "quad_fraction": 0.99, "n_boundary_edges": 0, "n_nonmanifold_edges": 0}
        return {"irregular_match_fraction": f, "irregular_low_match_fraction": f / 2, "source": side, "target": side}

    def pair(s, e, i):
        return {"quads": {"size": 0.03, "k5": {"std": cell(s), "ext": cell(e)}, "baselines": {"independent": cell(i)}}}

    per = {"a": pair(0.5, 0.6, 0.4), "b": pair(0.7, 0.6, 0.5)}
    s = cf.summarize_quads(per)
    g = s["groups"]
    assert g["k5"]["ext"]["n_better"] == 1 and g["k5"]["ext"]["n_pairs"] == 2 and "n_better" not in g["k5"]["std"]
    assert g["k5"]["std"]["irregular_match_fraction"]["mean"] == pytest.approx(0.6)
    assert g["baselines"]["independent"]["n_quads"]["mean"] == 100 and g["k5"]["std"]["n_boundary_edges_total"] == 0
    assert s["cells"]["ext"] == {"a|k5": 0.6, "b|k5": 0.6} and s["pooled"]["independent"]["max"] == 0.5
    assert s["cells_low"]["std"] == {"a|k5": 0.25, "b|k5": 0.35} and g["k5"]["ext"]["n_better_low"] == 1


def test_surface_ground_truth_of_a_remeshed_variant():
    from prodmaps import datasets

    gt = cf.surface_ground_truth("anny_humans", "anny_000", "anny_013_remesh_iso")
    var = datasets.load_shape("anny_humans", "anny_013_remesh_iso")
    base = datasets.load_shape("anny_humans", "anny_013")
    assert not gt["same_triangulation"] and gt["face_21"].shape == (var.n_vertices,)
    X = np.einsum("vc,vcd->vd", gt["bary_21"], base.vertices[base.faces[gt["face_21"]]])
    assert np.linalg.norm(X - var.vertices, axis=1).max() < 0.01  # metres: the variant lies on its base
    assert gt["p2p_12"].shape == (5002,) and gt["p2p_12"].max() < var.n_vertices
    with pytest.raises(ValueError, match="variant"):
        cf.surface_ground_truth("anny_humans", "anny_013_remesh_iso", "anny_000")
