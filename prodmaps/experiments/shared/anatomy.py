"""Body frames and the anchor-based test functions of Figures 7 and 9 (a human, a quadruped).

Anchors are found from coordinates in the **body frame**: ``x`` the body's left, ``y`` its back
(it faces ``-y``), ``z`` up, the origin on the body's mid-plane. The embedded humans and TOSCA's
animals are stored in that frame; a dataset in another frame names the rotation from its
coordinates to the body frame (:data:`FRAMES`, e.g. FAUST: up ``+y``, facing ``+z``), and its
coordinates are then taken from the centre of their bounding box (FAUST_r sits in a unit box).
Rotations keep distances, so geodesic distances do not depend on the frame; only which vertex is
"left" or "up" does. Lengths are in the mesh's units times ``length_scale`` (the human function was written
in metres for a ~1.7 m body; :func:`length_scale` gives the factor for a shape in other units).
"""

from __future__ import annotations

import numpy as np

from ...geodesics import distances

__all__ = ["FRAMES", "HUMAN_AREA", "body_frame", "body_coordinates", "body_transform", "length_scale",
           "human_composite", "quadruped_composite", "composite_function", "COMPOSITES"]

FRAMES = {
    "body": ((1, 0, 0), (0, 1, 0), (0, 0, 1)),  # the embedded humans, TOSCA's animals
    "faust": ((1, 0, 0), (0, 0, -1), (0, 1, 0)),  # FAUST and FAUST_r: up +y, facing +z, the body's left +x
}
"""Rotations (rows: the body frame's x, y, z in the dataset's coordinates) by dataset frame name."""
HUMAN_AREA = 1.7226
"""The surface area (m²) the human function's lengths were written for (the embedded ``anny_000``)."""


def body_frame(frame=None) -> np.ndarray:
    """The rotation ``R`` ``(3, 3)`` of ``frame`` (a name of :data:`FRAMES`, a 3x3 rotation, or None: the body frame).

    >>> body_frame("faust") @ np.array([0.0, 1.0, 0.0])  # FAUST's +y is up
    array([0., 0., 1.])
    """
    R = np.asarray(FRAMES[frame] if isinstance(frame, str) and frame in FRAMES else
                   (FRAMES["body"] if frame is None else frame), dtype=np.float64)
    if isinstance(frame, str) and frame not in FRAMES:
        raise ValueError(f"frame must be one of {list(FRAMES)} or a 3x3 rotation, got {frame!r}")
    if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
        raise ValueError(f"frame must be a proper rotation (3x3, orthogonal, determinant +1), got {R.tolist()}")
    return R


def body_coordinates(vertices, frame=None) -> np.ndarray:
    """``vertices`` ``(n, 3)`` in the body frame (x left, y back, z up).

    The array itself for the body frame; in another frame, rotated and taken from the centre of
    the bounding box (module doc).
    """
    V = np.asarray(vertices, dtype=np.float64)
    R = body_frame(frame)
    if np.array_equal(R, np.eye(3)):
        return V
    return (V - 0.5 * (V.min(axis=0) + V.max(axis=0))) @ R.T


def body_transform(reference, frame=None):
    """The map ``V -> V`` in the body frame with ``reference``'s centre: one transform for every panel of a figure.

    ``reference`` ``(n, 3)``: the vertices whose bounding box gives the centre (in another frame
    than the body frame); the body frame's map returns its argument unchanged.

    >>> to_body = body_transform(np.array([[0.0, 0.0, 0.0], [2.0, 4.0, 6.0]]), "faust")
    >>> to_body(np.array([[1.0, 2.0, 3.0]])).tolist()  # the centre goes to the origin
    [[0.0, 0.0, 0.0]]
    """
    R = body_frame(frame)
    if np.array_equal(R, np.eye(3)):
        return lambda V: V
    ref = np.asarray(reference, dtype=np.float64)
    c = 0.5 * (ref.min(axis=0) + ref.max(axis=0))
    return lambda V: (np.asarray(V, dtype=np.float64) - c) @ R.T


def length_scale(mesh, scale="metres") -> float:
    """The factor of the human function's lengths: 1 for ``"metres"``, ``sqrt(area / HUMAN_AREA)`` for ``"area"``.

    A number is returned as it is.
    """
    if scale == "metres":
        return 1.0
    if scale == "area":
        return float(np.sqrt(mesh.area / HUMAN_AREA))
    if isinstance(scale, (int, float)) and scale > 0:
        return float(scale)
    raise ValueError(f"length scale must be 'metres', 'area' or a positive number, got {scale!r}")


def human_composite(mesh, *, frame=None, scale: float = 1.0):
    """The human stand-in for the paper's cat: ``(f (n,), parts, anchors)`` (module doc of the figure).

    Indicator on the left lower leg (geodesic distance to the left foot tip < 0.45), a Gaussian
    (width 0.07) at the frontmost vertex 0.75 ± 0.02 up the right leg, a sine of ``x``
    (period 0.12) on the left arm (distance to the hand tip < 0.55), an increasing ramp in ``z``
    on the head (distance to its top < 0.22); lengths times ``scale``.
    """
    x, y, z = body_coordinates(mesh.vertices, frame).T
    left, right = np.flatnonzero(x > 0), np.flatnonzero(x < 0)
    foot_l = left[np.argmin(z[left])]  # lowest vertex of the left leg
    foot_r = right[np.argmin(z[right])]
    hand_l = int(np.argmax(x))  # tip of the left hand
    head_top = int(np.argmax(z))
    d_fl, d_fr, d_hl, d_top = distances(mesh, np.array([foot_l, foot_r, hand_l, head_top]))
    cand = np.flatnonzero(np.abs(d_fr - 0.75 * scale) < 0.02 * scale)  # ring around the right thigh
    centre = int(cand[np.argmin(y[cand])])  # its frontmost vertex
    d_c = distances(mesh, np.array([centre]))[0]
    indicator = (d_fl < 0.45 * scale).astype(float)
    gaussian = np.exp(-d_c**2 / (2 * (0.07 * scale) ** 2))
    sine = np.where(d_hl < 0.55 * scale, np.sin(2 * np.pi * x / (0.12 * scale)), 0.0)
    head = d_top < 0.22 * scale
    zh = z[head]
    ramp = np.where(head, (z - zh.min()) / (zh.max() - zh.min()), 0.0)
    parts = {"indicator": indicator, "gaussian": gaussian, "sine": sine, "increasing": ramp}
    anchors = {"foot_left": int(foot_l), "foot_right": int(foot_r), "hand_left": hand_l,
               "head_top": head_top, "gaussian_centre": centre}
    return indicator + gaussian + sine + ramp, parts, anchors


def quadruped_composite(mesh, *, frame=None, scale: float | None = None):
    """The paper's Figure 7 function on a four-legged animal: ``(f (n,), parts, anchors)``.

    In the body frame (head towards ``-y``, tail towards ``+y``, ``z`` up) and lengths in units of
    ``scale`` (default ``sqrt(area)``): an indicator on the left front leg (geodesic distance to
    its paw < 0.3), a Gaussian (width 0.05) at the frontmost vertex 0.4 ± 0.015 up the right
    front leg, a sine of ``y`` (period 0.09) on the tail (distance to its tip < 0.45), and an
    increasing ramp in ``z`` on the ears (distance to the top of the head < 0.12).
    """
    s = float(np.sqrt(mesh.area)) if scale is None else float(scale)
    x, y, z = body_coordinates(mesh.vertices, frame).T
    cy = float(np.average(y))
    front_l = np.flatnonzero((x > 0) & (y < cy))
    front_r = np.flatnonzero((x < 0) & (y < cy))
    paw_l = int(front_l[np.argmin(z[front_l])])  # lowest vertex of the left front leg
    paw_r = int(front_r[np.argmin(z[front_r])])
    tail = int(np.argmax(y))  # the tail's tip
    front = np.flatnonzero(y < cy)
    head_top = int(front[np.argmax(z[front])])  # between the ears
    d_pl, d_pr, d_tail, d_top = distances(mesh, np.array([paw_l, paw_r, tail, head_top]))
    cand = np.flatnonzero(np.abs(d_pr - 0.4 * s) < 0.015 * s)  # a ring at the top of the right front leg
    if cand.size == 0:
        cand = np.array([int(np.argmin(np.abs(d_pr - 0.4 * s)))])
    centre = int(cand[np.argmin(y[cand])])
    d_c = distances(mesh, np.array([centre]))[0]
    indicator = (d_pl < 0.3 * s).astype(float)
    gaussian = np.exp(-d_c**2 / (2 * (0.05 * s) ** 2))
    sine = np.where(d_tail < 0.45 * s, np.sin(2 * np.pi * y / (0.09 * s)), 0.0)
    ears = d_top < 0.12 * s
    ze = z[ears]
    ramp = np.where(ears, (z - ze.min()) / (ze.max() - ze.min()), 0.0)
    parts = {"indicator": indicator, "gaussian": gaussian, "sine": sine, "increasing": ramp}
    anchors = {"paw_left": paw_l, "paw_right": paw_r, "tail_tip": tail, "head_top": head_top,
               "gaussian_centre": centre}
    return indicator + gaussian + sine + ramp, parts, anchors


COMPOSITES = ("human", "quadruped")


def composite_function(mesh, kind: str = "human", *, frame=None, scale="metres"):
    """Figure 7's test function on ``mesh``: ``(f (n,), parts, anchors)``.

    ``kind``: ``"human"`` (:func:`human_composite`, lengths times :func:`length_scale` of
    ``scale``) or ``"quadruped"`` (:func:`quadruped_composite`, lengths relative to
    ``sqrt(area)``); ``frame`` the dataset's frame (:data:`FRAMES`).
    """
    if kind == "human":
        return human_composite(mesh, frame=frame, scale=length_scale(mesh, scale))
    if kind == "quadruped":
        return quadruped_composite(mesh, frame=frame)
    raise ValueError(f"kind must be one of {COMPOSITES}, got {kind!r}")
