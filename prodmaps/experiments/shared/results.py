"""What every notebook writes: ``results.json`` and repeatable PNG figures.

Every notebook writes into its ``out_dir``:

* ``results.json`` — every number it reports, under ``"results"``, plus ``"parameters"``,
  ``"prodmaps_version"`` and the versions of numpy/scipy (no timestamps, so reruns are
  byte-identical when the numbers are);
* PNG figures saved by :func:`save_figure` (fixed DPI, no metadata, no anti-aliasing of
  lines), or rendered by :mod:`prodmaps.experiments.shared.render`.

Matplotlib is imported inside the functions that need it.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import scipy

from ... import __version__
from ...files import atomic_path

__all__ = ["write_results", "read_results", "save_figure", "setup_matplotlib", "to_jsonable", "flatten"]


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


def write_results(out_dir, results: dict, parameters: dict) -> Path:
    """Write ``results.json`` atomically into ``out_dir`` and return its path."""
    doc = {"parameters": to_jsonable(parameters), "results": to_jsonable(results), "prodmaps_version": __version__,
           "versions": {"numpy": np.__version__, "scipy": scipy.__version__}}
    path = Path(out_dir) / "results.json"
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(doc, indent=2, sort_keys=True) + "\n")
    return path


def flatten(obj, prefix: str = "", number_lists: bool = False) -> dict:
    """Nested dicts/lists -> ``{dotted.key: leaf}``.

    Empty containers are kept as leaves, and so are lists of numbers with ``number_lists``.
    """
    if isinstance(obj, dict) and obj:
        items = obj.items()
    elif isinstance(obj, list) and obj and not (number_lists and all(isinstance(v, (int, float)) for v in obj)):
        items = enumerate(obj)
    else:
        return {prefix: obj}
    out = {}
    for k, v in items:
        out.update(flatten(v, f"{prefix}.{k}" if prefix else str(k), number_lists))
    return out


def read_results(out_dir) -> dict:
    """The parsed ``results.json`` of a run folder."""
    return json.loads((Path(out_dir) / "results.json").read_text())


def _in_kernel() -> bool:
    """True inside a Jupyter kernel (a papermill run, an open notebook), False in scripts."""
    if "ipykernel" not in sys.modules:
        return False
    try:
        from IPython import get_ipython
    except ImportError:
        return False
    shell = get_ipython()
    return shell is not None and getattr(shell, "kernel", None) is not None


def setup_matplotlib():
    """Repeatable matplotlib (fixed fonts and DPI), headless; returns pyplot.

    In a Jupyter kernel the inline backend is selected, so ``plt.show()`` (or the end of a cell)
    puts each figure into the executed notebook; elsewhere (scripts, tests) the Agg backend. The
    PNGs written by :func:`save_figure` do not depend on the backend: both render with Agg and
    the rcParams set here.
    """
    import matplotlib

    if _in_kernel():
        matplotlib.use("module://matplotlib_inline.backend_inline")
    else:
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
    path = Path(out_dir) / (name if name.endswith(".png") else name + ".png")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=100, metadata={"Software": None}, facecolor="white")
    return path
