"""Pairs in worker processes: the same numbers as one after the other, in the pairs' order."""

import numpy as np
import pytest

from prodmaps.experiments import fig08_area_curves as fig08
from prodmaps.experiments import study_no17 as no17_study
from prodmaps.experiments import study_truncation as truncation_study
from prodmaps.experiments.fig12_13_p2p import point_map_recovery
from prodmaps.experiments.fig14_quad_transfer.crossfields import figure14_joint_study
from prodmaps.experiments.shared import maps, parallel
from prodmaps.experiments.shared.protocol import PAPER_COLUMNS, ProtocolSettings, run_protocol
from prodmaps.experiments.shared.store import ShapeStore
from prodmaps.pipeline.schedulers import thread_env

DS = "anny_humans"
PAIRS = [("anny_000", "anny_003"), ("anny_003", "anny_000"), ("anny_000", "anny_009")]


def _sq(x, y=1):
    return x * x + y


def test_map_tasks_keeps_the_order_in_workers_and_here():
    tasks = [(i, 2 * i) for i in range(7)]
    expected = [_sq(*t) for t in tasks]
    assert list(parallel.map_tasks(_sq, tasks, workers=1)) == expected
    assert list(parallel.map_tasks(_sq, tasks, workers=2)) == expected
    assert list(parallel.map_tasks(_sq, [], workers=2)) == []
    with pytest.raises(ValueError, match="positive integer"):
        list(parallel.map_tasks(_sq, tasks, workers=0))


def _pid(_, sleep=0.0):
    import os
    import time

    time.sleep(sleep)
    return os.getpid()


def test_workers_are_kept_and_a_key_returns_to_its_worker():
    parallel.shutdown_workers()
    # "b" is slow: the worker of "a" is free first and runs the second "a" task itself
    first = list(parallel.map_tasks(_pid, [(0,), (1, 1.0), (2,)], workers=2, keys=["a", "b", "a"]))
    assert first[0] == first[2] != first[1]  # one worker per key
    again = list(parallel.map_tasks(_pid, [(0,), (1,)], workers=2, keys=["b", "a"]))
    assert again == [first[1], first[0]]  # the same processes, the same key -> worker
    with pytest.raises(ValueError, match="keys"):
        list(parallel.map_tasks(_pid, [(0,)], workers=2, keys=["a", "b"]))
    parallel.shutdown_workers()
    assert list(parallel.map_tasks(_pid, [(0,), (1,)], workers=2, keys=["a", "b"]))[0] not in first


def test_a_free_worker_takes_the_waiting_task_of_a_busy_one():
    parallel.shutdown_workers()
    # "a" is slow and has a second task waiting: the worker of "b" is free first and takes it,
    # and "a" moves to that worker
    out = list(parallel.map_tasks(_pid, [(0, 1.0), (1,), (2,)], workers=2, keys=["a", "b", "a"]))
    assert out[1] == out[2] != out[0]
    # both keys are now held by one worker: the idle one takes the last of them ("b")
    again = list(parallel.map_tasks(_pid, [(0,)] * 2, workers=2, keys=["a", "b"]))
    assert again == [out[2], out[0]]
    parallel.shutdown_workers()


def _pair_facts(store, i, src, item, tag, *, scale):
    import os

    return src, item * scale, tag, os.getpid(), store.n_eig, id(store)


def test_map_by_source_groups_a_source_in_one_worker_and_keeps_the_items_order(store):
    import os

    items = [("a", 1), ("b", 2), ("a", 3), ("c", 4), ("b", 5)]
    out = list(parallel.map_by_source(_pair_facts, store, items, "x", workers=2, scale=10))
    assert [i for i, _ in out] == list(range(5))
    assert [r[:3] for _, r in out] == [(s, 10 * v, "x") for s, v in items]
    pid = {}
    for _, (src, _, _, p, n_eig, _) in out:
        assert pid.setdefault(src, p) == p != os.getpid() and n_eig == store.n_eig  # the store rebuilt there
    assert parallel.worker_store(parallel.store_spec(store)).n_eig == store.n_eig
    assert parallel.worker_store(store) is store
    serial = list(parallel.map_by_source(_pair_facts, store, items, "x", workers=1, scale=10))
    assert [r[:3] for _, r in serial] == [r[:3] for _, r in out]
    assert all(r[3] == os.getpid() and r[5] == id(store) for _, r in serial)  # here: the store itself


def _facts(_):
    from threadpoolctl import threadpool_info

    return parallel.default_workers(), max(i["num_threads"] for i in threadpool_info())


def test_a_worker_runs_one_blas_thread_and_no_workers_of_its_own():
    assert list(parallel.map_tasks(_facts, [(0,), (1,)], workers=2)) == [(1, 1), (1, 1)]
    assert list(parallel.map_tasks(_facts, [(0,)], workers=1))[0][1] == 1  # here too, while a task runs


def test_default_workers_reads_the_environment(monkeypatch):
    monkeypatch.setenv(parallel.WORKERS_ENV, "3")
    assert parallel.default_workers() == 3
    monkeypatch.setenv(parallel.WORKERS_ENV, "none")
    with pytest.raises(ValueError, match="PRODMAPS_WORKERS"):
        parallel.default_workers()
    monkeypatch.delenv(parallel.WORKERS_ENV)
    assert parallel.default_workers() >= 1


def test_several_notebooks_at_once_share_the_cpus_among_their_workers(monkeypatch):
    monkeypatch.delenv(parallel.WORKERS_ENV, raising=False)
    monkeypatch.setattr("os.cpu_count", lambda: 8)
    assert thread_env(1) == {} and thread_env(4)["PRODMAPS_WORKERS"] == "2"
    monkeypatch.setenv(parallel.WORKERS_ENV, "5")  # the user's choice stays
    assert "PRODMAPS_WORKERS" not in thread_env(4)


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    return ShapeStore(DS, 40, cache_folder=tmp_path_factory.mktemp("cache"))


def test_protocol_errors_do_not_depend_on_the_number_of_workers(store):
    s = ProtocolSettings(sizes=[(9, 9), (19, 29)], columns={m: PAPER_COLUMNS[m] for m in (
        "std", "our_l2", "our_B", "our_default")}, families=["XYZ", "Indicator", "HKS"])
    one = run_protocol(store, PAIRS, s, progress=False, workers=1)
    two = run_protocol(store, PAIRS, s, progress=False, workers=2)
    assert one.pairs == two.pairs == PAIRS and one.cols == two.cols
    for z in s.sizes:
        assert one.map_deviation[z] == two.map_deviation[z] and one.ranks[z] == two.ranks[z]
        assert len(one.ranks[z]["our_B"]) == len(PAIRS)
        for st in ("approx", "transfer"):
            for m in s.columns:
                assert len(one.errors[z][st][m]) == len(PAIRS)
                for a, b in zip(one.errors[z][st][m], two.errors[z][st][m]):
                    assert np.array_equal(a, b)


def test_area_curves_are_measured_in_workers_with_the_same_numbers(store):
    s = ProtocolSettings(sizes=[(9, 9)], columns=fig08.columns(["std", "B"], rtol=1e-3, eps_ridge=1e-6, max_gain=2.0),
                         families=["XYZ", "Indicator"])
    gamma = np.linspace(0.0, 0.1, 5)
    curves = {}
    for w in (1, 2):
        c = curves[w] = fig08.AreaCurves(gamma, s.families, list(s.columns))
        run_protocol(store, PAIRS, s, progress=False, workers=w, collect=c)
    serial = fig08.AreaCurves(gamma, s.families, list(s.columns))  # a plain callable: called in this process
    run_protocol(store, PAIRS, s, progress=False, collect=lambda *a: serial(*a))
    ref = curves[1].mean()
    for other in (curves[2], serial):
        got = other.mean()
        for c in ref:
            for st in ref[c]:
                for m in ref[c][st]:
                    for f in ref[c][st][m]:
                        # the same arrays, summed in another process: numpy's SIMD sums may round
                        # the last bit differently with another memory alignment
                        np.testing.assert_allclose(got[c][st][m][f], ref[c][st][m][f], rtol=1e-13, atol=0)
    one = curves[1].mean()["paper"]["transfer"]["B"]["Indicator"]
    assert one.shape == gamma.shape and np.all(np.diff(one) >= 0)  # a fraction grows with gamma
    per_pair = curves[2].auc_per_pair()["paper"]["approx"]["std"]
    assert per_pair and all(len(v) == len(PAIRS) for v in per_pair.values())  # one curve per pair, every family


def test_point_map_recovery_does_not_depend_on_the_number_of_workers(store):
    kw = dict(target_dim=12, source_dim=10, maps=("gt",), n_eval=60, seed=3, verbose=False)
    one = point_map_recovery(store, PAIRS, workers=1, **kw)["results"]
    two = point_map_recovery(store, PAIRS, workers=2, **kw)["results"]
    assert one["pairs"] == two["pairs"] == [f"{a}->{b}" for a, b in PAIRS]
    assert one["per_pair"] == two["per_pair"] and one["mean_error"] == two["mean_error"]


@pytest.mark.slow
def test_figure14_study_does_not_depend_on_the_number_of_workers():
    pairs = [("anny_000", "anny_003"), ("anny_010", "anny_016")]
    params = {"quad_size": 0}  # no quad meshes: the designs and their measures
    one = figure14_joint_study(DS, pairs, [6], params=params, verbose=False, workers=1)
    two = figure14_joint_study(DS, pairs, [6], params=params, verbose=False, workers=2)
    for name in one["pairs"]:
        a, b = dict(one["pairs"][name]), dict(two["pairs"][name])
        a.pop("seconds"), b.pop("seconds")
        assert a == b
    f1, f2 = one["shown"][2], two["shown"][2]  # the fields of pair 0, computed in a worker for workers=2
    assert set(f1) == set(f2) and (6, "std") in f1
    for key in f1:
        assert all(np.array_equal(a, b) for a, b in zip(f1[key], f2[key]))


def test_studies_do_not_depend_on_the_number_of_workers(store):
    kw = dict(sizes=[(9, 9)], map_kinds=["gt"], families=["XYZ", "HKS"], rtols=[1e-4, 1e-3, 1e-2],
              eps_list=[1e-6, 1e-4], progress=False)
    one = truncation_study.run(store, PAIRS, workers=1, **kw)
    two = truncation_study.run(store, PAIRS, workers=2, **kw)
    assert one["results"]["summary"] == two["results"]["summary"]
    assert one["results"]["product_preservation_deviation"] == two["results"]["product_preservation_deviation"]
    assert all(np.array_equal(a, b) for a, b in zip(one["gains"]["k9_9/gt"], two["gains"]["k9_9/gt"]))
    assert len(one["gains"]["k9_9/gt"]) == len(PAIRS)
    kw = dict(k_M=9, k_N=9, families=("XYZ",), n_eval=50, progress=False)
    s1 = no17_study.score_recipes(store, PAIRS[:2], [maps.DEFAULT_RECIPE], workers=1, **kw)
    s2 = no17_study.score_recipes(store, PAIRS[:2], [maps.DEFAULT_RECIPE], workers=2, **kw)
    assert s1["transfer"] == s2["transfer"] and s1["geo_error"] == s2["geo_error"]
    assert len(s1["geo_error"]["gt"]) == 2
