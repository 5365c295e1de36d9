"""Study: NO17 maps (ours vs pyFM) and extended vs standard point-map recovery on the embedded data.

Usage (from the repository root)::

    python benchmarks/study_p2p.py [OUT_DIR]        # default OUT_DIR: <tmpdir>/prodmaps_study_p2p

Writes ``study_p2p.json`` and ``study_p2p.md`` to OUT_DIR.

Part A — NO17 as in pyFM's demo, ours vs pyFM (optional dependency ``pyfmaps``): both sides
compute their own Laplacian eigenpairs (128) and the demo descriptors (100 WKS energies plus
wave-kernel maps at 5 landmarks, every 5th column kept), fit a 35x35 map with
``w_descr=1, w_lap=1e-2, w_dcomm=1e-1, w_orient=0`` (pyFM's canonical weighting and
resolvent Laplacian mask = our defaults) and convert it with the standard nearest-neighbour
rule. Landmarks: 5 Euclidean farthest-point samples of shape 1 from vertex 0, the same vertex
ids on shape 2 (identity ground truth of the family). Reported: mean geodesic error over
sqrt(area of shape 1) (``pm.geodesics.map_error``, heat-method distances) and fit times.

Part B — extended vs standard conversion at the paper's size 40x30: ``C_12`` has shape
``(k2, k1) = (40, 30)`` (rows = target N with k_N = 40 columns, columns = source M with
k_M = 30 columns, constant included; the paper writes C as k_N x k_M, Section 3). Maps:
ground truth, NO17 computed at 40x30 (demo descriptors, as in Part A), and ground truth plus
Gaussian noise on the free columns ``C[:, 1:]`` with relative Frobenius size ``noise``.
Conversions: ``std`` (pm.p2p, [OBCS*12]), ``ext`` (pm.p2p extended with its defaults:
t = 1/λ_max of the kernel's eigenpairs on shape 1, n_eig = 30, rtol = 1e-3, unique pairs), and a
control ``std_heat`` (standard conversion with both sides' deltas replaced by heat kernels at
the same t, in the original basis: isolates the effect of the products from the smoothing).
Sensitivity sweeps over t, n_eig and rtol on two pairs.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import prodmaps as pm
import prodmaps.geodesics  # noqa: F401
from prodmaps import fmaps
from prodmaps.datasets import dataset_dir
from prodmaps.neighbors import nearest_neighbors
from prodmaps.p2p import from_fmap

ROOT = Path(__file__).resolve().parents[1]  # the repository: where results and the registry live

SHAPES = dataset_dir("anny_humans") / "shapes"
NO17_PAIRS = [("000", "013"), ("000", "001"), ("000", "005"), ("002", "007"), ("011", "016"), ("023", "028")]
EXT_PAIRS = [("000", "001"), ("000", "003"), ("000", "005"), ("002", "007"), ("004", "009"), ("000", "013")]
NOISES = (0.1, 0.25, 0.5)
SEED = 0
W = dict(w_descr=1.0, w_lap=1e-2, w_dcomm=1e-1, w_orient=0.0)


def load(name):
    return pm.load_mesh(SHAPES / f"anny_{name}.ply")


_GEO = {}


def geo_error(mesh_1, p2p, name_1):
    """Mean and median geodesic error over sqrt(area_1) (identity ground truth)."""
    if name_1 not in _GEO:
        _GEO[name_1] = pm.geodesics.all_pairs(mesh_1)  # cached on disk
    e = pm.geodesics.map_error(mesh_1, p2p, np.arange(p2p.size), dist=_GEO[name_1])
    return float(e.mean()), float(np.median(e))


def std_heat(C, b1, b2, t):
    """Control: standard conversion with heat kernels h_t instead of deltas (original basis)."""
    k2, k1 = C.shape
    w1 = np.exp(-b1.evals[:k1] * t)
    w2 = np.exp(-b2.evals[:k2] * t)
    return nearest_neighbors(b2.vecs[:, :k2] * w2, (b1.vecs[:, :k1] * w1) @ C.T)


def part_a(out):
    try:
        from pyFM.functional import FunctionalMapping
        from pyFM.mesh import TriMesh
    except ImportError:
        out["part_a"] = "skipped: pyfmaps (pyFM) not installed"
        return
    rows = []
    for s1, s2 in NO17_PAIRS:
        m1, m2 = load(s1), load(s2)
        lm = fmaps.farthest_point_landmarks(m1.vertices, 5)
        # ours
        t0 = time.perf_counter()
        b1, b2 = pm.eigenbasis(m1, 128), pm.eigenbasis(m2, 128)
        d1, d2 = fmaps.no17_demo_descriptors(b1, b2, lm, n_descr=100, subsample_step=5, k_descr=128)
        t_pre = time.perf_counter() - t0
        C, info = fmaps.fit_no17(b1.truncate(35), b2.truncate(35), d1, d2, return_info=True, **W)
        p_ours = from_fmap(C, b1, b2)
        # pyFM, its own pipeline
        model = FunctionalMapping(
            TriMesh(m1.vertices.copy(), m1.faces.copy()), TriMesh(m2.vertices.copy(), m2.faces.copy())
        )
        t0 = time.perf_counter()
        model.preprocess(n_descr=100, descr_type="WKS", landmarks=lm, subsample_step=5, k_process=128, k_descr=128)
        t_pre_py = time.perf_counter() - t0
        t0 = time.perf_counter()
        model.fit(K=(35, 35), **W)
        t_fit_py = time.perf_counter() - t0
        p_py = model.get_p2p(n_jobs=1)
        e_ours, med_ours = geo_error(m1, p_ours, s1)
        e_py, med_py = geo_error(m1, p_py, s1)
        row = dict(pair=f"{s1}->{s2}", err_ours=e_ours, err_pyfm=e_py, median_ours=med_ours, median_pyfm=med_py,
                   ratio=e_ours / e_py, fit_s_ours=info["time"], fit_s_pyfm=t_fit_py, pre_s_ours=t_pre,
                   pre_s_pyfm=t_pre_py, nit_ours=info["nit"], n_descr=int(d1.shape[1]),
                   same_p2p=float(np.mean(p_ours == p_py)))
        rows.append(row)
        print("A", row, flush=True)
    out["part_a"] = rows


def part_b(out):
    rng = np.random.default_rng(SEED)
    rows, sweep = [], []
    for ip, (s1, s2) in enumerate(EXT_PAIRS):
        m1, m2 = load(s1), load(s2)
        B1, B2 = pm.eigenbasis(m1, 128), pm.eigenbasis(m2, 128)
        b1, b2 = B1.truncate(30), B2.truncate(40)
        lm = fmaps.farthest_point_landmarks(m1.vertices, 5)
        d1, d2 = fmaps.no17_demo_descriptors(B1, B2, lm, n_descr=100, subsample_step=5, k_descr=128)
        maps = {"ground truth": pm.fmap_from_p2p(np.arange(m2.n_vertices), b1, b2),
                "computed (NO17)": fmaps.fit_no17(b1, b2, d1, d2, **W)}
        gt = maps["ground truth"]
        for nz in NOISES:
            E = rng.normal(size=(40, 29))
            C = gt.copy()
            C[:, 1:] += nz * np.linalg.norm(gt[:, 1:]) * E / np.linalg.norm(E)
            maps[f"gt + noise {nz}"] = C
        t_def = 1.0 / b1.evals[29]
        for kind, C in maps.items():
            res = {}
            for conv in ("std", "ext", "std_heat"):
                t0 = time.perf_counter()
                if conv == "std":
                    p = from_fmap(C, b1, b2, method="std")
                elif conv == "ext":
                    p = from_fmap(C, b1, b2, method="extended")
                else:
                    p = std_heat(C, b1, b2, t_def)
                res[conv + "_s"] = time.perf_counter() - t0  # conversion only
                res[conv] = geo_error(m1, p, s1)[0]
            row = dict(pair=f"{s1}->{s2}", map=kind, **res)
            rows.append(row)
            print("B", row, flush=True)
            if ip < 2 and kind in ("ground truth", "computed (NO17)", "gt + noise 0.25"):
                grid = [dict(t_scale=ts) for ts in (0.1, 0.3, 3.0, 10.0)]
                grid += [dict(n_eig=ne) for ne in (10, 20)]
                grid += [dict(rtol=r) for r in (1e-2, 1e-4)]
                for params in grid:
                    p = from_fmap(C, b1, b2, method="extended", **params)
                    srow = dict(
                        pair=f"{s1}->{s2}", map=kind, params=params, ext=geo_error(m1, p, s1)[0], std=res["std"]
                    )
                    sweep.append(srow)
                    print("S", srow, flush=True)
    out["part_b"] = rows
    out["sweep"] = sweep


def to_markdown(out):
    L = ["# study_p2p", "", f"prodmaps study, seed {SEED}; errors: mean geodesic error / sqrt(area of shape 1).", ""]
    if isinstance(out.get("part_a"), list):
        L += [
            "## A. NO17 (pyFM demo settings, 35x35, std conversion): ours vs pyFM",
            "",
            "| pair | err ours | err pyFM | ours/pyFM | fit s ours | fit s pyFM | same p2p |",
            "|---|---|---|---|---|---|---|",
        ]
        for r in out["part_a"]:
            L.append(f"| {r['pair']} | {r['err_ours']:.4f} | {r['err_pyfm']:.4f} | {r['ratio']:.3f} | "
                     f"{r['fit_s_ours']:.2f} | {r['fit_s_pyfm']:.2f} | {r['same_p2p']:.3f} |")
        a = out["part_a"]
        L += [f"| **mean** | {np.mean([r['err_ours'] for r in a]):.4f} | {np.mean([r['err_pyfm'] for r in a]):.4f} | "
              f"{np.mean([r['err_ours'] for r in a]) / np.mean([r['err_pyfm'] for r in a]):.3f} | "
              f"{np.mean([r['fit_s_ours'] for r in a]):.2f} | {np.mean([r['fit_s_pyfm'] for r in a]):.2f} | |", ""]
    else:
        L += [f"## A. {out.get('part_a')}", ""]
    L += ["## B. Point-map recovery at C (k2, k1) = (40, 30): std vs extended", "",
          "| pair | map | std | ext | std_heat | ext s |", "|---|---|---|---|---|---|"]
    for r in out["part_b"]:
        L.append(
            f"| {r['pair']} | {r['map']} | {r['std']:.4f} | {r['ext']:.4f} | {r['std_heat']:.4f} | {r['ext_s']:.1f} |"
        )
    L += ["", "Means over pairs:", "", "| map | std | ext | std_heat | ext better on |", "|---|---|---|---|---|"]
    kinds = list(dict.fromkeys(r["map"] for r in out["part_b"]))
    for k in kinds:
        rs = [r for r in out["part_b"] if r["map"] == k]
        better = sum(r["ext"] < r["std"] for r in rs)
        L.append(f"| {k} | {np.mean([r['std'] for r in rs]):.4f} | {np.mean([r['ext'] for r in rs]):.4f} | "
                 f"{np.mean([r['std_heat'] for r in rs]):.4f} | {better}/{len(rs)} pairs |")
    L += ["", "## Sensitivity of the extended conversion (defaults: t_scale=1, n_eig=30, rtol=1e-3)", "",
          "| pair | map | params | ext | std |", "|---|---|---|---|---|"]
    for r in out["sweep"]:
        L.append(f"| {r['pair']} | {r['map']} | {r['params']} | {r['ext']:.4f} | {r['std']:.4f} |")
    return "\n".join(L) + "\n"


def main(argv):
    out_dir = Path(argv[1]) if len(argv) > 1 else Path(tempfile.gettempdir()) / "prodmaps_study_p2p"
    out_dir.mkdir(parents=True, exist_ok=True)
    out = {"seed": SEED, "weights": W, "pairs_no17": NO17_PAIRS, "pairs_ext": EXT_PAIRS, "noises": NOISES}
    t0 = time.perf_counter()
    if os.environ.get("STUDY_SKIP_A") != "1":
        part_a(out)
    part_b(out)
    out["total_s"] = time.perf_counter() - t0
    (out_dir / "study_p2p.json").write_text(json.dumps(out, indent=1, default=float))
    (out_dir / "study_p2p.md").write_text(to_markdown(out))
    print(f"wrote {out_dir}/study_p2p.json and .md in {out['total_s']:.0f} s")


if __name__ == "__main__":
    main(sys.argv)
