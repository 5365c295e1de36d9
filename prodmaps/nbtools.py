"""Small helpers shared by the notebooks: results files, repeatable figures, notebook hygiene.

Every notebook writes into its ``out_dir``:

* ``results.json`` — every number it reports, under ``"results"``, plus ``"parameters"``,
  ``"prodmaps_version"`` and the versions of numpy/scipy (no timestamps, so reruns are
  byte-identical when the numbers are);
* PNG figures saved by :func:`save_figure` (fixed DPI, no metadata, no anti-aliasing of
  lines), or rendered by :mod:`prodmaps.render`.

Matplotlib is imported inside the functions that need it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

__all__ = ["write_results", "read_results", "save_figure", "setup_matplotlib", "to_jsonable",
           "strip_notebook", "notebook_has_outputs", "resolve_profile"]


def to_jsonable(obj):
    """Convert numpy scalars/arrays (recursively) to plain Python for JSON."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        raise ValueError("refusing to write a non-finite number to results.json")
    if isinstance(obj, Path):
        return str(obj)
    return obj


def resolve_profile(profile: str, profiles: dict, **overrides) -> dict:
    """Parameters of ``profile`` from a notebook's ``profiles`` table, with non-None overrides."""
    if profile not in profiles:
        raise ValueError(f"unknown profile {profile!r}; choose one of {sorted(profiles)}")
    params = dict(profiles[profile])
    params.update({k: v for k, v in overrides.items() if v is not None})
    return params


def write_results(out_dir, results: dict, parameters: dict) -> Path:
    """Write ``results.json`` atomically into ``out_dir`` and return its path."""
    import scipy

    from . import __version__

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    doc = {
        "parameters": to_jsonable(parameters),
        "results": to_jsonable(results),
        "prodmaps_version": __version__,
        "versions": {"numpy": np.__version__, "scipy": scipy.__version__},
    }
    path = out / "results.json"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(doc, indent=2, sort_keys=True) + "\n")
    os.replace(tmp, path)
    return path


def read_results(out_dir) -> dict:
    return json.loads((Path(out_dir) / "results.json").read_text())


def setup_matplotlib():
    """Headless, repeatable matplotlib (Agg backend, fixed fonts and DPI). Returns pyplot."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    plt.rcParams.update({
        "figure.dpi": 100, "savefig.dpi": 100, "font.family": "DejaVu Sans", "font.size": 9,
        "lines.antialiased": False, "patch.antialiased": False, "text.antialiased": True,
        "svg.hashsalt": "prodmaps", "axes.grid": False,
    })
    return plt


def save_figure(fig, out_dir, name: str) -> Path:
    """Save a matplotlib figure as ``out_dir/name.png`` with no metadata (repeatable bytes)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / (name if name.endswith(".png") else name + ".png")
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=100, metadata={"Software": None}, facecolor="white")
    os.replace(tmp, path)
    return path


# ------------------------------------------------------------------ notebook hygiene
def notebook_has_outputs(path) -> bool:
    """True if a committed notebook carries outputs or execution counts."""
    nb = json.loads(Path(path).read_text())
    return any(
        c.get("outputs") or c.get("execution_count") is not None
        for c in nb.get("cells", []) if c.get("cell_type") == "code"
    )


def strip_notebook(path) -> None:
    """Remove outputs, execution counts and volatile metadata in place."""
    path = Path(path)
    nb = json.loads(path.read_text())
    for c in nb.get("cells", []):
        if c.get("cell_type") == "code":
            c["outputs"] = []
            c["execution_count"] = None
        c.get("metadata", {}).pop("execution", None)
        c.get("metadata", {}).pop("papermill", None)
    nb.get("metadata", {}).pop("papermill", None)
    path.write_text(json.dumps(nb, indent=1, ensure_ascii=False) + "\n")


if __name__ == "__main__":  # python -m prodmaps.nbtools strip notebooks/*.ipynb
    import sys

    if len(sys.argv) >= 3 and sys.argv[1] == "strip":
        for p in sys.argv[2:]:
            strip_notebook(p)
    else:
        print("usage: python -m prodmaps.nbtools strip NOTEBOOK...")
