"""The prefetch journal and its replay: the same values, computed ahead, recorded on misses only."""

import json
import os
import subprocess
import sys

import numpy as np

from prodmaps import datasets
from prodmaps.experiments import prefetch
from prodmaps.experiments.maps import no17_demo_map
from prodmaps.experiments.store import ShapeStore

DS = "anny_humans"


def _lines(path):
    return [json.loads(x) for x in path.read_text().splitlines() if x.strip()]


def test_a_miss_is_journaled_once_and_replayed_to_the_same_values(tmp_path, monkeypatch):
    journal = tmp_path / "journal.jsonl"
    monkeypatch.setenv(prefetch.JOURNAL_ENV, str(journal))
    first = tmp_path / "first"
    s = ShapeStore(DS, 12, cache_folder=first)
    b = s.basis("anny_000")
    gt = datasets.ground_truth(DS, "anny_000", "anny_003")
    C = no17_demo_map(s, "anny_000", "anny_003", gt, 6, 8)
    ShapeStore(DS, 12, cache_folder=first).basis("anny_000")  # a hit: not journaled again
    no17_demo_map(s, "anny_000", "anny_003", np.roll(gt, 1), 6, 8)  # not the ground truth: not replayable
    reqs = _lines(journal)
    ops = [r["op"] for r in reqs]
    assert ops.count("basis") == 2 and ops.count("no17") == 1  # anny_000 (once), anny_003 inside the map
    assert reqs[0] == {"op": "basis", "dataset": DS, "n_eig": 12, "kind": "cotan", "sid": "anny_000"}
    no17 = next(r for r in reqs if r["op"] == "no17")
    assert (no17["sid_1"], no17["sid_2"], no17["k1"], no17["k2"]) == ("anny_000", "anny_003", 6, 8)

    # replayed into another cache: the stores there read exactly the arrays computed here
    monkeypatch.delenv(prefetch.JOURNAL_ENV)
    second = tmp_path / "second"
    counts = prefetch.replay(prefetch.read_plan(journal), cache_folder=second)
    assert counts == {"done": 3, "failed": 0}
    s2 = ShapeStore(DS, 12, cache_folder=second)
    assert sorted(p.name.split("_")[0] for p in second.iterdir()) == ["eig", "eig", "no17"]
    assert np.array_equal(s2.basis("anny_000").vecs, b.vecs)
    assert np.array_equal(no17_demo_map(s2, "anny_000", "anny_003", gt, 6, 8), C)


def test_a_plan_keeps_the_first_order_without_repeats_or_bad_lines(tmp_path):
    a = {"op": "basis", "dataset": DS, "n_eig": 8, "kind": "cotan", "sid": "anny_003"}
    b = {"op": "descriptor", "dataset": DS, "n_eig": 8, "kind": "cotan", "sid": "anny_003", "name": "shot"}
    plan = tmp_path / "plan.jsonl"
    line = json.dumps(a, sort_keys=True, separators=(",", ":"))
    plan.write_text("\n".join([line, "not json", json.dumps(b, sort_keys=True, separators=(",", ":")), line, "[1]"]))
    assert prefetch.read_plan(plan) == [a, b]
    assert prefetch.keep_plan(plan, tmp_path / "kept" / "plan.jsonl") == 2
    assert prefetch.read_plan(tmp_path / "kept" / "plan.jsonl") == [a, b]
    assert len((tmp_path / "kept" / "plan.jsonl").read_text().splitlines()) == 2
    assert prefetch.plan_path("root", "paper").as_posix() == "root/paper/prefetch/paper.jsonl"


def test_the_prefetcher_process_fills_the_cache_and_skips_what_it_cannot_do(tmp_path):
    plan = tmp_path / "plan.jsonl"
    plan.write_text(json.dumps({"op": "basis", "dataset": DS, "n_eig": 8, "kind": "cotan", "sid": "anny_003"}) + "\n"
                    + json.dumps({"op": "basis", "dataset": DS, "n_eig": 8, "kind": "cotan", "sid": "no_such"}) + "\n")
    env = {**os.environ, "PRODMAPS_CACHE": str(tmp_path / "cache")}
    env.pop(prefetch.JOURNAL_ENV, None)
    r = subprocess.run([sys.executable, "-m", "prodmaps.experiments.prefetch", str(plan)], env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "1 values ready, 1 skipped" in r.stderr
    assert len(list((tmp_path / "cache" / "experiments").glob("eig_*.npz"))) == 1
    bad = subprocess.run([sys.executable, "-m", "prodmaps.experiments.prefetch"], env=env, capture_output=True,
                         text=True, timeout=60)
    assert bad.returncode == 2 and "usage" in bad.stderr


def test_the_paper_plan_is_a_clean_journal_of_the_default_data():
    from prodmaps.pipeline.registry import find_project_root

    plan = prefetch.plan_path(find_project_root(), "paper")
    lines = [x for x in plan.read_text().splitlines() if x.strip()]
    reqs = prefetch.read_plan(plan)
    assert len(reqs) == len(lines) > 0  # every line parses, none repeated
    assert {r["op"] for r in reqs} <= {"basis", "descriptor", "no17"}
    assert {r["dataset"] for r in reqs} == {DS}  # the embedded data only: nothing of FAUST
    assert all("/" not in json.dumps(r) for r in reqs)  # no paths
