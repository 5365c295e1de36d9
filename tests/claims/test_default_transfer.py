"""Acceptance of the library's default extended transfer on the smoke run of `study_default`.

Over every condition (ground-truth / NO17 / perturbed maps; 9/9, 29/39, 27/35, 6/7; intra, inter
and remeshed pairs) and all nine families: never above the standard transfer by more than 0.01,
HKS/WKS far below it with ground-truth maps, and clearly below it on average. The paper's Approach
B at rtol = 1e-3 fails the first condition on the same numbers (the reason for the default).
"""

import numpy as np
import pytest

pytestmark = pytest.mark.notebook


@pytest.fixture(scope="module")
def study(smoke_results):
    return smoke_results("study_default")[1]


def test_every_condition_and_family_is_covered(study):
    conds = set(study["errors"])
    for mk in ("gt", "computed", "perturbed"):
        for z in ("9_9", "29_39", "27_35", "6_7"):
            for kind in ("intra", "inter"):
                assert f"{mk}/{z}/{kind}" in conds
    assert any(c.endswith("/variant") for c in conds)
    fams = set(next(iter(study["errors"].values())))
    assert fams == {"hk k", "hk K", "HKS", "WKS", "Random", "XYZ", "Indicator", "SHOT", "AWFT"}


def test_default_never_worse_than_std_plus_001(study):
    bad = [(c, f, v["our_default"], v["std"]) for c, fams in study["errors"].items() for f, v in fams.items()
           if v["our_default"] > v["std"] + 0.01]
    assert not bad, bad
    # the paper's fixed threshold does not have this property on the same data
    assert study["summary"]["our_B"]["cells_above_std_plus_0.01"] > 0


def test_default_never_worse_than_std_plus_001_per_single_function(study):
    # every (condition, pair, function column), not only family means -- with ground-truth and
    # perturbed maps. With ICP-refined NO17 maps the truncation test is blind (an orthogonalised C has
    # CᵀC = I whatever the map lost), and single heat kernels hk K of one intra pair come out above
    # std + 0.01 at 27/35 and 29/39 (see docs/guide/default_transfer.md): asserted as
    # the known limit, not hidden
    s = study["summary"]["our_default"]
    assert s["single_functions"] == sum(v["our_default"]["functions"] for v in study["single"].values()) > 0
    for cond, v in study["single"].items():
        d = v["our_default"]
        if not cond.startswith("computed/"):
            assert d["above_0.01"] == 0 and d["worst_excess"] <= 0.01, (cond, d)
        else:
            assert d["above_0.01"] <= 0.02 * d["functions"], (cond, d)


def test_default_far_below_std_for_hks_wks_with_ground_truth(study):
    for fam in ("HKS", "WKS"):
        r = np.array([v[fam]["our_default"] / v[fam]["std"] for c, v in study["errors"].items() if c.startswith("gt/")])
        assert r.mean() < 0.5 and r.max() < 0.75, (fam, r)


def test_default_clearly_below_std_on_average(study):
    s = study["summary"]["our_default"]
    assert s["ratio_of_means"] < 0.9 and s["mean_ratio_to_std"] < 0.9
    # the trade the default makes: the gain rule (Approach B with a map-based threshold) is lower on
    # average but puts single functions far above the standard transfer; the default puts none there
    g = study["summary"]["our_B_gainrule"]
    assert g["single_above_std_plus_0.01"] > s["single_above_std_plus_0.01"]
