"""Figure 7: a composite function approximated and transferred with a ground-truth map, std vs products.

Conventions: ``C_12 = Φ2ᵀ A2 Φ1[p2p_21]`` ``(k_N + 1, k_M + 1)``; ``k_M``, ``k_N`` are the paper's
counts (non-constant functions); the reference on the target is the pull-back ``f[p2p_21]``.
The function: :func:`prodmaps.experiments.shared.anatomy.composite_function` (a human, or a
four-legged animal as the paper's cat).
"""

from __future__ import annotations

import time

import numpy as np

from .. import datasets
from ..approx import PAPER_RTOL
from ..basis import eigenbasis
from ..metrics import relative_error
from ..operators import laplacian
from ..p2p import fmap_from_p2p
from ..transfers import transfer_operator
from .shared.anatomy import composite_function

__all__ = ["function_transfer"]


def function_transfer(dataset: str, source_id: str, target_id: str, sizes, *, rtol: float = PAPER_RTOL,
                      rtol_compare=(), pairs_convention: str = "ordered", composite: str = "human", frame=None,
                      length_scale="metres", verbose: bool = True) -> dict:
    """Figure 7: the composite function approximated on the source and transferred to the target.

    For every ``(k_M, k_N)`` in ``sizes``: approximation and transfer errors (std / products with
    Approach B at ``rtol``), the transfer of each part alone, and products at the ``rtol_compare``
    thresholds. The function: ``composite`` (``"human"`` or ``"quadruped"``) in the dataset's
    ``frame`` with ``length_scale`` (:func:`prodmaps.experiments.shared.anatomy.composite_function`).
    Returns ``{"results": ..., "meshes": (m1, m2), "f": (n1,), "g_true": (n2,),
    "fields": {key: (approx_std, approx_prod, transfer_std, transfer_prod, transfer_default)}}``.
    """
    mesh_1 = datasets.load_shape(dataset, source_id)
    mesh_2 = datasets.load_shape(dataset, target_id)
    p2p_21 = datasets.ground_truth(dataset, source_id, target_id)  # (n2,) target -> source
    f, parts, anchors = composite_function(mesh_1, composite, frame=frame, scale=length_scale)  # (n1,)
    g_true = f[p2p_21]  # (n2,) ground-truth transfer
    mass_1 = laplacian(mesh_1)[1]
    support = {k: round(float(mass_1[np.abs(v) > 1e-3].sum() / mass_1.sum()), 3) for k, v in parts.items()}
    full_1 = eigenbasis(mesh_1, max(a for a, _ in sizes) + 1)
    full_2 = eigenbasis(mesh_2, max(b for _, b in sizes) + 1)
    kw = {"pairs": pairs_convention}
    errors, fields, extra = {}, {}, {}
    for kM, kN in sizes:
        t0 = time.perf_counter()
        b1, b2 = full_1.truncate(kM + 1), full_2.truncate(kN + 1)
        C = fmap_from_p2p(p2p_21, b1, b2)  # (kN + 1, kM + 1)
        err_1 = lambda a: relative_error(a, f, b1.mass)  # approximation error, on the source
        err_2 = lambda t: relative_error(t, g_true, b2.mass)  # transfer error, on the target
        std = transfer_operator(C, b1, b2, "std")
        prod = transfer_operator(C, b1, b2, "svd", rtol=rtol, **kw)  # the paper's Approach B
        # beside the paper: Approach B with the gain rule's threshold, and the library's default transfer
        gain = transfer_operator(C, b1, b2, "svd_gain", **kw)
        default = transfer_operator(C, b1, b2, "default")
        approx_std, approx_prod = std.approximate(f), prod.approximate(f)  # (n1,)
        trans_std, trans_prod, trans_default = std(f), prod(f), default(f)  # (n2,)
        key = f"kM{kM}_kN{kN}"
        errors[key] = {
            "approx": {"std": err_1(approx_std), "prod": err_1(approx_prod), "gain_rule": err_1(gain.approximate(f)),
                       "default": err_1(default.approximate(f))},
            "transfer": {"std": err_2(trans_std), "prod": err_2(trans_prod), "gain_rule": err_2(gain(f)),
                         "default": err_2(trans_default)},
            "gain_rule_rtol": gain.rtol,
        }
        Fp = np.column_stack(list(parts.values()))  # (n1, 4): each part alone, same pipeline
        Gp = Fp[p2p_21]
        eps, epp = relative_error(std(Fp), Gp, b2.mass), relative_error(prod(Fp), Gp, b2.mass)
        errors[key]["transfer_per_part"] = {name: {"std": eps[i], "prod": epp[i]} for i, name in enumerate(parts)}
        at = {r: transfer_operator(C, b1, b2, "svd", rtol=r, **kw) for r in rtol_compare}
        extra[key] = {f"rtol{r:g}": {"approx_prod": err_1(op.approximate(f)), "transfer_prod": err_2(op(f))}
                      for r, op in at.items()}
        fields[key] = (approx_std, approx_prod, trans_std, trans_prod, trans_default)
        if verbose:
            e = errors[key]
            print(f"k_M = {kM}, k_N = {kN}: approx std {e['approx']['std']:.4f} prod {e['approx']['prod']:.4f} | "
                  f"transfer std {e['transfer']['std']:.4f} prod {e['transfer']['prod']:.4f}  "
                  f"[{time.perf_counter() - t0:.1f} s]")
    results = {
        "error_definition": "sqrt(int (f-g)^2)/sqrt(int g^2), area-weighted (source for approx, target for transfer)",
        "pair": f"{source_id}->{target_id}", "anchors": anchors, "errors": errors, "other_rtol": extra,
    }
    return {"results": results, "meshes": (mesh_1, mesh_2), "f": f, "g_true": g_true, "fields": fields,
            "support": support}
