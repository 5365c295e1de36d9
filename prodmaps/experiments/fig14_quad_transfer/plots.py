"""Small matplotlib helpers for cross fields and quad meshes (orthographic views, no GL).

Views are orthographic projections with a depth test on a coarse screen grid, so crosses and
singularities on hidden parts are not drawn. ``VIEWS`` are :mod:`prodmaps.experiments.shared.render`'s: the
embedded humans are z-up and face -y. All functions return matplotlib objects and draw
deterministically (fixed sub-sampling seed).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ...fields.crossfield import field_vectors, singularities
from ...fields.frames import tangent_frames
from ..shared.render import VIEWS

__all__ = ["VIEWS", "plot_cross_field", "joint_figure", "pairs_figure", "quads_pairs_figure", "plot_quad_mesh",
           "quad_figure"]

def _camera(view):
    d, up = (np.asarray(x, float) for x in VIEWS[view])
    right = np.cross(up, d)
    return d, up, right  # d points from the object to the camera


def _visible_faces(fr, view, front):
    """Screen centroids ``(m, 2)`` and the faces whose centroid depth is within a cell of the nearest in its cell."""
    d, up, right = _camera(view)
    c3 = fr.centroids
    P2, depth, cell = np.stack([c3 @ right, c3 @ up], axis=1), c3 @ d, 2.0 * np.sqrt(fr.area.mean())
    ij = np.floor((P2 - P2.min(0)) / cell).astype(np.int64)
    key = ij[:, 0] * (ij[:, 1].max() + 1) + ij[:, 1]
    best = np.full(key.max() + 1, np.inf)
    np.minimum.at(best, key[front], -depth[front])
    return P2, front & (-depth <= best[key] + cell)


def _shaded_mesh(ax, V, F, view, facecolors=None):
    from matplotlib.collections import PolyCollection

    d, up, right = _camera(view)
    fr = tangent_frames(V, F)
    P = np.stack([V @ right, V @ up], axis=1)  # (n, 2)
    depth = V @ d  # larger = closer
    front = fr.normal @ d > 0
    order = np.argsort(depth[F].mean(1))  # far first (painter)
    order = order[front[order]]
    lum = 0.35 + 0.65 * np.clip(fr.normal @ d, 0, 1)
    if facecolors is None:
        col = np.repeat(lum[:, None], 3, axis=1) * 0.92
    else:
        col = np.asarray(facecolors, float)[:, :3] * lum[:, None]
    ax.add_collection(PolyCollection(P[F[order]], facecolors=col[order], edgecolors="none", antialiased=False))
    ax.set_xlim(P[:, 0].min(), P[:, 0].max())
    ax.set_ylim(P[:, 1].min(), P[:, 1].max())
    ax.set_aspect("equal")
    ax.axis("off")
    return fr, P, front


def plot_cross_field(V, F, z, *, ax=None, view="front", n_glyphs=1500, glyph_scale=0.5,
                     show_singularities=True, color="tab:blue", seed=0):
    """Shaded mesh with crosses (two segments per sampled face) and singularities; returns the axes.

    Singularities: red for a positive index, blue for a negative one. ``z`` ``(m,)`` is a 4-power field
    in the face frames.
    """
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    V = np.asarray(V, float)
    F = np.asarray(F, np.int64)
    if ax is None:
        _, ax = plt.subplots(figsize=(3, 5))
    fr, P, front = _shaded_mesh(ax, V, F, view)
    _, up, right = _camera(view)
    c2, vis = _visible_faces(fr, view, front)
    cand = np.flatnonzero(vis)
    rng = np.random.default_rng(seed)
    pick = cand if cand.size <= n_glyphs else np.sort(rng.choice(cand, n_glyphs, replace=False,
                                                                 p=fr.area[cand] / fr.area[cand].sum()))
    X = field_vectors(np.asarray(z), fr, 4)[pick][:, :2, :]  # (g, 2, 3) two directions
    L = glyph_scale * np.sqrt(np.sum(fr.area) / max(pick.size, 1)) / 2
    segs = []
    for a in range(2):
        x2 = np.stack([X[:, a] @ right, X[:, a] @ up], axis=1)
        segs.append(np.stack([c2[pick] - L * x2, c2[pick] + L * x2], axis=1))
    ax.add_collection(LineCollection(np.concatenate(segs), colors=color, linewidths=0.6, antialiased=False))
    if show_singularities:
        v, ind = singularities(fr, np.asarray(z), 4)
        if v.size:
            keep = np.isin(v, F[vis])
            ax.scatter(P[v[keep], 0], P[v[keep], 1], s=10, c=np.where(ind[keep] > 0, "red", "blue"),
                       zorder=3, linewidths=0)
    return ax


def joint_figure(mesh_1, mesh_2, fields: dict, names, *, titles=None, view="front", n_glyphs=400, suptitle=None):
    """Jointly designed fields of one pair: one column per design, source (top) and target (bottom).

    ``fields`` maps a name to ``(z1, z2)`` (e.g. ``figure14_joint_pair(..., keep_fields=True)["fields"]``
    re-keyed by name). Returns the figure.
    """
    def draw(ax, name, r, mesh):
        plot_cross_field(mesh.vertices, mesh.faces, fields[name][r], ax=ax, view=view, n_glyphs=n_glyphs)
        if r == 0:
            ax.set_title((titles or {}).get(name, name), fontsize=8)

    return _source_target_figure(mesh_1, mesh_2, [n for n in names if n in fields], draw, suptitle)


def _source_target_figure(mesh_1, mesh_2, names, draw, suptitle):
    """One column per design, source (top) and target (bottom): ``draw(ax, name, row, mesh)``."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, len(names), figsize=(2.4 * len(names), 7.0), squeeze=False)
    for c, name in enumerate(names):
        for r, mesh in enumerate((mesh_1, mesh_2)):
            draw(axes[r, c], name, r, mesh)
    if suptitle:
        fig.suptitle(suptitle, fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, 0.97) if suptitle else None)
    return fig


def _strip_chart(ax, names, kinds: dict, baselines: dict, title: str) -> None:
    """One panel of per-pair values, dots for the ``kinds`` and marks for the ``baselines``.

    Both map a label to its values per pair (None: not drawn).
    """
    x = np.arange(len(names))
    for j, (kd, v) in enumerate(kinds.items()):
        ax.plot(x + 0.1 * (j - len(kinds) / 2), [np.nan if t is None else t for t in v], "o", ms=4, label=kd)
    for (b, v), mk in zip(baselines.items(), ("k_", "kx")):
        ax.plot(x, [np.nan if t is None else t for t in v], mk, ms=9, label=b)
    ax.set_xticks(x, [n.replace("anny_", "").replace("tr_reg_", "") for n in names], rotation=60, fontsize=6)
    ax.set_title(title, fontsize=9)


def pairs_figure(per_pair: dict, ks, kinds, baselines=("independent", "copy"), measure="angle_regular_deg"):
    """Per-pair strip chart of ``measure`` for every kind and k (one panel per k), baselines as marks."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(ks), figsize=(3.6 * len(ks), 3.2), squeeze=False, sharey=True)
    names = list(per_pair)
    for a, k in zip(axes[0], ks):
        _strip_chart(a, names, {kd: [per_pair[n][f"k{k}"][kd][measure] for n in names] for kd in kinds},
                     {b: [per_pair[n]["baselines"].get(b, {}).get(measure) for n in names] for b in baselines},
                     f"k = {k}")
    axes[0, 0].set_ylabel(measure.replace("_", " "), fontsize=8)
    axes[0, -1].legend(fontsize=6)
    fig.tight_layout()
    return fig


def quads_pairs_figure(per_pair: dict, ks, kinds=("std", "ext", "default"), baselines=("independent", "pushforward"),
                       measures=("irregular_match_fraction", "irregular_low_match_fraction")):
    """Per-pair strip charts of quad-mesh measures, one row per measure and one column per k, per design.

    Default measures: the fractions of irregular vertices paired through the ground truth, all and at
    low-curvature places; the baselines as marks.
    """
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(measures), len(ks), figsize=(3.6 * len(ks), 2.8 * len(measures)), squeeze=False,
                             sharey="row")
    names = list(per_pair)
    quads = [per_pair[n]["quads"] for n in names]
    for row, measure in zip(axes, measures):
        for a, k in zip(row, ks):
            _strip_chart(a, names, {kd: [q[f"k{k}"][kd][measure] for q in quads] for kd in kinds},
                         {b: [q["baselines"][b][measure] for q in quads] for b in baselines}, f"quad meshes, k = {k}")
        row[0].set_ylabel(measure.replace("irregular_", "").replace("_", " "), fontsize=8)
    axes[0, -1].legend(fontsize=6)
    fig.tight_layout()
    return fig


def plot_quad_mesh(V, F, Vq, Q, polygons=(), *, ax=None, view="front", title=None, irregular=None):
    """A polygon mesh drawn over its surface ``(V, F)``: quads ``Q`` ``(q, 4)`` light blue, surface orange.

    The regions the other ``polygons`` close (holes next to singularities, often large and far from
    planar) show as orange surface; front-facing quads in painter's order (orthographic ``view``);
    ``irregular`` vertex ids of ``Vq`` as red dots.
    """
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    if ax is None:
        _, ax = plt.subplots(figsize=(3, 6))
    hole = np.array([1.0, 0.62, 0.3])
    fr, _, front = _shaded_mesh(ax, V, F, view, facecolors=np.tile(hole, (len(F), 1)) if len(polygons) else None)
    Q = np.asarray(Q, dtype=np.int64).reshape(-1, 4)
    d, up, right = _camera(view)
    P = np.stack([Vq @ right, Vq @ up], axis=1)
    if Q.size:
        C = Vq[Q]  # (q, 4, 3)
        front_q = np.cross(C[:, 2] - C[:, 0], C[:, 3] - C[:, 1]) @ d > 0  # normal by the diagonals
        order = np.argsort((Vq @ d)[Q].mean(1))
        order = order[front_q[order]]
        ax.add_collection(PolyCollection(P[Q[order]], facecolors=(0.85, 0.9, 1.0), edgecolors=(0.1, 0.2, 0.5),
                                         linewidths=0.3))
    if irregular is not None and len(irregular):
        # visible as plot_cross_field decides it: the nearest mesh vertex belongs to a visible face
        vis = _visible_faces(fr, view, front)[1]
        irr = np.asarray(irregular, dtype=np.int64)
        irr = irr[np.isin(cKDTree(V).query(Vq[irr])[1], np.asarray(F)[vis])]
        ax.plot(P[irr, 0], P[irr, 1], "o", ms=1.8, color=(0.8, 0.0, 0.0))
    if title:
        ax.set_title(title, fontsize=8)
    return ax


def quad_figure(mesh_1, mesh_2, quad_meshes: dict, stats: dict, names, *, titles=None, suptitle=None):
    """Quad meshes of source (top) and target (bottom), one column per design, with their counts.

    ``quad_meshes[name]`` is ``((V, Q, polygons, irregular) source, (...) target)`` as returned by
    :func:`prodmaps.experiments.fig14_quad_transfer.crossfields.quad_meshes_pair`; ``stats[name]`` its ``"stats"``
    (``{"source", "target", "irregular_matched", ...}``). Quads light blue, other polygons orange,
    irregular vertices red.
    """
    def draw(ax, name, r, mesh):
        Vq, Q, polys, irr = quad_meshes[name][r]
        st = stats[name][("source", "target")[r]]
        t = ((titles or {}).get(name, name) + "\n") if r == 0 else ""
        extra = (f"\n{stats[name]['irregular_matched']} irregular matched" if r == 1
                 and "irregular_matched" in stats[name] else "")
        plot_quad_mesh(mesh.vertices, mesh.faces, Vq, Q, polys, ax=ax, irregular=irr,
                       title=t + f"{st['n_quads']} quads + {st['n_polygons']} polygons, "
                                 f"{st['n_irregular']} irregular" + extra)

    return _source_target_figure(mesh_1, mesh_2, [n for n in names if n in quad_meshes], draw, suptitle)
