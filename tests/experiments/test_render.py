"""The shared renderer: colour maps, camera bounds, the rendering probe, figure grids, off-screen renders."""

from __future__ import annotations

import matplotlib.colors as mcolors
import matplotlib.figure
import numpy as np
import pytest

from prodmaps.experiments.shared import render
from prodmaps.experiments.shared.render import (
    VIEWS,
    camera_bounds,
    error_colormap,
    function_colormap,
    render_grid,
    render_mesh,
    rendering_available,
)


# ------------------------------------------------------------------------------ colour maps
def _luminance(rgb):
    rgb = np.asarray(rgb)[..., :3]
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def test_error_colormap_grey_to_dark_red():
    cmap = error_colormap()
    assert isinstance(cmap, mcolors.Colormap)
    assert cmap.name == "grey_to_darkred"
    np.testing.assert_allclose(cmap(0.0)[:3], (0.86, 0.86, 0.86), atol=1e-6)
    np.testing.assert_allclose(cmap(1.0)[:3], (0.4, 0.0, 0.05), atol=1e-6)
    lo = np.array(cmap(0.0)[:3])
    assert np.ptp(lo) < 1e-9  # small errors: neutral grey
    t = np.linspace(0.0, 1.0, 257)
    lum = _luminance(cmap(t))
    assert np.all(np.diff(lum) <= 1e-12)  # darker as the error grows
    assert lum[0] - lum[-1] > 0.6
    hi = np.array(cmap(1.0)[:3])
    assert hi[0] > 4 * max(hi[1], hi[2])  # large errors: red dominates
    assert cmap(0.0)[3] == cmap(1.0)[3] == 1.0  # opaque


def test_function_colormap_blue_grey_red():
    cmap = function_colormap()
    assert isinstance(cmap, mcolors.Colormap)
    assert cmap.name == "blue_grey_red"
    neg, mid, pos = (np.array(cmap(x)[:3]) for x in (0.0, 0.5, 1.0))
    np.testing.assert_allclose(neg, (0.15, 0.3, 0.75), atol=1e-6)
    np.testing.assert_allclose(pos, (0.8, 0.1, 0.1), atol=1e-6)
    np.testing.assert_allclose(mid, (0.84, 0.84, 0.84), atol=0.01)  # zero: light grey
    assert neg[2] > neg[0] and pos[0] > pos[2]  # negative blue, positive red
    # the grey centre is the lightest colour: lightness rises to 0.5 and falls after it
    t = np.linspace(0.0, 1.0, 201)
    lum = _luminance(cmap(t))
    assert abs(t[np.argmax(lum)] - 0.5) <= 0.01
    # each call builds a fresh colour map object (callers may modify it)
    assert function_colormap() is not cmap and error_colormap() is not error_colormap()


# ------------------------------------------------------------------------------ camera bounds
def test_camera_bounds_of_one_array():
    v = np.array([[0.0, 1.0, 2.0], [3.0, -1.0, 5.0], [1.0, 0.5, -2.0]])
    b = camera_bounds(v)
    assert b.shape == (6,)
    assert b.dtype == np.float64
    np.testing.assert_array_equal(b, [0.0, 3.0, -1.0, 1.0, -2.0, 5.0])


def test_camera_bounds_union_of_arrays():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(50, 3))
    c = rng.normal(size=(20, 3)) + np.array([10.0, -5.0, 0.0])
    b = camera_bounds(a, c)
    allv = np.vstack([a, c])
    expected = [allv[:, 0].min(), allv[:, 0].max(), allv[:, 1].min(), allv[:, 1].max(),
                allv[:, 2].min(), allv[:, 2].max()]
    np.testing.assert_array_equal(b, expected)
    assert b[1] == c[:, 0].max() and b[2] == c[:, 1].min()  # the second array extends the bounds
    # order of the arrays does not matter; lists and ints are accepted
    np.testing.assert_array_equal(camera_bounds(c, a), b)
    np.testing.assert_array_equal(camera_bounds([[0, 0, 0]], [[1, 2, 3]]), [0, 1, 0, 2, 0, 3])
    with pytest.raises(ValueError):
        camera_bounds()


# ------------------------------------------------------------------------------ rendering probe
def test_rendering_available_false_does_not_probe(monkeypatch, capsys):
    def boom(*a, **k):
        raise AssertionError("probe_rendering must not run when render_images=False")

    monkeypatch.setattr(render, "probe_rendering", boom)
    assert rendering_available(False) is False
    assert "render_images=False" in capsys.readouterr().out


@pytest.mark.parametrize("ok, reason", [(True, "ok"), (False, "off-screen rendering unavailable: no GL")])
def test_rendering_available_reports_the_probe(monkeypatch, capsys, ok, reason):
    monkeypatch.setattr(render, "probe_rendering", lambda *a, **k: (ok, reason))
    assert rendering_available(True) is ok
    assert capsys.readouterr().out.strip() == f"rendering: {reason}"


# ------------------------------------------------------------------------------ render_grid (no VTK)
def _panels(n, shape=(12, 8)):
    rng = np.random.default_rng(1)
    return [rng.integers(0, 256, size=shape + (3,), dtype=np.uint8) for _ in range(n)]


def test_render_grid_panels_titles_captions():
    import matplotlib.pyplot as plt

    panels = _panels(5)
    titles = [f"panel {i}" for i in range(5)]
    captions = [f"err {i / 10:.2f}" for i in range(5)]
    fig = render_grid(panels, ncols=3, titles=titles, captions=captions, suptitle="five panels",
                      panel_size=(2.0, 3.0))
    try:
        assert isinstance(fig, matplotlib.figure.Figure)
        axes = fig.axes
        assert len(axes) == 6  # 2 rows x 3 columns, the last one empty
        np.testing.assert_allclose(fig.get_size_inches(), (6.0, 6.0))
        with_image = [ax for ax in axes if ax.images]
        assert len(with_image) == 5
        assert not axes[5].images and axes[5].get_title() == ""
        for i, ax in enumerate(axes[:5]):
            np.testing.assert_array_equal(np.asarray(ax.images[0].get_array()), panels[i])
            assert ax.get_title() == titles[i]
            assert [t.get_text() for t in ax.texts] == [captions[i]]
            assert not ax.axison  # no ticks or frames
        assert fig._suptitle is not None and fig._suptitle.get_text() == "five panels"
    finally:
        plt.close(fig)


def test_render_grid_defaults_one_row_and_colorbar():
    import matplotlib.pyplot as plt

    panels = _panels(4, shape=(6, 5))
    fig = render_grid(panels, colorbar=(error_colormap(), (0.0, 0.25), "error"))
    try:
        image_axes = [ax for ax in fig.axes if ax.images]
        assert len(image_axes) == 4
        assert all(ax.get_title() == "" and not ax.texts for ax in image_axes)
        np.testing.assert_allclose(fig.get_size_inches(), (8.0, 3.0))  # one row of ncols = n panels
        extra = [ax for ax in fig.axes if ax not in image_axes]
        assert len(extra) == 1  # the shared colour bar
        cbar_ax = extra[0]
        assert cbar_ax.get_ylabel() == "error" or cbar_ax.get_xlabel() == "error"
        lims = cbar_ax.get_ylim() if cbar_ax.get_ylabel() == "error" else cbar_ax.get_xlim()
        np.testing.assert_allclose(lims, (0.0, 0.25))
        assert fig._suptitle is None
    finally:
        plt.close(fig)


def test_render_grid_more_rows_than_needed_are_blank():
    import matplotlib.pyplot as plt

    fig = render_grid(_panels(3), ncols=2, titles=["a", "b", "c"])
    try:
        assert len(fig.axes) == 4
        assert [ax.get_title() for ax in fig.axes] == ["a", "b", "c", ""]
        assert [len(ax.images) for ax in fig.axes] == [1, 1, 1, 0]
    finally:
        plt.close(fig)


# ------------------------------------------------------------------------------ render_mesh (VTK, off screen)
@pytest.fixture(scope="module")
def gl():
    ok, reason = render.probe_rendering()
    if not ok:
        pytest.skip(reason)
    return True


@pytest.fixture(scope="module")
def ball():
    from prodmaps.mesh import icosphere

    return icosphere(2)


def _foreground(img):
    return np.any(img != 255, axis=-1)


def test_render_mesh_image_size_and_content(gl, ball):
    img = render_mesh(ball.vertices, ball.faces, window_size=(120, 80))
    assert isinstance(img, np.ndarray)
    assert img.shape == (80, 120, 3)  # window_size is (width, height)
    assert img.dtype == np.uint8
    assert img.flags.c_contiguous and img.flags.writeable
    np.testing.assert_array_equal(img[0, 0], (255, 255, 255))  # white background in the corner
    fg = _foreground(img)
    assert 0.05 < fg.mean() < 0.95  # a sphere, not an empty or full frame
    assert fg[40, 60]  # the centre of the frame is the sphere
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 20  # shaded, not flat
    # repeatable: the same call gives the same pixels
    np.testing.assert_array_equal(render_mesh(ball.vertices, ball.faces, window_size=(120, 80)), img)


def test_render_mesh_scalars_change_the_image(gl, ball):
    kw = dict(window_size=(64, 64))
    plain = render_mesh(ball.vertices, ball.faces, **kw)
    z = ball.vertices[:, 2]
    by_z = render_mesh(ball.vertices, ball.faces, z, clim=(-1.0, 1.0), cmap="viridis", **kw)
    by_minus_z = render_mesh(ball.vertices, ball.faces, -z, clim=(-1.0, 1.0), cmap="viridis", **kw)
    assert by_z.shape == plain.shape == (64, 64, 3)
    assert np.abs(by_z.astype(int) - plain.astype(int)).mean() > 5
    assert np.abs(by_z.astype(int) - by_minus_z.astype(int)).mean() > 5
    np.testing.assert_array_equal(_foreground(by_z), _foreground(plain))  # same silhouette
    # viridis: the top (z = 1) is yellow-green, the bottom (z = -1) purple-blue
    top = by_z[8:20, 26:38].reshape(-1, 3).astype(float).mean(0)
    bottom = by_z[44:56, 26:38].reshape(-1, 3).astype(float).mean(0)
    assert top[1] > top[2] and bottom[2] > bottom[1]
    # the colour scale is the given clim, not the data range: a wider clim washes the colours together
    wide = render_mesh(ball.vertices, ball.faces, z, clim=(-100.0, 100.0), **kw)
    fg = _foreground(plain)
    assert wide[fg].astype(float).std(0).sum() < by_z[fg].astype(float).std(0).sum()


def test_render_mesh_scalars_need_clim(gl, ball):
    with pytest.raises(ValueError, match="clim"):
        render_mesh(ball.vertices, ball.faces, ball.vertices[:, 0], window_size=(32, 32))


def test_render_mesh_region_views_and_framing(gl, ball):
    kw = dict(window_size=(64, 64))
    plain = render_mesh(ball.vertices, ball.faces, **kw)
    region = ball.vertices[:, 2] > 0.3  # the top cap
    red = render_mesh(ball.vertices, ball.faces, region=region, region_color=(1.0, 0.0, 0.0), **kw)
    redness = red[..., 0].astype(int) - red[..., 1].astype(int)
    assert (redness > 80).sum() > 50  # the cap is painted red
    assert (redness[:32] > 80).sum() > 5 * (redness[32:] > 80).sum()  # ... in the upper half (z up)
    assert ((plain[..., 0].astype(int) - plain[..., 1].astype(int)) > 80).sum() == 0
    # the view looks from another side: a lopsided shape looks different from the side
    v = ball.vertices.copy()
    v[v[:, 0] > 0.5, 0] += 0.8  # a bump towards +x: seen from the front (along y), hidden from the side
    front = render_mesh(v, ball.faces, view="front", **kw)
    side = render_mesh(v, ball.faces, view="side", **kw)
    assert set(VIEWS) == {"front", "back", "side", "top"}
    assert _foreground(front).sum() > 1.2 * _foreground(side).sum()  # the bump widens the front silhouette
    # larger camera bounds frame more space around the sphere: it covers fewer pixels; zoom does the opposite
    far = render_mesh(ball.vertices, ball.faces, camera_bounds=camera_bounds(ball.vertices * 3.0), **kw)
    near = render_mesh(ball.vertices, ball.faces, zoom=1.5, **kw)
    n_plain = _foreground(plain).sum()
    assert _foreground(far).sum() < 0.3 * n_plain
    assert _foreground(near).sum() > 1.5 * n_plain
    with pytest.raises(KeyError):
        render_mesh(ball.vertices, ball.faces, view="diagonal", **kw)


def test_headless_render_prints_no_x_server_warning():
    import os
    import subprocess
    import sys

    ok, reason = render.probe_rendering()
    if not ok:
        pytest.skip(reason)
    code = ("import numpy as np\nfrom prodmaps.experiments.shared.render import render_mesh\n"
            "from prodmaps.mesh import ellipsoid\nm = ellipsoid(1)\n"
            "img = render_mesh(m.vertices, m.faces, window_size=(40, 60))\nprint(img.shape)\n")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "VTK_DEFAULT_OPENGL_WINDOW")}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "(60, 40, 3)"
    assert "X server" not in r.stderr and "WARN" not in r.stderr, r.stderr
