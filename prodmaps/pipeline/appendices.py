"""The report's appendices: the figure gallery, the studies, one appendix per dataset, the runs.

Each builder appends to a :class:`.document.Document` ``d``; ``inputs`` is the report's
:class:`.report.ReportInputs`, ``settings`` its :class:`.report.ReportSettings`, ``all_ds`` every
dataset's :class:`.report_data.DatasetReport` in the report's order, ``captions`` the figures'
captions (:func:`.prose.report_captions`) and ``base`` the report's folder (links are relative to it).

* :func:`gallery_appendix` (**A**): each run's panels of every dataset side by side, arranged by its
  caption's ``layout``, under its caption (a run without one is marked);
* :func:`studies_appendix` (**B**): each study's blocks (a study run of the main results computed on
  a prepared dataset is shown once, as that dataset's), its caption and figures;
* :func:`dataset_appendix` (**C1, C2, ...**): the results folder and commit, every claim with its
  settings (:data:`APPENDIX_CLAIMS`: verdicts, paired comparisons, margin, what it leaves out,
  evidence), the table summaries and every published table cell beside ours;
* :func:`runs_appendix` (**D**): one row per run with its time on each dataset and its notebook,
  failed runs with the first lines of their error, the environment, and the table values that
  match no published number.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from .document import Document
from .execute import package_versions
from .links import notebook_link, relative_path, without_machine_paths
from .main_text import verdict_text
from .prose import CAPTIONS, text_blocks
from .report_data import CRITERIA, load_claims, printed, within_draw_noise, within_published

__all__ = ["APPENDIX_CLAIMS", "gallery_appendix", "studies_appendix", "dataset_appendix", "runs_appendix"]

_PACKAGES = ("numpy", "scipy", "matplotlib", "pyvista", "vtk", "pymeshlab", "potpourri3d",
             "robust-laplacian", "papermill", "nbclient", "ipykernel", "dask", "distributed")  # versions in Appendix D
APPENDIX_CLAIMS = ["claim", "verdict", "rule", "default", "intra / inter", "other readings", "paired comparison",
                   "margin", "left out", "evidence"]  # a dataset appendix's claims table


def _other_readings(c) -> str:
    return "; ".join(f"{'textbook families' if r == 'textbook' else r}: {x}" for r, x in c.readings.items())


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


def gallery_appendix(d: Document, text, all_ds, captions: dict, base: Path) -> None:
    """Appendix A, the figure gallery (nothing without figures): ``gallery.md``, then each run's panels.

    ``text`` reads a text file of the paper's prose into blocks (:func:`.prose.report_text`).
    """
    if any(ds.figures for ds in all_ds):
        d.h(2, "Appendix A: figure gallery")
        d.extend(text("gallery.md"))
        _gallery(d, all_ds, captions, base)


def _gallery(d: Document, all_ds, captions: dict, base: Path, level: int = 3) -> None:
    """Per run: its heading and caption, then each figure's panels of every dataset side by side."""
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
            d.figure([[[relative_path(panels[ds], base), names[ds] if several else stem] for ds in r] for r in rows],
                     f"`{stem}`" if several and len(stems) > 1 else "")


def _demoted(blocks, top: int) -> list:
    """``blocks`` with their headings shifted so that the highest is at ``top``."""
    levels = [b[1] for b in blocks if b[0] == "h"]
    shift = top - min(levels) if levels else 0
    return [("h", b[1] + shift, b[2]) if b[0] == "h" else b for b in blocks]


def studies_appendix(d: Document, inputs, all_ds, captions: dict, base: Path) -> None:
    """Appendix B, the studies (nothing without one): each study's blocks, its caption and figures."""
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
                d.figure([[[relative_path(p, base), f"{Path(p).stem} on {names.get(s.dataset, s.dataset)}"]]], "")


def _cell_rows(cells, multi: bool) -> list:
    """Every published cell with ours: value, SE, difference as printed, and what they count as."""
    rows = []
    for c in cells:
        v, se, p = c["value"], c["se"], c["published"]
        if v is None:
            ours = ["—", "—", "", "", ""]
        elif c.get("not_compared"):  # the dataset's frame differs from the paper's (datasets.coordinate_frame)
            ours = [printed(v), "—" if se is None else printed(se), printed(v - p, signed=True), "not compared",
                    "not compared"]
        else:
            diff = v - p
            noise = "—" if se is None else ("yes" if within_draw_noise(diff, se) else "no")
            ours = [printed(v), "—" if se is None else printed(se), printed(diff, signed=True),
                    "yes" if within_published(diff) else "no", noise]
        rows.append(([c["k_M"], c["k_N"]] if multi else []) + [c["function"], c["stage"], c["method"], f"{p:.2f}"]
                    + ours + [c["run"] or ""])
    return rows


def dataset_appendix(d: Document, ds, label: str, inputs, base: Path) -> None:
    """Appendix ``label`` (``C1``, ...) of the dataset ``ds``: its claims, table summaries and table cells."""
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
        rows.append([f"`{cid}`", verdict_text(c) + (" (single case)" if c.single_case else ""), c.rule, c.default,
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


def runs_appendix(d: Document, inputs, settings, all_ds, base: Path) -> None:
    """Appendix D, the runs: times per dataset, notebooks, failures, environment, unmatched table values."""
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
             + [notebook_link(by[r].folder, base, read, notebooks) if r in by else ""] for r in names])
    failed = [i for i in infos if i.status != "ok"]
    if failed:
        d.p("**Failed or not run** on the embedded humans: " + ", ".join(f"`{i.name}`" for i in failed)
            + ". A failed run keeps `error.txt` and `executed.ipynb` in its folder.")
    for i in failed:
        if i.status == "failed" and (i.folder / "error.txt").is_file():
            excerpt = "\n".join((i.folder / "error.txt").read_text().splitlines()[:15])
            d.p(f"`{i.name}`, the first lines of its error:")
            d.code(excerpt if settings.machine_paths else without_machine_paths(excerpt, settings.registry))
    d.p("Environment: " + ", ".join(f"{p} {v}" for p, v in package_versions(_PACKAGES).items()) + ".")
    if inputs.unmatched:
        d.h(3, "Table values that match no published number")
        d.table(["run", "entry", "reason"],
                [[e.get("run", "") if isinstance(e, dict) else "",
                  "`" + json.dumps({k: v for k, v in e.items() if k != "run"} if isinstance(e, dict) else e) + "`",
                  why] for e, why in inputs.unmatched])
