"""The paper's qualitative claims on representation (Figures 4, 5, 6, 10), on the smoke results.

Runs the four notebooks' smoke profiles through papermill (module-scoped, into temporary
folders) and asserts on their ``results.json``; plus the repeatability of the renders.
"""

import numpy as np
import pytest

from prodmaps.experiments.shared import render
from prodmaps.experiments.shared.results import read_results, save_figure

NOTEBOOKS = {
    "fig04": "notebooks/fig04_coordinate_reconstruction.ipynb",
    "fig05": "notebooks/fig05_higher_order.ipynb",
    "fig06": "notebooks/fig06_indicator_region.ipynb",
    "fig10": "notebooks/fig10_lmh.ipynb",
}
PNGS = {
    "fig04": ["fig04_coordinate_reconstruction.png", "fig04_error_vs_k.png"],
    "fig05": ["fig05_higher_order.png"],
    "fig06": ["fig06_indicator_region.png"],
    "fig10": ["fig10_lmh.png"],
}

pytestmark = [pytest.mark.slow, pytest.mark.notebook]


@pytest.fixture(scope="module")
def runs(smoke_run):
    """Smoke executions shared with the baseline diff (tests/conftest.py: smoke_run)."""
    out = {}
    for name in NOTEBOOKS:
        d = smoke_run(name)
        out[name] = (d, read_results(d))
    return out


def res(runs, name):
    return runs[name][1]["results"]


def test_smoke_parameters_recorded(runs):
    for name in NOTEBOOKS:
        assert runs[name][1]["parameters"]["profile"] == "smoke"


def test_fig04_products_lower_error_for_every_k(runs):
    r = res(runs, "fig04")
    assert r["pairs"] == "ordered"
    ks = sorted(r["errors"]["std"], key=lambda s: int(s[1:]))
    assert {"k9", "k19"} <= set(ks)
    for k in ks:
        std, prod = r["errors"]["std"][k], r["errors"]["prod"][k]
        assert prod["mean"] < std["mean"], k
        for c in "xyz":  # every coordinate, not only the mean
            assert prod[c] < std[c], (k, c)
        # the other pair convention also beats the standard basis
        assert r["errors"]["prod_unique"][k]["mean"] < std["mean"]
    # and the error falls with k in both bases
    for b in ("std", "prod"):
        e = [r["errors"][b][k]["mean"] for k in ks]
        assert all(np.diff(e) < 0), (b, e)
    # sizes: k+1 columns, ordered products 1 + k + k^2
    assert r["sizes"]["k9"]["std"] == 10 and r["sizes"]["k9"]["extended"] == 1 + 9 + 81
    assert r["sizes"]["k9"]["extended_unique"] == 1 + 9 + 45


def test_fig05_higher_orders_lower_error(runs):
    r = res(runs, "fig05")
    orders = ["order1", "order2", "order3", "order4"]
    fine = r["errors"]["rtol_1e-06"]
    e = [fine[o]["mean"] for o in orders]
    assert all(np.diff(e) < 0), e  # strictly lower with every order
    sizes = [r["sizes"]["rtol_1e-06"][o]["columns"] for o in orders]
    assert sizes == [10, 55, 220, 715]  # multisets on 9 non-constant functions + constant
    # at the paper's threshold every order with products still beats the plain basis; with unit-norm
    # eigenvectors (the default reading) 1e-3 cuts the higher-order columns, so orders 3 and 4 add
    # nothing there (measured 0.2789 vs 0.2788 for order 2): the ledger judges the claim at 1e-6 then
    paper = r["errors"]["rtol_1e-03"]
    assert all(paper[o]["mean"] < paper["order1"]["mean"] for o in orders[1:])
    assert paper["order3"]["mean"] < paper["order2"]["mean"] * 1.01


def test_fig06_thresholded_region_closer_with_products(runs):
    r = res(runs, "fig06")
    for k in r["errors"]["std"]:
        std, prod = r["errors"]["std"][k], r["errors"]["prod"][k]
        assert prod["rel_l2"] < std["rel_l2"], k
        assert prod["sym_diff"] < std["sym_diff"], k
        assert prod["iou"] > std["iou"], k
    assert r["errors"]["prod"]["k19"]["iou"] > 0.8


def test_fig10_products_lower_error_for_every_basis(runs):
    r = res(runs, "fig10")
    assert set(r["errors"]) == {"MH", "LMH"}
    for b, e in r["errors"].items():
        assert e["prod"]["mean"] < e["std"]["mean"], b
        assert e["prod"]["region_mean"] < e["std"]["region_mean"], b
    # the localized functions are localized, and they represent the region better than MH
    assert r["region"]["lmh_mass_inside_min"] > 0.9
    assert r["errors"]["LMH"]["std"]["region_mean"] < r["errors"]["MH"]["std"]["region_mean"]
    assert r["sizes"]["MH"]["std"] == r["sizes"]["LMH"]["std"] == 20


def test_figures_written(runs):
    ok, why = render.probe_rendering()
    for name, files in PNGS.items():
        for f in files:
            if not ok and f != "fig04_error_vs_k.png":
                continue  # 3D renders are skipped by the notebooks without a GL backend
            p = runs[name][0] / f
            assert p.is_file(), p
            assert p.stat().st_size < 400_000, (p, p.stat().st_size)


def test_render_twice_gives_identical_pixels(tmp_path, human_0):
    ok, why = render.probe_rendering()
    if not ok:
        pytest.skip(why)
    X, F = human_0.vertices, human_0.faces
    f = X[:, 2]
    cam = np.ravel(np.column_stack([X.min(0), X.max(0)]))
    imgs = [render.render_mesh(X, F, f, clim=(-1.0, 1.0), cmap="Reds", camera_bounds=cam, window_size=(120, 180))
            for _ in range(2)]
    np.testing.assert_array_equal(imgs[0], imgs[1])
    assert (imgs[0] < 250).any(axis=2).mean() > 0.05  # the shape is visible, not a blank frame
    region = X[:, 2] > 0.5
    a = render.render_mesh(X, F, region=region, camera_bounds=cam, window_size=(120, 180))
    b = render.render_mesh(X, F, region=region, camera_bounds=cam, window_size=(120, 180))
    np.testing.assert_array_equal(a, b)
    # the composed, saved figure is byte-identical too
    paths = []
    for i in range(2):
        fig = render.render_grid([imgs[i], a], titles=["f", "region"], captions=["0.1", "0.2"],
                                 colorbar=("Reds", (-1.0, 1.0), "f"))
        paths.append(save_figure(fig, tmp_path / str(i), "grid"))
    assert paths[0].read_bytes() == paths[1].read_bytes()
