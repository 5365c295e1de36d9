"""The held-out check of every reading: the frozen reading scored on a run's data, without choosing again."""

import json
from pathlib import Path

import pytest

from prodmaps.experiments import fig12_13_p2p, study_family_readings, study_no17, study_normalization
from prodmaps.experiments.shared.families import PUBLISHED_READINGS

BASE = Path(__file__).resolve().parents[2] / "paper" / "baselines" / "smoke"
FIELDS = {"reading", "alternatives", "cells", "frozen", "cells_n", "within", "within_noise", "choice_here", "agrees"}


def _results(run):
    return json.loads((BASE / run / "results.json").read_text())["results"]


def test_family_readings_score_the_library_reading_not_the_choice_of_the_data():
    res = _results("study_family_readings")
    rows = study_family_readings.reading_summary(res)
    assert rows and all(FIELDS <= set(r) for r in rows)
    for r in rows:
        fam = next(f for f in res["scores"] if r["reading"].startswith(f.replace("_", " ")))
        assert r["frozen"] == res["published_readings"][fam]  # frozen, not re-chosen
        assert r["choice_here"] == res["chosen"][fam] and r["agrees"] == (r["frozen"] == r["choice_here"])
        assert 0 <= r["within"] <= r["within_noise"] <= r["cells_n"]  # the draw-noise band contains ±0.02
        assert r["alternatives"] == len(res["scores"][fam])
    # the library's readings are the frozen ones whatever the data chooses
    hks = next(r for r in rows if r["reading"].startswith("HKS"))
    assert hks["frozen"] == PUBLISHED_READINGS["HKS"] != hks["choice_here"]  # the smoke data would choose otherwise


def test_a_changed_choice_shows_as_disagreement():
    res = json.loads(json.dumps(_results("study_family_readings")))
    fam = next(iter(res["scores"]))
    other = next(r for r in res["scores"][fam] if r != res["published_readings"][fam])
    res["chosen"][fam], res["agrees"][fam] = other, False
    row = next(r for r in study_family_readings.reading_summary(res) if r["choice_here"] == other)
    assert row["agrees"] is False and row["frozen"] == res["published_readings"][fam]


def test_normalisation_and_recipe_and_heat_time_rows():
    norm = study_normalization.reading_summary(_results("study_normalization"))
    assert len(norm) == 1 and FIELDS <= set(norm[0]) and norm[0]["frozen"] == study_normalization.LIBRARY_READING
    assert norm[0]["within"] <= norm[0]["cells_n"] and norm[0]["within_noise"] is None
    heat = fig12_13_p2p.reading_summary(_results("fig12_13"))
    assert len(heat) == 1 and heat[0]["frozen"] == "extended t x1" and heat[0]["alternatives"] == 3
    assert heat[0]["frozen_error"] == pytest.approx(min(
        r["mean_error"] for r in _results("fig12_13")["sweep"]["rows"] if r["setting"] == "extended t x1"))
    # a smoke run without the library's recipe has nothing to report; with it, one row
    assert study_no17.reading_summary(_results("study_no17")) == []
    comp = {"summary": {"gt": {}, "a": {}, "b": {}}, "rows": [
        {"recipe": "a", "diff": 0.01}, {"recipe": "a", "diff": -0.05}, {"recipe": "b", "diff": 0.001}]}
    comp["summary"]["a"]["mean_abs"], comp["summary"]["b"]["mean_abs"] = 0.03, 0.001
    comp["summary"]["gt"]["mean_abs"] = 0.0
    row = study_no17.reading_summary({"comparison": comp, "default_recipe": "a"})[0]
    got = (row["within"], row["cells_n"], row["choice_here"], row["agrees"], row["alternatives"])
    assert got == (1, 2, "b", False, 2)


def test_the_tables_score_every_frozen_reading_by_its_cells():
    from prodmaps.experiments.shared.families import PAPER_LABELS
    from prodmaps.experiments.tables_transfer import held_out_rows

    tabs = {t: _results(f"tab0{t[1]}") for t in ("T1", "T2", "T3", "T5", "T6")}
    rows = {r["reading"]: r for r in held_out_rows(tabs)}
    assert rows["HKS parameters"]["frozen"] == PUBLISHED_READINGS["HKS"]
    assert "NO17 recipe" in rows and "Approach B's normalisation" in rows
    for r in rows.values():
        assert 0 <= r["within"] <= r["within_noise"] <= r["cells_n"]
    # the cells are counted from the printed tables: recount one family by hand
    hks = [e for t in ("T1", "T3", "T5", "T6") for e in tabs[t]["table"]
           if e["function"] == PAPER_LABELS["HKS"] and e["method"] == "std"]
    assert rows["HKS parameters"]["cells_n"] == len(hks) > 0
    # one table less, fewer cells; no tables, no rows
    fewer = held_out_rows({k: v for k, v in tabs.items() if k != "T6"})
    assert fewer[0]["cells_n"] < rows["hk k parameters"]["cells_n"]
    assert held_out_rows({}) == []
