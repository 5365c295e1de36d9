"""Building, part 1: the report's data, read from results folders; nothing here renders.

The unit is **one dataset's report data**, a :class:`DatasetReport`: its verdict column (one
:class:`ClaimResult` per claim of the ledger), its table summaries (:class:`TableSummary`, our
values beside the published ones), the figures it shows (:class:`Figure`) and the sections of its
studies (:class:`Study`, blocks of :mod:`.document`). It is either

* built from a results folder by :func:`dataset_report` (``OUT/<profile>`` for the embedded
  humans, ``OUT/<profile>-<dataset>`` for a prepared dataset, :func:`other_datasets`), or
* loaded from the JSON a publication stored beside the committed report
  (:meth:`DatasetReport.load`: ``paper/report_data/<dataset>.json``), for a dataset that was not
  rerun; :meth:`DatasetReport.save` writes it, image paths relative to the report's folder.

Each dataset contributes a verdict column, an appendix of every table cell (:func:`table_cells`)
and its panels of the figure gallery the same way, whichever of the two it came from; a stored
file of an older format is migrated on load. :func:`collect_runs` reads the run folders
themselves (status, time, figures). :func:`reading_scores` reads what the studies scored for each
reading the paper leaves open (the report's forking paths, :mod:`.forking`).

The experiments modules the report needs (the claims ledger, the comparison rules, the published
tables) are imported here, in one block, and nowhere else in the report's modules: the names the
other modules use are re-exported below (:data:`VERDICTS`, :data:`TABLE_KEYS`, :data:`CRITERIA`,
:data:`LEDGER_FILE`, :func:`load_claims`, :func:`load_published_rows`, :func:`match_published`).
"""

from __future__ import annotations

import importlib
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

from .. import datasets
from ..experiments.shared import claims as ledger  # the one import block of the experiments layer (see the module doc)
from ..experiments.shared import compare
from ..experiments.shared import published as pub
from ..files import atomic_path, read_json
from .execute import DEFAULT_DATASET
from .registry import load_registry

__all__ = ["DATASET_NAMES", "DATA_FOLDER", "VERDICTS", "SOURCES", "TABLE_KEYS", "CRITERIA", "LEDGER_FILE",
           "BEAT_METHODS", "RunInfo", "collect_runs", "table_entries", "run_dataset", "overridden_parameters",
           "other_datasets", "ClaimResult", "claim_results", "verdict_counts", "TableSummary", "table_summaries",
           "table_cells", "reading_scores", "REJECTED_NORMALIZATION", "Figure", "Study", "DatasetReport",
           "dataset_report", "migrate",
           "load_claims", "load_published_rows", "match_published", "within_published", "within_draw_noise",
           "printed"]

DATASET_NAMES = {"anny_humans": "embedded humans", "faust": "FAUST", "tosca": "TOSCA", "faust_r": "FAUST_r",
                 "tosca_r": "TOSCA_r", "tosca_r_noniso": "TOSCA_r non-isometric"}  # as the report names them
DATA_FOLDER = "report_data"  # beside the committed report: report_data/<dataset>.json
_FORMAT = 2  # of the stored JSON (1: before the table cells, run times and reading scores were stored)

VERDICTS = ledger.VERDICTS
SOURCES = ledger.SOURCES  # "paper" (the totals) and "package" ("Beyond the paper")
TABLE_KEYS = pub.TABLE_KEYS
BEAT_METHODS = ("our_B", "our_B_gainrule", "our_default")  # the paper's B, the gain rule, the default
# the numbers the report's text states (placeholders of paper/report_text)
CRITERIA = {"within": pub.WITHIN, "draw_z": pub.DRAW_Z, "rounding_rel": compare.ROUNDING_REL,
            "tie_rel": compare.TIE_REL, "printed_decimals": pub.PRINTED_DECIMALS, "span_tol": ledger.SPAN_TOL}
LEDGER_FILE = Path(ledger.LEDGER).resolve().relative_to(Path(__file__).resolve().parents[2]).as_posix()  # as shown
load_claims = ledger.load_ledger
match_published = pub.match_entries
within_published = pub.within_published
within_draw_noise = pub.within_draw_noise
printed = pub.printed  # a number as the report prints it (the printed difference decides within ±0.02)


def load_published_rows(path=None) -> list[dict]:
    """The published table values (default: the package's CSV); ``[]`` when the file does not exist."""
    path = Path(path) if path is not None else pub.PUBLISHED_CSV
    return pub.load_published(path) if path.is_file() else []


# ------------------------------------------------------------------------------ run folders
@dataclass
class RunInfo:
    """One run folder of a results folder: its registry entry, status, time, results and figures."""

    name: str
    folder: Path
    reproduces: str = ""
    title: str = ""
    status: str = "missing"
    seconds: float | None = None
    doc: dict = field(default_factory=dict)
    manifest: dict = field(default_factory=dict)
    figures: list = field(default_factory=list)
    report: str = ""  # the module owning the run's report section (registry key `report`)
    dataset_figures: bool = False  # its figures in every dataset's section (registry key `dataset_figures`)
    datasets: tuple = ()  # the datasets with values of their own in the registry (`[runs.<run>.datasets.<dataset>]`)


def collect_runs(results_dir, registry=None) -> list[RunInfo]:
    """Registered runs (registry order) plus any other run folders found in ``results_dir``."""
    results_dir = Path(results_dir)
    try:
        runs = load_registry(registry)
    except Exception:
        runs = {}
    names = list(runs)
    if results_dir.is_dir():
        names += sorted(p.name for p in results_dir.iterdir()
                        if p.is_dir() and not p.name.startswith(".") and p.name not in runs
                        and ((p / "results.json").is_file() or (p / "manifest.json").is_file()))
    infos = []
    for n in names:
        folder = results_dir / n
        info = RunInfo(n, folder)
        if n in runs:
            info.reproduces, info.title = runs[n].reproduces, runs[n].title
            info.report, info.dataset_figures = runs[n].report, runs[n].dataset_figures
            info.datasets = tuple(runs[n].datasets)
        info.doc = read_json(folder / "results.json", {})
        info.manifest = read_json(folder / "manifest.json", {})
        if info.manifest:
            info.status = info.manifest.get("status", "?")
            info.seconds = info.manifest.get("seconds")
        elif info.doc:
            info.status = "ok"
        info.figures = sorted(folder.glob("*.png"))
        infos.append(info)
    return infos


def table_entries(info: RunInfo) -> list:
    """The run's table values (``results.table`` or a top-level ``table``), each tagged with the run."""
    res = info.doc.get("results", {})
    tab = res.get("table") if isinstance(res, dict) else None
    tab = tab if tab is not None else info.doc.get("table")
    if not isinstance(tab, list):
        return []
    return [dict(e, run=info.name) if isinstance(e, dict) else e for e in tab]


def run_dataset(info: RunInfo) -> str:
    """The dataset a run's results were computed on (``anny_humans`` when they do not say)."""
    res = info.doc.get("results", {}) if info.doc else {}
    return res.get("dataset", DEFAULT_DATASET) if isinstance(res, dict) else DEFAULT_DATASET


def overridden_parameters(infos) -> dict:
    """``{run: {name: value}}``: parameters given on the command line (``-p``), from the manifests."""
    return {i.name: dict(i.manifest["overrides"]) for i in infos
            if isinstance(i.manifest.get("overrides"), dict) and i.manifest["overrides"]}


def other_datasets(results_dir) -> dict:
    """``{dataset: folder}`` of the sibling folders ``<results_dir>-<dataset>`` (e.g. ``results/paper-faust``)."""
    results_dir = Path(results_dir).resolve()
    return {ds: results_dir.with_name(f"{results_dir.name}-{ds}") for ds in datasets.names()
            if results_dir.with_name(f"{results_dir.name}-{ds}").is_dir()}


# ------------------------------------------------------------------------------ verdicts
@dataclass
class ClaimResult:
    """One claim judged on one dataset: its verdict and what the report shows beside it.

    ``verdict``: the paper's setting's (one of :data:`VERDICTS`). ``paper``, ``rule``, ``default``:
    the outcome at the paper's settings, with the threshold rule and with the default transfer
    (``"yes"``, ``"no"``, ``"inconclusive"``, ``"—"`` not measured; None: not recorded); the last
    two are the package's, never part of the verdict. ``readings``: the verdict under each other
    family reading (``{"textbook": ...}``); ``subsets``: per pair kind (``{"intra": ..., "inter": ...}``).
    ``source``: ``"paper"`` or ``"package"``; ``kind``: ``"measured"``, ``"not empirical"`` or
    ``"not reproducible"``; ``margin`` and ``why``: the claim's practical margin and its reason;
    ``single_case``: the verdict rests on one pair or function; ``excluded``: ``{unit: reason}``
    of the ties by construction left out; ``sensitivity``: ``{margin: verdict}``; ``comparisons``:
    the paired comparisons (``label``, ``n``, ``ours``, ``ref``, ``mean_diff``, ``se``, ``rel``,
    ``outcome``).
    """

    verdict: str
    readings: dict = field(default_factory=dict)
    paper: str | None = "—"
    rule: str | None = "—"
    default: str | None = "—"
    subsets: dict = field(default_factory=dict)
    evidence: str | None = ""
    source: str = "paper"
    kind: str = "measured"
    margin: float | None = None
    why: str = ""
    single_case: bool = False
    excluded: dict = field(default_factory=dict)
    sensitivity: dict = field(default_factory=dict)
    comparisons: list = field(default_factory=list)


def claim_results(verdicts) -> dict[str, ClaimResult]:
    """``{claim id: ClaimResult}`` in ledger order, from the ledger's verdicts (subset ``all``, else the first)."""
    by_claim: dict = {}
    for v in verdicts:
        by_claim.setdefault(v.claim.id, {})[v.subset] = v
    out = {}
    for cid, subs in by_claim.items():
        v = subs.get("all", next(iter(subs.values())))
        out[cid] = ClaimResult(v.verdict, ledger.reading_verdicts(v), *(ledger.setting_mark(v, s) for s in
                                                                        ("paper", "rule", "default")),
                               {k: subs[k].verdict for k in ("intra", "inter") if k in subs}, v.evidence,
                               v.claim.source, v.claim.kind, v.claim.practical_margin, v.claim.why, v.single_case,
                               v.excluded, dict(v.paper.get("sensitivity", {})), v.comparisons)
    return out


def verdict_counts(verdicts: dict) -> dict:
    """``{source: {verdict: n}}`` of ``{claim id: ClaimResult}`` (the ledger's :func:`verdict_counts`).

    Claims the ledger no longer has (a stored report's) count under their recorded source.
    """
    out = {s: dict.fromkeys(VERDICTS, 0) for s in ledger.SOURCES}
    for c in verdicts.values():
        out[c.source][c.verdict] = out[c.source].get(c.verdict, 0) + 1
    return out


# ------------------------------------------------------------------------------ tables
@dataclass
class TableSummary:
    """One published table against our values of its cells.

    ``within``: cells within ±``CRITERIA["within"]`` of the published value; ``missed``: the others;
    ``in_noise``: of those, the ones within draw noise (None when a value has no standard error);
    ``beats``: per method of :data:`BEAT_METHODS`, ``[wins, families]`` of the product transfer
    against ``std`` over all, intra- and inter-subject pairs (None where not measured), the ties by
    construction left out of both (``ties``: ``"<size> <family>"`` of the families in the span of the
    source basis, where every extended transfer equals the standard one up to its truncation).
    """

    table: str
    compared: int
    published: int
    within: int | None = None
    missed: int | None = None
    in_noise: int | None = None
    mean_diff: float | None = None
    largest_diff: float | None = None
    beats: dict = field(default_factory=dict)
    ties: list = field(default_factory=list)


def _span_ties(errors: dict) -> list:
    """``"<size> <family>"`` of the families in the span of the source basis (ties by construction)."""
    return [f"{z} {f}" for z, size in errors.items() for f in ledger.span_ties(size.get("approx", {}).get("std", {}))]


def _beats(errors: dict, method: str) -> list | None:
    """``[wins, families]``: where ``method`` transfers better than ``std``, over the sizes of ``errors``.

    Families in the span of the source basis (:func:`_span_ties`) count neither way.
    """
    ties = set(_span_ties(errors))
    cells = [(tr[method][f], tr["std"][f]) for z, size in errors.items() for tr in [size.get("transfer", {})]
             if method in tr and "std" in tr for f in tr["std"] if f"{z} {f}" not in ties]
    return [sum(compare.lower(o, s) for o, s in cells), len(cells)] if cells else None


def table_summaries(infos, published_rows, matches, *, only_run: bool = False) -> list[TableSummary]:
    """One :class:`TableSummary` per published table (``only_run``: only tables whose run has results)."""
    out = []
    for t in sorted({r["table"] for r in published_rows}, key=int):
        info = next((i for i in infos if i.reproduces == f"Table {t}"), None)
        if only_run and not (info and info.doc):
            continue
        got = [(r, e) for r, e in matches if r["table"] == t]
        diffs = [abs(e["value"] - r["value"]) for r, e in got]
        missed = [(e["value"] - r["value"], e.get("se")) for r, e in got
                  if not pub.within_published(e["value"] - r["value"])]
        res = info.doc.get("results", {}) if info else {}
        s = TableSummary(t, len(got), sum(1 for r in published_rows if r["table"] == t),
                         beats={m: [_beats(res.get(f"errors{sub}", {}), m) for sub in ("", "_intra", "_inter")]
                                for m in BEAT_METHODS}, ties=_span_ties(res.get("errors", {})))
        if diffs:
            s.within, s.missed = sum(map(pub.within_published, diffs)), len(missed)
            s.mean_diff, s.largest_diff = sum(diffs) / len(diffs), max(diffs)
            if all(se is not None for _, se in missed):
                s.in_noise = sum(pub.within_draw_noise(dv, se) for dv, se in missed)
        out.append(s)
    return out


def table_cells(published_rows, matches, tables=None) -> list[dict]:
    """Every published cell beside ours, in the CSV's order (``tables``: only these tables, e.g. ``{"1", "3"}``).

    Each cell is ``{table, fmap, k_M, k_N, function, stage, method, published, value, se, run}``:
    ``value`` (ours), ``se`` (its standard error) and ``run`` are None / ``""`` where we have no value.
    """
    by_key = {tuple(r[k] for k in TABLE_KEYS): e for r, e in matches}
    out = []
    for r in published_rows:
        if tables is not None and r["table"] not in tables:
            continue
        e = by_key.get(tuple(r[k] for k in TABLE_KEYS)) or {}
        out.append({**{k: r[k] for k in TABLE_KEYS}, "published": r["value"], "value": e.get("value"),
                    "se": e.get("se"), "run": e.get("run", "")})
    return out


# ------------------------------------------------------------------------------ readings (forking paths)
# the runs whose module has reading_summary(results): the frozen reading scored on the run's data
_READING_RUNS = {"study_family_readings": "prodmaps.experiments.study_family_readings",
                 "study_normalization": "prodmaps.experiments.study_normalization",
                 "study_no17": "prodmaps.experiments.study_no17", "fig12_13": "prodmaps.experiments.fig12_13_p2p"}
_TABLES_MODULE = "prodmaps.experiments.tables_transfer"  # held_out_rows({"T1": results, ...})
FRAME_DEPENDENT = ("XYZ",)  # table functions whose values depend on the shapes' coordinate frame
REJECTED_NORMALIZATION = "metres"  # the normalisation the library used before (a table claim's verdict under it)


def _row(r: dict) -> dict:
    """A reading row of the experiments (``reading_summary``, ``held_out_rows``) in the report's fields."""
    out = {"label": r["reading"], "alternatives": r.get("alternatives"), "cells": r.get("cells") or "",
           "frozen": r.get("frozen") or "", "choice": r.get("choice_here") or "", "n": r.get("cells_n"),
           "within": r.get("within"), "in_noise": r.get("within_noise")}
    return out | ({"frozen_error": r["frozen_error"]} if r.get("frozen_error") is not None else {})


def _tables_row(r: dict, tables_module) -> dict:
    """A row of ``held_out_rows``: the published cells that judge it named, the normalisation by its study's name."""
    row = _row(r)
    cells = dict(tables_module.READING_CELLS, **{"Approach B's normalisation": tables_module.READING_CELLS.get(
        "normalisation", ("our_B", ()))})
    method, tables = ("std", tables_module.GT_TABLES) if row["label"].endswith(" parameters") else cells.get(
        row["label"], (None, ()))
    if method:
        row["cells"] = f"published {'Approach B' if method == 'our_B' else method} cells ({', '.join(tables)})"
    if row["label"] == "Approach B's normalisation":
        row["frozen"] = getattr(importlib.import_module(_READING_RUNS["study_normalization"]), "LIBRARY_READING",
                                row["frozen"])
    return row


def reading_scores(infos) -> dict:
    """What the runs of ``infos`` scored for each open reading: this dataset's forking-path rows.

    ``{reading: {"label", "alternatives", "cells", "frozen", "choice", "n", "within", "in_noise"}}``
    (and ``frozen_error`` for a reading no published cell judges): the reading the library uses
    (``frozen``, chosen on FAUST's eight registrations), how many readings were scored on which
    published cells, the reading these results would choose (``choice``), and the frozen
    reading's cells here: ``n``, within ±0.02, within draw noise (None without standard errors).
    The counts come from the tables' runs (``tables_transfer.held_out_rows``: the tables' own
    pairs, with standard errors), else from the studies; the studies (``reading_summary`` of
    ``study_family_readings``, ``study_normalization``, ``study_no17``, ``fig12_13``) add what
    was scored and the choice. A run's ``results["forking_paths"]`` (rows of these fields, keyed
    by reading) is taken as it is, over both.
    """
    docs = {i.name: i.doc.get("results") for i in infos if i.doc and isinstance(i.doc.get("results"), dict)}
    tables = {r["table_name"]: r for r in docs.values()
              if isinstance(r.get("table_name"), str) and isinstance(r.get("table"), list) and "fmap" in r}
    out: dict = {}
    if tables:
        module = importlib.import_module(_TABLES_MODULE)
        out = {r["reading"]: _tables_row(r, module) for r in module.held_out_rows(tables)}
    for run, module in _READING_RUNS.items():
        if run not in docs:
            continue
        for r in importlib.import_module(module).reading_summary(docs[run]):
            row = _row(r)
            if r["reading"] in out:  # the tables' cells and counts (with SE) stay; the study: what it scored, chose
                row = out[r["reading"]] | {k: row[k] for k in ("alternatives", "frozen", "choice")} | {
                    k: v for k, v in row.items() if k == "frozen_error"}
            out[r["reading"]] = row
    for res in docs.values():
        if isinstance(res.get("forking_paths"), dict):
            out.update({k: dict(v) for k, v in res["forking_paths"].items()})
    return out


def _normalization_readings(infos, verdicts: dict) -> None:
    """Add each table claim's verdict under :data:`REJECTED_NORMALIZATION` to ``verdicts[claim].readings``.

    From ``study_normalization``'s ``claim_verdicts`` (the ledger's table claims judged on the
    study's values under each reading); the study's own verdict under the chosen reading is added
    too where it differs from the claim's (the study's pairs are not the tables').
    """
    res = next((i.doc.get("results") for i in infos if i.name == "study_normalization" and i.doc), None)
    by_reading = (res or {}).get("claim_verdicts") or {}
    chosen = (res or {}).get("chosen_reading")
    for cid, v in by_reading.get(REJECTED_NORMALIZATION, {}).items():
        if cid in verdicts and v != "not measured here":
            verdicts[cid].readings[f"{REJECTED_NORMALIZATION} normalisation"] = v
            mine = by_reading.get(chosen, {}).get(cid)
            if mine not in (None, "not measured here", verdicts[cid].verdict):
                verdicts[cid].readings["chosen reading, study's pairs"] = mine


# ------------------------------------------------------------------------------ one dataset
@dataclass
class Figure:
    """The figures of a run shown in a dataset's section (registry ``dataset_figures``)."""

    run: str
    reproduces: str
    images: list  # Paths


@dataclass
class Study:
    """A study's section: the blocks of its run's ``report_blocks`` and the run's figures."""

    run: str
    dataset: str  # the dataset its results were computed on
    blocks: list
    images: list  # Paths


@dataclass
class DatasetReport:
    """One dataset's part of the report (see the module doc). ``folder``: the results folder as shown."""

    dataset: str
    folder: str
    commit: str
    runs: list = field(default_factory=list)  # the runs with results
    shapes: list = field(default_factory=list)
    pairs: list = field(default_factory=list)  # ordered [source, target] pairs of its tables
    verdicts: dict = field(default_factory=dict)  # {claim id: ClaimResult}
    tables: list = field(default_factory=list)  # [TableSummary]
    figures: list = field(default_factory=list)  # [Figure]
    studies: list = field(default_factory=list)  # [Study]
    cells: list | None = None  # table_cells of its tables (None: not stored, a format-1 file)
    run_times: dict = field(default_factory=dict)  # {run: [status, seconds or None]}
    readings: dict = field(default_factory=dict)  # reading_scores: {reading: {...}}

    @property
    def name(self) -> str:
        """The dataset as the report names it (``FAUST``, ``embedded humans``)."""
        return DATASET_NAMES.get(self.dataset, self.dataset)

    def counts(self) -> dict:
        """``{verdict: number of claims}`` over :data:`VERDICTS`, the paper's and the package's together."""
        return {k: sum(1 for c in self.verdicts.values() if c.verdict == k) for k in VERDICTS}

    def counts_by_source(self) -> dict:
        """``{"paper": {verdict: n}, "package": {verdict: n}}``: the report's totals (:func:`verdict_counts`)."""
        return verdict_counts(self.verdicts)

    def images(self) -> list:
        """Every image the dataset's section shows."""
        return [p for x in (*self.figures, *self.studies) for p in x.images]

    def path(self, report_folder) -> Path:
        """Where :meth:`save` writes it: ``<report folder>/report_data/<dataset>.json``."""
        return Path(report_folder) / DATA_FOLDER / f"{self.dataset}.json"

    def save(self, report_folder) -> Path:
        """Write it as JSON beside the report; its images must lie in ``report_folder`` (copied there)."""
        folder = Path(report_folder).resolve()

        def rel(p):
            try:
                return Path(p).resolve().relative_to(folder).as_posix()
            except ValueError:
                raise ValueError(f"image {p} is not in the report's folder {folder}: copy the figures first "
                                 "(report settings copy_figures=True)") from None

        doc = {"format": _FORMAT, **asdict(self)}
        for kind in ("figures", "studies"):
            for x in doc[kind]:
                x["images"] = [rel(p) for p in x["images"]]
        path = self.path(folder)
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
        return path

    @classmethod
    def load(cls, report_folder, dataset: str) -> DatasetReport | None:
        """The dataset's data stored beside the report by :meth:`save`, or None when there is none."""
        folder = Path(report_folder).resolve()
        path = folder / DATA_FOLDER / f"{dataset}.json"
        if not path.is_file():
            return None
        doc = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(doc, dict) or doc.get("dataset") != dataset or doc.get("format") not in (1, _FORMAT):
            raise ValueError(f"{path}: not the report data of {dataset!r} (format {_FORMAT}); delete it and "
                             f"publish a run of {dataset} (prodmaps reproduce --dataset {dataset}, make publish)")
        doc = migrate(doc)
        return cls(doc["dataset"], doc["folder"], doc["commit"], doc["runs"], doc["shapes"], doc["pairs"],
                   {c: ClaimResult(**v) for c, v in doc["verdicts"].items()},
                   [TableSummary(**t) for t in doc["tables"]],
                   [Figure(f["run"], f["reproduces"], [folder / p for p in f["images"]]) for f in doc["figures"]],
                   [Study(s["run"], s["dataset"], [tuple(b) for b in s["blocks"]], [folder / p for p in s["images"]])
                    for s in doc["studies"]], doc["cells"], doc["run_times"], doc["readings"])


def migrate(doc: dict) -> dict:
    """A stored report data document brought to the current format (a copy; the current format as it is).

    Format 1 (before the table cells, the run times and the reading scores were stored) gains
    ``cells = None`` (the report says they were not stored), ``run_times = {}`` and ``readings = {}``;
    its verdicts gain the defaults of the fields added since (``source = "paper"``, no paired
    statistics, nothing excluded).

    Examples
    --------
    >>> migrate({"format": 1, "dataset": "faust", "verdicts": {}})["format"]
    2
    """
    fmt = doc.get("format")
    if fmt == _FORMAT:
        return doc
    if fmt != 1:
        raise ValueError(f"report data of format {fmt!r}: this version reads formats 1 and {_FORMAT}")
    return {**doc, "format": _FORMAT, "cells": None, "run_times": {}, "readings": {},
            "verdicts": {c: {**v, "source": v.get("source", "paper")} for c, v in doc.get("verdicts", {}).items()}}


def _studies(infos, *, dataset: str | None = None) -> list[Study]:
    """The ``report_blocks`` sections of the runs (of ``dataset``'s section, else the main results')."""
    out = []
    for info in infos:
        if not (info.report and info.doc):
            continue
        ds = dataset or run_dataset(info)
        blocks = importlib.import_module(info.report).report_blocks(info.doc.get("results", {}),
                                                                    DATASET_NAMES.get(ds, ds), main=dataset is None)
        if blocks:
            out.append(Study(info.name, ds, [tuple(b) for b in blocks], list(info.figures)))
    return out


def dataset_report(folder, dataset: str = DEFAULT_DATASET, *, main: bool = False, registry=None,
                   published_rows=(), infos=None, shown: str | None = None, commit: str = "unknown") -> DatasetReport:
    """One dataset's report data, built from its results folder (``OUT/<profile>[-<dataset>]``).

    ``main``: the report's own results (every run's table values and figures, studies computed on
    another dataset shown as that dataset's), else a prepared dataset's (the runs with results; the
    figures of the runs with ``dataset_figures`` or values of their own for this dataset in the
    registry). ``infos``: the folder's :func:`collect_runs`, if already read; ``shown``: how the
    report names the folder; ``commit``: the code's commit.
    """
    folder = Path(folder)
    infos = collect_runs(folder, registry) if infos is None else infos
    present = [i for i in infos if i.doc]
    shapes, pairs = set(), []
    for i in present:
        res = i.doc.get("results", {})
        for p in res.get("pairs", []) if isinstance(res.get("pairs"), list) else []:
            if isinstance(p, (list, tuple)) and len(p) == 2 and list(p) not in pairs:
                pairs.append(list(p))
                shapes.update(p)
    used = infos if main else present
    entries = [e for i in used for e in table_entries(i)]
    matches = match_published(entries, published_rows)[0] if published_rows else []
    if dataset in datasets.names() and datasets.coordinate_frame(dataset):
        # coordinates moved from the paper's frame: XYZ cells are not compared (their values stay in the appendix)
        moved = [(r, e) for r, e in matches if r["function"] in FRAME_DEPENDENT]
        matches = [(r, e) for r, e in matches if r["function"] not in FRAME_DEPENDENT]
    else:
        moved = []
    tables = (table_summaries(used, published_rows, matches, only_run=not main)
              if published_rows and (main or entries) else [])
    cells = table_cells(published_rows, matches + moved, {t.table for t in tables}) if tables else []
    for c in cells:
        if c["function"] in FRAME_DEPENDENT and moved:
            c["not_compared"] = f"not compared: {datasets.coordinate_frame(dataset)}"
    studies = _studies(infos) if main else _studies(present, dataset=dataset)
    in_studies = {s.run for s in studies}  # a study's figures are shown with its section
    figures = [Figure(i.name, i.reproduces, list(i.figures)) for i in present if i.figures
               and i.name not in in_studies and (main or i.dataset_figures or dataset in i.datasets)]
    own = [i for i in present if not main or run_dataset(i) == dataset]  # a main study run on FAUST is FAUST's
    verdicts = claim_results(ledger.evaluate_folder(folder))
    _normalization_readings(own, verdicts)
    return DatasetReport(dataset, shown if shown is not None else str(folder), commit, [i.name for i in present],
                         sorted(shapes), pairs, verdicts, tables, figures, studies, cells,
                         {i.name: [i.status, i.seconds] for i in infos if i.doc or i.manifest}, reading_scores(own))
