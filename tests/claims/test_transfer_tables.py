"""Claims of Tables 1-6, Figure 8 and the truncation study on the smoke results.

Each notebook's smoke profile runs once through papermill (module-scoped fixtures, temporary
folders); the tests read its ``results.json``.

Asserted as the paper states them (they reproduce on the embedded data, Table 1 setting:
ground-truth map, ``k_M = k_N = 9``, Approach B with the paper's ``rtol = 1e-3``):

* WKS and Random functions (in or near the span of the products) are transferred with
  products at less than half the standard error; approximations with products are better
  than the standard ones for WKS, Random, XYZ and Indicator; ``hk k`` lies in the span of the
  basis (standard approximation exact).
* Figure 8: the approximation curves (dashed) with products lie above the standard ones for the
  indicator.

Asserted as *our* findings (the truncation study; not claims of the paper): on the default data
the paper's ``rtol = 1e-3`` keeps singular directions whose transfer gain is far above 1, and
``rtol = 1e-2`` transfers coordinates and indicators better; the map-based "gain" rule does at
least as well as the fixed threshold there, the source-only cross-validation does not.

Not asserted (measured and shown in the notebooks and the report, whatever the outcome): HKS
(our HKS family is smooth: the standard transfer is already near exact), products beating the
standard transfer for XYZ, Indicator, SHOT, AWFT, hk K at ``rtol = 1e-3``, and every claim
with computed maps (Tables 2 and 4, Figure 8's transfer curves).
"""

import numpy as np
import pytest

from prodmaps.experiments.shared.published import load_published, match_entries

pytestmark = pytest.mark.notebook


# ------------------------------------------------------------------------------ Table 1
def test_table1_outputs_well_formed(smoke_results):
    d, res = smoke_results("tab01")
    for f in ("T1_ours.csv", "T1_vs_published.csv", "table.json", "T1_vs_published.png"):
        assert (d / f).is_file(), f
    assert len(res["pairs"]) == 2 and res["fmap"] == "ground_truth"
    matches, unmatched = match_entries(res["table"], load_published())
    assert not unmatched, unmatched
    # every published T1 cell of the smoke families is filled, with a finite error
    rows = set(res["errors"]["k9_9"]["transfer"]["std"])
    labels = {r for r in rows if " (" not in r}  # "HKS (textbook)": another reading, no published cell
    assert rows - labels == {"HKS (textbook)"}
    assert len(matches) == 6 * len(labels)
    assert all(np.isfinite(e["value"]) and e["value"] >= 0 for e in res["table"])
    assert res["map_deviation_from_gt"]["k9_9"]["mean"] < 1e-12  # the ground-truth map
    # each value carries its standard error over the pairs: the population std over 2 pairs, / sqrt(2 - 1)
    for e in res["table"]:
        std = res["errors_std_over_pairs"]["k9_9"][e["stage"]][e["method"]][e["function"]]
        assert e["se"] == pytest.approx(std, rel=1e-12, abs=1e-15)
    assert any(e["se"] > 1e-4 for e in res["table"])  # the two pairs differ


def test_table1_hkk_in_span(smoke_results):
    _, res = smoke_results("tab01")
    e = res["errors"]["k9_9"]
    assert e["approx"]["std"]["hk k"] < 1e-8  # the heat kernels from k_M + 1 eigenpairs lie in the basis


@pytest.mark.parametrize("fam", ["WKS", "Random"])
@pytest.mark.parametrize("method", ["our_l1", "our_l2", "our_B"])
def test_table1_products_far_below_std_transfer(smoke_results, fam, method):
    _, res = smoke_results("tab01")
    t = res["errors"]["k9_9"]["transfer"]
    assert t[method][fam] < 0.5 * t["std"][fam], (fam, method, t[method][fam], t["std"][fam])


@pytest.mark.parametrize("fam", ["WKS", "Random", "XYZ", "Indicator"])
def test_table1_products_improve_approximation(smoke_results, fam):
    _, res = smoke_results("tab01")
    a = res["errors"]["k9_9"]["approx"]
    for method in ("our_l1", "our_l2", "our_B"):
        assert a[method][fam] < a["std"][fam], (fam, method)


# ------------------------------------------------------------------------------ Table 2
@pytest.mark.slow
def test_table2_computed_maps_well_formed(smoke_results):
    _, res = smoke_results("tab02")
    assert res["fmap"] == "computed_NO17" and res["settings"] == [[29, 39]]
    matches, unmatched = match_entries(res["table"], load_published())
    assert not unmatched and len(matches) == len(res["table"]) > 0
    dev = res["map_deviation_from_gt"]["k29_39"]["per_pair"]
    assert all(0.0 < v < 1.0 for v in dev)  # a computed map: close to, not equal to, the ground truth
    for st in ("approx", "transfer"):
        for m, row in res["errors"]["k29_39"][st].items():
            assert all(np.isfinite(v) and v >= 0 for v in row.values()), (st, m)


# ------------------------------------------------------------------------------ Figure 8
@pytest.mark.slow
def test_fig08_curves_are_area_fractions(smoke_results):
    d, res = smoke_results("fig08")
    assert (d / "fig08_area_curves.png").is_file()
    g = np.asarray(res["gamma"])
    assert g[0] == 0.0 and g[-1] == 1.0
    for crit in res["curves"].values():
        for st in crit.values():
            for m in st.values():
                for c in m.values():
                    c = np.asarray(c)
                    assert c.shape == g.shape
                    assert np.all(np.diff(c) >= -1e-12) and c.min() >= 0 and c.max() <= 1 + 1e-12


@pytest.mark.slow
def test_fig08_products_improve_indicator_approximation(smoke_results):
    _, res = smoke_results("fig08")
    for crit in ("paper", "scale_free"):
        auc = res["auc"][crit]["approx"]
        assert auc["B"]["Indicator"] > auc["std"]["Indicator"]
        assert auc["l2"]["Indicator"] > auc["std"]["Indicator"]


# ------------------------------------------------------------------------------ truncation study
@pytest.mark.slow
def test_study_gains_explain_the_threshold(smoke_results):
    """With unit-norm eigenvectors (the default reading), 1e-3 keeps only directions that the map
    transfers with gain about 1; smaller thresholds keep amplified ones (measured, smoke: median
    largest kept gain 1.2-1.6 at 1e-3, 5.6-11.8 at 1e-4; under the metre reading it was 20-100 at 1e-3)."""
    _, res = smoke_results("study_truncation")
    for key, g in res["median_max_gain_of_kept_directions"].items():
        assert g["0.001"] < 2.0, key
        assert g["0.0001"] > 2.0 * g["0.001"], key
        assert g["0.1"] < 1.2, key      # the leading directions are transferred with gain about 1
        assert g["0.0001"] >= g["0.001"] >= g["0.01"] >= g["0.1"], key


@pytest.mark.slow
@pytest.mark.parametrize("fam", ["XYZ", "Indicator"])
def test_study_paper_threshold_near_the_oracle_and_gain_rule_never_worse(smoke_results, fam):
    """Coordinates and indicators: the paper's 1e-3 is within 5 % of the best threshold in hindsight
    and beats both 1e-2 and the standard transfer; the gain rule is never worse than 1e-3; source-only
    cross-validation keeps too much (measured, smoke: XYZ 0.283 at 1e-3 = oracle vs std 0.352)."""
    _, res = smoke_results("study_truncation")
    rt = [float(r) for r in res["rtols"]]
    for key, summ in res["summary"].items():
        s = summ[fam]
        err = s["rtol"]["transfer"]
        ch = s["chosen"]
        assert ch["paper"]["transfer"] <= 1.05 * ch["oracle"]["transfer"], key
        assert err[rt.index(1e-3)] < err[rt.index(1e-2)] < s["std_transfer"], key
        assert ch["gain"]["transfer"] <= ch["paper"]["transfer"] * (1 + 1e-9), key
        assert ch["gain"]["transfer"] < ch["cv"]["transfer"], key
        # the approximation on the source, not the map, dominates the error at the paper's threshold
        assert s["rtol"]["map_part"][rt.index(1e-3)] < s["rtol"]["approx"][rt.index(1e-3)], key


@pytest.mark.slow
def test_study_wks_products_far_below_std_at_every_threshold_that_keeps_products(smoke_results):
    _, res = smoke_results("study_truncation")
    rt = [float(r) for r in res["rtols"]]
    for key, summ in res["summary"].items():
        s = summ["WKS"]
        kept = [e for r, e in zip(rt, s["rtol"]["transfer"]) if r <= 1e-2]  # above, only the basis is kept
        assert max(kept) < 0.5 * s["std_transfer"], key
