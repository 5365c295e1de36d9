"""Figure 14 (Section 5.4): consistent cross fields and quad layouts through a functional map.

The cross-field library is :mod:`prodmaps.fields`; this module is the experiment of the Figure 14
notebook (layer 2: it reads datasets and compares with a ground truth).

:func:`figure14_experiment` runs, for one pair of shapes,

1. a source cross field on shape 1 (curvature-aligned, :func:`~prodmaps.fields.crossfield.cross_field`);
2. the **reference**: its push-forward through the ground-truth point map (evaluation only);
3. target fields on shape 2 designed from the source field through the functional map only
   (:func:`~prodmaps.fields.consistency.design_consistent_field`):
   ``"std"`` with ``C`` ``(k+1, k+1)`` in the Laplace–Beltrami basis and ``"ext"`` with ``C~``
   in the extended basis (products of basis functions, ``pairs="unique"``, Approach-B
   threshold ``rtol``); optionally the ``"p2p"`` oracle (the same extended-basis comparison with
   the exact point-map transfer: what a perfect transfer would give);
4. a quad layout on each surface from its own field (:mod:`~prodmaps.fields.stripes`);

and measures, per target: the area-weighted mean and 90th percentile of the angle to the
reference cross (modulo 90°), the singularities (count, and position error after matching to
the reference's singularities of the same index), and the layout consistency with the source
layout transported by the ground truth.

``k`` is the paper's k: the number of **non-constant** eigenfunctions (``C`` has ``k+1`` rows
and columns); the paper uses ``k = 5`` and a ground-truth functional map.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from scipy.optimize import linear_sum_assignment
from scipy.sparse.csgraph import dijkstra

from ..basis import eigenbasis
from ..fields.consistency import consistency_problem, design_consistent_field
from ..fields.crossfield import angle_stats, cross_field, curvature_guide, pushforward_field, singularities
from ..fields.frames import Frames, mesh_frames
from ..fields.stripes import layout_consistency, mean_edge_length, quad_texture, stripe_patterns
from ..mapping import fmap_from_p2p
from ..mesh import Mesh, edges

__all__ = ["figure14_experiment", "figure14_study", "dataset_pair", "summary_rows", "match_singularities",
           "graph_distances",
           "DEFAULTS"]

DEFAULTS = {
    "source_scale": 0.05,  # smoothing length of the source field / sqrt(area)
    "smoothness": 1e-3,  # μ of the target design
    "rtol": 1e-3,  # Approach-B threshold of the extended bases (the paper's)
    "power": 0.0,  # magnitude exponent of the cross-field action (0: direction only)
    "period_edges": 16.0,  # stripe period in mean edge lengths of the source
}


def graph_distances(V: np.ndarray, F: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """Edge-graph (Dijkstra) distances ``(s, n)`` from ``sources`` (an upper bound of geodesics)."""
    e, _ = edges(np.asarray(F))
    w = np.linalg.norm(V[e[:, 1]] - V[e[:, 0]], axis=1)
    n = V.shape[0]
    G = sp.csr_matrix((np.concatenate([w, w]), (np.concatenate([e[:, 0], e[:, 1]]),
                                                np.concatenate([e[:, 1], e[:, 0]]))), shape=(n, n))
    return np.atleast_2d(dijkstra(G, directed=False, indices=np.asarray(sources, dtype=np.int64)))


def match_singularities(V, F, sing_a, index_a, sing_b, index_b, *, radius: float | None = None) -> dict:
    """Match two sets of singular vertices of one mesh (same index only), minimising distances.

    Optimal assignment (Hungarian) on edge-graph distances; pairs of different index are not
    allowed. Returns counts, the mean/median matched distance (mesh units), and the fraction
    of ``b`` (the reference) matched within ``radius`` (default 3 mean edge lengths).
    """
    sa, sb = np.asarray(sing_a), np.asarray(sing_b)
    ia, ib = np.asarray(index_a), np.asarray(index_b)
    if radius is None:
        radius = 3.0 * mean_edge_length(V, F)
    out = {"n_a": int(sa.size), "n_b": int(sb.size), "radius": float(radius)}
    if sa.size == 0 or sb.size == 0:
        out.update(n_matched=0, mean_dist=float("nan"), median_dist=float("nan"), recall=0.0)
        return out
    D = graph_distances(V, F, sb)[:, sa]  # (nb, na)
    big = 1e6 * (D[np.isfinite(D)].max() + 1.0)
    cost = np.where(ib[:, None] == ia[None, :], D, big)
    r, c = linear_sum_assignment(cost)
    ok = cost[r, c] < big
    d = D[r[ok], c[ok]]
    out.update(n_matched=int(ok.sum()), mean_dist=float(d.mean()) if d.size else float("nan"),
               median_dist=float(np.median(d)) if d.size else float("nan"),
               recall=float(np.sum(d <= radius) / sb.size))
    return out


def _field_metrics(fr2: Frames, z, z_ref, valid, sing_ref, V2, F2) -> dict:
    st = angle_stats(z, z_ref, fr2.area, 4, valid)
    v, ind = singularities(fr2, z, 4)
    m = match_singularities(V2, F2, v, ind, sing_ref[0], sing_ref[1])
    return {"angle_mean_deg": st["mean_deg"], "angle_p90_deg": st["p90_deg"],
            "n_singularities": int(v.size), "index_sum": float(ind.sum()),
            "sing_matched": m["n_matched"], "sing_unmatched": int(v.size + sing_ref[0].size - 2 * m["n_matched"]),
            "sing_mean_dist": m["mean_dist"],
            "sing_median_dist": m["median_dist"], "sing_recall": m["recall"]}


def figure14_experiment(mesh_1: Mesh, mesh_2: Mesh, p2p_21: np.ndarray, k: int = 5, *,
                        kinds=("std", "ext"), source_scale: float = DEFAULTS["source_scale"],
                        smoothness: float = DEFAULTS["smoothness"], rtol: float = DEFAULTS["rtol"],
                        power: float = DEFAULTS["power"], align_target: float = 0.0,
                        period: float | None = None, with_layouts: bool = True, basis_1=None, basis_2=None,
                        C_12=None) -> dict:
    """Run the Figure 14 pipeline on one pair (see the module doc).

    Parameters
    ----------
    mesh_1, mesh_2 : source and target shapes.
    p2p_21 : ground-truth point map ``(n2,)`` (each vertex of shape 2 -> a vertex of shape 1);
        used for the ground-truth functional map (unless ``C_12`` is given), the reference field
        and the layout score, never by the designs.
    k : the paper's k, non-constant eigenfunctions (``C`` is ``(k+1, k+1)``).
    kinds : designs to run, among ``"std"``, ``"ext"`` and ``"p2p"`` (oracle).
    source_scale, smoothness, rtol, power : see :data:`DEFAULTS` and
        :func:`~prodmaps.fields.consistency.consistency_problem`.
    align_target : weight of the target's own curvature alignment (0: the map alone).
    period : stripe period (mesh units); default ``period_edges`` mean edge lengths of shape 1.
    with_layouts : compute the stripe layouts and their consistency (about 2 s per field at 5k vertices).
    basis_1, basis_2 : precomputed eigenbases with at least ``k+1`` columns (optional).
    C_12 : a functional map ``(k+1, k+1)`` to use instead of the ground truth.

    Returns a dict: ``"params"``, ``"timings"`` (seconds), ``"fields"`` (``source``,
    ``reference`` and one per kind, unit power fields), ``"metrics"`` (one dict per kind and for
    the ``"reference"``), ``"layouts"`` (quad textures ``q`` per shape/field) and ``"info"``.
    """
    t_all = time.perf_counter()
    timings = {}
    p2p_21 = np.asarray(p2p_21, dtype=np.int64)
    if p2p_21.shape != (mesh_2.n_vertices,):
        raise ValueError(f"p2p_21 must have shape (n2,) = ({mesh_2.n_vertices},); got {p2p_21.shape}")
    if not isinstance(k, (int, np.integer)) or k < 1:
        raise ValueError(f"k (non-constant eigenfunctions) must be a positive integer, got {k!r}")
    for kd in kinds:
        if kd not in ("std", "ext", "p2p"):
            raise ValueError(f"unknown kind {kd!r}; choose among 'std', 'ext', 'p2p'")
    t = time.perf_counter()
    b1 = basis_1 if basis_1 is not None else eigenbasis(mesh_1, k + 1)
    b2 = basis_2 if basis_2 is not None else eigenbasis(mesh_2, k + 1)
    b1, b2 = b1.truncate(k + 1), b2.truncate(k + 1)
    C = fmap_from_p2p(p2p_21, b1, b2) if C_12 is None else np.asarray(C_12, dtype=np.float64)
    timings["bases"] = time.perf_counter() - t
    t = time.perf_counter()
    fr1, fr2 = mesh_frames(mesh_1), mesh_frames(mesh_2)
    z1 = cross_field(mesh_1, scale=source_scale)
    z_ref, valid = pushforward_field(fr1, z1, fr2, p2p_21)
    guide2 = curvature_guide(mesh_2, fr2)[0] if align_target > 0 else None
    timings["source_field"] = time.perf_counter() - t
    V2, F2 = mesh_2.vertices, mesh_2.faces
    sing_ref = singularities(fr2, z_ref, 4)
    fields = {"source": z1, "reference": z_ref}
    metrics, info = {}, {}
    for kd in kinds:
        t = time.perf_counter()
        P = consistency_problem(fr1, b1, fr2, b2, C, kind=kd, rtol=rtol, power=power, p2p_21=p2p_21)
        z2, inf = design_consistent_field(P, z1, smoothness=smoothness, align=align_target, guide=guide2)
        timings[f"design_{kd}"] = time.perf_counter() - t
        fields[kd] = z2
        info[kd] = inf
        metrics[kd] = _field_metrics(fr2, z2, z_ref, valid, sing_ref, V2, F2)
        metrics[kd]["consistency"] = inf["consistency"]
    metrics["reference"] = _field_metrics(fr2, z_ref, z_ref, valid, sing_ref, V2, F2)
    layouts = {}
    if with_layouts:
        t = time.perf_counter()
        per = period
        if per is None:
            per = DEFAULTS["period_edges"] * mean_edge_length(mesh_1.vertices, mesh_1.faces)
        layouts["source"] = quad_texture(stripe_patterns(fr1, z1, period=per))
        for name in ("reference",) + tuple(kinds):
            layouts[name] = quad_texture(stripe_patterns(fr2, fields[name], period=per))
            sc = layout_consistency(layouts["source"], layouts[name], p2p_21, _lumped(mesh_2))
            metrics[name]["layout_agreement"] = sc["agreement"]
            metrics[name]["layout_correlation"] = sc["correlation"]
        layouts["period"] = per
        timings["layouts"] = time.perf_counter() - t
    timings["total"] = time.perf_counter() - t_all
    params = {"k": int(k), "kinds": list(kinds), "source_scale": source_scale, "smoothness": smoothness,
              "rtol": rtol, "power": power, "align_target": align_target,
              "period": layouts.get("period", period), "n_valid_faces": int(valid.sum())}
    return {"params": params, "timings": timings, "fields": fields, "metrics": metrics,
            "layouts": layouts, "info": info}


def _lumped(mesh: Mesh) -> np.ndarray:
    from ..operators import lumped_mass

    return lumped_mass(mesh.vertices, mesh.faces)


def dataset_pair(dataset: str, id_1: str, id_2: str):
    """``(mesh_1, mesh_2, p2p_21)`` of a dataset pair (ground truth from :mod:`prodmaps.datasets`).

    ``dataset_pair("anny_humans", "anny_000", "anny_003")`` is the paper-like pair.
    """
    from .. import datasets

    return (datasets.load_shape(dataset, id_1), datasets.load_shape(dataset, id_2),
            np.asarray(datasets.ground_truth(dataset, id_1, id_2), dtype=np.int64))


def summary_rows(result: dict) -> list[dict]:
    """Flat rows (one per field) of a :func:`figure14_experiment` result, for tables/results.json."""
    rows = []
    for name, m in result["metrics"].items():
        rows.append({"field": name, "k": result["params"]["k"], **m})
    return rows


def figure14_study(dataset: str, source_id: str, target_id: str, ks, *, rtol: float = DEFAULTS["rtol"],
                   gain_rule: bool = True, with_layouts: bool = True, verbose: bool = True) -> dict:
    """Figure 14 on one dataset pair for every ``k`` in ``ks`` (the paper's k; the first is shown).

    For each ``k``: the standard-basis design (``"std"``), the extended-basis design at the paper's
    Approach-B threshold ``rtol`` (``"ext"``) and, with ``gain_rule``, at the threshold the map-based
    gain rule picks (``"ext_gain_rule"``, :func:`prodmaps.truncation.select_rtol`; no ground truth).
    Returns ``{"results": {"k<k>": {field: metrics}}, "shown": the first k's full result, "meshes": (m1, m2)}``.
    """
    from ..truncation import select_rtol

    mesh_1, mesh_2, p2p_21 = dataset_pair(dataset, source_id, target_id)
    kmax = max(int(k) for k in ks) + 1
    B1, B2 = eigenbasis(mesh_1, kmax), eigenbasis(mesh_2, kmax)
    out, shown = {}, None
    for i, k in enumerate(ks):
        res = figure14_experiment(mesh_1, mesh_2, p2p_21, int(k), kinds=("std", "ext"), rtol=rtol,
                                  with_layouts=with_layouts or i == 0, basis_1=B1, basis_2=B2)
        metrics = dict(res["metrics"])
        metrics["rtol"] = {"ext": rtol}
        if gain_rule:
            b1, b2 = B1.truncate(int(k) + 1), B2.truncate(int(k) + 1)
            r_g = select_rtol(b1, method="gain", C_12=fmap_from_p2p(p2p_21, b1, b2), basis_2=b2, pairs="unique")
            g = figure14_experiment(mesh_1, mesh_2, p2p_21, int(k), kinds=("ext",), rtol=r_g,
                                    with_layouts=with_layouts, basis_1=B1, basis_2=B2)
            metrics["ext_gain_rule"] = g["metrics"]["ext"]
            metrics["rtol"]["ext_gain_rule"] = r_g
        metrics["seconds"] = res["timings"]["total"]
        out[f"k{k}"] = _finite_or_none(metrics)
        if shown is None:
            shown = res
        if verbose:
            print(f"k = {k}: mean angle error std {metrics['std']['angle_mean_deg']:.2f}°, ext "
                  f"{metrics['ext']['angle_mean_deg']:.2f}°" + (f", ext with the gain rule (rtol "
                  f"{metrics['rtol']['ext_gain_rule']:.3g}) {metrics['ext_gain_rule']['angle_mean_deg']:.2f}°"
                  if gain_rule else ""))
    return {"results": out, "shown": shown, "meshes": (mesh_1, mesh_2)}


def _finite_or_none(obj):
    """Replace NaN (e.g. a distance with no matched singularity) by None, recursively (JSON-safe)."""
    if isinstance(obj, dict):
        return {k: _finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj
