"""Sphinx configuration of the prodmaps documentation site (``make docs``).

Notebooks are never executed here (``nb_execution_mode = "off"``): the gallery is written by
:mod:`prodmaps.pipeline.gallery` into ``docs/_generated/`` at the start of each build, from the run
folder in ``$PRODMAPS_DOCS_RUNS`` (e.g. ``results/smoke``) when set, else from the committed
notebooks and smoke baselines.
"""

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(ROOT))

import prodmaps  # noqa: E402
from prodmaps.pipeline import gallery  # noqa: E402

_runs = os.environ.get("PRODMAPS_DOCS_RUNS") or None
if _runs is not None:  # `make docs DOCS_RUNS=results/smoke`: relative to the project root, not to docs/
    _runs = Path(_runs).expanduser()
    _runs = _runs if _runs.is_absolute() else ROOT / _runs
    if not any(_runs.glob("*/executed.ipynb")):
        raise RuntimeError(f"PRODMAPS_DOCS_RUNS={os.environ['PRODMAPS_DOCS_RUNS']}: no executed notebooks in "
                           f"{_runs} (expected <run>/executed.ipynb, e.g. results/smoke after `make reproduce-smoke`)")
_names = gallery.write_gallery(HERE / "_generated" / "gallery", _runs)
gallery.write_report_page(HERE / "_generated", ROOT / "paper" / "REPORT.md", _names)

project = "prodmaps"
author = "prodmaps developers"
copyright = "prodmaps developers"
release = version = prodmaps.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "myst_nb",
]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "**.ipynb_checkpoints"]

nb_execution_mode = "off"
nb_output_stderr = "remove"
myst_enable_extensions = ["dollarmath", "colon_fence"]
myst_heading_anchors = 3
# Notebook and report text links to repository files that are not pages of the site, and its
# headings start where the narrative needs them; those two classes of warning are not errors here.
suppress_warnings = ["myst.xref_missing", "myst.header", "mystnb.unknown_mime_type"]

autodoc_default_options = {"show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # types are in the numpydoc Parameters blocks: one block per entry
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
napoleon_use_param = False  # shapes such as "(n, 3) array_like" stay text, not cross-references

html_theme = "pydata_sphinx_theme"
html_title = "prodmaps"
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_show_sourcelink = False
