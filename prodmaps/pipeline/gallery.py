"""Sources of the documentation site's gallery and report page (called by ``docs/conf.py``).

The site never executes a notebook. For each registered run, the gallery page is

* the executed notebook ``RUNS/<run>/executed.ipynb`` of a smoke (or paper) run folder when one is
  given (``make docs DOCS_RUNS=results/smoke``): its figures are inline;
* otherwise the committed notebook (outputs stripped) preceded by the figures of the committed
  smoke baselines (``paper/baselines/smoke/<run>/*.png``), so ``make docs`` works on a clean clone.

The report page is ``paper/REPORT.md`` with its links to executed notebooks pointed at the
gallery pages and its figures copied beside it.
"""

from __future__ import annotations

import contextlib
import re
import shutil
from collections import Counter
from pathlib import Path

from .registry import load_registry, project_root

__all__ = ["write_gallery", "write_report_page"]


def write_gallery(dest, runs_dir=None, *, registry=None, baselines=None) -> list[str]:
    """Write ``dest/index.md`` and one ``dest/<run>.ipynb`` per registered run; returns the run names.

    ``runs_dir`` is a profile folder (``OUT/smoke``) whose executed notebooks are used where present.
    """
    import nbformat

    dest = Path(dest)
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    root = project_root(registry)
    baselines = Path(baselines) if baselines else root / "paper" / "baselines" / "smoke"
    runs = load_registry(registry)
    lines = ["# Gallery", "",
             "One page per registered run: the notebook that reproduces a figure or table of the paper. ",
             ("Pages are the executed notebooks of the run folder `" + Path(runs_dir).name + "`, figures inline."
              if runs_dir else "Pages are the committed notebooks (not executed at build time) with the figures "
              "of the committed smoke baselines; `make docs DOCS_RUNS=results/smoke` shows executed notebooks."),
             "", "```{toctree}", ":maxdepth: 1", ""]
    shared = Counter(run.notebook for run in runs.values())
    for name, run in runs.items():
        executed = Path(runs_dir) / name / "executed.ipynb" if runs_dir else None
        if executed is not None and executed.is_file():
            nb = nbformat.read(executed, as_version=4)
        else:
            nb = nbformat.read(run.notebook, as_version=4)
            for cell in nb.cells:
                if cell.cell_type == "code":
                    cell.outputs, cell.execution_count = [], None
            figs = sorted((baselines / name).glob("*.png"))
            for png in figs:
                shutil.copyfile(png, dest / f"{name}__{png.name}")
            note = [f"*{run.reproduces}* — smoke-profile figures from the committed baselines "
                    f"(`paper/baselines/smoke/{name}/`); the notebook below is shown without outputs.", ""]
            note += [f"![{png.stem}]({name}__{png.name})" for png in figs]
            nb.cells.insert(_after_title(nb), nbformat.v4.new_markdown_cell("\n".join(note)))
        if shared[run.notebook] > 1:  # one notebook, several runs (Tables 1-6): title each page by its run
            i = _after_title(nb) - 1
            if i >= 0:
                first, _, rest = nb.cells[i].source.lstrip().partition("\n")
                nb.cells[i].source = f"# {run.reproduces}: {run.title or first[2:]}\n{rest}"
        nb.metadata.pop("widgets", None)
        nbformat.write(nb, dest / f"{name}.ipynb")
        lines.append(name)
    lines += ["```", ""]
    (dest / "index.md").write_text("\n".join(lines), encoding="utf-8")
    return list(runs)


def _after_title(nb) -> int:
    """Index after the first markdown cell that starts with a level-1 heading (0 if none)."""
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "markdown" and cell.source.lstrip().startswith("# "):
            return i + 1
    return 0


_RUN_LINK = re.compile(r"\]\(\.\./results/[^/)]+/([A-Za-z0-9_]+)/executed\.html\)")
# a published report links the committed notebooks: [text](../notebooks/<file>.ipynb)
_NB_LINK = re.compile(r"\[([^\]]+)\]\(\.\./notebooks/([^)\s]+?)\.ipynb\)")


def write_report_page(dest, report=None, gallery_names=()) -> Path:
    """Write ``dest/report.md`` from ``paper/REPORT.md``: notebook links to gallery pages, figures copied."""
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    report = Path(report) if report else project_root() / "paper" / "REPORT.md"
    text = report.read_text(encoding="utf-8")
    names = set(gallery_names)
    text = _RUN_LINK.sub(lambda m: f"](gallery/{m.group(1)}.ipynb)" if m.group(1) in names else "]()", text)
    by_notebook = {}
    with contextlib.suppress(Exception):  # no registry here: the links become plain text
        for name, run in load_registry().items():
            by_notebook.setdefault(run.notebook.stem, name)

    def _nb(m):
        run = m.group(1) if m.group(1) in names else by_notebook.get(m.group(2))
        return f"[{m.group(1)}](gallery/{run}.ipynb)" if run in names else m.group(1)

    text = _NB_LINK.sub(_nb, text)
    text = text.replace("]()", "]")  # a run without a gallery page: plain text
    figures = report.parent / "report_figures"
    if figures.is_dir():
        shutil.copytree(figures, dest / "report_figures", dirs_exist_ok=True)
    out = dest / "report.md"
    out.write_text(text, encoding="utf-8")
    return out
