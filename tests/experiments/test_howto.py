"""The how-to's reading of the user's own inputs: wrong files are refused by name, never used silently."""

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.experiments import howto_own_meshes as howto


@pytest.fixture(scope="module")
def repaired(tmp_path_factory):
    """A mesh file whose first vertex and last two vertices are unreferenced: ``kept`` is 1..n, the file has n + 3."""
    s = pm.mesh.ellipsoid(1)
    V = np.vstack([[[9.0, 9, 9]], s.vertices, [[8.0, 8, 8], [7.0, 7, 7]]])
    path = tmp_path_factory.mktemp("howto") / "dirty.ply"
    pm.save_mesh(path, V, s.faces + 1)
    mesh, kept = pm.io.load_mesh_repaired(path, verbose=False)
    return mesh, kept, len(V)


def test_user_function_file_must_hold_one_value_per_file_vertex(repaired, tmp_path):
    mesh, kept, n_file = repaired
    good = np.arange(n_file, dtype=float)
    np.save(tmp_path / "f.npy", good)
    np.testing.assert_array_equal(howto.user_function(str(tmp_path / "f.npy"), mesh, kept, n_file), good[kept])
    np.save(tmp_path / "col.npy", good[:, None])  # one column is one function
    np.testing.assert_array_equal(howto.user_function(str(tmp_path / "col.npy"), mesh, kept, n_file), good[kept])
    np.save(tmp_path / "xyz.npy", np.c_[good, good, good])  # three functions were flattened and sampled
    with pytest.raises(ValueError, match=r"shape \(45, 3\)"):
        howto.user_function(str(tmp_path / "xyz.npy"), mesh, kept, n_file)
    np.savetxt(tmp_path / "long.txt", np.arange(n_file + 10.0))  # values of another mesh: silently cut before
    with pytest.raises(ValueError, match=f"\\({n_file}\\) expected, got {n_file + 10}"):
        howto.user_function(str(tmp_path / "long.txt"), mesh, kept, n_file)
    np.savetxt(tmp_path / "short.txt", np.arange(10.0))
    with pytest.raises(ValueError, match="expected, got 10"):
        howto.user_function(str(tmp_path / "short.txt"), mesh, kept)


def test_user_landmarks_in_range(repaired):
    mesh, kept, n_file = repaired
    np.testing.assert_array_equal(howto.user_landmark_pairs([[1, 2]], mesh, None, kept, kept, n_file, n_file),
                                  [[0, 1]])
    with pytest.raises(ValueError, match="mesh 1 .* got \\[-1\\]"):  # -1 was the file's last vertex
        howto.user_landmark_pairs([[-1, 2]], mesh, None, kept, kept, n_file, n_file)
    with pytest.raises(ValueError, match="mesh 2 .* got \\[45\\]"):
        howto.user_landmark_pairs([[1, n_file]], mesh, None, kept, kept, n_file, n_file)


def test_user_ground_truth_is_checked(repaired, tmp_path):
    mesh, kept, n_file = repaired
    gt = np.r_[0, np.arange(1, n_file - 2), 1, 2]  # file vertex -> file vertex, the dropped ones anywhere
    np.savetxt(tmp_path / "gt.txt", gt, fmt="%d")
    np.testing.assert_array_equal(howto.user_ground_truth(tmp_path / "gt.txt", kept, kept, n_file, n_file),
                                  np.arange(mesh.n_vertices))
    np.savetxt(tmp_path / "other.txt", np.arange(n_file - 5), fmt="%d")  # the other direction (n1 != n2)
    with pytest.raises(ValueError, match=f"mesh 2's file \\({n_file}\\).*p2p_12"):
        howto.user_ground_truth(tmp_path / "other.txt", kept, kept, n_file - 5, n_file)
    np.savetxt(tmp_path / "big.txt", gt + 3, fmt="%d")  # indices reaching past the end of the file
    with pytest.raises(ValueError, match="in \\[0, 45\\)"):
        howto.user_ground_truth(tmp_path / "big.txt", kept, kept, n_file, n_file)
    np.savetxt(tmp_path / "dropped.txt", np.r_[0, np.zeros(n_file - 1, int)], fmt="%d")  # onto a dropped vertex
    with pytest.raises(ValueError, match="repair of mesh 1 removed"):
        howto.user_ground_truth(tmp_path / "dropped.txt", kept, kept, n_file, n_file)
