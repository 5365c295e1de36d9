"""Notebook files: declared parameters, output stripping, HTML export of executed notebooks.

* :func:`declared_parameters` reads the ``parameters`` cell with papermill, so the runner can
  refuse a ``-p NAME=VALUE`` the notebook does not declare; :func:`parameters_cell` reads it
  with :mod:`ast` alone, for :func:`prodmaps.pipeline.registry.run_parameters` in a kernel.
* :func:`strip` removes outputs (committed notebooks carry none; a test enforces it).
* :func:`export_html` writes an executed notebook as standalone HTML, figures embedded.

papermill, nbformat, nbstripout and nbconvert are imported inside the functions.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

from ..files import atomic_path

__all__ = ["declared_parameters", "parameters_cell", "parameter_default", "strip", "export_html", "code_lines"]


def declared_parameters(notebook) -> dict:
    """``{name: {"default": source text, "help": comment}}`` of the notebook's ``parameters`` cell."""
    import papermill

    return {k: {"default": v.get("default"), "help": v.get("help", "")}
            for k, v in papermill.inspect_notebook(str(notebook)).items()}


def parameters_cell(notebook) -> dict:
    r"""``{name: default as source text}`` of the notebook's ``parameters`` cell, read with :mod:`ast`.

    Every top-level ``name = value`` of the first code cell tagged ``parameters``, in order, with
    ``value`` as written (``"None"``, ``"[9, 19]"``, ``'"smoke"'``; comments dropped): the names and
    defaults :func:`declared_parameters` reads through papermill, without importing it. Raises
    ``ValueError`` if the notebook has no such cell.

    Examples
    --------
    >>> import json, tempfile
    >>> from pathlib import Path
    >>> cell = {"cell_type": "code", "metadata": {"tags": ["parameters"]}, "outputs": [], "execution_count": None,
    ...         "source": 'profile = "smoke"\nks = None   # the paper\'s k\nrtol = 1e-3\n'}
    >>> path = Path(tempfile.mkdtemp()) / "demo.ipynb"
    >>> _ = path.write_text(json.dumps({"cells": [cell], "metadata": {}, "nbformat": 4, "nbformat_minor": 5}))
    >>> parameters_cell(path)
    {'profile': '"smoke"', 'ks': 'None', 'rtol': '1e-3'}
    """
    path = Path(notebook)
    nb = json.loads(path.read_text(encoding="utf-8"))
    for cell in nb.get("cells", []):
        if cell.get("cell_type") == "code" and "parameters" in cell.get("metadata", {}).get("tags", []):
            src = cell.get("source", "")
            src = "".join(src) if isinstance(src, list) else src
            return {t.id: ast.get_source_segment(src, node.value) for node in ast.parse(src, filename=str(path)).body
                    if isinstance(node, ast.Assign) for t in node.targets if isinstance(t, ast.Name)}
    raise ValueError(f"{path}: no code cell tagged `parameters`")


def parameter_default(notebook, name: str):
    """The default of parameter ``name`` as a Python value (``None`` if absent or not a literal)."""
    return literal((declared_parameters(notebook).get(name) or {}).get("default"))


def literal(text):
    """A default's source text as a Python value (``None`` if ``text`` is None or not a literal)."""
    try:
        return ast.literal_eval(text) if text is not None else None
    except (ValueError, SyntaxError):
        return None


def strip(path) -> None:
    """Strip outputs, execution counts and volatile metadata in place (``nbstripout``)."""
    import nbformat
    from nbstripout import strip_output

    nb = nbformat.read(str(path), as_version=4)
    nb = strip_output(nb, keep_output=False, keep_count=False, keep_id=True,
                      extra_keys=["metadata.papermill", "cell.metadata.papermill", "cell.metadata.execution"])
    with atomic_path(path) as tmp:
        nbformat.write(nb, str(tmp))


def export_html(executed, html_path=None) -> Path:
    """Write ``executed`` (an ``.ipynb``) as standalone HTML with its figures embedded."""
    import nbformat
    from nbconvert import HTMLExporter

    executed = Path(executed)
    html_path = Path(html_path) if html_path is not None else executed.with_suffix(".html")
    nb = nbformat.read(str(executed), as_version=4)
    body, _ = HTMLExporter(template_name="classic").from_notebook_node(nb)
    with atomic_path(html_path) as tmp:
        tmp.write_text(body, encoding="utf-8")
    return html_path


def code_lines(path) -> int:
    """Number of non-blank lines in the code cells of a notebook file."""
    nb = json.loads(Path(path).read_text(encoding="utf-8"))
    return sum(1 for c in nb.get("cells", []) if c.get("cell_type") == "code"
               for line in "".join(c.get("source", [])).splitlines() if line.strip())


if __name__ == "__main__":  # python -m prodmaps.pipeline.notebooks strip notebooks/*.ipynb
    import sys

    if len(sys.argv) >= 3 and sys.argv[1] == "strip":
        for p in sys.argv[2:]:
            strip(p)
    else:
        print("usage: python -m prodmaps.pipeline.notebooks strip NOTEBOOK...")
