"""Claims of the transfer figures (Figures 7, 9, 11, 12/13, 14) on the smoke results.

Each notebook's smoke profile runs once through papermill (the session fixture `smoke_results`, temporary
folder); the tests read its ``results.json``.

Asserted as the paper states them (they reproduce on the embedded data):

* Figure 11: HKS and WKS transferred with products far below the standard transfer; the
  product curve keeps falling as the target basis grows while the standard one is flat.
* Figures 7 and 9 at the smoke size ``k_M = k_N = 9`` (the paper's Table 1 size, chosen before
  measuring): products lower the error; the transfer onto other connectivities stays within a
  few hundredths of the transfer onto the regular mesh of the same shape.

Figures 12/13 and 14 are checked here for well-formed measurements only, never for which
method wins; their verdicts (Figure 13 holds, Figure 12 does not, Figure 14 holds at k = 5) are
the ledger's, asserted in ``test_ledger.py``.
"""

import numpy as np
import pytest

pytestmark = pytest.mark.notebook


# ----------------------------------------------------------------------------- Figure 11
def _curve(r, desc, method):
    dims = r["target_dims"]
    return np.array([r["errors"][desc][method][f"d{d}"] for d in dims])


@pytest.mark.parametrize("desc", ["HKS", "WKS"])
def test_fig11_products_far_below_standard(smoke_results, desc):
    _, r = smoke_results("fig11")
    std, prod = _curve(r, desc, "std"), _curve(r, desc, "prod")
    assert np.all(prod < std), (desc, prod, std)
    # measured (smoke, unit-norm eigenvectors, rtol 1e-3): prod/std 0.25 (HKS) and 0.16 (WKS) at the
    # largest dimension; on the source the extended approximation is 0.18x (HKS) and 0.15x (WKS) the
    # standard one: 1e-3 on this normalisation leaves part of the (representable) products out
    assert prod[-1] < 0.3 * std[-1], (desc, prod[-1], std[-1])
    assert r["approximation_on_source"][desc]["prod"] < 0.25 * r["approximation_on_source"][desc]["std"]


@pytest.mark.parametrize("desc", ["HKS", "WKS"])
def test_fig11_product_curve_keeps_falling_standard_flat(smoke_results, desc):
    _, r = smoke_results("fig11")
    assert len(r["target_dims"]) >= 3
    std, prod = _curve(r, desc, "std"), _curve(r, desc, "prod")
    # measured: HKS 0.0082 -> 0.0063, WKS 0.032 -> 0.017 over target dimensions 10..40
    assert prod[-1] < 0.8 * prod[0], prod                    # falls overall
    assert prod[-1] <= 1.01 * prod.min(), prod                # ends at (about) its minimum
    assert prod[1] / prod[-1] > 1.05, prod                    # still falling after the first step
    assert abs(std[-1] / std[1] - 1.0) < 0.05, std            # the standard error has stopped moving
    # the standard transfer cannot beat the source truncation (φ_i² is not in the source span)
    assert std[-1] > 0.9 * r["approximation_on_source"][desc]["std"]


# ----------------------------------------------------------------------------- Figure 7
@pytest.mark.slow
def test_fig07_products_lower_error_at_table1_size(smoke_results):
    d, r = smoke_results("fig07")
    e = r["errors"]["kM9_kN9"]
    for stage in ("approx", "transfer"):
        assert 0.0 < e[stage]["prod"] < e[stage]["std"] < 1.0, (stage, e[stage])
    # the ground-truth map of a near-isometric pair: transfer error close to the approximation error
    assert abs(e["transfer"]["std"] - e["approx"]["std"]) < 0.05
    assert (d / "fig07_kM9_kN9.png").is_file()


# ----------------------------------------------------------------------------- Figure 9
@pytest.mark.slow
def test_fig09_products_better_and_stable_across_connectivity(smoke_results):
    d, r = smoke_results("fig09")
    assert set(r["errors"]) == {"anny_025_remesh_nonuniform", "anny_000_thin"}
    for tgt, by_lap in r["errors"].items():
        assert set(by_lap) == {"cotan", "robust"}
        for lap, by_size in by_lap.items():
            e = by_size["kM9_kN9"]
            assert e["variant"]["prod"] < e["variant"]["std"], (tgt, lap, e)
            for m in ("std", "prod"):
                assert abs(e["variant"][m] - e["reference"][m]) < 0.03, (tgt, lap, m, e)
    assert (d / "fig09_kM9_kN9.png").is_file() and (d / "fig09_triangle_quality.png").is_file()


# ----------------------------------------------------------------------------- Figures 12/13
@pytest.mark.slow
def test_fig12_13_measurements_well_formed(smoke_results):
    d, r = smoke_results("fig12_13")
    assert r["map_size"]["C_shape"][0] > r["map_size"]["C_shape"][1]   # k_N > k_M (target rows)
    for m in ("gt", "no17"):
        c = r["curves"][m]
        for method in ("std", "extended", "extended_closed_form"):
            y = np.asarray(c[method])
            assert np.all(np.diff(y) >= 0) and 0.0 <= y[0] and y[-1] <= 1.0
            assert 0.0 < r["mean_error"][m][method] < 0.5
        for key in ("extended_vs_std_pairs", "closed_form_vs_std_pairs"):
            assert set(r[key][m]) == {"better", "tie", "worse"}
            assert sum(r[key][m].values()) == len(r["pairs"])
    # the sensitivity sweep: the standard conversion and the extended one per setting and size
    rows = r["sweep"]["rows"]
    assert {row["setting"] for row in rows} >= {"std", "extended t x1"}
    assert all(0.0 < row["mean_error"] < 1.0 for row in rows)
    # the ground-truth map is better than the computed one with the standard conversion
    assert r["mean_error"]["gt"]["std"] < r["mean_error"]["no17"]["std"]
    assert (d / "fig12_13_p2p.png").is_file()


# ----------------------------------------------------------------------------- Figure 14
@pytest.mark.slow
def test_fig14_joint_cross_fields_well_formed(smoke_results):
    d, r = smoke_results("fig14")
    cf = r["cross_fields"]
    assert len(cf["pairs"]) >= 2
    for name, p in cf["pairs"].items():
        base = p["baselines"]
        assert base["pushforward"]["angle_mean_deg"] < 1e-9  # consistent by construction
        assert ("copy" in base) == ("remesh" not in name)  # the face copy only on one triangulation
        for k in (kk for kk in p if kk.startswith("k")):
            for kd in ("std", "ext", "default", "p2p"):
                x = p[k][kd]
                assert 0.0 < x["angle_regular_deg"] <= x["angle_mean_deg"] + 5.0
                assert x["angle_mean_deg"] <= x["angle_p90_deg"] <= 45.0
                assert 0.0 <= x["sing_recall"] <= 1.0 and 0.2 < x["regular_fraction"] < 1.0
                assert x["n_sing_low_2"] < x["n_sing_2"]  # the comparison leaves the forced singularities out
                assert x["consistency_energy"] < 1.0
        q = p["quads"]
        ks = [kk for kk in p if kk.startswith("k")]
        assert set(q) == {"size"} | set(ks) | {"baselines"}
        settings = [(k, n) for k in ks for n in ("std", "ext", "default")]
        settings += [("baselines", "independent"), ("baselines", "pushforward")]
        for grp, n in settings:
            st = q[grp][n]
            for side in ("source", "target"):
                x = st[side]
                assert x["n_quads"] > 100 and x["n_irregular"] <= x["n_vertices"]
                # watertight, manifold edges, all quads but the hole polygons next to singularity clusters
                assert x["n_boundary_edges"] == 0 and x["n_nonmanifold_edges"] == 0
                assert x["quad_fraction"] > 0.95 and x["polygons_near_singularities"] >= 0.8 * x["n_polygons"]
            assert 0 <= st["irregular_matched"] <= min(st["irregular_matched_of"], st["irregular_target"])
            assert st["irregular_matched_of"] == st["source"]["n_irregular"]
            assert 0 <= st["irregular_low_matched"] <= min(st["irregular_low_source"], st["irregular_low_target"])
    Q = cf["summary"]["quads"]
    assert set(Q["cells_low"]["std"]) == {f"{n}|{k}" for n in cf["pairs"] for k in cf["pairs"][n] if k.startswith("k")}
    assert all(r["n_boundary_edges_total"] == 0 for row in Q["groups"].values() for r in row.values())
    S = cf["summary"]["angle_regular_deg"]
    assert set(S["cells"]["std"]) == {f"{n}|{k}" for n in cf["pairs"] for k in cf["pairs"][n] if k.startswith("k")}
    assert S["k5"]["ext"]["n_pairs"] == len(cf["pairs"])
    assert (d / "fig14_cross_fields.png").is_file() and (d / "fig14_pairs.png").is_file()
    assert (d / "fig14_quads.png").is_file() and (d / "fig14_quads_pairs.png").is_file()


@pytest.mark.slow
def test_fig14_point_map_transport_well_formed(smoke_results):
    d, r = smoke_results("fig14")
    pmt = r["point_map_transport"]
    q = pmt["quad_mesh"]
    assert q["n_quads"] > 100 and q["n_quads"] > 0.25 * q["n_triangles"]
    assert q["snap_max_m"] < 0.05                                  # quad vertices sit on the source
    for method in ("std", "extended"):
        m = pmt["measures"]["k5"][method]
        assert 0 <= m["flipped"] + m["degenerate"] <= q["n_quads"]
        assert 0.0 < m["vertex_error_mean"] < 0.5
        assert m["distinct_target_vertices"] <= q["n_vertices"]
    # the ground-truth transfer keeps the quads about as square as on the source
    assert abs(pmt["measures"]["truth"]["angle_dev_mean"] - pmt["measures"]["source"]["angle_dev_mean"]) < 5.0
    assert (d / "fig14_point_map_transport.png").is_file()
