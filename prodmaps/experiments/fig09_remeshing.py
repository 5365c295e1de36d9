"""Figure 9: the composite function transferred onto meshes with another connectivity, std vs products.

Conventions: ``C_12 = Φ2ᵀ A2 Φ1[p2p_21]`` ``(k_N + 1, k_M + 1)``; ``k_M``, ``k_N`` are the paper's
counts (non-constant functions); the reference on the target is the pull-back ``f[p2p_21]``.
The function: :func:`prodmaps.experiments.shared.anatomy.composite_function`. A target is a
variant id of ``dataset`` (a remesh made by ``prepare variants``, ground truth through its base
shape) or ``"<dataset>:<id>"``, a shape of another dataset in the same correspondence group (an
original FAUST registration to its FAUST_r remesh, :func:`prodmaps.datasets.ground_truth_between`).
"""

from __future__ import annotations

import time

from .. import datasets
from ..approx import PAPER_RTOL
from ..basis import eigenbasis
from ..metrics import relative_error
from ..p2p import fmap_from_p2p
from ..transfers import transfer
from .shared.anatomy import composite_function
from .shared.compare import outcome

__all__ = ["remeshing_transfer"]


def remeshing_transfer(dataset: str, targets, sizes, *, source_ids=None, laplacians=("cotan", "robust"),
                       rtol: float = PAPER_RTOL, pairs_convention: str = "ordered", frame=None,
                       length_scale="metres", verbose: bool = True) -> dict:
    """Figure 9: the composite function transferred onto meshes with another connectivity.

    Each target (a variant id, or ``"<dataset>:<id>"``, module doc) gets the regular family mesh
    ``source_ids[i]`` (default its base shape; for a target of another dataset, the shape of
    ``dataset`` with the same id) as source; the same transfer onto the regular mesh of the
    target's shape (for another dataset's shape: the source itself) is the stability reference.
    Both shapes of a pair use the same Laplacian. The function: the human composite in the
    dataset's ``frame`` with ``length_scale``. Returns
    ``{"results": {errors, summary, pairs}, "cases": [...], "fields": {(target, lap, kM, kN): (std, prod)}}``.
    """
    where = [_target(dataset, t) for t in targets]  # (dataset, id) of each target
    if source_ids is None:
        source_ids = [datasets.base_shape(dataset, t) if ds == dataset else t for ds, t in where]
    if len(source_ids) != len(targets):
        raise ValueError("source_ids must list one source per target")
    cases = []
    for src, tgt, (ds2, id2) in zip(source_ids, targets, where):
        m1, m2 = datasets.load_shape(dataset, src), datasets.load_shape(ds2, id2)
        f, _, _ = composite_function(m1, frame=frame, scale=length_scale)  # (n1,) defined on the regular source
        if ds2 == dataset:
            base = datasets.base_shape(dataset, tgt)
            p2p_21 = datasets.ground_truth(dataset, src, tgt)  # (n2,) variant vertex -> source vertex
        else:
            base = src  # the same pose in another triangulation: the source is the regular mesh
            p2p_21 = datasets.ground_truth_between((dataset, src), (ds2, id2))
        cases.append({"source": src, "target": tgt, "base": base, "m1": m1, "m2": m2,
                      "m_ref": datasets.load_shape(dataset, base), "f": f, "p2p_21": p2p_21,
                      "p2p_ref": datasets.ground_truth(dataset, src, base)})
    k1_max, k2_max = max(a for a, _ in sizes) + 1, max(b for _, b in sizes) + 1
    errors, fields = {}, {}
    for c in cases:
        for lap in laplacians:
            t0 = time.perf_counter()
            B1 = eigenbasis(c["m1"], k1_max, kind=lap)
            B2 = eigenbasis(c["m2"], k2_max, kind=lap)
            Br = eigenbasis(c["m_ref"], k2_max, kind=lap)
            for kM, kN in sizes:
                b1, b2, br = B1.truncate(kM + 1), B2.truncate(kN + 1), Br.truncate(kN + 1)
                out = {}
                for name, bb, p2p in (("variant", b2, c["p2p_21"]), ("reference", br, c["p2p_ref"])):
                    g, C = c["f"][p2p], fmap_from_p2p(p2p, b1, bb)  # ground truth, C (kN + 1, kM + 1)
                    ts = transfer(c["f"], C, b1, bb, "std")
                    tp = transfer(c["f"], C, b1, bb, "svd", rtol=rtol, pairs=pairs_convention)  # the paper's B
                    out[name] = {"std": relative_error(ts, g, bb.mass), "prod": relative_error(tp, g, bb.mass)}
                    if name == "variant":
                        fields[(c["target"], lap, kM, kN)] = (ts, tp)
                errors.setdefault(c["target"], {}).setdefault(lap, {})[f"kM{kM}_kN{kN}"] = out
            if verbose:
                print(f"{c['target']} [{lap}]: {time.perf_counter() - t0:.1f} s")
    summary = {}
    for tgt, by_lap in errors.items():
        for lap, by_size in by_lap.items():
            for key, e in by_size.items():
                v, r = e["variant"], e["reference"]
                summary[f"{tgt}/{lap}/{key}"] = {
                    "prod": v["prod"], "std": v["std"], "prod_vs_std": outcome(v["prod"], v["std"]),
                    "std_change_vs_reference": v["std"] - r["std"], "prod_change_vs_reference": v["prod"] - r["prod"]}
    results = {"error_definition": "sqrt(int (f-g)^2)/sqrt(int g^2), area-weighted on the target",
               "pairs": [f"{c['source']}->{c['target']}" for c in cases], "errors": errors, "summary": summary}
    return {"results": results, "cases": cases, "fields": fields, "source_ids": source_ids}


def _target(dataset: str, target: str) -> tuple[str, str]:
    """``(dataset, id)`` of a target: ``"<dataset>:<id>"`` names another dataset's shape, else ``dataset``'s."""
    ds, sep, sid = str(target).partition(":")
    return (ds, sid) if sep else (dataset, str(target))
