"""The reproduction report: ``paper/REPORT.md`` and ``paper/REPORT.html`` from a results folder.

``build_report(results_dir)`` reads every run folder ``results_dir/<run>/`` written by
``prodmaps reproduce`` (``results.json``, PNGs, ``manifest.json``, ``executed.html``) and writes,
in this order:

1. **Claims**: one row per entry of the claims ledger (:mod:`prodmaps.experiments.shared.claims`) — the
   verdict computed from the results, whether the rule holds at the paper's settings, with the
   threshold rule and with the library's default transfer, one line of evidence, and links to the
   notebook (executed, as HTML) that decides it; table claims also per pair kind (intra / inter).
2. **Tables 1–6**: per table, how close our values are to the published ones (count within
   ±0.02, mean and largest difference) and, per transfer method, for how many families products
   beat the standard transfer over all, intra- and inter-subject pairs; the systematic differences
   stated once.
3. **Studies**: their figures and the conclusion computed from their numbers.
4. **Runs**: status, time, figures and links; the per-value tables in an appendix. Every other
   number stays in the runs' ``results.json``.

How a notebook reports table values: :mod:`prodmaps.experiments.shared.published`.
"""

from __future__ import annotations

import datetime as _dt
import html
import importlib
import json
import os
import platform
import re
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from ..experiments.shared import claims as ledger
from ..experiments.shared import compare
from ..experiments.shared import published as pub
from ..experiments.shared.published import PUBLISHED_CSV, TABLE_KEYS, load_published, match_entries
from ..files import atomic_path, read_json
from .execute import git_commit, package_versions
from .registry import RegistryError, load_registry, project_root

__all__ = ["collect_runs", "build_report", "publish", "PublishError", "partial_problems", "kept_dataset"]

_PACKAGES = ("numpy", "scipy", "matplotlib", "pyvista", "vtk", "pymeshlab", "potpourri3d",
             "robust-laplacian", "papermill", "nbclient", "ipykernel", "dask", "distributed")


# ------------------------------------------------------------------------------ runs
@dataclass
class RunInfo:
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


def _entries_of(info: RunInfo) -> list:
    res = info.doc.get("results", {})
    tab = res.get("table") if isinstance(res, dict) else None
    tab = tab if tab is not None else info.doc.get("table")
    if not isinstance(tab, list):
        return []
    return [dict(e, run=info.name) if isinstance(e, dict) else e for e in tab]


# ------------------------------------------------------------------------------ rendering
class _Doc:
    """Tiny block document rendered to Markdown and to standalone HTML."""

    def __init__(self):
        self.blocks = []
        self.copied = []  # figures copied beside the report (report_figures/...)

    def __getattr__(self, kind):  # h(level, text), p(text), table(header, rows), img(src, alt), code(text), ul(items)
        if kind not in ("h", "p", "table", "img", "code", "ul"):
            raise AttributeError(kind)
        return lambda *args: self.blocks.append((kind, *args))

    def counts(self, label, counts: dict):
        """Verdict counts: a sentence in Markdown, a row of coloured badges in HTML."""
        self.blocks.append(("counts", label, {k: n for k, n in counts.items() if n}))

    def markdown(self) -> str:
        row = lambda r: "| " + " | ".join(str(c).replace("|", "\\|") for c in r) + " |"
        lines = {"h": lambda level, text: ["#" * level + " " + text], "p": lambda text: [text],
                 "table": lambda header, rows: [row(header), "|" + "---|" * len(header), *map(row, rows)],
                 "img": lambda src, alt: [f"![{alt}]({src})"], "code": lambda text: ["```\n" + text.rstrip() + "\n```"],
                 "ul": lambda items: [f"- {i}" for i in items],
                 "counts": lambda label, n: [f"{label}: " + ", ".join(f"{c} {k}" for k, c in n.items()) + "."]}
        return "\n".join(x for kind, *args in self.blocks for x in [*lines[kind](*args), ""]).rstrip() + "\n"

    @staticmethod
    def _inline(text: str) -> str:
        s = html.escape(str(text))
        s = re.sub(r"`([^`]+)`", r"<code>\1</code>", s)
        s = re.sub(r"\[([^\]]+)\]\(([^)\s]+)\)", r'<a href="\2">\1</a>', s)
        s = re.sub(r"\*\*([^*]+)\*\*", r"<b>\1</b>", s)
        return re.sub(r"(?<![\w*])\*([^*\s][^*]*)\*(?![\w*])", r"<i>\1</i>", s)

    # verdict -> badge class, longest phrases first so "holds with the threshold rule" is not "holds"
    _BADGES = (("holds with the threshold rule within rounding", "v-rule"), ("holds with the threshold rule", "v-rule"),
               ("holds within rounding", "v-round"), ("does not hold", "v-not"),
               ("not measured here", "v-none"), ("not demonstrable in this setting", "v-none"), ("holds", "v-holds"))
    _NUMBER = re.compile(r"[-+−]?(\d[\d,]*\.?\d*(e[-+]?\d+)?|\.\d+)\s*(%|x|s)?", re.I)
    _STYLE = (
        "body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;line-height:1.45;max-width:1400px;"
        "margin:2em auto;padding:0 1em;color:#222}h1{font-size:1.6em}h2{margin-top:1.6em;border-bottom:1px solid #ddd}"
        "table{border-collapse:collapse;margin:.6em 0;font-size:.9em}td,th{border:1px solid #ddd;padding:3px 8px;"
        "text-align:left;vertical-align:top;overflow-wrap:anywhere}th{background:#f3f4f6;position:sticky;top:0;overflow-wrap:normal}"
        "td:first-child code{white-space:normal}td:nth-child(n+2){min-width:4em}td.num{text-align:right;"
        "font-variant-numeric:tabular-nums;white-space:nowrap}tr:nth-child(even) td{background:#fafafa}"
        "img{max-width:100%;border:1px solid #ddd;margin:.3em 0}pre{background:#f6f6f6;padding:.5em;overflow-x:auto}"
        ".badge{display:inline-block;padding:1px 8px;border-radius:10px;font-size:.85em;font-weight:600;"
        "white-space:nowrap}.v-holds{background:#d1fadf;color:#05603a}.v-round{background:#e0f2fe;color:#075985}"
        ".v-rule{background:#fef0c7;color:#93370d}.v-not{background:#fee4e2;color:#b42318}"
        ".v-none{background:#eaecf0;color:#475467}.counts{font-size:1.05em}.counts .badge{font-size:1em;"
        "margin:0 .3em .3em 0;padding:3px 10px}details summary{cursor:pointer;color:#475467}"
        "details{max-width:22em}")

    @classmethod
    def _badge(cls, verdict: str, text: str | None = None) -> str:
        for phrase, css in cls._BADGES:
            if verdict.startswith(phrase):
                return f'<span class="badge {css}">{html.escape(text or verdict)}</span>'
        return html.escape(text or verdict)

    @classmethod
    def _cell(cls, text, header: str = "") -> str:
        """One table cell: verdicts as badges, quotes folded, numbers right-aligned."""
        t = str(text)
        plain = t.strip("*")
        for phrase, _ in cls._BADGES:
            if plain.startswith(phrase):
                head, rest = plain[: len(phrase)], plain[len(phrase):].replace("**", "")
                return "<td>" + cls._badge(head) + cls._inline(rest) + "</td>"
        if header == "the paper's words" and len(t) > 48:
            short = t[:40].rsplit(" ", 1)[0] + " …"
            return f"<td><details><summary>{html.escape(short)}</summary>{cls._inline(t)}</details></td>"
        if cls._NUMBER.fullmatch(t.strip()):
            return f'<td class="num">{cls._inline(t)}</td>'
        return f"<td>{cls._inline(t)}</td>"

    def html(self, title: str) -> str:
        inline, esc = self._inline, html.escape
        render = {
            "h": lambda level, text: f"<h{level}>{inline(text)}</h{level}>", "p": lambda text: f"<p>{inline(text)}</p>",
            "table": lambda header, rows: "\n".join(
                ["<table><tr>" + "".join(f"<th>{inline(c)}</th>" for c in header) + "</tr>"]
                + ["<tr>" + "".join(self._cell(c, str(h)) for c, h in zip(r, header)) + "</tr>" for r in rows]
                + ["</table>"]),
            "counts": lambda label, n: f'<p class="counts"><b>{inline(label)}:</b> '
                                       + "".join(self._badge(k, f"{c} {k}") for k, c in n.items()) + "</p>",
            "img": lambda src, alt: f'<p><img src="{esc(src)}" alt="{esc(alt)}"></p>',
            "code": lambda text: f"<pre>{esc(text)}</pre>",
            "ul": lambda items: "<ul>" + "".join(f"<li>{inline(i)}</li>" for i in items) + "</ul>"}
        return "\n".join(["<!DOCTYPE html>", "<html><head><meta charset=\"utf-8\">", f"<title>{esc(title)}</title>",
                          f"<style>{self._STYLE}</style></head><body>",
                          *(render[kind](*args) for kind, *args in self.blocks), "</body></html>"]) + "\n"


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
    """A traceback for a committed report, without this machine's paths.

    Paths in the project become relative, installed packages ``<site-packages>/...``, and any other
    absolute path is cut to ``…/<file name>``.
    """
    text = re.sub(r"(?:/[^\s/\"':,]+)+/(site-packages|dist-packages)/", r"<\1>/", text)
    try:
        text = text.replace(str(project_root(registry).resolve()) + "/", "")
    except ValueError:  # no project
        pass
    return re.sub(r"(?<![\w.<>~/:-])/(?:[^\s/\"':,]+/)+([^\s/\"':,]+)", r"…/\1", text)  # not in a URL


def _num(v, signed=False) -> str:
    return "" if v is None else (f"{v:+.3f}" if signed else f"{v:.3f}")


SYSTEMATIC_DIFFERENCES = [
    "**Data.** The main columns: the embedded 5k-vertex synthetic humans (6 subjects x 10 poses); the 20 "
    "table pairs `pairs(\"anny_humans\", \"all\", n=20, seed=0)` hold 4 intra- and 16 inter-subject pairs. "
    "FAUST (or any subset of it, e.g. the eight public registrations) and TOSCA need the user's files "
    "(`python -m prodmaps.prepare faust ...`); when prepared, their runs have their own verdict column and section.",
    "**Function families.** Section 5.1 gives no parameters for its families; the tables use the readings "
    "that reproduce the published standard columns, the control no product method touches "
    "(`study_family_readings`, `prodmaps.experiments.shared.families.PUBLISHED_READINGS`): heat kernels hk k and "
    "hk K at one time, t = 5e-4·area (the text defines them as the same kernels under two truncations), "
    "Random with U[0, 1] coefficients on the ordered extended basis of unit-area "
    "eigenfunctions, indicators of balls of U[0.3, 0.5] of the area, SHOT of radius 0.05·sqrt(area). "
    "**HKS** differs in kind: the textbook HKS (SOG09) is smooth (standard error near 0.01 where the paper "
    "has ~0.55); the published numbers fit only an HKS dominated by the squares of the highest "
    "eigenfunctions, as with the eigenvalues paired in reverse order. The tables carry both HKS rows and "
    "every claim is judged under both.",
    "**AWFT** takes the parameters of the demo its authors released with their AWFT code (200 "
    "eigenpairs, anisotropies 100 and 300 at four angles plus the isotropic operator, low-pass windows "
    "τ = 0.002 and 0.05, the signals geometry vectors 3 and 4, shape index, Fiedler vector and constant; "
    "`prodmaps.experiments.shared.families.AWFT_RELEASE`), the reading the standard column chooses; this "
    "project's curvature smoothing stands in for the release's.",
    "**Approach A's ε** is not in the paper: fixed before measuring (ridge 1e-6 σ_max², lasso 1e-4), so "
    "our A behaves like B.",
    "**Approach B's normalisation** is not stated in the paper, and with A-orthonormal eigenfunctions "
    "the threshold `rtol = 1e-3` keeps different product directions in metres and in centimetres. The "
    "normalisation study (`study_normalization`) scores every reading by the published cells it "
    "reproduces: eigenvectors of unit Euclidean norm (what a standard eigensolver returns; free of the "
    "mesh's units) reproduce the published Approach B columns, A-orthonormal eigenfunctions in metres "
    "do not (XYZ and indicators 2-5x worse). The library and every profile use the unit-Euclidean "
    "reading (`prodmaps.approx.DEFAULT_NORMALIZATION`); the earlier reports' \"does not hold\" for "
    "the tables came from the metre reading.",
    "**Products at a fixed threshold** can still amplify small singular directions whose images under "
    "C~ do not cancel (see the truncation study), most with computed maps.",
]


def _verdict_cell(v) -> str:
    """The verdict, then under each other family reading of the run: ``"holds (textbook families: does not hold)"``."""
    head = f"**{v.verdict}**" if v.verdict == "does not hold" else v.verdict
    return head + "".join(f" ({r} families: {x})" for r, x in ledger.reading_verdicts(v).items())


def _link(path: Path, base: Path, text: str) -> str:
    return f"[{text}]({_rel(path, base)})" if path.is_file() else text


def _nb_link(run_folder: Path, base: Path, text: str, notebooks: dict | None = None) -> str:
    """Link to a run's executed notebook, or with ``notebooks`` (a published report) to its committed one."""
    if notebooks is None:
        return _link(run_folder / "executed.html", base, text)
    nb = notebooks.get(Path(run_folder).name)
    return _link(nb, base, text) if nb is not None else text


def _claims_section(d: "_Doc", verdicts, results_dir: Path, base: Path, others: dict, notebooks: dict | None,
                    kept: dict) -> None:
    d.h(2, "Claims of the paper, judged on these results")
    by_claim: dict = {}
    for v in verdicts:
        by_claim.setdefault(v.claim.id, {})[v.subset] = v
    d.counts(f"Totals over {len(by_claim)} claims", {
        k: sum(1 for subs in by_claim.values() if subs.get("all", next(iter(subs.values()))).verdict == k)
        for k in ledger.VERDICTS})
    other_verdicts = {ds: {v.claim.id: v for v in vs if v.subset == "all" or len(v.claim.subsets) == 1}
                      for ds, (_, vs) in others.items()}
    for ds, vs in other_verdicts.items():
        d.counts(f"On {DATASET_NAMES.get(ds, ds)}", {k: sum(1 for v in vs.values() if v.verdict == k)
                                                    for k in ledger.VERDICTS})
    for ds, k in kept.items():
        d.counts(f"On {DATASET_NAMES.get(ds, ds)} (kept from the report published at commit `{k.commit}`)",
                 {v: sum(1 for c in k.column.values() if _verdict_of(c) == v) for v in ledger.VERDICTS})
    d.p("One row per entry of the claims ledger (`prodmaps/experiments/shared/claims.toml`). The verdict is "
        "computed from the runs' numbers by the entry's rule: **holds** at the paper's settings, **holds "
        "with the threshold rule** (Approach B with `select_rtol(method=\"gain\")`, no ground truth) but not "
        "at the paper's, **does not hold**, **not demonstrable in this setting** (the entry's oracle, e.g. the "
        "exact point-map transfer, does not beat C there, so no product effect can show; the evidence starts "
        "with the oracle and no-map numbers), or **not measured here**; \"within rounding\" when a margin under "
        f"{compare.ROUNDING_REL:g} relative decides it (rounding on another machine could flip it), ties "
        f"within {compare.TIE_REL:g} relative never count as wins. The columns *paper*, *rule* and "
        "*default* say whether the rule holds at the paper's settings, with the threshold rule and with the "
        "library's default extended transfer. Table claims are also judged on intra- and inter-subject "
        "pairs separately.")
    if others or kept:
        d.p("Verdict columns per dataset: *" + DATASET_NAMES.get("anny_humans", "anny_humans") + "* (the default "
            "data, always) and " + ", ".join(f"*{DATASET_NAMES.get(ds, ds)}*" for ds in [*others, *kept])
            + " (prepared from the user's own files; see its section below).")
    rows = []
    for cid, subs in by_claim.items():
        v = subs.get("all", next(iter(subs.values())))
        c = v.claim
        cells = [f"`{cid}`", c.where, f"“{c.quote[:110]}{'…' if len(c.quote) > 110 else ''}”", _verdict_cell(v),
                 ledger.setting_mark(v, "paper"), ledger.setting_mark(v, "rule"), ledger.setting_mark(v, "default")]
        kinds = "; ".join(f"{k}: {subs[k].verdict}" for k in ("intra", "inter") if k in subs)
        links = ", ".join(_nb_link(results_dir / r, base, c.notebook or r if len(c.runs) == 1 else r, notebooks)
                          for r in c.runs)  # one notebook per run the claim is judged on
        for ds in others:
            ov = other_verdicts.get(ds, {}).get(cid)
            cells.append(_verdict_cell(ov) + f" (paper {ledger.setting_mark(ov, 'paper')}, default "
                         f"{ledger.setting_mark(ov, 'default')})" if ov and ov.verdict != "not measured here"
                         else "not measured here")
        for ds, k in kept.items():
            cells.append(k.column.get(cid, "not measured here"))
        cells += [kinds, v.evidence, links]
        rows.append(cells)
    d.table(["claim", "where", "the paper's words", "verdict", "paper", "rule", "default"]
            + [f"{DATASET_NAMES.get(ds, ds)}" for ds in [*others, *kept]] + ["intra / inter", "evidence", "notebook"],
            rows)


def _table_summaries(d: "_Doc", infos, published_rows, matches,
                     heading: str = "Tables 1–6: our values beside the published ones", only_run: bool = False,
                     differences: bool = True) -> None:
    d.h(2 if heading.startswith("Tables 1") else 3, heading)
    d.p("Relative errors (the paper's area-weighted normalised L2). Each row compares our values with "
        "the published values of the same cells; *within ±0.02* counts the cells whose difference "
        "|ours − published| is at most 0.02 (the paper prints two decimals). The product columns say for "
        "how many function families the product transfer beats the standard one (lower by more than "
        "rounding: a tie, as the default's hk k, which is the standard transfer, does not count), over all "
        "pairs and on intra- / inter-subject pairs. *Missed, within draw noise*: of the cells off by more than "
        f"{pub.WITHIN:g}, those within {pub.WITHIN:g} + {pub.DRAW_Z:g}·√2·SE of the published value, SE the "
        "standard error of our mean over its pairs: what two independent draws of as many pairs explain at "
        "about 95 %, taking the paper's means to be as noisy as ours (its pairs and functions are unknown); the "
        "others differ by more than the draw explains.")
    rows = []
    for t in sorted({r["table"] for r in published_rows}, key=int):
        info = next((i for i in infos if i.reproduces == f"Table {t}"), None)
        if only_run and not (info and info.doc):
            continue
        got = [(r, e) for r, e in matches if r["table"] == t]
        n_pub = sum(1 for r in published_rows if r["table"] == t)
        diffs = [abs(e["value"] - r["value"]) for r, e in got]
        missed = [(e["value"] - r["value"], e.get("se")) for r, e in got
                  if not pub.within_published(e["value"] - r["value"])]
        noise = (f"{sum(pub.within_draw_noise(dv, se) for dv, se in missed)} of {len(missed)}"
                 if diffs and all(se is not None for _, se in missed) else "—")
        res = info.doc.get("results", {}) if info else {}
        beat = [" · ".join(_beats(res.get(f"errors{sub}", {}), lab) for sub in ("", "_intra", "_inter"))
                for lab in ("our_B", "our_B_gainrule", "our_default")]  # the paper's B, the gain rule, the default
        rows.append([f"Table {t}", f"{len(got)} of {n_pub}",
                     f"{sum(map(pub.within_published, diffs))}" if diffs else "—", noise,
                     f"{sum(diffs) / len(diffs):.3f}" if diffs else "—", f"{max(diffs):.3f}" if diffs else "—", *beat])
    d.table(["table", "cells compared", f"within ±{pub.WITHIN:g}", "missed, within draw noise", "mean |diff|",
             "largest |diff|", "products beat std: paper B (all · intra · inter)", "gain rule", "default"], rows)
    if differences:
        d.p("Systematic differences (stated once):")
        d.ul(SYSTEMATIC_DIFFERENCES)


def _beats(errors: dict, method: str) -> str:
    """``"wins/families"``: where ``method`` transfers better than ``std``, over the sizes of ``errors``."""
    trs = [tr for tr in (size.get("transfer", {}) for size in errors.values()) if method in tr and "std" in tr]
    n_f = sum(len(tr["std"]) for tr in trs)
    return f"{sum(compare.lower(tr[method][f], tr['std'][f]) for tr in trs for f in tr['std'])}/{n_f}" if n_f else "—"


def _study_sections(d: "_Doc", infos, base: Path, copy_figures: bool, dataset: str | None = None) -> set:
    """The ``report_blocks`` sections (``main=False`` with ``dataset``) and figures of the runs; returns their names."""
    shown = set()
    for info in infos:
        if not (info.report and info.doc):
            continue
        res = info.doc.get("results", {})
        ds = dataset or _run_dataset(info)
        blocks = importlib.import_module(info.report).report_blocks(res, DATASET_NAMES.get(ds, ds),
                                                                    main=dataset is None)
        if not blocks:
            continue
        for kind, *args in blocks:
            getattr(d, kind)(*args)
        _figures(d, info, base, copy_figures, prefix=f"{dataset}/" if dataset else "")
        shown.add(info.name)
    return shown


def _run_dataset(info) -> str:
    """The dataset a run's results were computed on (``anny_humans`` when they do not say)."""
    res = info.doc.get("results", {}) if info.doc else {}
    return res.get("dataset", "anny_humans") if isinstance(res, dict) else "anny_humans"


def _figures(d: "_Doc", info, base: Path, copy_figures: bool, prefix: str = "") -> None:
    for fig in info.figures:
        if copy_figures:
            dest = base / "report_figures" / f"{prefix}{info.name}" / fig.name
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(fig, dest)
            d.copied.append(dest.resolve())
            fig = dest
        d.img(_rel(fig, base), f"{info.name} {fig.stem}")


DATASET_NAMES = {"anny_humans": "embedded humans", "faust": "FAUST", "tosca": "TOSCA"}


def other_datasets(results_dir) -> dict:
    """``{dataset: folder}`` of the sibling folders ``<results_dir>-<dataset>`` (e.g. ``results/paper-faust``)."""
    from ..datasets import names

    results_dir = Path(results_dir).resolve()
    return {ds: results_dir.with_name(f"{results_dir.name}-{ds}") for ds in names()
            if results_dir.with_name(f"{results_dir.name}-{ds}").is_dir()}


def _dataset_section(d: "_Doc", ds: str, folder: Path, infos, published_rows, base: Path, copy_figures: bool,
                     out_root: Path | None = None) -> None:
    name = DATASET_NAMES.get(ds, ds)
    present = [i for i in infos if i.doc]
    d.h(2, f"On {name}")
    shapes, pairs = set(), []
    for i in present:
        res = i.doc.get("results", {})
        for p in res.get("pairs", []) if isinstance(res.get("pairs"), list) else []:
            if isinstance(p, (list, tuple)) and len(p) == 2 and list(p) not in pairs:
                pairs.append(list(p))
                shapes.update(p)
    d.p(f"Runs on `{ds}` (`{_shown(folder, base, out_root=out_root)}`): "
        + ", ".join(f"`{i.name}`" for i in present) + ". "
        + (f"Shapes: {', '.join(f'`{x}`' for x in sorted(shapes))}. " if shapes else "")
        + (f"{len(pairs)} ordered (source, target) pairs in the tables: "
           + ", ".join(f"{a}→{b}" for a, b in pairs) + "." if pairs else ""))
    entries = [e for i in present for e in _entries_of(i)]
    if published_rows and entries:
        matches, _ = match_entries(entries, published_rows)
        _table_summaries(d, present, published_rows, matches, heading=f"Tables on {name}: our values beside the "
                         "published ones", only_run=True, differences=False)
    for i in present:
        if i.dataset_figures and i.figures:
            d.h(3, f"{i.name} on {name}" + (f" — {i.reproduces}" if i.reproduces else ""))
            _figures(d, i, base, copy_figures, prefix=f"{ds}/")
    _study_sections(d, present, base, copy_figures, dataset=ds)


def build_report(results_dir, out=None, *, registry=None, published=None, html_out=None,
                 copy_figures: bool = False, datasets: dict | None = None, notebooks: dict | None = None,
                 kept: dict | None = None, notes=(), generated_by: str = "prodmaps report",
                 copied: list | None = None, machine_paths: bool = True):
    """Write the Markdown and HTML reports for ``results_dir`` (e.g. ``results/paper``).

    ``out`` defaults to ``RESULTS_DIR/REPORT.md``, beside the results it reads; the HTML goes
    beside it (``.html``). The committed ``paper/REPORT.md`` is written only by :func:`publish`.
    Image and notebook links are relative to the report's folder. ``copy_figures=True`` copies the
    PNGs into ``<report folder>/report_figures/<run>/`` and links those instead (so a committed
    report shows its figures although ``results/`` is not committed). ``datasets``
    (``{name: folder}``, default: the sibling folders ``<results_dir>-<dataset>``, see
    :func:`other_datasets`) adds a verdict column and a section per prepared dataset.
    ``notebooks`` (``{run: source notebook}``) links the source notebooks instead of the executed
    ones; ``kept`` (``{dataset: KeptDataset}``) adds a dataset's column and sections taken from an
    earlier report; ``notes`` are paragraphs shown under the title. Parameters overridden on the
    command line (recorded in the runs' manifests) are always shown. ``copied``, a list, receives
    the paths of the figures copied. ``machine_paths=False`` (a published report) names folders outside
    the project ``<out>/paper/...`` instead of by their paths on this machine.
    Returns ``(md_path, html_path)``.
    """
    results_dir = Path(results_dir).resolve()
    out_root = None if machine_paths else results_dir.parent
    out = (Path(out) if out is not None else results_dir / "REPORT.md").resolve()
    html_out = Path(html_out).resolve() if html_out is not None else out.with_suffix(".html")
    base = out.parent
    if html_out.parent != base:  # the links are relative to the report's folder, shared by both files
        raise ValueError(f"html_out must be in the folder of the Markdown report ({base}), got {html_out}")
    infos = collect_runs(results_dir, registry)
    pub_path = Path(published) if published is not None else PUBLISHED_CSV
    published_rows = load_published(pub_path) if pub_path.is_file() else []
    entries = [e for i in infos for e in _entries_of(i)]
    matches, unmatched = match_entries(entries, published_rows)
    verdicts = ledger.evaluate_folder(results_dir)
    extra = other_datasets(results_dir) if datasets is None else {k: Path(v).resolve() for k, v in datasets.items()}
    others = {ds: (f, ledger.evaluate_folder(f)) for ds, f in extra.items()}
    kept = {ds: k for ds, k in (kept or {}).items() if ds not in others}

    d = _Doc()
    d.h(1, "Reproduction report: Improved Functional Mappings via Product Preservation")
    d.p("Nogneng, Melzi, Rodolà, Castellani, Bronstein, Ovsjanikov, Eurographics 2018. "
        f"Generated by `{generated_by}` from `{_shown(results_dir, None, registry, out_root)}` on "
        f"{_dt.datetime.now(_dt.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}, "
        f"code at commit `{_git_commit(registry)}`; Python {platform.python_version()} on {platform.system()} "
        f"{platform.machine()}.")
    for note in notes:
        d.p(note)
    overridden = overridden_parameters(infos)
    if overridden:
        d.p("**Parameters overridden on the command line** (these runs do not use the registry's settings): "
            + "; ".join(f"`{r}`: " + ", ".join(f"`{k}={json.dumps(v)}`" for k, v in ov.items())
                        for r, ov in overridden.items()) + ".")
    _claims_section(d, verdicts, results_dir, base, others, notebooks, kept)
    if published_rows:
        _table_summaries(d, infos, published_rows, matches)
    shown_in_dataset = set()  # (run, dataset) a dataset's own section shows
    for ds, (folder, _) in others.items():
        ds_infos = collect_runs(folder, registry)
        _dataset_section(d, ds, folder, ds_infos, published_rows, base, copy_figures, out_root)
        shown_in_dataset |= {(i.name, ds) for i in ds_infos if i.doc}
    d.blocks += [b for k in kept.values() for b in k.blocks]
    # a study of the main run that ran on a prepared dataset (FAUST when prepared) is not repeated
    # when that dataset's section already shows the same run
    studies = _study_sections(d, [i for i in infos if (i.name, _run_dataset(i)) not in shown_in_dataset],
                              base, copy_figures)

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
            + f"; outputs in `{_shown(i.folder, base, registry, out_root)}`; "
            + _nb_link(i.folder, base, read, notebooks)
            + "; every number in `results.json`.")
        if i.status == "failed" and (i.folder / "error.txt").is_file():
            excerpt = "\n".join((i.folder / "error.txt").read_text().splitlines()[:15])
            d.code(excerpt if machine_paths else _without_machine_paths(excerpt, registry))
        _figures(d, i, base, copy_figures)

    if published_rows:
        d.h(2, "Appendix: every published table value beside ours")
        by_key = {tuple(r[k] for k in TABLE_KEYS): e for r, e in matches}
        for t in sorted({r["table"] for r in published_rows}, key=int):
            prow = [r for r in published_rows if r["table"] == t]
            settings = sorted({(r["fmap"], r["k_M"], r["k_N"]) for r in prow})
            d.h(3, f"Table {t}: " + "; ".join(f"{f}, k_M = {a}, k_N = {b}" for f, a, b in settings))
            multi = len(settings) > 1
            header = (["k_M", "k_N"] if multi else []) + ["function", "stage", "method", "published", "ours",
                                                          "difference", "SE of ours", "run"]
            trows = []
            for r in prow:
                e = by_key.get(tuple(r[k] for k in TABLE_KEYS))
                se = "—" if not e or e.get("se") is None else f"{e['se']:.3f}"
                ours = ([_num(e["value"]), _num(e["value"] - r["value"], True), se, e["run"]] if e
                        else ["—", "", "", ""])
                trows.append(([r["k_M"], r["k_N"]] if multi else [])
                             + [r["function"], r["stage"], r["method"], f"{r['value']:.2f}", *ours])
            d.table(header, trows)
        if unmatched:
            d.h(3, "Table values that match no published number")
            d.table(["run", "entry", "reason"],
                    [[e.get("run", "") if isinstance(e, dict) else "",
                      "`" + json.dumps({k: v for k, v in e.items() if k != "run"} if isinstance(e, dict) else e) + "`",
                      why] for e, why in unmatched])

    for path, text in ((out, d.markdown()), (html_out, d.html("prodmaps reproduction report"))):
        with atomic_path(path) as tmp:
            tmp.write_text(text, encoding="utf-8")
    if copied is not None:
        copied += d.copied
    return out, html_out


# ------------------------------------------------------------------------------ publishing
def overridden_parameters(infos) -> dict:
    """``{run: {name: value}}``: parameters given on the command line (``-p``), from the manifests."""
    return {i.name: dict(i.manifest["overrides"]) for i in infos
            if isinstance(i.manifest.get("overrides"), dict) and i.manifest["overrides"]}


def _verdict_of(cell: str) -> str:
    """The verdict a report cell starts with (``"**does not hold** (paper no, ...)"`` -> ``"does not hold"``)."""
    text = str(cell).replace("**", "").split(" (paper", 1)[0].strip()
    return max((v for v in ledger.VERDICTS if text.startswith(v)), key=len, default="")


@dataclass
class KeptDataset:
    """A prepared dataset's verdict column and sections taken from an earlier (committed) report."""

    dataset: str
    commit: str
    column: dict  # {claim id: cell}
    blocks: list  # the dataset's ``##`` sections as _Doc blocks


def _split_cells(line: str) -> list[str]:
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line.strip()[1:-1])]


def _blocks_from_markdown(text: str) -> list:
    """Parse Markdown written by ``_Doc.markdown`` back into its blocks (so both files render it)."""
    blocks, lines, i = [], text.splitlines(), 0
    while i < len(lines):
        line = lines[i]
        if not line.strip():
            i += 1
        elif line.startswith("```"):
            j = i + 1
            while j < len(lines) and not lines[j].startswith("```"):
                j += 1
            blocks.append(("code", "\n".join(lines[i + 1:j])))
            i = j + 1
        elif line.startswith("#"):
            level = len(line) - len(line.lstrip("#"))
            blocks.append(("h", level, line[level:].strip()))
            i += 1
        elif line.startswith(("|", "- ")):  # a table or a list: the lines that start alike
            j = i
            while j < len(lines) and lines[j].startswith("|" if line[0] == "|" else "- "):
                j += 1
            if line[0] == "|":
                rows = [_split_cells(x) for x in lines[i:j] if not re.fullmatch(r"\|(---\|)+", x.strip())]
                blocks.append(("table", rows[0], rows[1:]))
            else:
                blocks.append(("ul", [x[2:] for x in lines[i:j]]))
            i = j
        else:
            m = re.fullmatch(r"!\[([^\]]*)\]\(([^)\s]+)\)", line.strip())
            blocks.append(("img", m.group(2), m.group(1)) if m else ("p", line))
            i += 1
    return blocks


def kept_dataset(report, dataset: str) -> KeptDataset | None:
    """The column and sections of ``dataset`` in an earlier report (``paper/REPORT.md``), or None."""
    report = Path(report)
    if not report.is_file():
        return None
    text = report.read_text(encoding="utf-8")
    name = DATASET_NAMES.get(dataset, dataset)
    sections = re.split(r"(?m)^(?=## )", text)
    mine = [sec for sec in sections if sec.startswith("## ") and (
        sec.splitlines()[0] == f"## On {name}" or sec.splitlines()[0].endswith(f" on {name}"))]
    if not mine:
        return None
    claims = next((sec for sec in sections if sec.startswith("## Claims of the paper")), "")
    table = [line for line in claims.splitlines() if line.startswith("|")]
    header = _split_cells(table[0]) if table else []
    column = {cells[0].strip("`"): cells[header.index(name)] for cells in map(_split_cells, table[2:])
              if name in header and len(cells) == len(header)}
    # the commit of the run the section came from: an earlier kept note's, else the report's own
    m = (re.search(rf"{re.escape(name)} was not rerun for this report.*?published at commit `([^`]+)`", text)
         or re.search(r"code at commit `([^`]+)`", text))
    return KeptDataset(dataset, m.group(1) if m else "unknown", column, _blocks_from_markdown("".join(mine)))


class PublishError(ValueError):
    """A results folder that is not a complete paper run (the message says what is partial)."""


def partial_problems(results_dir, registry=None) -> list[str]:
    """What keeps ``results_dir`` from being a complete paper-profile run of every registered notebook."""
    results_dir = Path(results_dir)
    runs = load_registry(registry)
    infos = {i.name: i for i in collect_runs(results_dir, registry)}
    failed = [n for n in runs if infos[n].status == "failed"]
    missing = [n for n in runs if not infos[n].doc and n not in failed]
    failed += [n for n in runs if infos[n].doc and infos[n].status not in ("ok", "failed")]
    profiles = sorted({f"{n} ({infos[n].manifest['profile']})" for n in runs
                       if infos[n].manifest.get("profile") not in (None, "paper")})
    over = overridden_parameters(infos.values())
    return [p for p in (
        missing and f"{len(missing)} of {len(runs)} registered runs have no results: " + ", ".join(missing),
        failed and "failed: " + ", ".join(failed),
        profiles and "not the paper profile: " + ", ".join(profiles),
        over and "parameters overridden: " + "; ".join(
            f"{r} " + ", ".join(f"{k}={json.dumps(v)}" for k, v in ov.items()) for r, ov in over.items())) if p]


def publish(results_dir=None, dest=None, *, registry=None, allow_partial: bool = False, published=None):
    """Regenerate the committed report (``paper/REPORT.md`` and ``.html``) from a paper run.

    Refuses (:class:`PublishError`) a results folder that is not a complete, failure-free paper
    run at the registry's parameters, unless ``allow_partial``: then the report says, under its
    title, what is partial. The figures it shows are copied into ``paper/report_figures/`` (stale
    ones removed) and its notebook links point at the committed notebooks, so every local link
    resolves in a fresh clone. A prepared dataset (``<results_dir>-faust``) is reported from its
    folder when present; otherwise its column and sections are kept from the current committed
    report, with its figures. Returns ``(md_path, html_path, problems)``.
    """
    root = project_root(registry)
    results_dir = Path(results_dir) if results_dir is not None else root / "results" / "paper"
    dest = Path(dest) if dest is not None else root / "paper" / "REPORT.md"
    if not results_dir.is_dir():
        raise FileNotFoundError(f"{results_dir}: no such results folder; run `make reproduce` first")
    problems = partial_problems(results_dir, registry)
    if problems and not allow_partial:
        raise PublishError(f"refusing to publish {results_dir}, a partial paper run: " + "; ".join(problems)
                           + ". Rerun those (make reproduce), or publish anyway with --allow-partial "
                           "(make publish ALLOW_PARTIAL=1): the report then says what is partial.")
    notes = ["**Partial publication:** " + "; ".join(problems) + "."] if problems else []
    fresh = other_datasets(results_dir)
    kept = {ds: k for ds in DATASET_NAMES if ds not in fresh and ds != "anny_humans" and (k := kept_dataset(dest, ds))}
    notes += [f"{DATASET_NAMES[ds]} was not rerun for this report (no `{results_dir.name}-{ds}` folder): its "
              f"verdict column and sections are kept from the report published at commit `{k.commit}`."
              for ds, k in kept.items()]
    notebooks = {n: r.notebook for n, r in load_registry(registry).items()}
    copied: list = []
    figures = dest.parent.resolve() / "report_figures"
    md, html_path = build_report(results_dir, dest, registry=registry, published=published, copy_figures=True,
                                 notebooks=notebooks, kept=kept, notes=notes, generated_by="prodmaps publish",
                                 copied=copied, machine_paths=False)
    keep = set(copied)
    for f in sorted(figures.rglob("*"), reverse=True) if figures.is_dir() else []:
        rel = f.relative_to(figures).parts
        if rel and rel[0] in kept:
            continue
        if f.is_file() and f.resolve() not in keep:
            f.unlink()
        elif f.is_dir() and not any(f.iterdir()):
            f.rmdir()
    return md, html_path, problems
