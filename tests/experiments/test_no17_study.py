"""The NO17 study's scoring: per-recipe transfer errors, geodesic errors, the published comparison."""

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.experiments import study_no17 as no17_study
from prodmaps.experiments.shared import maps
from prodmaps.experiments.shared.store import ShapeStore

DS = "anny_humans"


@pytest.fixture(scope="module")
def scores(tmp_path_factory):
    store = ShapeStore(DS, 41, cache_folder=tmp_path_factory.mktemp("cache"))
    pairs = list(pm.datasets.pairs(DS, "all", n=1, seed=0))
    return no17_study.score_recipes(store, pairs, ["pyfm", "authors_noicp", "authors", maps.DEFAULT_RECIPE],
                                    families=("hk_k", "XYZ"), n_eval=300, progress=False)


def test_scores_hold_every_recipe_family_and_pair(scores):
    names = ["pyfm", "authors_noicp", "authors", maps.DEFAULT_RECIPE]
    assert scores["recipes"] == names and scores["sizes"] == [29, 39]
    assert set(scores["transfer"]) == {"gt", *names}
    for r, by_f in scores["transfer"].items():
        assert set(by_f) == {"hk_k", "XYZ"} and all(len(v) == 1 and 0 <= v[0] < 2 for v in by_f.values())
        assert len(scores["geo_error"][r]) == 1 and 0 <= scores["geo_error"][r][0] < 0.5
    assert set(scores["fit_seconds"]) == set(names)
    # hk k lies in the source span: the ground-truth map transfers it best and maps best; ICP helps
    hk = {r: v["hk_k"][0] for r, v in scores["transfer"].items()}
    geo = {r: v[0] for r, v in scores["geo_error"].items()}
    assert hk["gt"] < min(hk["pyfm"], hk["authors"]) and geo["gt"] < min(geo["pyfm"], geo["authors"])
    assert hk["authors"] < hk["authors_noicp"] and geo["authors"] < geo["authors_noicp"]
    # the paper profiles' recipe maps better than pyFM's unrefined demo (the maps before study_no17)
    assert hk[maps.DEFAULT_RECIPE] < hk["pyfm"] and geo[maps.DEFAULT_RECIPE] < geo["pyfm"]


def test_comparison_with_the_published_column(scores):
    cmp = no17_study.compare_published(scores)
    rows = {(r["recipe"], r["family"]): r for r in cmp["rows"]}
    assert len(rows) == 5 * 2
    hk = rows[("authors", "hk_k")]
    assert hk["published"] == pytest.approx(0.13) and rows[("gt", "XYZ")]["published"] == pytest.approx(0.13)
    assert hk["diff"] == pytest.approx(hk["ours"] - 0.13, abs=1e-15)
    s = cmp["summary"]["authors"]
    diffs = [abs(rows[("authors", f)]["diff"]) for f in ("hk_k", "XYZ")]
    assert s["mean_abs"] == pytest.approx(np.mean(diffs)) and s["max_abs"] == pytest.approx(max(diffs))
    assert s["within_0.03"] == sum(d <= 0.03 for d in diffs) and s["cells"] == 2
    best = no17_study.best_recipe(cmp)
    assert best != "gt" and cmp["summary"][best]["mean_abs"] == min(
        v["mean_abs"] for r, v in cmp["summary"].items() if r != "gt")
    with pytest.raises(ValueError, match="no computed recipe"):
        no17_study.best_recipe({"summary": {"gt": cmp["summary"]["gt"]}})


def test_unknown_recipe_fails_before_any_work():
    with pytest.raises(ValueError, match="unknown NO17 recipe"):
        no17_study.score_recipes(ShapeStore(DS, 41, disk_cache=False), [("anny_000", "anny_001")], ["zoom"])


def test_format_table_has_a_line_per_recipe(scores):
    text = no17_study.format_table(no17_study.compare_published(scores))
    lines = text.splitlines()
    assert len(lines) == 1 + 5 and lines[1].startswith("gt") and "(0.13)" in lines[2]
