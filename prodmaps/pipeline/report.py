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

The paper-specific prose is not in code: it is read from ``report_text/`` beside the run registry
(``paper/report_text/``): Markdown files of headings, paragraphs, bullet lists and fenced code
(:data:`TEXT_FILES`; ``{name}`` placeholders filled at build time, ``{{`` for a literal brace,
HTML comments dropped; an absent file contributes nothing), the figures' captions
(:data:`CAPTIONS`, :func:`report_captions`) and the datasets' scopes (``datasets.toml``).

The document, one column per dataset (the embedded humans, then the registered datasets' order):

1. the title, notes (what is partial, what is kept), overridden parameters, a line of contents;
2. the main text: **Summary** (scope, the verdict counts of the paper's claims, what does not hold,
   what is not reproduced and why, one rerun command with its time), **Glossary**, **Claims**
   (the paper's, then this package's own apart), **Tables 1–6** (cells within ±0.02 and within
   draw noise), **Forking paths** (:mod:`.forking`), **What differs from the paper**;
3. the appendices: **A** the figure gallery (each run's panels of every dataset side by side, its
   caption), **B** the studies, **C1, C2, ...** one per dataset (claims with their settings,
   paired comparison and evidence; table summaries; every table cell), **D** the runs.

A paragraph already shown is not shown again (a study's text on a second dataset).
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

from ..datasets import names as datasets_names
from ..files import atomic_path, parse_toml
from .document import Document, anchor, words
from .execute import DEFAULT_DATASET, git_commit, package_versions
from .forking import forking_blocks, forking_paths, reading_verdict_blocks
from .registry import RegistryError, project_root, registry_path
from .report_data import (
    CRITERIA,
    DATASET_NAMES,
    LEDGER_FILE,
    VERDICTS,
    DatasetReport,
    collect_runs,
    dataset_report,
    load_claims,
    load_published_rows,
    match_published,
    other_datasets,
    overridden_parameters,
    printed,
    reading_scores,
    run_dataset,
    table_entries,
    within_draw_noise,
    within_published,
)

__all__ = ["TEXT_FILES", "CAPTIONS", "ReportSettings", "ReportInputs", "read_inputs", "build_document",
           "copy_figures", "build_report", "report_text", "report_captions", "text_blocks", "write_document"]

TEXT_FILES = ("title.md", "summary.md", "not_reproduced.md", "rerun.md", "glossary.md", "claims.md",
              "beyond_the_paper.md", "tables.md", "forking_paths.md", "systematic_differences.md", "gallery.md")
CAPTIONS = "captions.toml"  # the figures' captions, one entry per run
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


# ------------------------------------------------------------------------------ text files
def text_blocks(text: str) -> list:
    r"""Blocks of a report text: ``#`` headings, bullet lists (``- `` items), fenced code and paragraphs.

    Chunks are separated by blank lines; a paragraph's or an item's lines are joined with spaces; a
    chunk fenced by lines of three backticks is code, kept as it is.

    Examples
    --------
    >>> text_blocks("# Title\n\nOne paragraph\nwrapped.\n\n- an item\n  wrapped\n- another\n")
    [('h', 1, 'Title'), ('p', 'One paragraph wrapped.'), ('ul', ['an item wrapped', 'another'])]
    >>> text_blocks("```\nmake reproduce\n```")
    [('code', 'make reproduce')]
    """
    blocks = []
    for chunk in re.split(r"\n\s*\n", text.strip()):
        fenced = re.fullmatch(r"```[^\n]*\n(.*?)\n?```", chunk.strip(), flags=re.S)
        if fenced:
            blocks.append(("code", fenced.group(1)))
            continue
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


# ------------------------------------------------------------------------------ the document
class _Seconds(dict):
    """``{run: "12.3"}`` for the ``{seconds[run]}`` placeholders; ``"—"`` for a run without a time."""

    def __missing__(self, key):
        return "—"


def _verdict_text(c) -> str:
    """The verdict, bold when it does not hold."""
    return f"**{c.verdict}**" if c.verdict == "does not hold" else c.verdict


def _other_readings(c) -> str:
    return "; ".join(f"{'textbook families' if r == 'textbook' else r}: {x}" for r, x in c.readings.items())


APPENDIX_CLAIMS = ["claim", "verdict", "rule", "default", "intra / inter", "other readings", "paired comparison",
                   "margin", "left out", "evidence"]  # a dataset appendix's claims table


def _comparison_text(x: dict) -> str:
    """One paired comparison: its mean improvement (or mean) ± SE, n, relative size, bound or test, outcome."""
    value = x.get("mean_diff", x.get("mean"))
    num = lambda v, signed=False: f"{v:+.3g}" if signed else f"{v:.3g}"  # noqa: E731
    parts = [] if value is None else [num(value, "mean_diff" in x) + (
        f" ± {x['se']:.2g}" if isinstance(x.get("se"), (int, float)) else "")]
    parts += [f"n = {x['n']}"] if x.get("n") is not None else []
    parts += [f"{x['rel']:+.0%}"] if isinstance(x.get("rel"), (int, float)) else []
    parts += [f"bound {x['bound']:g}"] if isinstance(x.get("bound"), (int, float)) else []
    parts += [str(x["test"])] if x.get("test") else []
    text = ", ".join(parts) + (f" ({x['outcome']})" if x.get("outcome") else "")
    return f"{x['label']}: {text}" if x.get("label") else text


def _comparisons_text(c, most: int = 4) -> str:
    """A claim's paired comparisons (the first ``most``; how many more)."""
    parts = [_comparison_text(x) for x in c.comparisons[:most] if isinstance(x, dict)]
    if len(c.comparisons) > most:
        parts.append(f"… {len(c.comparisons) - most} more")
    return "; ".join(parts) or "—"


def _margin_text(c) -> str:
    """A claim's practical margin, why, and the verdicts at the other margins tried."""
    if c.margin is None:
        return "—"
    text = f"{c.margin:g}" + (f" ({c.why})" if c.why else "")
    others = "; ".join(f"at {m}: {v}" for m, v in c.sensitivity.items())
    return text + (f"; {others}" if others else "")


def _datasets(inputs: ReportInputs) -> list:
    """Every dataset's report data in the report's order: the main results, then the registered datasets' order."""
    order = [*datasets_names(), *DATASET_NAMES]
    others = sorted([*inputs.datasets, *inputs.kept],
                    key=lambda d: (order.index(d.dataset) if d.dataset in order else len(order), d.dataset))
    return [inputs.main, *others]


SUMMARY_WORDS = 600  # the summary's budget: one page


def _weak_claims(main, claims, all_ds) -> list:
    """``[(claim id, where, {verdict: [DatasetReport]})]``: the paper's claims that do not hold or are inconclusive."""
    out = []
    for cid, c in main.verdicts.items():
        if cid not in claims or c.source != "paper":
            continue
        by_verdict: dict = {}
        for ds in all_ds:
            v = ds.verdicts.get(cid)
            if v is not None and v.verdict in ("does not hold", "inconclusive"):
                by_verdict.setdefault(v.verdict, []).append(ds)
        if by_verdict:
            out.append((cid, claims[cid].where, by_verdict))
    return out


def _weak_blocks(weak, detail: int) -> list:
    """The summary's list of the claims that do not hold or are inconclusive, those that do not hold first.

    ``detail`` 3: per claim, its datasets and the first one's evidence; 2: the evidence only for the
    claims that do not hold; 1: no evidence; 0: the claims' ids per verdict.
    """
    if not weak:
        return []
    weak = sorted(weak, key=lambda w: "does not hold" not in w[2])
    lead = ("p", "**Does not hold, or inconclusive**, on at least one dataset" + (
        ", with the evidence on the first (each dataset's appendix gives all of it):" if detail >= 2 else
        " (each dataset's appendix gives the evidence):"))
    if detail == 0:
        verdicts = list(dict.fromkeys(v for _, _, by in weak for v in by))
        return [lead, ("ul", [f"{v}: " + ", ".join(f"`{cid}`" for cid, _, by in weak if v in by) for v in verdicts])]
    items = []
    for cid, where, by in weak:
        item = f"`{cid}` ({where}): " + "; ".join(f"{v} on {', '.join(x.name for x in sets)}" for v, sets in by.items())
        first = next(iter(by.values()))[0]
        if first.verdicts[cid].evidence and (detail == 3 or (detail == 2 and "does not hold" in by)):
            item += f". {first.name}: {_short(first.verdicts[cid].evidence)}"
        items.append(item)
    return [lead, ("ul", items)]


def _summary(d: Document, inputs: ReportInputs, text, all_ds: list) -> None:
    """The summary: scope, verdict table, what does not hold, what is not reproduced, the rerun command.

    What does not hold is listed as detailed as keeps the summary within :data:`SUMMARY_WORDS`.
    """
    main, claims = inputs.main, load_claims()
    head = Document(text("summary.md"))
    counts = {ds.dataset: ds.counts_by_source()["paper"] for ds in all_ds}
    found = dict.fromkeys([*VERDICTS, *(v for c in counts.values() for v in c)])  # a stored file's older verdicts
    shown = [v for v in found if any(c.get(v) for c in counts.values())]
    n_paper = sum(1 for c in main.verdicts.values() if c.source == "paper")
    head.table([f"verdict (of the paper's {n_paper} claims)"] + [ds.name for ds in all_ds],
               [[v] + [str(counts[ds.dataset].get(v, 0)) for ds in all_ds] for v in shown])
    package = {ds.dataset: ds.counts_by_source()["package"] for ds in all_ds}
    if any(sum(c.values()) for c in package.values()):
        head.p("This package's own claims, counted apart (see *Beyond the paper*): " + "; ".join(
            f"{ds.name}: " + ", ".join(f"{n} {v}" for v, n in package[ds.dataset].items() if n) for ds in all_ds
            if sum(package[ds.dataset].values())) + ".")
    tail = Document(text("not_reproduced.md"))
    unmeasured = [f"`{cid}`" for cid, c in main.verdicts.items() if c.source == "paper" and all(
        ds.verdicts.get(cid) is None or ds.verdicts[cid].verdict == "not measured here" for ds in all_ds)]
    if unmeasured:
        tail.p("Not measured on any dataset of this report: " + ", ".join(unmeasured) + ".")
    tail.extend(text("rerun.md"))
    weak = _weak_claims(main, claims, all_ds)
    for detail in (3, 2, 1, 0):  # the most detailed list of what does not hold that keeps the summary on one page
        middle = _weak_blocks(weak, detail)
        if words(Document([*head.blocks, *middle, *tail.blocks]).markdown()) <= SUMMARY_WORDS:
            break
    d.h(2, "Summary")
    d.extend([*head.blocks, *middle, *tail.blocks])


def _short(text: str, n: int = 120) -> str:
    """``text`` cut at a word boundary to at most ``n`` characters (``…`` where cut)."""
    text = str(text)
    return text if len(text) <= n else text[:n].rsplit(" ", 1)[0].rstrip(",;:") + " …"


def _glossary(d: Document, text) -> None:
    items = [i for kind, *args in text("glossary.md") if kind == "ul" for i in args[0]]
    if not items:
        return
    d.h(2, "Glossary")
    rows = []
    for item in items:
        m = re.match(r"\*\*(.+?)\*\*[:\s—–-]+(.*)", item)
        rows.append([m.group(1), m.group(2)] if m else ["", item])
    d.table(["term", "meaning"], rows)


def _claims_table(d: Document, inputs: ReportInputs, settings: ReportSettings, all_ds, base: Path, source: str):
    claims, rows = load_claims(), []
    for cid, c in inputs.main.verdicts.items():
        if cid not in claims or c.source != source:
            continue
        claim = claims[cid]
        links = ", ".join(_nb_link(inputs.results_dir / r, base, claim.notebook or r if len(claim.runs) == 1 else r,
                                   settings.notebooks) for r in claim.runs)  # one notebook per run it is judged on
        rows.append([f"`{cid}`", claim.where, f"“{_short(claim.quote, 70)}”"]
                    + [_verdict_text(ds.verdicts[cid]) if cid in ds.verdicts else "not measured here" for ds in all_ds]
                    + [links])
    d.table(["claim", "where", "the paper's words"] + [ds.name for ds in all_ds] + ["notebook"], rows)
    return len(rows)


def _claims_section(d: Document, inputs: ReportInputs, settings: ReportSettings, text, all_ds, base: Path) -> None:
    d.h(2, "Claims of the paper, judged on each dataset")
    d.extend(text("claims.md"))
    _claims_table(d, inputs, settings, all_ds, base, "paper")
    if any(c.source == "package" for c in inputs.main.verdicts.values()):
        d.h(2, "Beyond the paper: this package's own claims")
        d.extend(text("beyond_the_paper.md"))
        _claims_table(d, inputs, settings, all_ds, base, "package")


def _counted(t) -> str:
    """A table's cells within ±0.02 · within draw noise, of the cells compared."""
    if not t.compared or t.within is None:
        return "—"
    noise = "—" if t.in_noise is None else str(t.within + t.in_noise)
    return f"{t.within} · {noise} of {t.compared}"


def _tables_section(d: Document, inputs: ReportInputs, text, all_ds) -> None:
    d.h(2, "Tables 1–6 beside the published values")
    d.extend(text("tables.md"))
    tables = sorted({t.table for ds in all_ds for t in ds.tables}, key=int)
    by = {(ds.dataset, t.table): t for ds in all_ds for t in ds.tables}
    n_pub = {t: sum(1 for r in inputs.published if r["table"] == t) for t in tables}
    d.table(["table", "published cells"] + [ds.name for ds in all_ds],
            [[f"Table {t}", str(n_pub[t])] + [_counted(by[(ds.dataset, t)]) if (ds.dataset, t) in by else "—"
                                              for ds in all_ds] for t in tables])


def _forking_section(d: Document, text, all_ds) -> None:
    paths = forking_paths(all_ds)
    table_claims = [cid for cid, c in load_claims().items() if c.where.startswith("Table")]
    verdicts = reading_verdict_blocks(all_ds, {ds.dataset: ds.name for ds in all_ds}, table_claims)
    d.h(2, "Forking paths: readings chosen on one dataset, checked on the others")
    d.extend(text("forking_paths.md"))
    d.extend(forking_blocks(paths, {ds.dataset: ds.name for ds in all_ds}, [ds.dataset for ds in all_ds]))
    if verdicts and verdicts[0][0] == "table":
        d.p("The table claims whose verdict changes under another reading the ledger judged (per dataset: the "
            "verdict as chosen, then each reading that changes it):")
    d.extend(verdicts)


# ------------------------------------------------------------------------------ appendices
def _caption_text(entry: dict | None, reproduces: str) -> str:
    """A run's caption: what the paper's figure shows (a study: its question), what to look at, what ours shows."""
    if entry is None:
        return f"**Caption missing**: add an entry to `report_text/{CAPTIONS}`."
    parts = []
    figure = re.match(r"(Figures? [\d, and]*\d|Tables? [\d, and]*\d)", reproduces or "")
    if entry.get("paper"):
        parts.append((f"**The paper's {figure.group(1)}:**" if figure else "**The question:**") + f" {entry['paper']}")
    if entry.get("look"):
        parts.append(f"**Look at:** {entry['look']}")
    if entry.get("ours"):
        parts.append(f"**Ours:** {entry['ours']}")
    return " ".join(parts)


def _arrange(panels: dict, layout) -> list:
    """Rows of ``[dataset, image]`` panels: the caption's ``layout`` (rows of datasets), the rest in a last row."""
    rows, placed = [], set()
    for row in layout or []:
        r = [ds for ds in row if ds in panels]
        placed.update(r)
        if r:
            rows.append(r)
    rest = [ds for ds in panels if ds not in placed]
    if rest:
        rows.append(rest)
    return rows


def _gallery(d: Document, all_ds, captions: dict, base: Path, level: int = 3) -> None:
    runs: dict = {}
    for ds in all_ds:
        for f in ds.figures:
            runs.setdefault(f.run, {"reproduces": f.reproduces, "by": {}})["by"][ds.dataset] = f.images
    names = {ds.dataset: ds.name for ds in all_ds}
    for run, x in runs.items():
        d.h(level, f"{x['reproduces'] or 'Figure'} (`{run}`)")
        d.p(_caption_text(captions.get(run), x["reproduces"]))
        stems = list(dict.fromkeys(Path(p).stem for imgs in x["by"].values() for p in imgs))
        for stem in stems:
            panels = {ds: next(p for p in imgs if Path(p).stem == stem) for ds, imgs in x["by"].items()
                      if any(Path(p).stem == stem for p in imgs)}
            rows = _arrange(panels, (captions.get(run) or {}).get("layout"))
            several = len(x["by"]) > 1
            d.figure([[[_rel(panels[ds], base), names[ds] if several else stem] for ds in r] for r in rows],
                     f"`{stem}`" if several and len(stems) > 1 else "")


def _demoted(blocks, top: int) -> list:
    """``blocks`` with their headings shifted so that the highest is at ``top``."""
    levels = [b[1] for b in blocks if b[0] == "h"]
    shift = top - min(levels) if levels else 0
    return [("h", b[1] + shift, b[2]) if b[0] == "h" else b for b in blocks]


def _studies_appendix(d: Document, inputs: ReportInputs, all_ds, captions: dict, base: Path) -> None:
    in_dataset = {(r, ds.dataset) for ds in inputs.datasets for r in ds.runs}
    studies = [(ds, s) for ds in all_ds for s in ds.studies
               if ds is not inputs.main or (s.run, s.dataset) not in in_dataset]
    if not studies:
        return
    d.h(2, "Appendix B: studies")
    d.extend(text_blocks("Each study runs one question the paper leaves open on the named dataset; its tables are "
                         "computed from its run's results."))
    names = {ds.dataset: ds.name for ds in all_ds}
    order = list(dict.fromkeys(s.run for _, s in studies))
    for run in order:
        first = True
        for _, s in [(ds, s) for ds, s in studies if s.run == run]:
            d.extend(_demoted(s.blocks, 3))
            if first:
                d.p(_caption_text(captions.get(run), "study"))
                first = False
            for p in s.images:
                d.figure([[[_rel(p, base), f"{Path(p).stem} on {names.get(s.dataset, s.dataset)}"]]], "")


def _cell_rows(cells, multi: bool) -> list:
    """Every published cell with ours: value, SE, difference as printed, and what they count as."""
    rows = []
    for c in cells:
        v, se, p = c["value"], c["se"], c["published"]
        if v is None:
            ours = ["—", "—", "", "", ""]
        else:
            diff = v - p
            noise = "—" if se is None else ("yes" if within_draw_noise(diff, se) else "no")
            ours = [printed(v), "—" if se is None else printed(se), printed(diff, signed=True),
                    "yes" if within_published(diff) else "no", noise]
        rows.append(([c["k_M"], c["k_N"]] if multi else []) + [c["function"], c["stage"], c["method"], f"{p:.2f}"]
                    + ours + [c["run"] or ""])
    return rows


def _dataset_appendix(d: Document, ds, label: str, inputs: ReportInputs, base: Path) -> None:
    claims = load_claims()
    d.h(2, f"Appendix {label}: {ds.name}")
    kept = ds in inputs.kept
    d.p(f"Results `{ds.folder}`, code at commit `{ds.commit}`"
        + (" (kept from that publication: not rerun for this report)" if kept else "") + ". Runs: "
        + ", ".join(f"`{r}`" for r in ds.runs) + "."
        + (f" {len(ds.shapes)} shapes and {len(ds.pairs)} ordered (source, target) pairs: "
           + ", ".join(f"{a}→{b}" for a, b in ds.pairs) + "." if ds.pairs else ""))
    d.h(3, f"Claims on {ds.name}")
    rows = []
    for cid, c in ds.verdicts.items():
        if cid not in claims:
            continue
        rows.append([f"`{cid}`", _verdict_text(c) + (" (single case)" if c.single_case else ""), c.rule, c.default,
                     "; ".join(f"{k}: {v}" for k, v in c.subsets.items()) or "—", _other_readings(c) or "—",
                     _comparisons_text(c), _margin_text(c),
                     "; ".join(f"{k}: {r}" for k, r in c.excluded.items()) or "—", c.evidence or ""])
    d.table(APPENDIX_CLAIMS, rows)
    if ds.tables:
        d.h(3, f"Tables on {ds.name}")

        def beats(b):
            return " · ".join("—" if x is None else f"{x[0]}/{x[1]}" for x in b)

        d.table(["table", "cells compared", f"within ±{CRITERIA['within']:g}", "missed, within draw noise",
                 "mean |diff|", "largest |diff|", "products beat std: paper B (all · intra · inter)", "gain rule",
                 "default"],
                [[f"Table {t.table}", f"{t.compared} of {t.published}", "—" if t.within is None else f"{t.within}",
                  "—" if t.in_noise is None else f"{t.in_noise} of {t.missed}",
                  "—" if t.mean_diff is None else f"{t.mean_diff:.3f}",
                  "—" if t.largest_diff is None else f"{t.largest_diff:.3f}", *map(beats, t.beats.values())]
                 for t in ds.tables])
    if ds.cells is None:
        d.p(f"The cells of {ds.name}'s tables were not stored by the publication at commit `{ds.commit}`; rerun "
            f"`prodmaps reproduce --dataset {ds.dataset}` and publish to list them here.")
        return
    for t in sorted({c["table"] for c in ds.cells}, key=int):
        cells = [c for c in ds.cells if c["table"] == t]
        sizes = list(dict.fromkeys((c["fmap"], c["k_M"], c["k_N"]) for c in cells))
        d.h(4, f"Table {t} on {ds.name}: " + "; ".join(f"{f}, k_M = {a}, k_N = {b}" for f, a, b in sizes))
        multi = len(sizes) > 1
        d.table((["k_M", "k_N"] if multi else []) + ["function", "stage", "method", "published", "ours", "SE",
                                                     "difference", f"within ±{CRITERIA['within']:g}",
                                                     "within draw noise", "run"], _cell_rows(cells, multi))


def _runs_appendix(d: Document, inputs: ReportInputs, settings: ReportSettings, all_ds, base: Path) -> None:
    infos, notebooks = inputs.runs, settings.notebooks
    d.h(2, "Appendix D: runs")
    read = "notebook" if notebooks is not None else "executed notebook"
    names = list(dict.fromkeys([i.name for i in infos] + [r for ds in all_ds for r in ds.run_times]))
    by = {i.name: i for i in infos}

    def time(ds, run):
        st, sec = ds.run_times.get(run, (None, None))
        if st is None:
            return "—"
        return (f"{sec:.1f}" if sec is not None else "ok") if st == "ok" else st

    d.table(["run", "reproduces"] + [f"{ds.name} (s)" for ds in all_ds] + ["read"],
            [[f"`{r}`", by[r].reproduces if r in by else ""] + [time(ds, r) for ds in all_ds]
             + [_nb_link(by[r].folder, base, read, notebooks) if r in by else ""] for r in names])
    failed = [i for i in infos if i.status != "ok"]
    if failed:
        d.p("**Failed or not run** on the embedded humans: " + ", ".join(f"`{i.name}`" for i in failed)
            + ". A failed run keeps `error.txt` and `executed.ipynb` in its folder.")
    for i in failed:
        if i.status == "failed" and (i.folder / "error.txt").is_file():
            excerpt = "\n".join((i.folder / "error.txt").read_text().splitlines()[:15])
            d.p(f"`{i.name}`, the first lines of its error:")
            d.code(excerpt if settings.machine_paths else _without_machine_paths(excerpt, settings.registry))
    d.p("Environment: " + ", ".join(f"{p} {v}" for p, v in package_versions(_PACKAGES).items()) + ".")
    if inputs.unmatched:
        d.h(3, "Table values that match no published number")
        d.table(["run", "entry", "reason"],
                [[e.get("run", "") if isinstance(e, dict) else "",
                  "`" + json.dumps({k: v for k, v in e.items() if k != "run"} if isinstance(e, dict) else e) + "`",
                  why] for e, why in inputs.unmatched])


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
                  data="; ".join(_scope(folder, ds) for ds in all_ds))

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
    _summary(d, inputs, text, all_ds)
    _glossary(d, text)
    _claims_section(d, inputs, settings, text, all_ds, base)
    if inputs.published:
        _tables_section(d, inputs, text, all_ds)
    _forking_section(d, text, all_ds)
    differences = text("systematic_differences.md")
    if differences:
        d.h(2, "What differs from the paper, and why")
        d.extend(differences)
    if any(ds.figures for ds in all_ds):
        d.h(2, "Appendix A: figure gallery")
        d.extend(text("gallery.md"))
        _gallery(d, all_ds, captions, base)
    _studies_appendix(d, inputs, all_ds, captions, base)
    for n, ds in enumerate(all_ds, 1):
        _dataset_appendix(d, ds, f"C{n}", inputs, base)
    _runs_appendix(d, inputs, settings, all_ds, base)
    d = _without_repeats(d)
    _contents(d)
    return d


def _scope(folder, ds) -> str:
    """How the summary names a dataset: its ``scope`` in ``report_text/datasets.toml``, else its name."""
    entry = _read_toml(folder, "datasets.toml").get(ds.dataset, {})
    return entry.get("scope", ds.name)


def _read_toml(folder, name: str) -> dict:
    path = Path(folder) / name if folder is not None else None
    return parse_toml(path.read_text(encoding="utf-8")) if path is not None and path.is_file() else {}


def report_captions(folder) -> dict:
    """``{run: {"paper", "look", "ours", "layout"}}`` of ``folder/captions.toml`` (``{}`` without the file).

    ``paper``: what the paper's figure shows; ``look``: what to look at; ``ours``: what our panel
    shows; ``layout`` (optional): rows of datasets, the panels' arrangement in the gallery
    (e.g. ``[["faust_r", "tosca_r"]]``: FAUST_r left, TOSCA_r right, as the paper's FAUST and
    centaur). Raises ``ValueError`` for an entry with other keys or without text.
    """
    doc = _read_toml(folder, CAPTIONS)
    for run, entry in doc.items():
        bad = set(entry) - {"paper", "look", "ours", "layout"} if isinstance(entry, dict) else {"(not a table)"}
        if bad or not any(entry.get(k) for k in ("paper", "look", "ours")):
            raise ValueError(f"{Path(folder) / CAPTIONS}: [{run}] needs text under paper, look, ours "
                             f"(and optionally layout); unknown keys {sorted(bad)}")
    return doc


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
