"""Tests of prodmaps.fields: frames, cross fields, operators, consistency."""

import numpy as np
import pytest

import prodmaps as pm
from prodmaps import fields as pf
from prodmaps.fields import crossfield as cf
from prodmaps.fields.consistency import consistency_problem, design_consistent_field, design_joint
from prodmaps.fields.frames import corner_angles
from prodmaps.mesh import ellipsoid, icosphere


# ----------------------------------------------------------------------------- helpers
def relabelled_copy(mesh, seed=0, angle=0.7):
    """A rigidly rotated copy with permuted vertices, permuted faces and rolled face corners.

    Returns ``(copy, p2p_21, R)``: vertex ``y`` of the copy is vertex ``p2p_21[y]`` of ``mesh``.
    """
    rng = np.random.default_rng(seed)
    n = mesh.n_vertices
    p = rng.permutation(n)
    inv = np.argsort(p)
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    F2 = inv[mesh.faces]
    shift = rng.integers(0, 3, F2.shape[0])
    F2 = np.take_along_axis(F2, (np.arange(3)[None] + shift[:, None]) % 3, axis=1)[rng.permutation(F2.shape[0])]
    return pm.Mesh(mesh.vertices[p] @ R.T, F2), p, R


def complete_basis(mesh):
    """All eigenpairs (k = n): projections are exact."""
    import scipy.linalg as sla

    W, A = pm.laplacian(mesh)
    evals, vecs = sla.eigh(W.toarray(), np.diag(A))
    evals[0] = 0.0
    vecs[:, 0] = 1 / np.sqrt(A.sum())
    return pm.Basis(vecs, np.maximum(evals, 0), A)


def direction_guide(fr, a=(0.3, 0.5, 0.8), N=4):
    """Unit N-power guide along the tangential projection of a fixed direction."""
    a = np.asarray(a, float) / np.linalg.norm(a)
    t = a[None] - (fr.normal @ a)[:, None] * fr.normal
    return cf.normalize_field(pf.to_complex(t, fr) ** N)


@pytest.fixture(scope="module")
def ico2():
    return icosphere(2)  # 162 vertices


def _pair(m1):
    """``m1``, a relabelled rotated copy, bases (21 columns) and a smooth aligned cross field."""
    m2, p, R = relabelled_copy(m1)
    fr1, fr2 = pf.mesh_frames(m1), pf.mesh_frames(m2)
    z1 = pf.aligned_field(fr1, direction_guide(fr1), 4, scale=0.1)
    return {"m1": m1, "m2": m2, "p": p, "R": R, "fr1": fr1, "fr2": fr2, "z1": z1,
            "b1": pm.eigenbasis(m1, 21), "b2": pm.eigenbasis(m2, 21)}


@pytest.fixture(scope="module")
def pair3():
    """The round icosphere(3) and its copy (see :func:`_pair`): for the tests of the geometry.

    Its Laplacian has repeated eigenvalues (2 x3, 6 x5, ...), so the eigenvectors inside an
    eigenspace, and anything built from individual ones, depend on the LAPACK/BLAS kernel: tests
    on it may only use the span of complete eigenspaces (or no eigenvectors at all).
    """
    return _pair(icosphere(3))


@pytest.fixture(scope="module")
def ell_pair3():
    """ellipsoid(3) (642 vertices, simple spectrum) and its copy (see :func:`_pair`).

    For the consistency designs: the standard design's test functions are the individual basis
    functions (a quartic form is not determined by a span), so it needs eigenvectors that are
    unique up to sign, the same on every machine.
    """
    return _pair(ellipsoid(3))


# ----------------------------------------------------------------------------- frames
def test_complex_gradient_of_linear_function_is_projected_gradient(ico2):
    fr = pf.mesh_frames(ico2)
    G = pf.complex_gradient(fr)
    assert G.shape == (ico2.n_faces, ico2.n_vertices)
    for axis in range(3):
        g = pf.to_vectors(G @ ico2.vertices[:, axis], fr)
        e = np.eye(3)[axis]
        expected = e[None] - fr.normal[:, [axis]] * fr.normal
        np.testing.assert_allclose(g, expected, atol=1e-12)


def test_to_complex_roundtrip_and_rotation(ico2):
    fr = pf.mesh_frames(ico2)
    z = np.exp(1j * np.linspace(0, 5, ico2.n_faces))
    np.testing.assert_allclose(pf.to_complex(pf.to_vectors(z, fr), fr), z, atol=1e-14)
    # multiplying by i is the rotation n x X
    np.testing.assert_allclose(pf.to_vectors(1j * z, fr), np.cross(fr.normal, pf.to_vectors(z, fr)), atol=1e-14)


def test_polygon_corner_degrees_of_squares_and_triangles(ico2):
    square = np.array([[[0.0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]]])  # (1, 4, 3)
    np.testing.assert_allclose(pf.polygon_corner_degrees(square), [[90.0] * 4], atol=1e-12)
    # on triangles: the mesh's corner angles (radians, another formula), in degrees
    V, F = ico2.vertices, ico2.faces
    np.testing.assert_allclose(pf.polygon_corner_degrees(V[F]), np.degrees(corner_angles(V, F)), atol=1e-9)
    np.testing.assert_allclose(pf.polygon_corner_degrees(V[F]).sum(axis=1), 180.0, atol=1e-9)


def test_holonomy_is_angle_defect_and_gauss_bonnet(ico2):
    fr = pf.mesh_frames(ico2)
    K = pf.angle_defect(ico2.vertices, ico2.faces)
    assert K.sum() == pytest.approx(4 * np.pi)
    np.testing.assert_allclose(pf.frames.wrap_angle(pf.vertex_holonomy(fr) - K), 0.0, atol=1e-12)
    S = pf.face_to_vertex(fr)
    np.testing.assert_allclose(np.asarray(S.sum(axis=1)).ravel(), 1.0)


def test_igl_local_basis_crosscheck(ico2):
    igl = pytest.importorskip("igl")
    if not hasattr(igl, "local_basis"):
        pytest.skip("this libigl wheel has no local_basis")
    fr = pf.mesh_frames(ico2)
    B1, B2, B3 = igl.local_basis(ico2.vertices, ico2.faces)
    np.testing.assert_allclose(B1, fr.u, atol=1e-10)
    np.testing.assert_allclose(np.abs(np.einsum("ij,ij->i", B3, fr.normal)), 1.0, atol=1e-10)


# ----------------------------------------------------------------------------- cross fields
def test_connection_laplacian_is_hermitian_psd_and_matches_edge_sum(ico2):
    fr = pf.mesh_frames(ico2)
    L, mass = pf.connection_laplacian(fr, 4)
    assert abs(L - L.conj().T).max() < 1e-12
    rng = np.random.default_rng(1)
    z = rng.normal(size=ico2.n_faces) + 1j * rng.normal(size=ico2.n_faces)
    de = pf.frames.dual_edges(fr)
    c = fr.centroids
    elen = np.linalg.norm(ico2.vertices[de["b"]] - ico2.vertices[de["a"]], axis=1)
    w = elen / np.linalg.norm(c[de["g"]] - c[de["f"]], axis=1)
    direct = np.sum(w * np.abs(z[de["g"]] - np.exp(4j * de["rho"]) * z[de["f"]]) ** 2)
    assert np.real(np.vdot(z, L @ z)) == pytest.approx(direct, rel=1e-12)
    _, lam = pf.smoothest_field(fr, 4, L=L)
    assert lam > 0  # no parallel cross field on a sphere


@pytest.mark.parametrize("N, expected", [(1, 2.0), (4, 2.0)])
def test_smoothest_field_indices_sum_to_euler_characteristic(pair3, N, expected):
    fr = pair3["fr1"]
    z, lam = pf.smoothest_field(fr, N)
    idx = pf.singularity_index(fr, z, N)
    assert idx.sum() == pytest.approx(expected)
    np.testing.assert_allclose(idx * N, np.round(idx * N), atol=1e-12)  # multiples of 1/N
    v, ind = pf.singularities(fr, z, N)
    if N == 4:
        assert v.size == 8 and np.all(ind == 0.25)  # 8 x (+1/4) on the round sphere


def test_singularities_match_libigl(pair3):
    igl = pytest.importorskip("igl")
    if not hasattr(igl, "find_cross_field_singularities"):
        pytest.skip("this libigl wheel has no find_cross_field_singularities")
    m, fr, z = pair3["m1"], pair3["fr1"], pair3["z1"]
    X = pf.field_vectors(z, fr, 4)
    _, ig = igl.find_cross_field_singularities(m.vertices, m.faces, X[:, 0].copy(), X[:, 1].copy(), False)
    ours = np.round(4 * pf.singularity_index(fr, z, 4)).astype(int) % 4
    np.testing.assert_array_equal(ours, np.asarray(ig).ravel() % 4)


def test_human_cross_field_index_sum_is_two(human_0):
    fr = pf.mesh_frames(human_0)
    z = pf.cross_field(human_0)
    assert z.shape == (human_0.n_faces,)
    np.testing.assert_allclose(np.abs(z), 1.0)
    v, ind = pf.singularities(fr, z)
    assert ind.sum() == pytest.approx(2.0)
    assert v.size > 0


def test_cross_angle_is_modulo_90_degrees():
    rng = np.random.default_rng(0)
    z = np.exp(1j * rng.uniform(0, 2 * np.pi, 50))
    for deg, expected in [(0, 0), (90, 0), (180, 0), (30, 30), (60, 30), (45, 45), (100, 10), (-20, 20)]:
        a = np.degrees(pf.cross_angle(pf.rotate_field(z, np.radians(deg)), z))
        np.testing.assert_allclose(a, expected, atol=1e-9)
    # vector fields (N = 1) are compared modulo 360°
    a = np.degrees(pf.cross_angle(pf.rotate_field(z, np.radians(90), N=1), z, N=1))
    np.testing.assert_allclose(a, 90, atol=1e-9)


def test_aligned_field_follows_curvature_on_ellipsoid():
    m = icosphere(3)
    m = pm.Mesh(m.vertices * [1.0, 1.0, 2.0], m.faces)
    fr = pf.mesh_frames(m)
    z = pf.cross_field(m, scale=0.05)
    eq = np.abs(fr.centroids[:, 2]) < 0.3
    horiz = np.cross([0.0, 0.0, 1.0], fr.normal)  # along the equator: the maximal curvature direction
    ref = cf.normalize_field(pf.to_complex(horiz, fr) ** 4)
    assert np.degrees(pf.cross_angle(z, ref)[eq]).mean() < 3.0
    q, w = pf.curvature_guide(m, fr)
    assert w.min() >= 0 and w.max() <= 1 and np.any(w == 0) is not None


def test_alignment_scale_trades_guide_for_smoothness(pair3):
    fr = pair3["fr1"]
    q = direction_guide(fr)
    L, _ = pf.connection_laplacian(fr)
    e_s, e_a = [], []
    for s in (0.01, 0.1, 1.0):
        z = pf.aligned_field(fr, q, scale=s)
        e_s.append(np.real(np.vdot(z, L @ z)))
        e_a.append(np.degrees(pf.cross_angle(z, q)).mean())
    assert e_s[0] > e_s[1] > e_s[2]
    assert e_a[0] < e_a[1] < e_a[2]
    assert e_a[0] < 5.0


def test_pushforward_through_rigid_relabelled_copy_is_exact(pair3):
    fr1, fr2, z1, p, R = pair3["fr1"], pair3["fr2"], pair3["z1"], pair3["p"], pair3["R"]
    z2, ok = pf.pushforward_field(fr1, z1, fr2, p)
    assert ok.all()
    # expected: rotate the 3D cross of the same triangle and express it in the copy's frames
    tri1 = {tuple(sorted(f)): i for i, f in enumerate(pair3["m1"].faces.tolist())}
    src = np.array([tri1[tuple(sorted(f))] for f in p[pair3["m2"].faces].tolist()])
    d = pf.field_vectors(z1, fr1)[src, 0] @ R.T
    expected = cf.normalize_field(pf.to_complex(d, fr2) ** 4)
    assert np.degrees(pf.cross_angle(z2, expected)).max() < 1e-8
    # singularities follow the relabelling
    np.testing.assert_array_equal(pf.singularity_index(fr2, z2), pf.singularity_index(fr1, z1)[p])
    with pytest.raises(ValueError, match="p2p_21"):
        pf.pushforward_field(fr1, z1, fr2, p[:-1])


# ----------------------------------------------------------------------------- the action on functions
def test_field_action_is_frame_independent_and_symmetric():
    rng = np.random.default_rng(3)
    g = rng.normal(size=(40, 5)) + 1j * rng.normal(size=(40, 5))
    z = np.exp(1j * rng.uniform(0, 2 * np.pi, 40))
    beta = rng.uniform(0, 2 * np.pi, 40)
    a = pf.field_action(g, z, 4)
    b = pf.field_action(g * np.exp(-1j * beta)[:, None], z * np.exp(-4j * beta), 4)  # other frames
    np.testing.assert_allclose(a, b, atol=1e-12)
    # rotating the cross by 90° does not change its power field, rotating by 45° flips the action
    np.testing.assert_allclose(pf.field_action(g, pf.rotate_field(z, np.pi / 4), 4), -a, atol=1e-12)


def test_consistency_energy_vanishes_for_the_pushed_field_with_complete_bases():
    ico1 = icosphere(1)  # 42 vertices: complete bases, and 903 extended columns
    m2, p, R = relabelled_copy(ico1, seed=2)
    fr1, fr2 = pf.mesh_frames(ico1), pf.mesh_frames(m2)
    b1, b2 = complete_basis(ico1), complete_basis(m2)
    C = pm.fmap_from_p2p(p, b1, b2)
    # the cross-field consistency energy, standard and extended, vanishes for the pushed field
    z1 = pf.aligned_field(fr1, direction_guide(fr1), scale=0.1)
    z2, _ = pf.pushforward_field(fr1, z1, fr2, p)
    for kind in ("std", "ext"):
        P = consistency_problem(fr1, b1, fr2, b2, C, kind=kind, rtol=1e-7)
        assert P.energy(z1, z2) < 1e-16
        assert P.energy(z1, pf.rotate_field(z2, np.radians(20))) > 1e-2


# ----------------------------------------------------------------------------- consistency design
def test_design_recovers_source_on_relabelled_copy_and_rotates_with_it(ell_pair3):
    d = ell_pair3
    C = pm.fmap_from_p2p(d["p"], d["b1"], d["b2"])  # (21, 21): k = 20
    z_ref, _ = pf.pushforward_field(d["fr1"], d["z1"], d["fr2"], d["p"])
    P = consistency_problem(d["fr1"], d["b1"], d["fr2"], d["b2"], C, kind="std", power=0)
    z2, info = design_consistent_field(P, d["z1"])
    assert z2.shape == (d["m2"].n_faces,)
    st_ = pf.angle_stats(z2, z_ref, d["fr2"].area)
    # bounds as on the round icosphere; this ellipsoid measures mean 2.02 / p90 4.14 degrees,
    # consistency 7.9e-4, then 2.80 and 20.0 degrees below (the same on the three OpenBLAS kernels;
    # the sphere's machine-dependent bases gave mean 1.17-1.35, p90 1.8-2.9, 1.27-1.67)
    assert st_["mean_deg"] < 3.0 and st_["p90_deg"] < 6.0
    assert info["consistency"] < 0.05
    beta = np.radians(20)
    z2r, _ = design_consistent_field(P, pf.rotate_field(d["z1"], beta))
    assert pf.angle_stats(z2r, pf.rotate_field(z2, beta), d["fr2"].area)["mean_deg"] < 3.0
    assert pf.angle_stats(z2r, z2, d["fr2"].area)["mean_deg"] > 15.0


def test_extended_design_beats_standard_on_small_copy():
    # an ellipsoid, not the round icosphere: the standard design tests the individual base
    # functions, which on the sphere are any orthonormal basis of the l <= 2 eigenspaces (machine
    # dependent: e_std was 1.59 / 3.62 / 4.01 degrees with the Haswell / Prescott / SkylakeX kernels)
    m1 = ellipsoid(2)  # 162 vertices, simple spectrum
    m2, p, _ = relabelled_copy(m1, seed=4)
    fr1, fr2 = pf.mesh_frames(m1), pf.mesh_frames(m2)
    b1, b2 = pm.eigenbasis(m1, 9), pm.eigenbasis(m2, 9)  # k = 8
    C = pm.fmap_from_p2p(p, b1, b2)
    z1 = pf.aligned_field(fr1, direction_guide(fr1), scale=0.1)
    z_ref, _ = pf.pushforward_field(fr1, z1, fr2, p)
    P = consistency_problem(fr1, b1, fr2, b2, C, kind="ext", power=0)
    assert P.info["tests"] == "products" and P.info["J"] == 8 + 36
    z_ext, info = design_consistent_field(P, z1)
    z_std, _ = design_consistent_field(consistency_problem(fr1, b1, fr2, b2, C, kind="std", power=0), z1)
    e_ext = pf.angle_stats(z_ext, z_ref, fr2.area)["mean_deg"]
    e_std = pf.angle_stats(z_std, z_ref, fr2.area)["mean_deg"]
    # measured on this ellipsoid: e_ext = 1.16, e_std = 7.41 degrees (the same to 1e-5 on the three
    # kernels; other simple-spectrum ellipsoids give 1.1-1.4 and 5.5-7.4). The old bounds
    # (e_ext < 1 < 2 < e_std) were measured on the sphere's machine-dependent bases (e_ext 0.28-0.35)
    # and do not carry over. The claim kept: the extended design within 2 degrees, the standard
    # one more than 5 degrees off.
    assert e_ext < 2.0 < 5.0 < e_std
    assert P.energy(z1, z_ref) < 1e-3 < P.energy(z1, pf.rotate_field(z_ref, np.radians(30)))


def test_joint_design_is_more_consistent_than_separate_fields(ell_pair3):
    d = ell_pair3
    C = pm.fmap_from_p2p(d["p"], d["b1"].truncate(11), d["b2"].truncate(11))
    q1 = direction_guide(d["fr1"], (0.3, 0.5, 0.8))
    q2 = direction_guide(d["fr2"], (0.9, 0.1, 0.3))  # an inconsistent guide on the target
    P = consistency_problem(d["fr1"], d["b1"], d["fr2"], d["b2"], C, kind="std", power=0)
    s1, s2 = pf.aligned_field(d["fr1"], q1, scale=0.1), pf.aligned_field(d["fr2"], q2, scale=0.1)
    z1, z2, info = design_joint(P, q1, q2, consistency=10.0)
    np.testing.assert_allclose(np.abs(z1), 1.0)
    assert info["consistency"] < 0.5 * P.energy(s1, s2)


def test_consistency_problem_rejects_bad_input(pair3):
    d = pair3
    C = pm.fmap_from_p2p(d["p"], d["b1"].truncate(6), d["b2"].truncate(6))
    with pytest.raises(ValueError, match="C_12"):
        consistency_problem(d["fr1"], d["b1"], d["fr2"], d["b2"], np.zeros((30, 6)))
    with pytest.raises(ValueError, match="kind"):
        consistency_problem(d["fr1"], d["b1"], d["fr2"], d["b2"], C, kind="sdt")
    with pytest.raises(ValueError, match="products"):
        consistency_problem(d["fr1"], d["b1"], d["fr2"], d["b2"], C, kind="std", tests="products")
    with pytest.raises(ValueError, match="p2p_21"):
        consistency_problem(d["fr1"], d["b1"], d["fr2"], d["b2"], C, kind="p2p")
    P = consistency_problem(d["fr1"], d["b1"], d["fr2"], d["b2"], C, kind="std")
    with pytest.raises(ValueError, match="z1"):
        design_consistent_field(P, d["z1"][:-1])
    with pytest.raises(ValueError, match="N"):
        pf.connection_laplacian(d["fr1"], 0)


# ----------------------------------------------------------------------------- surface ground truth
def _rotated_ellipsoid(subdivisions, axes, angle):
    """The ellipsoid with axes ``axes`` triangulated by a rotated icosphere (another connectivity)."""
    s = icosphere(subdivisions)
    c, si = np.cos(angle), np.sin(angle)
    R = np.array([[c, -si, 0.0], [si, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array([[1, 0, 0], [0, c, -si], [0, si, c]])
    return pm.Mesh((s.vertices @ R.T) * np.asarray(axes), s.faces)


def test_barycentric_pushforward_across_triangulations():
    axes = (1.0, 0.6, 0.4)
    m1 = _rotated_ellipsoid(3, axes, 0.0)  # 642 vertices
    m2 = _rotated_ellipsoid(3, axes, 0.45)  # the same surface, another triangulation
    fr1, fr2 = pf.mesh_frames(m1), pf.mesh_frames(m2)
    a = (0.3, 0.5, 0.8)
    z1, z2_true = direction_guide(fr1, a), direction_guide(fr2, a)  # one analytic field on both
    face, bary = pf.closest_point_correspondence(m2.vertices, m1.vertices, m1.faces)
    assert face.shape == (m2.n_vertices,) and bary.shape == (m2.n_vertices, 3)
    np.testing.assert_allclose(bary.sum(axis=1), 1.0)
    assert bary.min() >= 0.0
    X = np.einsum("vc,vcd->vd", bary, m1.vertices[m1.faces[face]])
    assert np.linalg.norm(X - m2.vertices, axis=1).max() < 0.02  # the inscribed polyhedra differ a little
    zb, ok = pf.pushforward_field_barycentric(fr1, z1, fr2, face, bary)
    assert ok.all()
    # away from the two points where the projected direction vanishes
    t = np.asarray(a) / np.linalg.norm(a)
    far = np.abs(fr2.normal @ t) < 0.9
    err_b = np.degrees(pf.cross_angle(zb, z2_true))[far]
    # the nearest-vertex ground truth distorts the image triangles: much worse on the same surface
    from scipy.spatial import cKDTree

    p = cKDTree(m1.vertices).query(m2.vertices)[1]
    zn, okn = pf.pushforward_field(fr1, z1, fr2, p)
    err_n = np.degrees(pf.cross_angle(zn, z2_true))[far & okn]
    assert np.mean(err_b) < 1.0 and np.mean(err_b) < 0.25 * np.mean(err_n)
    # on one triangulation with the identity correspondence it is the identity
    verts, first = np.unique(m1.faces.ravel(), return_index=True)  # one incident face per vertex
    onehot_face = first // 3
    bary_id = np.zeros((m1.n_vertices, 3))
    bary_id[verts, first % 3] = 1.0
    zi, _ = pf.pushforward_field_barycentric(fr1, z1, fr1, onehot_face, bary_id)
    assert np.degrees(pf.cross_angle(zi, z1)).mean() < 2.0
    with pytest.raises(ValueError, match="barycentric"):
        pf.pushforward_field_barycentric(fr1, z1, fr2, face, 2 * bary)
    with pytest.raises(ValueError, match="face_21"):
        pf.pushforward_field_barycentric(fr1, z1, fr2, face[:-1], bary[:-1])


def test_default_kind_transfers_through_the_default_operator(ell_pair3):
    from prodmaps.fields.operators import span_projector

    d = ell_pair3
    b1, b2 = d["b1"].truncate(7), d["b2"].truncate(7)
    C = pm.fmap_from_p2p(d["p"], b1, b2)
    P = consistency_problem(d["fr1"], b1, d["fr2"], b2, C, kind="default", tests="pairs")
    E = consistency_problem(d["fr1"], b1, d["fr2"], b2, C, kind="ext", tests="pairs")
    assert P.info["J"] == E.info["J"] == 6 + 15  # the same test functions
    np.testing.assert_allclose(P.W_2, E.W_2)  # the same comparison span
    np.testing.assert_allclose(P.H_1, E.H_1)
    x = np.random.default_rng(0).standard_normal(d["fr1"].n_faces)  # face values
    h = pf.face_to_vertex(d["fr1"]) @ x
    Q2 = span_projector(pm.product_basis(b2, 2, "unique"), 1e-3).Q
    expected = Q2.T @ (b2.mass * pm.transfer_operator(C, b1, b2, "default")(h))
    np.testing.assert_allclose(P.W_1.T @ x, expected, rtol=1e-8, atol=1e-10 * np.abs(expected).max())
    z_ref, _ = pf.pushforward_field(d["fr1"], d["z1"], d["fr2"], d["p"])
    assert P.energy(d["z1"], z_ref) < 0.05 < P.energy(d["z1"], pf.rotate_field(z_ref, np.radians(30)))
    with pytest.raises(ValueError, match="C_12"):
        consistency_problem(d["fr1"], b1, d["fr2"], b2, None, kind="default")
    with pytest.raises(ValueError, match="products"):
        consistency_problem(d["fr1"], b1, d["fr2"], b2, C, kind="default", tests="products")


# ----------------------------------------------------------------------------- C~ through the library's Approach B
def test_span_projector_is_the_library_approach_b_operator(ell_pair3):
    from prodmaps.fields.operators import span_projector

    b = ell_pair3["b1"].truncate(8)  # k = 7
    ext = pm.product_basis(b, 2, "unique")
    op = ext.operator("svd", rtol=1e-3)
    proj = span_projector(ext, 1e-3)
    assert proj.operator is op and proj.rank == op.rank < ext.K  # the library's cached operator, truncated
    F = np.random.default_rng(1).standard_normal((b.n, 4))
    a = pm.approximate(F, ext, "svd", rtol=1e-3)
    np.testing.assert_allclose(proj.basis_coefficients(F), a, rtol=1e-10, atol=1e-10 * np.abs(a).max())
    np.testing.assert_allclose(proj.coefficient_matrix() @ F, a, rtol=1e-7, atol=1e-8 * np.abs(a).max())
    Q = proj.Q
    np.testing.assert_allclose(Q.T @ (b.mass[:, None] * Q), np.eye(proj.rank), atol=1e-8)
    R = op.reconstruct(F)  # Q Qᵀ A F is Approach B's approximation; from_basis gives its coordinates
    np.testing.assert_allclose(Q @ proj.coefficients(F), R, atol=1e-8 * np.abs(R).max())
    np.testing.assert_allclose(proj.from_basis(a), proj.coefficients(F), atol=1e-8 * np.abs(a).max())
    # the ordered basis (the paper's pairs) spans the same kept space through span_factors
    Po = pm.product_basis(b, 2, "ordered").operator("svd", rtol=1e-3).span_factors()
    Qo = pm.product_basis(b, 2, "ordered").evaluate(Po)
    np.testing.assert_allclose(Qo.T @ (b.mass[:, None] * Qo), np.eye(Po.shape[1]), atol=1e-8)
    with pytest.raises(ValueError, match="Approach B"):
        pf.SpanProjector(ext.operator("ridge"))


def test_human_span_ranks_are_the_library_operators_and_free_of_units(human_0):
    # measured on anny_000, rtol 1e-3, unique pairs: the library keeps 12 / 28 / 64 directions at
    # k = 5 / 10 / 20 in metres and at x100; the former reading of this module (A-orthonormal
    # factors, no column weights: normalization="area") kept 18 / 37 / 95 in metres and 11 / 24 / 61 at x100
    from prodmaps.fields.operators import span_projector

    ranks = {}
    for s in (1.0, 100.0):
        B = pm.eigenbasis(pm.Mesh(human_0.vertices * s, human_0.faces), 21)
        for k in (5, 10, 20):
            ext = pm.product_basis(B.truncate(k + 1), 2, "unique")
            r = span_projector(ext, 1e-3).rank
            assert r == ext.operator("svd", rtol=1e-3).rank
            ranks[s, k] = (r, span_projector(ext, 1e-3, "area").rank)
    assert [ranks[1.0, k][0] for k in (5, 10, 20)] == [12, 28, 64]
    assert all(ranks[1.0, k][0] == ranks[100.0, k][0] for k in (5, 10, 20))  # free of the mesh's units
    assert all(ranks[1.0, k][1] > ranks[1.0, k][0] and ranks[1.0, k][1] != ranks[100.0, k][1] for k in (5, 10, 20))


def test_ext_consistency_transfers_by_the_library_approach_b(ell_pair3):
    from prodmaps.fields.operators import span_projector

    d = ell_pair3
    b1, b2 = d["b1"].truncate(7), d["b2"].truncate(7)
    C = pm.fmap_from_p2p(d["p"], b1, b2)
    P = consistency_problem(d["fr1"], b1, d["fr2"], b2, C, kind="ext", tests="pairs")
    ext1, ext2 = pm.product_basis(b1, 2, "unique"), pm.product_basis(b2, 2, "unique")
    assert P.info["rank_1"] == ext1.operator("svd", rtol=1e-3).rank
    assert P.info["rank_2"] == ext2.operator("svd", rtol=1e-3).rank
    x = np.random.default_rng(2).standard_normal(d["fr1"].n_faces)  # face values
    h = pf.face_to_vertex(d["fr1"]) @ x
    Ct = pm.extend_fmap(C, b1, b2, order=2, pairs="unique")
    g = ext2.evaluate(Ct @ pm.approximate(h, ext1, "svd", rtol=1e-3))  # B2 C~ a(h): the library's Approach B
    expected = span_projector(ext2, 1e-3).coefficients(g)
    np.testing.assert_allclose(P.W_1.T @ x, expected, rtol=1e-7, atol=1e-9 * np.abs(expected).max())
    # the former reading is still available, and is another truncation
    Pa = consistency_problem(d["fr1"], b1, d["fr2"], b2, C, kind="ext", tests="pairs", normalization="area")
    assert Pa.info["rank_1"] == ext1.operator("svd", rtol=1e-3, normalization="area").rank
