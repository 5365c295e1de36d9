"""Pictures: a function on a mesh or a point cloud (:func:`plot`), a point map by colour transfer (:func:`plot_map`).

Off-screen rendering with pyvista/VTK (optional dependency, imported on the first picture), made
to repeat: anti-aliasing off, fixed window size, no random lighting, a camera computed from the
geometry only. :func:`render` is the one home for drawing a mesh or a cloud with a given camera
(the notebooks' renderer, :mod:`prodmaps.experiments.shared.render`, draws through it).

* The automatic camera (:func:`auto_camera`) looks along the shape's axis of least extent (the
  principal axis of smallest variance of its points, so the silhouette is the widest) with the
  longest axis along the window's longer side (upright in a square or tall window), each axis'
  sign chosen so that its largest coordinate is positive (no assumption about which way the file
  is up), and frames the shape's extent in the window.
* Automatic colour limits (:func:`auto_clim`): the data's range; for signed data (values of both
  signs) a range symmetric about 0 with a diverging colour map, so 0 is the neutral colour.
* A point cloud is drawn as flat points whose size follows the points' spacing.
* A missing GL backend makes VTK crash instead of raising: :func:`probe_rendering` tries a
  render in a subprocess first. Without an X display VTK is told to open its EGL window first
  (:func:`headless_gl`); a ``VTK_DEFAULT_OPENGL_WINDOW`` you set wins.
"""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .checks import check_functions, check_p2p
from .mesh import Mesh
from .pointcloud import PointCloud

__all__ = ["plot", "plot_map", "render", "Camera", "auto_camera", "auto_clim", "map_colors", "probe_rendering",
           "headless_gl", "SIGNED_CMAP", "UNSIGNED_CMAP", "FIT_MARGIN", "POINT_SPACINGS"]

SIGNED_CMAP = "RdBu_r"
"""Colour map of signed data (blue negative, white 0, red positive)."""
UNSIGNED_CMAP = "viridis"
"""Colour map of data of one sign."""
FIT_MARGIN = 1.08
"""The framed extent is the shape's times this (a thin border around it)."""
POINT_SPACINGS = 2.5
"""A cloud's points are drawn this many median nearest-neighbour spacings wide (so the surface looks closed)."""


@dataclass(frozen=True)
class Camera:
    """A VTK camera: ``position``, ``focal_point``, ``up`` (3-vectors), ``view_angle`` (degrees, vertical), clipping.

    Examples
    --------
    >>> cam = Camera((0, 0, 5), (0, 0, 0), (0, 1, 0))
    >>> cam.view_angle, cam.clipping_range
    (30.0, (0.05, 50.0))
    """

    position: tuple
    focal_point: tuple
    up: tuple
    view_angle: float = 30.0
    clipping_range: tuple | None = None

    def __post_init__(self):
        for name in ("position", "focal_point", "up"):
            object.__setattr__(self, name, tuple(float(x) for x in getattr(self, name)))
        if self.clipping_range is None:
            dist = float(np.linalg.norm(np.subtract(self.position, self.focal_point)))
            object.__setattr__(self, "clipping_range", (0.01 * dist, 10 * dist))


def headless_gl() -> None:
    """Without an X display, make VTK open its EGL render window first (no X warning).

    Sets ``VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow`` in this process when ``DISPLAY`` is
    empty and the variable is not already set; VTK still falls back to its other windows.
    """
    if not os.environ.get("DISPLAY"):
        os.environ.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")


_PROBE = """from prodmaps.plotting import headless_gl
headless_gl()
import pyvista as pv
pv.OFF_SCREEN = True
p = pv.Plotter(off_screen=True, window_size=(32, 32))
p.add_mesh(pv.Sphere())
img = p.screenshot(return_img=True)
assert img.shape[:2] == (32, 32)
"""


def probe_rendering(timeout: float = 120.0) -> tuple[bool, str]:
    """Try an off-screen render in a subprocess; returns ``(ok, reason)`` (a missing GL backend crashes VTK)."""
    try:
        r = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return False, "off-screen rendering probe timed out"
    if r.returncode != 0:
        tail = (r.stderr or "").strip().splitlines()[-1:] or [f"exit code {r.returncode}"]
        return False, f"off-screen rendering unavailable: {tail[0]}"
    return True, "ok"


def _shape_arrays(shape):
    """``(points (n, 3), faces (m, 3) or None)`` of a Mesh or a PointCloud."""
    if isinstance(shape, Mesh):
        return shape.vertices, shape.faces
    if isinstance(shape, PointCloud):
        return shape.points, None
    raise TypeError(f"expected a prodmaps.Mesh or prodmaps.PointCloud, got {type(shape).__name__}")


def _principal_axes(points: np.ndarray) -> np.ndarray:
    """``(3, 3)`` rows: the principal axes by decreasing variance, each with its largest coordinate positive."""
    X = points - points.mean(0)
    _, vecs = np.linalg.eigh(X.T @ X)  # ascending variances
    axes = vecs[:, ::-1].T.copy()  # (3, 3) rows e1, e2, e3
    idx = np.argmax(np.abs(axes), axis=1)
    axes *= np.sign(axes[np.arange(3), idx])[:, None]
    if np.dot(np.cross(axes[0], axes[1]), axes[2]) < 0:  # right-handed: the camera sees the front of e1 x e2
        axes[2] = -axes[2]
    return axes


def auto_camera(points, window_size=(512, 512), *, view_angle: float = 30.0, axes=None) -> Camera:
    """A camera that frames ``points`` ``(n, 3)`` in the window, chosen from their principal axes (module doc).

    ``axes`` ``(3, 3)`` (rows: up, across, towards the camera) replaces the principal axes,
    e.g. ``np.eye(3)[[2, 0, 1]]`` to look from ``+y`` with ``z`` up.

    Examples
    --------
    >>> import numpy as np
    >>> P = np.random.default_rng(0).normal(size=(500, 3)) * [1.0, 5.0, 0.2]  # long along y, thin along z
    >>> cam = auto_camera(P)
    >>> np.round(np.abs(cam.up), 1).tolist(), bool(abs(cam.position[2]) > 5)  # y upright, seen along z
    ([0.0, 1.0, 0.0], True)
    """
    P = np.asarray(points, dtype=np.float64)
    w, h = (float(x) for x in window_size)
    if axes is None:
        A = _principal_axes(P)
        if w > h:  # a wide window: the longest axis across, the second upright
            A = np.stack([A[1], -A[0], A[2]])
    else:
        A = np.asarray(axes, dtype=np.float64)
    coords = P @ A.T  # (n, 3) along up, across, depth
    lo, hi = coords.min(0), coords.max(0)
    center = A.T @ (0.5 * (lo + hi))  # the bounding box's centre in the principal frame
    half_h, half_w, half_d = 0.5 * (hi - lo) * FIT_MARGIN
    t = np.tan(np.radians(view_angle) / 2)
    dist = max(half_h / t, half_w / (t * w / h), 1e-12) + half_d
    return Camera(center + dist * A[2], center, A[0], view_angle)


def auto_clim(values) -> tuple[float, float]:
    """Colour limits of ``values``: their range, symmetric about 0 when they take both signs.

    A constant function gets ``(v - 1, v + 1)`` (0 gets ``(-1, 1)``).

    Examples
    --------
    >>> auto_clim([0.5, 2.0]), auto_clim([-1.0, 3.0]), auto_clim([2.0, 2.0])
    ((0.5, 2.0), (-3.0, 3.0), (1.0, 3.0))
    """
    v = np.asarray(values, dtype=np.float64)
    lo, hi = float(v.min()), float(v.max())
    if lo < 0 < hi:
        m = max(-lo, hi)
        return -m, m
    if lo == hi:
        return lo - 1.0, hi + 1.0
    return lo, hi


def map_colors(points) -> np.ndarray:
    """A smooth colour for every point, ``(n, 3)`` in ``[0.1, 0.9]``: its position along the principal axes.

    Red, green and blue follow the three principal axes (:func:`auto_camera`'s), each rescaled
    to the points' extent; :func:`plot_map` pulls these colours back through a point map.

    Examples
    --------
    >>> import numpy as np
    >>> c = map_colors(np.random.default_rng(0).normal(size=(100, 3)))
    >>> c.shape, float(c.min()), float(c.max())
    ((100, 3), 0.1, 0.9)
    """
    P = np.asarray(points, dtype=np.float64)
    coords = (P - P.mean(0)) @ _principal_axes(P).T  # (n, 3)
    lo, hi = coords.min(0), coords.max(0)
    return np.clip(0.1 + 0.8 * (coords - lo) / np.where(hi > lo, hi - lo, 1.0), 0.1, 0.9)


def _pv_shape(points, faces):
    import pyvista as pv

    if faces is None:
        return pv.PolyData(np.asarray(points, dtype=np.float64))
    f = np.asarray(faces, dtype=np.int64)
    cells = np.hstack([np.full((f.shape[0], 1), f.shape[1]), f]).ravel()
    return pv.PolyData(np.asarray(points, dtype=np.float64), cells)


def _point_size(points: np.ndarray, camera: Camera, window_size) -> float:
    """Pixels per point: ``POINT_SPACINGS`` median nearest-neighbour spacings as seen by the camera, in [2, 24]."""
    from scipy.spatial import cKDTree

    d, _ = cKDTree(points).query(points, k=2)
    spacing = float(np.median(d[:, 1]))
    dist = float(np.linalg.norm(np.subtract(camera.position, camera.focal_point)))
    visible = 2 * dist * np.tan(np.radians(camera.view_angle) / 2)  # world height seen at the focal distance
    return float(np.clip(POINT_SPACINGS * spacing * window_size[1] / max(visible, 1e-300), 2.0, 24.0))


def render(points, faces=None, scalars=None, *, camera: Camera, clim=None, cmap=UNSIGNED_CMAP, rgb=None,
           window_size=(512, 512), color="lightgray", region=None, region_color=(0.85, 0.1, 0.1),
           point_size: float | None = None, background="white") -> np.ndarray:
    """Draw a mesh (``faces`` given) or a point cloud (``faces=None``) off screen: the RGB image ``(h, w, 3)`` uint8.

    Parameters
    ----------
    points : (n, 3) positions; faces : (m, 3) triangles or None (points).
    scalars : per-point values ``(n,)`` coloured with ``cmap`` within ``clim`` (required then).
    camera : the :class:`Camera` (e.g. :func:`auto_camera`).
    rgb : per-point colours ``(n, 3)`` in ``[0, 1]`` instead of ``scalars``.
    window_size : ``(width, height)`` pixels.
    color : the colour without scalars; region : boolean mask ``(n,)`` painted in ``region_color``.
    point_size : pixels per point of a cloud (default from the spacing of the points).

    Everything that could vary between runs is fixed: no anti-aliasing, the window size, the
    camera, the colour limits, the lights (VTK's light kit on meshes; points are unlit).
    """
    if scalars is not None and clim is None:
        raise ValueError("pass clim with scalars (pm.plotting.auto_clim(values) gives the automatic one)")
    headless_gl()
    import pyvista as pv

    pv.OFF_SCREEN = True
    pv.global_theme.multi_samples = 0
    pv.global_theme.smooth_shading = False
    mesh = _pv_shape(points, faces)
    cloud = faces is None
    p = pv.Plotter(off_screen=True, window_size=tuple(window_size), lighting="light_kit")
    p.set_background(background)
    style = {}
    if cloud:
        size = _point_size(np.asarray(points, dtype=np.float64), camera, window_size) if point_size is None \
            else float(point_size)
        style = dict(style="points", point_size=size, render_points_as_spheres=False, lighting=False)
    if scalars is not None:
        mesh.point_data["f"] = np.asarray(scalars, dtype=np.float64)
        p.add_mesh(mesh, scalars="f", clim=clim, cmap=cmap, show_scalar_bar=False,
                   interpolate_before_map=True, smooth_shading=False, **style)
    elif rgb is not None:
        mesh.point_data["rgb"] = np.round(255 * np.clip(np.asarray(rgb, dtype=np.float64), 0, 1)).astype(np.uint8)
        p.add_mesh(mesh, scalars="rgb", rgb=True, show_scalar_bar=False, smooth_shading=False, **style)
    else:
        p.add_mesh(mesh, color=color, smooth_shading=False, **style)
    if region is not None:
        sub = mesh.extract_points(np.flatnonzero(np.asarray(region)), adjacent_cells=False)
        if sub.n_points:
            p.add_mesh(sub, color=region_color, smooth_shading=False, **style)
    p.camera.position = camera.position
    p.camera.focal_point = camera.focal_point
    p.camera.up = camera.up
    p.camera.view_angle = camera.view_angle
    p.camera.clipping_range = camera.clipping_range
    img = p.screenshot(return_img=True)
    p.close()
    return np.asarray(img)[..., :3].copy()


def _save_png(img: np.ndarray, filename) -> None:
    from PIL import Image

    path = Path(filename)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(img).save(path, format="PNG")


def _window(window_size) -> tuple[int, int]:
    w = tuple(int(x) for x in window_size)
    if len(w) != 2 or min(w) < 8:
        raise ValueError(f"window_size must be (width, height) of at least 8 pixels each, got {window_size!r}")
    return w


def plot(shape, values=None, *, filename=None, window_size=(512, 512), cmap=None, clim=None, axes=None,
         point_size: float | None = None, color="lightgray") -> np.ndarray:
    """Draw a function on a mesh or a point cloud; return the picture and write it as PNG if asked.

    Parameters
    ----------
    shape : Mesh or PointCloud
    values : (n,) array_like, optional
        One value per vertex or point (none: the shape in ``color``).
    filename : str or pathlib.Path, optional
        Where to write the PNG.
    window_size : (width, height)
        Pixels (default 512 x 512).
    cmap : str or matplotlib colour map, optional
        Default ``SIGNED_CMAP`` for values of both signs, ``UNSIGNED_CMAP`` otherwise.
    clim : (low, high), optional
        Colour limits (default :func:`auto_clim`: symmetric about 0 for signed values). Pass the
        same limits to pictures that must share a colour scale.
    axes : (3, 3) array_like, optional
        Camera axes (rows: up, across, towards the camera; default the principal axes,
        :func:`auto_camera`).
    point_size : float, optional
        Pixels per point of a cloud (default from the points' spacing).
    color : the colour of the shape without ``values``.

    Returns
    -------
    (height, width, 3) uint8 ndarray
        The picture (also written to ``filename``).

    Raises
    ------
    TypeError
        If ``shape`` is neither a mesh nor a cloud.
    ValueError
        For values of the wrong shape or not finite, or a bad ``window_size``.
    ImportError
        Without pyvista (``pip install 'prodmaps[notebooks]'``).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import prodmaps as pm
    >>> mesh = pm.mesh.ellipsoid(2)
    >>> if pm.plotting.probe_rendering()[0]:  # a GL backend is there (VTK would crash without)
    ...     img = pm.plot(mesh, mesh.vertices[:, 0], window_size=(64, 48),
    ...                   filename=pathlib.Path(tempfile.mkdtemp()) / "x.png")
    ...     print(img.shape, bool((img != 255).any()))
    ... else:
    ...     print((48, 64, 3), True)
    (48, 64, 3) True
    """
    points, faces = _shape_arrays(shape)
    window_size = _window(window_size)
    if values is not None:
        values = check_functions(values, points.shape[0], "values")
        if values.ndim != 1:
            raise ValueError(f"values must be one value per vertex ({points.shape[0]},); got {values.shape}")
        clim = auto_clim(values) if clim is None else tuple(float(c) for c in clim)
        if cmap is None:
            cmap = SIGNED_CMAP if clim[0] < 0 < clim[1] and np.isclose(-clim[0], clim[1]) else UNSIGNED_CMAP
    camera = auto_camera(points, window_size, axes=axes)
    img = render(points, faces, values, camera=camera, clim=clim, cmap=cmap or UNSIGNED_CMAP,
                 window_size=window_size, point_size=point_size, color=color)
    if filename is not None:
        _save_png(img, filename)
    return img


def plot_map(shape_1, shape_2, p2p_21, *, filename=None, window_size=(512, 512), point_size: float | None = None,
             axes_1=None, axes_2=None) -> np.ndarray:
    """Draw a point map by colour transfer: shape 1 coloured by position, shape 2 by the colours the map pulls back.

    Every vertex of shape 1 gets a smooth colour from its position (:func:`map_colors`); every
    vertex ``y`` of shape 2 gets the colour of ``p2p_21[y]``. A good map shows the same smooth
    colours in the same places; errors show as colour jumps and patches out of place. The two
    pictures sit side by side, shape 1 on the left, each framed by its own :func:`auto_camera`.

    Parameters
    ----------
    shape_1, shape_2 : Mesh or PointCloud
        The two shapes (shape 1 is the map's target: ``p2p_21`` holds its vertices).
    p2p_21 : (n2,) int array_like
        For each vertex of shape 2 a vertex of shape 1.
    filename : str or pathlib.Path, optional
        Where to write the PNG.
    window_size : (width, height)
        Pixels of each of the two pictures.
    point_size : float, optional
        Pixels per point of a cloud.
    axes_1, axes_2 : (3, 3) array_like, optional
        Camera axes of each picture (:func:`auto_camera`).

    Returns
    -------
    (height, 2 * width, 3) uint8 ndarray
        The two pictures side by side (also written to ``filename``).

    Raises
    ------
    TypeError
        If a shape is neither a mesh nor a cloud.
    ValueError
        If ``p2p_21`` is not ``(n2,)`` vertex indices of shape 1.
    ImportError
        Without pyvista.

    Examples
    --------
    >>> import numpy as np
    >>> import prodmaps as pm
    >>> mesh = pm.mesh.ellipsoid(2)
    >>> cloud = pm.PointCloud(mesh.vertices[::-1])  # the same points in reverse order
    >>> p2p_21 = np.arange(mesh.n_vertices)[::-1]  # the true map from the cloud to the mesh
    >>> if pm.plotting.probe_rendering()[0]:
    ...     print(pm.plot_map(mesh, cloud, p2p_21, window_size=(64, 48)).shape)
    ... else:
    ...     print((48, 128, 3))
    (48, 128, 3)
    """
    v1, f1 = _shape_arrays(shape_1)
    v2, f2 = _shape_arrays(shape_2)
    p = check_p2p(p2p_21, v1.shape[0], v2.shape[0])
    window_size = _window(window_size)
    colors_1 = map_colors(v1)
    imgs = [render(v, f, rgb=c, camera=auto_camera(v, window_size, axes=ax), window_size=window_size,
                   point_size=point_size)
            for v, f, c, ax in ((v1, f1, colors_1, axes_1), (v2, f2, colors_1[p], axes_2))]
    img = np.concatenate(imgs, axis=1)
    if filename is not None:
        _save_png(img, filename)
    return img
