"""Building, part 2: the report's document from its data, and ``build_report`` that writes it.

:func:`read_inputs` gathers what a report shows (:class:`ReportInputs`): the main results folder
(``OUT/<profile>``, the embedded humans: its runs and its :class:`.report_data.DatasetReport`),
each prepared dataset's folder beside it (``OUT/<profile>-<dataset>``), the datasets carried over
from an earlier publication (``ReportSettings.kept``, loaded from ``paper/report_data/``) and the
published tables. :func:`build_document` turns them into a :class:`.document.Document` and writes
no file, so the report's structure is testable without rendering. :func:`build_report` does
both and writes ``REPORT.md`` and ``REPORT.html`` beside the results (the committed
``paper/REPORT.md`` is written only by :func:`.publishing.publish`). Its options are one
:class:`ReportSettings`.

The paper-specific prose is not in code: it is read from text files in ``report_text/`` beside
the run registry (``paper/report_text/``), each a Markdown file of headings, paragraphs and bullet
lists, with ``{name}`` placeholders filled at build time (``{{`` for a literal brace; HTML comments
are dropped). :data:`TEXT_FILES` names them; a file that is absent contributes nothing.

The document, in order:

1. the title (``title.md``), notes (what is partial, what is kept) and overridden parameters;
2. **Claims**: the verdict counts per dataset, the explanation (``claims.md``) and one row per
   claim of the ledger, with one verdict column per other dataset;
3. **Tables 1–6**: per published table, how close our values are (``tables.md``), then
   ``systematic_differences.md``;
4. one section per other dataset (fresh, then kept): its runs, shapes, pairs, tables, figures and
   studies; then the studies of the main results (one shown in a fresh dataset's section is not
   repeated);
5. **Runs** (status, time, links), **Figures**, and the appendix of every published value.

Figures are linked relative to the report's folder; ``copy_figures`` (:func:`copy_figures`)
first copies them into ``report_figures/[<dataset>/]<run>/`` there.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from ..files import atomic_path
from .document import Document
from .execute import DEFAULT_DATASET, git_commit, package_versions
from .registry import RegistryError, project_root, registry_path
from .report_data import (
    CRITERIA,
    DATASET_NAMES,
    LEDGER_FILE,
    TABLE_KEYS,
    DatasetReport,
    collect_runs,
    dataset_report,
    load_claims,
    load_published_rows,
    match_published,
    other_datasets,
    overridden_parameters,
    table_entries,
)

__all__ = ["TEXT_FILES", "ReportSettings", "ReportInputs", "read_inputs", "build_document", "copy_figures",
           "build_report", "report_text", "text_blocks"]

TEXT_FILES = ("title.md", "claims.md", "tables.md", "systematic_differences.md")
_PACKAGES = ("numpy", "scipy", "matplotlib", "pyvista", "vtk", "pymeshlab", "potpourri3d",
             "robust-laplacian", "papermill", "nbclient", "ipykernel", "dask", "distributed")


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


# ------------------------------------------------------------------------------ text files
def text_blocks(text: str) -> list:
    r"""Blocks of a report text: ``#`` headings, bullet lists (``- `` items) and paragraphs.

    Chunks are separated by blank lines; a paragraph's or an item's lines are joined with spaces.

    Examples
    --------
    >>> text_blocks("# Title\n\nOne paragraph\nwrapped.\n\n- an item\n  wrapped\n- another\n")
    [('h', 1, 'Title'), ('p', 'One paragraph wrapped.'), ('ul', ['an item wrapped', 'another'])]
    """
    blocks = []
    for chunk in re.split(r"\n\s*\n", text.strip()):
        lines = [ln.strip() for ln in chunk.strip().splitlines()]
        if not lines or not lines[0]:
            continue
        if lines[0].startswith("#"):
            level = len(lines[0]) - len(lines[0].lstrip("#"))
            blocks.append(("h", level, " ".join([lines[0][level:].strip(), *lines[1:]])))
        elif lines[0].startswith("- "):
            items = []
            for ln in lines:
                if ln.startswith("- "):
                    items.append(ln[2:])
                else:
                    items[-1] += " " + ln
            blocks.append(("ul", items))
        else:
            blocks.append(("p", " ".join(lines)))
    return blocks


def _text_folder(settings: ReportSettings) -> Path | None:
    if settings.text is not None:
        return Path(settings.text)
    try:
        return registry_path(settings.registry).parent / "report_text"
    except RegistryError:
        return None


def report_text(folder, name: str, **values) -> list:
    """The blocks of the text file ``folder/name`` with its ``{placeholders}`` filled; ``[]`` if absent."""
    path = Path(folder) / name if folder is not None else None
    if path is None or not path.is_file():
        return []
    text = re.sub(r"<!--.*?-->", "", path.read_text(encoding="utf-8"), flags=re.S)
    try:
        text = text.format_map(values)
    except (KeyError, ValueError, IndexError) as exc:
        raise ValueError(f"{path}: placeholder {exc} is not one the report fills ({', '.join(sorted(values))}); "
                         "write a literal brace as {{ or }}") from None
    return text_blocks(text)


# ------------------------------------------------------------------------------ paths and links
def _git_commit(registry=None) -> str:
    """The registry's project's :func:`.execute.git_commit` (``"unknown"`` outside a project)."""
    try:
        return git_commit(project_root(registry))
    except RegistryError:
        return "unknown"


def _rel(path: Path, start: Path) -> str:
    return Path(os.path.relpath(Path(path).resolve(), Path(start).resolve())).as_posix()


def _shown(path: Path, base: Path | None, registry=None, out_root: Path | None = None) -> str:
    """A folder relative to the project (``results/paper/fig02``), else to ``base``, else as given.

    With ``out_root`` (a published report: no machine path), a folder outside the project is named
    ``<out>/`` and its path below ``out_root`` (``<out>/paper/fig02``) instead.
    """
    try:
        return Path(path).resolve().relative_to(project_root(registry)).as_posix()
    except ValueError:  # RegistryError is a ValueError: no project found
        pass
    if out_root is not None:
        try:
            return "<out>/" + Path(path).resolve().relative_to(Path(out_root).resolve()).as_posix()
        except ValueError:
            return f"<out>/{Path(path).name}"
    return str(path) if base is None else _rel(path, base)


def _without_machine_paths(text: str, registry=None) -> str:
    """A traceback for a committed report: project paths relative, ``<site-packages>/...``, others ``…/<file>``."""
    text = re.sub(r"(?:/[^\s/\"':,]+)+/(site-packages|dist-packages)/", r"<\1>/", text)
    try:
        text = text.replace(str(project_root(registry).resolve()) + "/", "")
    except ValueError:  # no project
        pass
    return re.sub(r"(?<![\w.<>~/:-])/(?:[^\s/\"':,]+/)+([^\s/\"':,]+)", r"…/\1", text)  # not in a URL


def _link(path: Path, base: Path, text: str) -> str:
    return f"[{text}]({_rel(path, base)})" if path.is_file() else text


def _nb_link(run_folder: Path, base: Path, text: str, notebooks: dict | None = None) -> str:
    """Link to a run's executed notebook, or with ``notebooks`` (a published report) to its committed one."""
    if notebooks is None:
        return _link(run_folder / "executed.html", base, text)
    nb = notebooks.get(Path(run_folder).name)
    return _link(nb, base, text) if nb is not None else text


def _num(v, signed=False) -> str:
    return "" if v is None else (f"{v:+.3f}" if signed else f"{v:.3f}")


# ------------------------------------------------------------------------------ inputs
def read_inputs(results_dir, settings: ReportSettings, base) -> ReportInputs:
    """Read the results folders of a report written into the folder ``base`` (see the module doc)."""
    results_dir = Path(results_dir).resolve()
    out_root = None if settings.machine_paths else results_dir.parent
    reg, commit = settings.registry, _git_commit(settings.registry)
    infos = collect_runs(results_dir, reg)
    rows = load_published_rows(settings.published)
    matches, unmatched = match_published([e for i in infos for e in table_entries(i)], rows)
    main = dataset_report(results_dir, DEFAULT_DATASET, main=True, registry=reg, published_rows=rows, infos=infos,
                          shown=_shown(results_dir, None, reg, out_root), commit=commit)
    folders = (other_datasets(results_dir) if settings.datasets is None
               else {k: Path(v).resolve() for k, v in settings.datasets.items()})
    fresh = [dataset_report(f, ds, registry=reg, published_rows=rows, shown=_shown(f, base, reg, out_root),
                            commit=commit) for ds, f in folders.items()]
    return ReportInputs(results_dir, main.folder, commit, infos, main, fresh,
                        [k for k in settings.kept if k.dataset not in folders], rows, matches, unmatched)


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
    for s in inputs.main.studies:
        s.images = [copied.get(Path(p), p) for p in s.images]
    for d in inputs.datasets:
        for x in (*d.figures, *d.studies):
            x.images = [copy(p, root / d.dataset / x.run / Path(p).name) for p in x.images]
    return list(dict.fromkeys(copied.values()))


# ------------------------------------------------------------------------------ the document
def _verdict_text(c) -> str:
    """The verdict, then under each other family reading: ``"holds (textbook families: does not hold)"``."""
    head = f"**{c.verdict}**" if c.verdict == "does not hold" else c.verdict
    return head + "".join(f" ({r} families: {x})" for r, x in c.readings.items())


def _column_cell(c) -> str:
    """A dataset's verdict cell in the claims table."""
    if c is None or c.verdict == "not measured here":
        return "not measured here"
    return _verdict_text(c) + f" (paper {c.paper}, default {c.default})"


def _claims_section(d: Document, inputs: ReportInputs, settings: ReportSettings, text, base: Path) -> None:
    main, others = inputs.main, [*inputs.datasets, *inputs.kept]
    d.h(2, "Claims of the paper, judged on these results")
    d.counts(f"Totals over {len(main.verdicts)} claims", main.counts())
    for ds in inputs.datasets:
        d.counts(f"On {ds.name}", ds.counts())
    for ds in inputs.kept:
        d.counts(f"On {ds.name} (kept from the report published at commit `{ds.commit}`)", ds.counts())
    d.extend(text("claims.md"))
    if others:
        d.p("Verdict columns per dataset: *" + DATASET_NAMES.get(DEFAULT_DATASET, DEFAULT_DATASET) + "* (the default "
            "data, always) and " + ", ".join(f"*{ds.name}*" for ds in others)
            + " (prepared from the user's own files; see its section below).")
    claims, rows = load_claims(), []
    for cid, c in main.verdicts.items():
        claim = claims[cid]
        links = ", ".join(_nb_link(inputs.results_dir / r, base, claim.notebook or r if len(claim.runs) == 1 else r,
                                   settings.notebooks) for r in claim.runs)  # one notebook per run it is judged on
        rows.append([f"`{cid}`", claim.where, f"“{claim.quote[:110]}{'…' if len(claim.quote) > 110 else ''}”",
                     _verdict_text(c), c.paper, c.rule, c.default,
                     *(_column_cell(ds.verdicts.get(cid)) for ds in others),
                     "; ".join(f"{k}: {v}" for k, v in c.subsets.items()), c.evidence, links])
    d.table(["claim", "where", "the paper's words", "verdict", "paper", "rule", "default"]
            + [ds.name for ds in others] + ["intra / inter", "evidence", "notebook"], rows)


def _table_summaries(d: Document, tables, text, heading: str, level: int) -> None:
    d.h(level, heading)
    d.extend(text("tables.md"))

    def beats(b):
        return " · ".join("—" if x is None else f"{x[0]}/{x[1]}" for x in b)

    d.table(["table", "cells compared", f"within ±{CRITERIA['within']:g}", "missed, within draw noise",
             "mean |diff|", "largest |diff|", "products beat std: paper B (all · intra · inter)", "gain rule",
             "default"],
            [[f"Table {t.table}", f"{t.compared} of {t.published}", "—" if t.within is None else f"{t.within}",
              "—" if t.in_noise is None else f"{t.in_noise} of {t.missed}",
              "—" if t.mean_diff is None else f"{t.mean_diff:.3f}",
              "—" if t.largest_diff is None else f"{t.largest_diff:.3f}", *map(beats, t.beats.values())]
             for t in tables])


def _images(d: Document, run: str, images, base: Path) -> None:
    for p in images:
        d.img(_rel(p, base), f"{run} {Path(p).stem}")


def _dataset_section(d: Document, ds: DatasetReport, text, base: Path) -> None:
    d.h(2, f"On {ds.name}")
    d.p(f"Runs on `{ds.dataset}` (`{ds.folder}`): " + ", ".join(f"`{r}`" for r in ds.runs) + ". "
        + (f"Shapes: {', '.join(f'`{x}`' for x in ds.shapes)}. " if ds.shapes else "")
        + (f"{len(ds.pairs)} ordered (source, target) pairs in the tables: "
           + ", ".join(f"{a}→{b}" for a, b in ds.pairs) + "." if ds.pairs else ""))
    if ds.tables:
        _table_summaries(d, ds.tables, text, f"Tables on {ds.name}: our values beside the published ones", 3)
    for f in ds.figures:
        d.h(3, f"{f.run} on {ds.name}" + (f" — {f.reproduces}" if f.reproduces else ""))
        _images(d, f.run, f.images, base)
    for s in ds.studies:
        d.extend(s.blocks)
        _images(d, s.run, s.images, base)


def _provenance(inputs: ReportInputs, settings: ReportSettings) -> str:
    return (f"Generated by `{settings.generated_by}` from `{inputs.shown}` on "
            f"{_dt.datetime.now(_dt.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}, code at commit `{inputs.commit}`; "
            f"Python {platform.python_version()} on {platform.system()} {platform.machine()}.")


def build_document(inputs: ReportInputs, settings: ReportSettings, base) -> Document:
    """The report (see the module doc) as a :class:`.document.Document`, its links relative to ``base``."""
    base = Path(base).resolve()
    folder = _text_folder(settings)
    values = dict(CRITERIA, ledger_file=LEDGER_FILE, provenance=_provenance(inputs, settings))

    def text(name):
        return report_text(folder, name, **values)

    d = Document(text("title.md") or [("h", 1, "Reproduction report"), ("p", values["provenance"])])
    for note in settings.notes:
        d.p(note)
    overridden = overridden_parameters(inputs.runs)
    if overridden:
        d.p("**Parameters overridden on the command line** (these runs do not use the registry's settings): "
            + "; ".join(f"`{r}`: " + ", ".join(f"`{k}={json.dumps(v)}`" for k, v in ov.items())
                        for r, ov in overridden.items()) + ".")
    _claims_section(d, inputs, settings, text, base)
    if inputs.published:
        _table_summaries(d, inputs.main.tables, text, "Tables 1–6: our values beside the published ones", 2)
        d.extend(text("systematic_differences.md"))
    for ds in [*inputs.datasets, *inputs.kept]:
        _dataset_section(d, ds, text, base)
    # a study of the main results computed on a prepared dataset (FAUST when prepared) is not repeated
    # when that dataset's fresh section already shows the same run
    in_dataset = {(r, ds.dataset) for ds in inputs.datasets for r in ds.runs}
    studies = set()
    for s in inputs.main.studies:
        if (s.run, s.dataset) not in in_dataset:
            d.extend(s.blocks)
            _images(d, s.run, s.images, base)
            studies.add(s.run)
    _runs_and_figures(d, inputs, settings, base, studies)
    if inputs.published:
        _appendix(d, inputs)
    return d


def _runs_and_figures(d: Document, inputs: ReportInputs, settings: ReportSettings, base: Path, studies) -> None:
    infos, notebooks = inputs.runs, settings.notebooks
    out_root = None if settings.machine_paths else inputs.results_dir.parent
    d.h(2, "Runs")
    read = "notebook" if notebooks is not None else "executed notebook"
    d.table(["run", "reproduces", "status", "time (s)", "figures", "read"],
            [[f"`{i.name}`", i.reproduces, i.status, "" if i.seconds is None else f"{i.seconds:.1f}", len(i.figures),
              _nb_link(i.folder, base, read, notebooks)] for i in infos])
    failed = [i.name for i in infos if i.status not in ("ok",)]
    if failed:
        d.p("**Failed or not run:** " + ", ".join(f"`{n}`" for n in failed)
            + ". A failed run keeps `error.txt` and `executed.ipynb` in its folder.")
    d.p("Environment: " + ", ".join(f"{p} {v}" for p, v in package_versions(_PACKAGES).items()) + ".")
    d.h(2, "Figures")
    for i in infos:
        if i.name in studies or not (i.figures or i.status == "failed"):  # a study's figures: in its section
            continue
        d.h(3, f"{i.name}" + (f" — {i.reproduces}" if i.reproduces else ""))
        if i.title:
            d.p(i.title)
        d.p(f"Status **{i.status}**" + (f", {i.seconds:.1f} s" if i.seconds is not None else "")
            + f"; outputs in `{_shown(i.folder, base, settings.registry, out_root)}`; "
            + _nb_link(i.folder, base, read, notebooks) + "; every number in `results.json`.")
        if i.status == "failed" and (i.folder / "error.txt").is_file():
            excerpt = "\n".join((i.folder / "error.txt").read_text().splitlines()[:15])
            d.code(excerpt if settings.machine_paths else _without_machine_paths(excerpt, settings.registry))
        _images(d, i.name, i.figures, base)


def _appendix(d: Document, inputs: ReportInputs) -> None:
    d.h(2, "Appendix: every published table value beside ours")
    by_key = {tuple(r[k] for k in TABLE_KEYS): e for r, e in inputs.matches}
    for t in sorted({r["table"] for r in inputs.published}, key=int):
        prow = [r for r in inputs.published if r["table"] == t]
        settings = sorted({(r["fmap"], r["k_M"], r["k_N"]) for r in prow})
        d.h(3, f"Table {t}: " + "; ".join(f"{f}, k_M = {a}, k_N = {b}" for f, a, b in settings))
        multi = len(settings) > 1
        header = (["k_M", "k_N"] if multi else []) + ["function", "stage", "method", "published", "ours",
                                                      "difference", "SE of ours", "run"]
        trows = []
        for r in prow:
            e = by_key.get(tuple(r[k] for k in TABLE_KEYS))
            se = "—" if not e or e.get("se") is None else f"{e['se']:.3f}"
            ours = [_num(e["value"]), _num(e["value"] - r["value"], True), se, e["run"]] if e else ["—", "", "", ""]
            trows.append(([r["k_M"], r["k_N"]] if multi else [])
                         + [r["function"], r["stage"], r["method"], f"{r['value']:.2f}", *ours])
        d.table(header, trows)
    if inputs.unmatched:
        d.h(3, "Table values that match no published number")
        d.table(["run", "entry", "reason"],
                [[e.get("run", "") if isinstance(e, dict) else "",
                  "`" + json.dumps({k: v for k, v in e.items() if k != "run"} if isinstance(e, dict) else e) + "`",
                  why] for e, why in inputs.unmatched])


# ------------------------------------------------------------------------------ files
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
