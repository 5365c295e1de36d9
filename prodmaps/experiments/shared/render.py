"""The notebooks' figures: renders of meshes with named views, figure grids, shared colour maps.

Drawing goes through the library's renderer, :func:`prodmaps.plotting.render` (anti-aliasing
off, fixed window size, camera and colour limits, flat background, no lighting randomness);
what is here is the notebooks' convention on top of it: named views of z-up humans facing -y
(:data:`VIEWS`), cameras framing given bounds so that the panels of a figure share one scale,
colour limits always passed (``clim``), the figure grid and the paper's colour maps.

pyvista is imported inside the functions. A missing GL backend makes VTK crash instead of
raising, so call :func:`probe_rendering` (it tries in a subprocess) before rendering in tests.
Without an X display (``DISPLAY`` unset) VTK is told to open its EGL window first
(:func:`headless_gl`), so it does not print a "bad X server connection" warning into the
executed notebooks before falling back to EGL; a ``VTK_DEFAULT_OPENGL_WINDOW`` you set wins.
"""

from __future__ import annotations

import numpy as np

from ...plotting import Camera, headless_gl, probe_rendering, render

__all__ = ["probe_rendering", "render_mesh", "render_grid", "VIEWS", "error_colormap", "function_colormap",
           "camera_bounds", "rendering_available", "headless_gl"]

# camera direction (from the object towards the camera) and up vector per named view
VIEWS = {
    "front": ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    "back": ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    "side": ((1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),
    "top": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
}


def render_mesh(vertices, faces, scalars=None, *, clim=None, cmap="viridis", view="front",
                window_size=(300, 450), camera_bounds=None, color="lightgray",
                region=None, region_color=(0.85, 0.1, 0.1), zoom=1.0) -> np.ndarray:
    """Render one mesh off screen and return the RGB image ``(h, w, 3)`` uint8.

    Parameters
    ----------
    scalars : per-vertex values ``(n,)`` coloured with ``cmap`` within ``clim`` (required
        with scalars, so images of one figure share a colour scale).
    view : key of :data:`VIEWS`.
    camera_bounds : ``(xmin, xmax, ymin, ymax, zmin, zmax)`` to frame; default the mesh's
        bounds. Pass the same bounds to every panel of a figure to keep one scale.
    region : optional boolean mask ``(n,)`` painted in ``region_color`` (e.g. a region in red).
    """
    if scalars is not None and clim is None:
        raise ValueError("pass clim with scalars: panels of one figure must share colour limits")
    direction, up = VIEWS[view]
    v = np.asarray(vertices, dtype=np.float64)
    b = np.asarray(camera_bounds if camera_bounds is not None else np.ravel(np.column_stack([v.min(0), v.max(0)])),
                   dtype=float)
    center = 0.5 * (b[0::2] + b[1::2])
    radius = 0.5 * np.linalg.norm(b[1::2] - b[0::2])
    dist = 2.9 * radius / zoom
    camera = Camera(center + dist * np.asarray(direction), center, up, 30.0, (0.01 * dist, 10 * dist))
    return render(v, faces, scalars, camera=camera, clim=clim, cmap=cmap, window_size=window_size, color=color,
                  region=region, region_color=region_color)


def render_grid(panels, *, ncols=None, titles=None, captions=None, suptitle=None,
                colorbar=None, panel_size=(2.0, 3.0)):
    """Arrange rendered images in a matplotlib figure with titles above and captions below.

    ``panels`` is a list of images (from :func:`render_mesh`). ``colorbar`` is an optional
    ``(cmap, clim, label)`` drawn once for the whole figure. Returns the figure.
    """
    from .results import setup_matplotlib

    plt = setup_matplotlib()
    n = len(panels)
    ncols = ncols or n
    nrows = int(np.ceil(n / ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(panel_size[0] * ncols, panel_size[1] * nrows),
                             squeeze=False)
    for i, ax in enumerate(axes.ravel()):
        ax.axis("off")
        if i >= n:
            continue
        ax.imshow(panels[i], interpolation="nearest")
        if titles:
            ax.set_title(titles[i], fontsize=8)
        if captions:
            ax.text(0.5, -0.02, captions[i], transform=ax.transAxes, ha="center", va="top", fontsize=8)
    if suptitle:
        fig.suptitle(suptitle, fontsize=10)
    if colorbar is not None:
        import matplotlib as mpl

        cmap, clim, label = colorbar
        sm = mpl.cm.ScalarMappable(norm=mpl.colors.Normalize(*clim), cmap=cmap)
        fig.colorbar(sm, ax=axes.ravel().tolist(), fraction=0.02, pad=0.01, label=label)
    return fig


# ------------------------------------------------------------------ shared figure conventions
def error_colormap():
    """Reconstruction-error colours, light grey (small) to dark red (large): the paper's, grey instead of white."""
    import matplotlib.colors as mcolors

    return mcolors.LinearSegmentedColormap.from_list(
        "grey_to_darkred", [(0.86, 0.86, 0.86), (0.99, 0.73, 0.6), (0.87, 0.18, 0.13), (0.4, 0.0, 0.05)])


def function_colormap():
    """Signed function values: blue (-1) to light grey (0) to red (+1)."""
    import matplotlib.colors as mcolors

    return mcolors.LinearSegmentedColormap.from_list(
        "blue_grey_red", [(0.15, 0.3, 0.75), (0.84, 0.84, 0.84), (0.8, 0.1, 0.1)])


def camera_bounds(*vertex_arrays) -> np.ndarray:
    """``(xmin, xmax, ymin, ymax, zmin, zmax)`` framing all the given ``(n, 3)`` arrays."""
    allv = np.vstack([np.asarray(v, dtype=np.float64) for v in vertex_arrays])
    return np.ravel(np.column_stack([allv.min(0), allv.max(0)]))


def rendering_available(render_images: bool = True) -> bool:
    """Probe off-screen rendering in a subprocess (a missing GL backend crashes VTK) and print why not.

    Without rendering a notebook still computes and writes every number.
    """
    ok, reason = probe_rendering() if render_images else (False, "render_images=False")
    print("rendering:", reason)
    return ok
