"""Figures 12/13's evaluation: one seeded draw of evaluated vertices per source shape."""

import numpy as np
import pytest

from prodmaps.experiments.fig12_13_p2p import evaluation_vertices, point_map_recovery
from prodmaps.experiments.shared.store import ShapeStore

DS = "anny_humans"


def test_evaluation_vertices_are_a_seeded_draw_per_source():
    a = evaluation_vertices(5000, 300, 0, "anny_000")
    assert a.shape == (300,) and np.all(np.diff(a) > 0) and 0 <= a[0] and a[-1] < 5000  # sorted, distinct
    assert np.array_equal(a, evaluation_vertices(5000, 300, 0, "anny_000"))
    assert not np.array_equal(a, evaluation_vertices(5000, 300, 1, "anny_000"))  # the seed
    assert not np.array_equal(a, evaluation_vertices(5000, 300, 0, "anny_001"))  # the source
    assert np.array_equal(evaluation_vertices(40, 40, 0, "x"), np.arange(40))
    for bad in (0, 41):
        with pytest.raises(ValueError, match="n_eval"):
            evaluation_vertices(40, bad, 0, "x")


def test_pairs_of_one_source_share_their_geodesic_rows(tmp_path):
    """On shapes in correspondence by index, a source's pairs need ``n_eval`` distance rows in all."""
    store = ShapeStore(DS, 20, cache_folder=tmp_path / "cache")
    pairs = [("anny_000", "anny_003"), ("anny_000", "anny_009"), ("anny_000", "anny_011")]
    res = point_map_recovery(store, pairs, target_dim=12, source_dim=10, maps=("gt",), n_eval=80, seed=2,
                             verbose=False, workers=1)["results"]
    assert store.distance_rows("anny_000").n_solved == 80
    assert len(res["per_pair"]) == 3 and all(0 <= r["gt_std"] < 0.5 for r in res["per_pair"])
    # the order of the pairs changes nothing
    again = point_map_recovery(ShapeStore(DS, 20, cache_folder=tmp_path / "cache"), pairs[::-1], target_dim=12,
                               source_dim=10, maps=("gt",), n_eval=80, seed=2, verbose=False, workers=1)["results"]
    assert {r["pair"]: r for r in again["per_pair"]} == {r["pair"]: r for r in res["per_pair"]}


def test_subject_pairs_in_both_directions_or_once():
    from prodmaps.experiments.fig12_13_p2p import subject_pairs

    both = subject_pairs("anny_humans", "0")
    once = subject_pairs("anny_humans", "0", both_directions=False)
    assert len(both) == 10 * 9 and len(once) == 45  # 10 poses: 90 ordered pairs, 45 pairs of shapes
    assert set(once) | {(b, a) for a, b in once} == set(both) and all(a < b for a, b in once)
    assert subject_pairs("anny_humans", "0", 5, seed=1, both_directions=False) == \
        subject_pairs("anny_humans", "0", 5, seed=1, both_directions=False)
