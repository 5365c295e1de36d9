"""The experiments layer's shared per-shape data: in-memory and on-disk caches give the same numbers."""

import numpy as np
import pytest

import prodmaps as pm
from prodmaps import fmaps
from prodmaps.experiments.shared import maps
from prodmaps.experiments.shared.store import DiskCache, ShapeStore, code_fingerprint

DS = "anny_humans"


@pytest.fixture()
def store(tmp_path):
    return ShapeStore(DS, 20, cache_folder=tmp_path / "cache")


def test_basis_from_disk_equals_a_fresh_eigenbasis(store, tmp_path):
    b = store.basis("anny_000")
    ref = pm.eigenbasis(pm.datasets.load_shape(DS, "anny_000"), 20)
    assert np.array_equal(b.vecs, ref.vecs) and np.array_equal(b.evals, ref.evals)
    assert len(list((tmp_path / "cache").glob("eig_*.npz"))) == 1
    again = ShapeStore(DS, 20, cache_folder=tmp_path / "cache").basis("anny_000")  # another process, same file
    assert np.array_equal(again.vecs, b.vecs)
    assert store.basis("anny_000", 10).cache is b.cache  # truncations share one cache
    with pytest.raises(ValueError, match="n_eig=20"):
        store.basis("anny_000", 21)


def test_disk_key_names_what_the_value_depends_on(tmp_path):
    d = DiskCache(tmp_path)
    calls = []
    value = d.get("x", {"a": 1}, lambda: calls.append(1) or {"v": np.arange(3.0)})
    again = d.get("x", {"a": 1}, lambda: calls.append(1) or {"v": np.zeros(3)})
    other = d.get("x", {"a": 2}, lambda: calls.append(1) or {"v": np.ones(3)})
    assert calls == [1, 1] and np.array_equal(again["v"], value["v"]) and np.array_equal(other["v"], np.ones(3))
    off = DiskCache(tmp_path / "off", enabled=False)
    off.get("x", {"a": 1}, lambda: {"v": np.zeros(1)})
    assert not (tmp_path / "off").exists()
    assert code_fingerprint("prodmaps.basis") != code_fingerprint("prodmaps.basis", "prodmaps.eigensolver")


def test_no17_map_is_shared_and_equals_the_direct_fit(store, tmp_path):
    gt = pm.datasets.ground_truth(DS, "anny_000", "anny_003")
    C = maps.no17_demo_map(store, "anny_000", "anny_003", gt, 8, 10, recipe="pyfm", k_descr=20)
    lm = maps.landmark_pairs(store.mesh("anny_000").vertices, gt)
    D1, D2 = fmaps.no17_demo_descriptors(store.basis("anny_000"), store.basis("anny_003"), lm, n_descr=100,
                                         subsample_step=5, k_descr=20)
    direct = fmaps.fit_no17(store.basis("anny_000", 8), store.basis("anny_003", 10), D1, D2)
    assert C.shape == (10, 8) and np.array_equal(C, direct)  # the "pyfm" recipe is pyFM's demo fit, unrefined
    fresh = ShapeStore(DS, 20, cache_folder=tmp_path / "cache")
    assert np.array_equal(maps.no17_demo_map(fresh, "anny_000", "anny_003", gt, 8, 10, recipe="pyfm", k_descr=20), C)
    assert len(list((tmp_path / "cache").glob("no17_*.npz"))) == 1
    rec = maps.recipe(maps.DEFAULT_RECIPE)
    D = maps.no17_demo_map(store, "anny_000", "anny_003", gt, 8, 10)  # the paper profiles' recipe
    lm_d = maps.landmark_pairs(store.mesh("anny_000").vertices, gt, rec.n_landmarks)
    assert np.array_equal(D, maps.no17_fit(store.basis("anny_000"), store.basis("anny_003"), lm_d, 8, 10, rec))
    assert len(list((tmp_path / "cache").glob("no17_*.npz"))) == 2 and not np.allclose(D, C)
    if rec.refine == "icp":  # orthogonal ICP returns a partial isometry
        np.testing.assert_allclose(D.T @ D, np.eye(8), atol=1e-12)
    with pytest.raises(ValueError, match="unknown NO17 recipe"):
        maps.no17_demo_map(store, "anny_000", "anny_003", gt, 8, 10, recipe="nope")
    with pytest.raises(ValueError, match="refine"):
        maps.NO17Recipe(refine="bcicp")
    assert np.allclose(maps.functional_map("gt", store, "anny_000", "anny_003", gt, 8, 10),
                       pm.fmap_from_p2p(gt, store.basis("anny_000", 8), store.basis("anny_003", 10)))
    with pytest.raises(ValueError, match="map kind"):
        maps.functional_map("learned", store, "anny_000", "anny_003", gt, 8, 10)


def test_family_functions_are_seeded_by_family_not_by_subset(store):
    gt = pm.datasets.ground_truth(DS, "anny_000", "anny_013")
    F, G, cols = store.family_functions("anny_000", gt, 0, ["HKS", "XYZ"], k_M=9, seed=0)
    F2, _, cols2 = store.family_functions("anny_000", gt, 0, ["XYZ"], k_M=9, seed=0)
    assert np.array_equal(F[:, cols["XYZ"]], F2[:, cols2["XYZ"]])
    assert np.array_equal(G, F[gt]) and F.shape == (5002, 13)
    with pytest.raises(ValueError, match="unknown family"):
        store.family_functions("anny_000", gt, 0, ["hks"], k_M=9, seed=0)


def test_families_are_stored_and_equal_a_fresh_draw(store, tmp_path, monkeypatch):
    """Each family is computed once per machine (the tables, Figure 8 and the studies draw the same
    families on the same pairs): read back exactly, keyed by seed, k_M and the store's basis."""
    from prodmaps.experiments.shared import families as pfam

    seed = pfam.family_seed(0, 3, "Indicator")
    F = store.family("anny_000", "Indicator", k_M=9, seed=seed)
    ref, _ = pfam.make_family("Indicator", pm.datasets.load_shape(DS, "anny_000"), store.basis("anny_000"),
                              k_M=9, seed=seed)
    assert np.array_equal(F, ref)
    assert len(list((tmp_path / "cache").glob("family_*.npz"))) == 1
    other = ShapeStore(DS, 20, cache_folder=tmp_path / "cache")  # another process: read, not drawn again
    with monkeypatch.context() as mp:
        mp.setattr(pfam, "make_family", lambda *a, **k: pytest.fail("drawn again"))
        assert np.array_equal(other.family("anny_000", "Indicator", k_M=9, seed=seed), F)
    assert not np.array_equal(store.family("anny_000", "Indicator", k_M=9, seed=seed + 1), F)  # another seed
    assert len(list((tmp_path / "cache").glob("family_*.npz"))) == 2
