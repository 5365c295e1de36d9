"""Arguments renamed so that `k` always means the paper's count (non-constant eigenfunctions): a
count of basis columns with the constant is a `*_dim`. The old names warn and give the same numbers."""

import warnings

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.experiments.fig10_lmh import lmh_reconstruction
from prodmaps.experiments.fig12_13_p2p import point_map_recovery
from prodmaps.mesh import icosphere


@pytest.fixture(scope="module")
def bumpy():
    s = icosphere(3)  # 642 vertices, made asymmetric: a simple spectrum
    rng = np.random.default_rng(3)
    v = s.vertices * (1.0 + 0.08 * rng.random((s.n_vertices, 1)))
    v[:, 0] *= 1.6
    return pm.Mesh(v, s.faces, name="bumpy")


LMH = dict(region_top_fraction=0.2, mu_region=1e4, mu_orth=1e4)


def test_lmh_reconstruction_old_names_warn_and_give_the_same_numbers(bumpy):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new names do not warn
        new = lmh_reconstruction(bumpy, mh_dim=8, global_dim=5, local_dim=3, **LMH)
    with pytest.warns(DeprecationWarning, match="use mh_dim=, global_dim=, local_dim="):
        old = lmh_reconstruction(bumpy, k_mh=8, k_global=5, k_local=3, **LMH)
    assert old["results"] == new["results"]
    assert new["results"]["sizes"]["MH"]["std"] == 8 and new["results"]["sizes"]["LMH"]["std"] == 8  # 5 + 3
    with pytest.raises(TypeError, match="not also the old k_mh, k_global, k_local"):
        lmh_reconstruction(bumpy, mh_dim=8, k_global=5, local_dim=3, **LMH)
    with pytest.raises(TypeError, match="needs mh_dim, global_dim and local_dim"):
        lmh_reconstruction(bumpy, mh_dim=8, global_dim=5, **LMH)


def test_point_map_recovery_old_names_warn_and_take_the_same_path():
    # the arguments are resolved before anything is computed: an invalid `maps` shows which path ran
    with pytest.warns(DeprecationWarning, match="use target_dim=, source_dim="), \
            pytest.raises(ValueError, match="maps must be a subset"):
        point_map_recovery(None, [], k_target=12, k_source=10, maps=("bad",))
    with pytest.raises(TypeError, match="not also the old k_target, k_source"):
        point_map_recovery(None, [], target_dim=12, k_source=10)
    with pytest.raises(TypeError, match="needs target_dim and source_dim"):
        point_map_recovery(None, [], target_dim=12)
