"""Approach A at several weights: ridge columns of the protocol and the study of the published A column."""

import numpy as np
import pytest

from prodmaps.experiments import study_normalization as ns
from prodmaps.experiments.shared.protocol import ProtocolSettings, approach_a_label, run_protocol, with_parameters
from prodmaps.experiments.shared.store import ShapeStore

DS = "anny_humans"
PAIRS = [("anny_000", "anny_003"), ("anny_003", "anny_011")]


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    return ShapeStore(DS, 40, cache_folder=tmp_path_factory.mktemp("cache"))


def eps_section(ridge_eps: dict | None) -> list:
    """The report's section on Approach A's ε (``ns.report_blocks`` of a study with these ``ridge_eps`` results).

    The blocks from the section's heading on (``[]`` without one); the study's own scores are one row
    beside it, with no per-cell errors, so nothing follows the section.
    """
    scores = {"library": {"std": {"cells": 1, "within": 1, "mean_abs": 0.0, "max_abs": 0.0}}}
    blocks = ns.report_blocks({"scores": scores, "ridge_eps": ridge_eps}, "the embedded humans")
    head = [i for i, b in enumerate(blocks) if b == ("h", 3, "Approach A's ε (not in the paper)")]
    assert len(head) <= 1 and blocks[0][0] == "h"  # the study's own section comes first, then at most one ε section
    return blocks[head[0]:] if head else []


SQUARED = {"3e-05": {"cells": 30, "within": 21, "mean_abs": 0.024, "max_abs": 0.09}}  # the squared ridge's scores


def norm_penalty_section(norm_penalty: dict | None) -> list:
    """The blocks on Equation 4 as printed: what follows the squared ridge's four (heading, text, table, conclusion)."""
    section = eps_section({"tables_eps": 1e-6, "best": "3e-05", "scores": SQUARED, "hks": {},
                           "norm_penalty": norm_penalty})
    assert section[3][1].startswith("Conclusion, computed from the numbers: the published Approach A column")
    return section[4:]


def test_ridge_columns_at_two_weights_are_the_registry_ridge_at_those_weights(store):
    """Two ridge columns of one run give the numbers of a run with either alone; a larger ε shrinks more."""
    fams = ["XYZ", "HKS", "Random"]
    at = run_protocol(store, PAIRS, ProtocolSettings(sizes=[(9, 9)], families=fams, columns={
        "std": ("std", {}), "our_l2_eps1e-05": ("ridge", {"eps": 1e-5}), "our_l2_eps0.001": ("ridge", {"eps": 1e-3})}),
        progress=False)
    ref = run_protocol(store, PAIRS, ProtocolSettings(sizes=[(9, 9)], families=fams, columns={
        "std": ("std", {}), "our_l2": ("ridge", {"eps": 1e-5})}), progress=False)
    for st in ("approx", "transfer"):
        for a, b in zip(at.errors[(9, 9)][st]["our_l2_eps1e-05"], ref.errors[(9, 9)][st]["our_l2"]):
            assert np.array_equal(a, b)
    small = np.concatenate(at.errors[(9, 9)]["approx"]["our_l2_eps1e-05"])
    large = np.concatenate(at.errors[(9, 9)]["approx"]["our_l2_eps0.001"])
    assert small.mean() < large.mean()  # the weight 100x larger fits worse on the source


@pytest.mark.parametrize("columns, match", [
    ({"our_B": ("svd", {})}, "'std'"),  # no standard column
    ({"std": ("svd", {})}, "'std'"),  # 'std' must be the standard transfer
    ({"std": ("std", {}), "x": ("l2", {})}, "method must be one of"),  # the old spelling is no method
    ({"std": ("std", {}), "x": ("svd", {"eps": 1e-3})}, "takes no parameter"),
    ({"std": ("std", {}), "x": "svd"}, "must be \\(method, parameters\\)"),
])
def test_columns_are_checked_against_the_registry(columns, match):
    with pytest.raises(ValueError, match=match):
        ProtocolSettings(sizes=[(9, 9)], columns=columns)


def test_the_approach_a_column_is_named_as_in_the_paper():
    assert approach_a_label("T1") == approach_a_label(None) == "our_l2"
    assert approach_a_label("T6") == "our_A"
    assert with_parameters({"std": ("std", {}), "our_A": ("ridge", {"eps": 1e-6})}, normalization="area") == {
        "std": ("std", {}), "our_A": ("ridge", {"eps": 1e-6, "normalization": "area"})}


def test_ridge_eps_scores_the_published_a_cells_and_both_hks_readings(store):
    r = ns.ridge_eps(store, PAIRS, eps_values=[1e-6, 1e-3], tables={"T1": [(9, 9)], "T3": [(6, 7)], "T6": [(29, 39)]},
                     families=["HKS", "XYZ"], progress=False)
    assert list(r["tables"]) == ["T1", "T6"]  # Table 3 has no Approach A column
    assert set(r["scores"]) == {"1e-06", "0.001"} and r["best"] in r["scores"]
    for sc in r["scores"].values():
        # published A cells: T1 transfer (our_l2) 2 families; T6 approx and transfer (our_A) 2 families
        assert sc["cells"] == 2 + 4 and 0 <= sc["within"] <= sc["cells"] and sc["max_abs"] >= sc["mean_abs"] >= 0
    h = r["hks"]["0.001"]
    assert set(h) == {"published reading", "textbook", "published"}
    assert h["published"]["T6 29/39 approx"] == 0.14
    # the textbook HKS is smooth: the ridge barely touches it; the published reading loses more at a larger ε
    assert h["textbook"]["T6 29/39 approx"] < 0.05
    assert r["hks"]["1e-06"]["published reading"]["T6 29/39 approx"] < h["published reading"]["T6 29/39 approx"]
    with pytest.raises(ValueError, match="positive"):
        ns.ridge_eps(store, PAIRS, eps_values=[0.0])


def test_ridge_eps_report_orders_eps_by_value_and_computes_its_conclusion():
    r = {"tables_eps": 1e-6, "best": "3e-05",
         "scores": {"0.0001": {"cells": 30, "within": 16, "mean_abs": 0.039, "max_abs": 0.2},
                    "1e-06": {"cells": 30, "within": 14, "mean_abs": 0.037, "max_abs": 0.2},
                    "3e-05": {"cells": 30, "within": 21, "mean_abs": 0.024, "max_abs": 0.09}},
         "hks": {e: {"published": {"T6 29/39 approx": 0.14}, "published reading": {"T6 29/39 approx": v},
                     "textbook": {"T6 29/39 approx": w}}
                 for e, v, w in (("0.0001", 0.22, 0.002), ("1e-06", 0.014, 0.0004), ("3e-05", 0.123, 0.001))}}
    blocks = eps_section(r)
    table = next(b for b in blocks if b[0] == "table")
    assert [row[0] for row in table[2]] == ["1e-06 (the tables')", "3e-05", "0.0001"]
    text = blocks[-1][1]
    assert "ε = 3e-05 (21 of 30" in text and "against 14 at the tables' 1e-06" in text
    assert "gives 0.000 to 0.002 over the ε tried, none within ±0.02" in text and "0.014 to 0.220" in text
    assert eps_section(None) == [] and eps_section({"scores": {}}) == []
    # other data: the textbook HKS near the published value is said so, with its ε; the tables' ε the best
    r["hks"]["0.0001"]["textbook"]["T6 29/39 approx"] = 0.135
    r["tables"], r["best"] = {"T1": [[9, 9]], "T6": [[29, 39]]}, "1e-06"
    r["scores"]["1e-06"]["within"] = 25
    blocks = eps_section(r)
    text = blocks[-1][1]
    assert "within ±0.02 of it at ε = 0.0001 (0.135)" in text and "none within" not in text
    assert "ε = 1e-06 (the tables' ε) (25 of 30" in text and "against" not in text
    assert "Tables 1 and 6 in the study" in blocks[1][1] and "share their approximation" not in blocks[1][1]


def test_ridge_eps_rejects_values_that_share_a_key(store):
    with pytest.raises(ValueError, match="6 significant digits"):
        ns.ridge_eps(store, PAIRS, eps_values=[1e-5, 1.0000001e-5])


def test_equation_4_as_printed_is_scored_beside_the_squared_ridge(store):
    """``norm_eps_values``: Approach A with norms (``penalty="norm"``) in the same runs, its own scores and HKS."""
    import prodmaps as pm

    r = ns.ridge_eps(store, PAIRS, eps_values=[1e-6], tables={"T1": [(9, 9)], "T6": [(29, 39)]},
                     families=["HKS", "XYZ"], norm_eps_values=[1e-3, 1e-1], progress=False)
    npen = r["norm_penalty"]
    assert set(npen["scores"]) == {"0.001", "0.1"} and npen["best"] in npen["scores"]
    assert all(sc["cells"] == r["scores"]["1e-06"]["cells"] for sc in npen["scores"].values())  # the same cells
    for e in ("0.001", "0.1"):  # a minimiser never fits worse than a = 0: approximation errors at most 1
        approx = {c: v for c, v in npen["hks"][e]["published reading"].items() if c.endswith("approx")}
        assert approx and all(v <= 1.0 for v in approx.values())
    # the weight grows with ε: the source fits worse
    assert (npen["hks"]["0.001"]["published reading"]["T6 29/39 approx"]
            < npen["hks"]["0.1"]["published reading"]["T6 29/39 approx"])
    # a ridge column with penalty="norm" is the library's operator with penalty="norm"
    res = run_protocol(store, PAIRS[:1], ProtocolSettings(sizes=[(9, 9)], families=["XYZ"], columns={
        "std": ("std", {}), "norm": ("ridge", {"eps": 1e-3, "penalty": "norm"})}), progress=False)
    b1 = store.basis(PAIRS[0][0], 10)
    F = store.mesh(PAIRS[0][0]).vertices
    ext = pm.product_basis(b1)
    a = pm.approximation_operator(ext, "ridge", eps=1e-3, penalty="norm").coefficients(F)
    np.testing.assert_allclose(res.errors[(9, 9)]["approx"]["norm"][0],
                               pm.relative_error(ext.evaluate(a), F, b1.mass), rtol=1e-9)
    assert "norm_penalty" not in ns.ridge_eps(store, PAIRS[:1], eps_values=[1e-6], tables={"T1": [(9, 9)]},
                                              families=["XYZ"], norm_eps_values=None, progress=False)
    with pytest.raises(ValueError, match="give ridge_eps_values too"):  # never dropped in silence
        ns.run(store, PAIRS[:1], readings={}, tables={"T1": [(9, 9)]}, families=["XYZ"], norm_eps_values=[1e-3])


def test_norm_penalty_report_computes_which_form_fits():
    r = {"best": "0.003",
         "scores": {"0.01": {"cells": 30, "within": 15, "mean_abs": 0.042, "max_abs": 0.37},
                    "0.003": {"cells": 30, "within": 18, "mean_abs": 0.033, "max_abs": 0.22}},
         "hks": {e: {"published": {"T5 29/29 transfer": 0.43, "T1 9/9 transfer": 0.15},
                     "published reading": {"T5 29/29 transfer": v, "T1 9/9 transfer": 0.146}}
                 for e, v in (("0.01", 0.70), ("0.003", 0.653))}}
    blocks = norm_penalty_section(r)
    table = next(b for b in blocks if b[0] == "table")
    assert [row[0] for row in table[2]] == ["0.003", "0.01"]
    assert table[2][0][-1] == "0.653 (T5 29/29 transfer, published 0.43)"
    text = blocks[-1][1]
    assert "at best 18 of 30 Approach A cells over the ε tried (ε = 0.003 σ_max" in text
    assert "the squared ridge 21 at its best ε (mean |diff| 0.024)" in text
    assert "the squared form (the tables') fits the published column better" in text
    assert "transfer cell farthest from the paper is T5 29/29 transfer: 0.653 (published 0.43)" in text
    r["scores"]["0.003"]["within"] = 24
    assert "the printed form fits the published column better" in norm_penalty_section(r)[-1][1]
    r["scores"]["0.003"]["within"] = 21  # a tie in cells: the smaller mean |diff| decides, as best_reading
    assert "the squared form (the tables') fits" in norm_penalty_section(r)[-1][1]
    r["scores"]["0.003"]["mean_abs"] = 0.024
    assert "the two forms fit the published column equally" in norm_penalty_section(r)[-1][1]
    assert norm_penalty_section(None) == [] and norm_penalty_section({"scores": {}}) == []
    # the whole ε section ends with it, after the squared ridge's conclusion
    assert len(norm_penalty_section(r)) == 3 and norm_penalty_section(r)[0][1].startswith("Equation 4 as printed")
