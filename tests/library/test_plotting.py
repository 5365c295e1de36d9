"""Pictures: pm.plot on meshes and clouds, pm.plot_map, and the automatic camera and colour limits.

Rendering needs a GL backend, whose absence crashes VTK: the ``gl`` fixture probes it in a
subprocess first and skips the rendering tests with the probe's reason.
"""

from __future__ import annotations

import numpy as np
import pytest

import prodmaps as pm
from prodmaps.plotting import auto_camera, auto_clim, map_colors


@pytest.fixture(scope="module")
def gl():
    ok, reason = pm.plotting.probe_rendering()
    if not ok:
        pytest.skip(reason)
    return True


def _foreground(img):
    return np.any(img != 255, axis=-1)


# ------------------------------------------------------------------------------ without VTK
def test_auto_camera_looks_along_the_thinnest_axis_with_the_longest_upright():
    rng = np.random.default_rng(0)
    P = rng.normal(size=(2000, 3)) * [3.0, 0.3, 1.0] + [10.0, -5.0, 2.0]  # long x, thin y
    cam = auto_camera(P, (300, 400))
    np.testing.assert_allclose(np.abs(cam.up), [1, 0, 0], atol=0.02)  # the longest axis upright
    view = np.subtract(cam.position, cam.focal_point)
    np.testing.assert_allclose(np.abs(view / np.linalg.norm(view)), [0, 1, 0], atol=0.02)  # seen along y
    np.testing.assert_allclose(cam.focal_point, 0.5 * (P.min(0) + P.max(0)), atol=0.3)
    wide = auto_camera(P, (400, 300))  # a wide window: the longest axis across
    np.testing.assert_allclose(np.abs(wide.up), [0, 0, 1], atol=0.02)
    # the same points rotated give the rotated camera: nothing assumes which way is up
    R = np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0.0]])
    cam_r = auto_camera(P @ R.T, (300, 400))
    np.testing.assert_allclose(np.abs(cam_r.up), np.abs(R @ cam.up), atol=1e-9)
    # framing: twice the size, twice the distance
    far = auto_camera(2 * P, (300, 400))
    np.testing.assert_allclose(np.linalg.norm(np.subtract(far.position, far.focal_point)),
                               2 * np.linalg.norm(view), rtol=1e-9)


def test_auto_clim_and_map_colors():
    assert auto_clim([0.0, 2.0, 1.0]) == (0.0, 2.0)
    assert auto_clim([-0.5, 2.0]) == (-2.0, 2.0)  # signed: symmetric about 0
    assert auto_clim([-3.0, -1.0]) == (-3.0, -1.0)
    assert auto_clim(np.zeros(4)) == (-1.0, 1.0)
    P = pm.mesh.ellipsoid(2).vertices
    c = map_colors(P)
    assert c.shape == (162, 3) and c.min() >= 0.1 - 1e-12 and c.max() <= 0.9 + 1e-12
    np.testing.assert_allclose([c[:, j].min() for j in range(3)], 0.1, atol=1e-12)  # each channel spans its range
    np.testing.assert_allclose(np.abs(np.corrcoef(c[:, 0], P[:, 0])[0, 1]), 1.0, atol=1e-9)  # red along x (longest)


def test_plot_checks_its_input():
    mesh = pm.mesh.ellipsoid(1)
    with pytest.raises(ValueError, match=r"values must have shape \(42,\)"):
        pm.plot(mesh, np.zeros(41))
    with pytest.raises(ValueError, match="non-finite"):
        pm.plot(mesh, np.full(42, np.nan))
    with pytest.raises(TypeError, match="expected a prodmaps.Mesh or prodmaps.PointCloud"):
        pm.plot(mesh.vertices)
    with pytest.raises(ValueError, match="window_size"):
        pm.plot(mesh, window_size=(4, 4))
    with pytest.raises(ValueError, match=r"indices out of range"):
        pm.plot_map(mesh, mesh, np.full(42, 42))


# ------------------------------------------------------------------------------ rendering
def test_plot_writes_a_png_of_the_requested_size_on_a_mesh_and_a_cloud(gl, tmp_path):
    from PIL import Image

    mesh = pm.mesh.ellipsoid(3)
    cloud = pm.PointCloud(mesh.vertices)
    for shape, name in ((mesh, "mesh.png"), (cloud, "cloud.png")):
        img = pm.plot(shape, shape.vertices[:, 2], filename=tmp_path / name, window_size=(120, 90))
        assert img.shape == (90, 120, 3) and img.dtype == np.uint8
        with Image.open(tmp_path / name) as im:
            assert im.size == (120, 90) and im.format == "PNG"
            np.testing.assert_array_equal(np.asarray(im.convert("RGB")), img)
        fg = _foreground(img)
        assert 0.15 < fg.mean() < 0.95, name  # the shape fills the frame, with a border
        assert not fg[0].any() and not fg[-1].any() and not fg[:, 0].any() and not fg[:, -1].any()
        assert len(np.unique(img[fg].reshape(-1, 3), axis=0)) > 20  # coloured by the function
        np.testing.assert_array_equal(pm.plot(shape, shape.vertices[:, 2], window_size=(120, 90)), img)  # repeatable
    plain = pm.plot(mesh, window_size=(60, 60))
    assert _foreground(plain).any() and len(np.unique(plain.reshape(-1, 3), axis=0)) > 5  # grey, shaded


def test_signed_values_use_a_diverging_map_centred_on_zero(gl):
    mesh = pm.mesh.ellipsoid(3)
    f = mesh.vertices[:, 0]  # along the longest axis: the image's vertical
    img = pm.plot(mesh, f, window_size=(60, 100)).astype(int)
    top, bottom = img[8:30, 20:40].reshape(-1, 3).mean(0), img[70:92, 20:40].reshape(-1, 3).mean(0)
    # one end red (positive), the other blue (negative), whichever way the camera turned the shape
    reds = sorted([top, bottom], key=lambda c: c[0] - c[2])
    assert reds[0][2] > reds[0][0] + 30 and reds[1][0] > reds[1][2] + 30


def test_plot_map_colours_pulled_back_through_the_map(gl, tmp_path):
    mesh = pm.mesh.ellipsoid(3)
    rng = np.random.default_rng(0)
    perm = rng.permutation(mesh.n_vertices)
    cloud = pm.PointCloud(mesh.vertices[perm])  # cloud point i is mesh vertex perm[i]
    good = pm.plot_map(mesh, cloud, perm, window_size=(80, 100), filename=tmp_path / "map.png")
    assert good.shape == (100, 160, 3) and (tmp_path / "map.png").is_file()
    bad = pm.plot_map(mesh, cloud, rng.permutation(mesh.n_vertices), window_size=(80, 100))
    np.testing.assert_array_equal(bad[:, :80], good[:, :80])  # shape 1 is the same picture

    def roughness(img):  # colour jumps between neighbouring pixels of the shape
        fg = _foreground(img)
        d = np.abs(np.diff(img.astype(int), axis=1)).sum(-1)
        return float(d[fg[:, 1:] & fg[:, :-1]].mean())

    assert roughness(good[:, 80:]) < 0.5 * roughness(bad[:, 80:])  # a true map pulls back smooth colours
