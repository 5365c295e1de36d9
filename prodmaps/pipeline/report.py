"""Building, part 2: the report's document assembled from its data, and ``build_report`` that writes it.

:func:`read_inputs` gathers what a report shows (:class:`ReportInputs`): the main results folder
(``OUT/<profile>``, the embedded humans: its runs and its :class:`.report_data.DatasetReport`),
each prepared dataset's folder beside it (``OUT/<profile>-<dataset>``), the datasets carried over
from an earlier publication (``ReportSettings.kept``, loaded from ``paper/report_data/``) and the
published tables. :func:`build_document` assembles them into a :class:`.document.Document` and
writes no file, so the report's structure is testable without rendering. :func:`build_report`
does both and writes ``REPORT.md`` and ``REPORT.html`` beside the results (the committed
``paper/REPORT.md`` is written only by :func:`.publishing.publish`). Its options are one
:class:`ReportSettings`.

The document, one column per dataset (the embedded humans, then the registered datasets' order):

1. the title, notes (what is partial, what is kept), overridden parameters, a line of contents;
2. the main text (:mod:`.main_text`): **Summary**, **Glossary**, **Claims** (the paper's, then this
   package's own apart), **Tables 1–6**, **Forking paths** (:mod:`.forking`), then **What differs
   from the paper**;
3. the appendices (:mod:`.appendices`): **A** the figure gallery, **B** the studies, **C1, C2, ...**
   one per dataset, **D** the runs.

The paper-specific prose (headings, paragraphs, captions, the datasets' scopes) is read from
``report_text/`` beside the run registry (:mod:`.prose`); folders and links are named as
:mod:`.links` names them. A paragraph already shown is not shown again (a study's text on a
second dataset). Figures are linked relative to the report's folder; ``copy_figures``
(:func:`copy_figures`) first copies them into ``report_figures/[<dataset>/]<run>/`` there.
"""

from __future__ import annotations

import datetime as _dt
import json
import platform
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from ..datasets import names as datasets_names
from ..files import atomic_path
from .appendices import dataset_appendix, gallery_appendix, runs_appendix, studies_appendix
from .document import Document, anchor
from .execute import DEFAULT_DATASET, git_commit
from .links import shown_folder
from .main_text import claims_section, forking_section, glossary_section, summary_section, tables_section
from .prose import CAPTIONS, dataset_scope, report_captions, report_text
from .registry import RegistryError, project_root, registry_path
from .report_data import (
    CRITERIA,
    DATASET_NAMES,
    LEDGER_FILE,
    DatasetReport,
    collect_runs,
    dataset_report,
    load_published_rows,
    match_published,
    other_datasets,
    overridden_parameters,
    reading_scores,
    run_dataset,
    table_entries,
)

__all__ = ["ReportSettings", "ReportInputs", "read_inputs", "build_document", "copy_figures", "build_report",
           "write_document"]


@dataclass(frozen=True)
class ReportSettings:
    """How a report is built (every field optional).

    ``registry``: the run registry (default ``$PRODMAPS_RUNS``, else ``paper/runs.toml``);
    ``published``: the published tables CSV (default: the package's); ``datasets``: ``{dataset:
    results folder}`` of the other datasets (default: the sibling folders, see
    :func:`.report_data.other_datasets`); ``kept``: :class:`.report_data.DatasetReport` of datasets
    not rerun, carried over (one with a fresh folder is ignored); ``notebooks``: ``{run: committed
    notebook}`` linked instead of the executed notebooks; ``notes``: paragraphs under the title;
    ``generated_by``: the command named in the provenance; ``machine_paths=False`` (a published
    report): folders outside the project are named ``<out>/...``, tracebacks lose this machine's
    paths; ``copy_figures``: copy the PNGs beside the report; ``text``: the folder of the text files
    (default ``report_text/`` beside the registry).
    """

    registry: object = None
    published: object = None
    datasets: dict | None = None
    kept: tuple = ()
    notebooks: dict | None = None
    notes: tuple = ()
    generated_by: str = "prodmaps report"
    machine_paths: bool = True
    copy_figures: bool = False
    text: object = None
    strict_captions: bool = False


@dataclass
class ReportInputs:
    """What one report shows, read by :func:`read_inputs`."""

    results_dir: Path
    shown: str  # the results folder as the report names it
    commit: str
    runs: list  # [RunInfo] of the main results
    main: DatasetReport
    datasets: list = field(default_factory=list)  # [DatasetReport] built from fresh folders
    kept: list = field(default_factory=list)  # [DatasetReport] carried over
    published: list = field(default_factory=list)  # published table rows
    matches: list = field(default_factory=list)  # (published row, our entry) of the main results
    unmatched: list = field(default_factory=list)  # (our entry, reason)


def _text_folder(settings: ReportSettings) -> Path | None:
    if settings.text is not None:
        return Path(settings.text)
    try:
        return registry_path(settings.registry).parent / "report_text"
    except RegistryError:
        return None


def _git_commit(registry=None) -> str:
    """The registry's project's :func:`.execute.git_commit` (``"unknown"`` outside a project)."""
    try:
        return git_commit(project_root(registry))
    except RegistryError:
        return "unknown"


def read_inputs(results_dir, settings: ReportSettings, base) -> ReportInputs:
    """Read the results folders of a report written into the folder ``base`` (see the module doc)."""
    results_dir = Path(results_dir).resolve()
    out_root = None if settings.machine_paths else results_dir.parent
    reg, commit = settings.registry, _git_commit(settings.registry)
    infos = collect_runs(results_dir, reg)
    rows = load_published_rows(settings.published)
    matches, unmatched = match_published([e for i in infos for e in table_entries(i)], rows)
    main = dataset_report(results_dir, DEFAULT_DATASET, main=True, registry=reg, published_rows=rows, infos=infos,
                          shown=shown_folder(results_dir, None, reg, out_root), commit=commit)
    folders = (other_datasets(results_dir) if settings.datasets is None
               else {k: Path(v).resolve() for k, v in settings.datasets.items()})
    fresh = [dataset_report(f, ds, registry=reg, published_rows=rows, shown=shown_folder(f, base, reg, out_root),
                            commit=commit) for ds, f in folders.items()]
    kept = [k for k in settings.kept if k.dataset not in folders]
    for ds in [*fresh, *kept]:  # readings scored by a main study run computed on a prepared dataset are that dataset's
        own = reading_scores([i for i in infos if i.doc and run_dataset(i) == ds.dataset])
        ds.readings = {**own, **ds.readings}
    return ReportInputs(results_dir, main.folder, commit, infos, main, fresh, kept, rows, matches, unmatched)


def copy_figures(inputs: ReportInputs, folder) -> list[Path]:
    """Copy the figures of the main runs and the fresh datasets into ``folder/report_figures/``; link those.

    ``report_figures/<run>/`` for the main results, ``report_figures/<dataset>/<run>/`` for another
    dataset (carried-over datasets already point there). Returns the copies.
    """
    root = Path(folder).resolve() / "report_figures"
    copied: dict = {}

    def copy(src: Path, dest: Path) -> Path:
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, dest)
        copied[Path(src)] = dest.resolve()
        return dest.resolve()

    for info in inputs.runs:
        info.figures = [copy(f, root / info.name / f.name) for f in info.figures]
    for x in (*inputs.main.figures, *inputs.main.studies):
        x.images = [copied.get(Path(p), p) for p in x.images]
    for d in inputs.datasets:
        for x in (*d.figures, *d.studies):
            x.images = [copy(p, root / d.dataset / x.run / Path(p).name) for p in x.images]
    return list(dict.fromkeys(copied.values()))


class _Seconds(dict):
    """``{run: "12.3"}`` for the ``{seconds[run]}`` placeholders; ``"—"`` for a run without a time."""

    def __missing__(self, key):
        return "—"


def _datasets(inputs: ReportInputs) -> list:
    """Every dataset's report data in the report's order: the main results, then the registered datasets' order."""
    order = [*datasets_names(), *DATASET_NAMES]
    others = sorted([*inputs.datasets, *inputs.kept],
                    key=lambda d: (order.index(d.dataset) if d.dataset in order else len(order), d.dataset))
    return [inputs.main, *others]


def _provenance(inputs: ReportInputs, settings: ReportSettings) -> str:
    return (f"Generated by `{settings.generated_by}` from `{inputs.shown}` on "
            f"{_dt.datetime.now(_dt.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}, code at commit `{inputs.commit}`; "
            f"Python {platform.python_version()} on {platform.system()} {platform.machine()}.")


def _without_repeats(d: Document) -> Document:
    """The document without a paragraph or a caption it already showed (a study's text on a second dataset)."""
    seen, out = set(), Document()
    for b in d.blocks:
        key = b[1] if b[0] == "p" else None
        if key is not None and key in seen:
            continue
        seen.add(key)
        out.blocks.append(b)
    return out


def _contents(d: Document) -> None:
    """A line of links to the level-2 sections, after the title's paragraphs."""
    heads = [b[2] for b in d.blocks if b[:2] == ("h", 2)]
    at = next((i for i, b in enumerate(d.blocks) if b[:2] == ("h", 2)), len(d.blocks))
    d.blocks.insert(at, ("p", "Contents: " + " · ".join(f"[{h}](#{anchor(h)})" for h in heads) + "."))


def build_document(inputs: ReportInputs, settings: ReportSettings, base) -> Document:
    """The report (see the module doc) as a :class:`.document.Document`, its links relative to ``base``."""
    base = Path(base).resolve()
    folder = _text_folder(settings)
    all_ds = _datasets(inputs)
    seconds = _Seconds({r: f"{s:.0f}" for r, (st, s) in inputs.main.run_times.items() if st == "ok" and s is not None})
    values = dict(CRITERIA, ledger_file=LEDGER_FILE, provenance=_provenance(inputs, settings), seconds=seconds,
                  n_paper=sum(1 for c in inputs.main.verdicts.values() if c.source == "paper"),
                  n_package=sum(1 for c in inputs.main.verdicts.values() if c.source == "package"),
                  data="; ".join(dataset_scope(folder, ds) for ds in all_ds))

    def text(name):
        return report_text(folder, name, **values)

    captions = report_captions(folder)
    runs = {f.run for ds in all_ds for f in ds.figures} | {s.run for ds in all_ds for s in ds.studies}
    missing = sorted(r for r in runs if r not in captions)
    if missing and settings.strict_captions:
        raise ValueError(f"no caption for the runs {', '.join(missing)}: add an entry for each to "
                         f"{(folder or Path('report_text')) / CAPTIONS} (what the paper's figure shows, what to look "
                         "at, what our panel shows)")
    d = Document(text("title.md") or [("h", 1, "Reproduction report"), ("p", values["provenance"])])
    for note in settings.notes:
        d.p(note)
    overridden = overridden_parameters(inputs.runs)
    if overridden:
        d.p("**Parameters overridden on the command line** (these runs do not use the registry's settings): "
            + "; ".join(f"`{r}`: " + ", ".join(f"`{k}={json.dumps(v)}`" for k, v in ov.items())
                        for r, ov in overridden.items()) + ".")
    summary_section(d, inputs, text, all_ds)
    glossary_section(d, text)
    claims_section(d, inputs, settings, text, all_ds, base)
    if inputs.published:
        tables_section(d, inputs, text, all_ds)
    forking_section(d, text, all_ds)
    differences = text("systematic_differences.md")
    if differences:
        d.h(2, "What differs from the paper, and why")
        d.extend(differences)
    gallery_appendix(d, text, all_ds, captions, base)
    studies_appendix(d, inputs, all_ds, captions, base)
    for n, ds in enumerate(all_ds, 1):
        dataset_appendix(d, ds, f"C{n}", inputs, base)
    runs_appendix(d, inputs, settings, all_ds, base)
    d = _without_repeats(d)
    _contents(d)
    return d


def write_document(doc: Document, md: Path, html_out: Path) -> None:
    """Write the document as Markdown to ``md`` and as HTML to ``html_out`` (each atomically)."""
    for path, content in ((md, doc.markdown()), (html_out, doc.html("prodmaps reproduction report"))):
        with atomic_path(path) as tmp:
            tmp.write_text(content, encoding="utf-8")


def _outputs(results_dir: Path, out, html_out) -> tuple[Path, Path]:
    out = (Path(out) if out is not None else results_dir / "REPORT.md").resolve()
    html_out = Path(html_out).resolve() if html_out is not None else out.with_suffix(".html")
    if html_out.parent != out.parent:  # the links are relative to the report's folder, shared by both files
        raise ValueError(f"html_out must be in the folder of the Markdown report ({out.parent}), got {html_out}")
    return out, html_out


def build_report(results_dir, out=None, settings: ReportSettings | None = None, *, html_out=None):
    """Write the Markdown and HTML reports for ``results_dir`` (e.g. ``results/paper``).

    ``out`` defaults to ``RESULTS_DIR/REPORT.md``, beside the results it reads; the HTML goes
    beside it (``html_out``, in the same folder: the links are relative to it). ``settings``: a
    :class:`ReportSettings` (default: all defaults). Returns ``(md_path, html_path)``.
    """
    settings = settings or ReportSettings()
    results_dir = Path(results_dir).resolve()
    out, html_out = _outputs(results_dir, out, html_out)
    inputs = read_inputs(results_dir, settings, out.parent)
    if settings.copy_figures:
        copy_figures(inputs, out.parent)
    write_document(build_document(inputs, settings, out.parent), out, html_out)
    return out, html_out
