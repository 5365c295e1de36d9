"""The reproduction report: ``paper/REPORT.md`` and ``paper/REPORT.html`` from a results folder.

``build_report(results_dir)`` reads every run folder ``results_dir/<run>/`` written by
``prodmaps reproduce`` (``results.json``, PNGs, ``manifest.json``) and writes a report with,
per run: what it reproduces, status and run time, every figure (relative image links), the
parameters, the package versions and the data it ran on; and per paper table: the published
value, ours and the difference.

How a notebook reports table values: :mod:`prodmaps.experiments.published`.
"""

from __future__ import annotations

import datetime as _dt
import html
import json
import os
import platform
import re
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from ..experiments.published import PUBLISHED_CSV, TABLE_KEYS, load_published, match_entries
from .registry import load_registry, project_root

__all__ = ["collect_runs", "build_report"]

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


def _read_json(p: Path) -> dict:
    try:
        return json.loads(p.read_text())
    except (OSError, ValueError):
        return {}


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
        info.doc = _read_json(folder / "results.json")
        info.manifest = _read_json(folder / "manifest.json")
        if info.manifest:
            info.status = info.manifest.get("status", "?")
            info.seconds = info.manifest.get("seconds")
        elif info.doc:
            info.status = "ok"
        if folder.is_dir():
            info.figures = sorted(folder.glob("*.png"))
        infos.append(info)
    return infos


_MAX_NUMBERS = 40


def _flatten(obj, prefix=""):
    from .diffing import flatten

    return flatten(obj, prefix) if obj else {}


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

    def h(self, level, text):
        self.blocks.append(("h", level, text))

    def p(self, text):
        self.blocks.append(("p", text))

    def table(self, header, rows):
        self.blocks.append(("table", header, rows))

    def img(self, src, alt):
        self.blocks.append(("img", src, alt))

    def code(self, text):
        self.blocks.append(("code", text))

    def ul(self, items):
        self.blocks.append(("ul", items))

    def markdown(self) -> str:
        out = []
        for b in self.blocks:
            if b[0] == "h":
                out.append("#" * b[1] + " " + b[2])
            elif b[0] == "p":
                out.append(b[1])
            elif b[0] == "table":
                out.append("| " + " | ".join(b[1]) + " |")
                out.append("|" + "---|" * len(b[1]))
                out += ["| " + " | ".join(str(c).replace("|", "\\|") for c in r) + " |" for r in b[2]]
            elif b[0] == "img":
                out.append(f"![{b[2]}]({b[1]})")
            elif b[0] == "code":
                out.append("```\n" + b[1].rstrip() + "\n```")
            elif b[0] == "ul":
                out += [f"- {i}" for i in b[1]]
            out.append("")
        return "\n".join(out).rstrip() + "\n"

    @staticmethod
    def _inline(text: str) -> str:
        s = html.escape(str(text))
        s = re.sub(r"`([^`]+)`", r"<code>\1</code>", s)
        return re.sub(r"\*\*([^*]+)\*\*", r"<b>\1</b>", s)

    def html(self, title: str) -> str:
        out = ["<!DOCTYPE html>", "<html><head><meta charset=\"utf-8\">", f"<title>{html.escape(title)}</title>",
               "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;padding:0 1em}"
               "table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ccc;padding:2px 8px;"
               "text-align:right}th{background:#eee}td:first-child,th:first-child{text-align:left}"
               "img{max-width:100%;border:1px solid #ddd;margin:.3em 0}pre{background:#f6f6f6;padding:.5em;"
               "overflow-x:auto}.bad{color:#b00}</style></head><body>"]
        for b in self.blocks:
            if b[0] == "h":
                out.append(f"<h{b[1]}>{self._inline(b[2])}</h{b[1]}>")
            elif b[0] == "p":
                out.append(f"<p>{self._inline(b[1])}</p>")
            elif b[0] == "table":
                out.append("<table><tr>" + "".join(f"<th>{self._inline(c)}</th>" for c in b[1]) + "</tr>")
                out += ["<tr>" + "".join(f"<td>{self._inline(c)}</td>" for c in r) + "</tr>" for r in b[2]]
                out.append("</table>")
            elif b[0] == "img":
                out.append(f"<p><img src=\"{html.escape(b[1])}\" alt=\"{html.escape(b[2])}\"></p>")
            elif b[0] == "code":
                out.append(f"<pre>{html.escape(b[1])}</pre>")
            elif b[0] == "ul":
                out.append("<ul>" + "".join(f"<li>{self._inline(i)}</li>" for i in b[1]) + "</ul>")
        out.append("</body></html>")
        return "\n".join(out) + "\n"


def _git_commit() -> str:
    try:
        r = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=project_root(), capture_output=True,
                           text=True, timeout=10)
        return r.stdout.strip() if r.returncode == 0 else "unknown"
    except (OSError, subprocess.TimeoutExpired):
        return "unknown"


def _installed_versions() -> list[str]:
    from importlib import metadata

    out = []
    for p in _PACKAGES:
        try:
            out.append(f"{p} {metadata.version(p)}")
        except metadata.PackageNotFoundError:
            pass
    return out


def _rel(path: Path, start: Path) -> str:
    return Path(os.path.relpath(Path(path).resolve(), Path(start).resolve())).as_posix()


def _show(path: Path) -> str:
    """Path relative to the repository when inside it, else absolute."""
    try:
        return Path(path).resolve().relative_to(project_root()).as_posix()
    except ValueError:
        return str(path)


def _num(v, signed=False) -> str:
    return "" if v is None else (f"{v:+.3f}" if signed else f"{v:.3f}")


def build_report(results_dir, out=None, *, registry=None, published=None, html_out=None,
                 copy_figures: bool = False):
    """Write the Markdown and HTML reports for ``results_dir`` (e.g. ``results/paper``).

    ``out`` defaults to ``paper/REPORT.md``; the HTML goes beside it (``.html``). Image links
    are relative to the report's folder. ``copy_figures=True`` copies the PNGs into
    ``<report folder>/report_figures/<run>/`` and links those instead (so a committed report
    shows its figures although ``results/`` is not committed). Returns ``(md_path, html_path)``.
    """
    results_dir = Path(results_dir).resolve()
    out = Path(out) if out is not None else project_root(registry) / "paper" / "REPORT.md"
    out = out.resolve()
    html_out = Path(html_out) if html_out is not None else out.with_suffix(".html")
    base = out.parent
    infos = collect_runs(results_dir, registry)
    pub_path = Path(published) if published is not None else PUBLISHED_CSV
    published_rows = load_published(pub_path) if pub_path.is_file() else []
    entries = [e for i in infos for e in _entries_of(i)]
    matches, unmatched = match_entries(entries, published_rows)

    d = _Doc()
    d.h(1, "Reproduction report: Improved Functional Mappings via Product Preservation")
    d.p("Nogneng, Melzi, Rodolà, Castellani, Bronstein, Ovsjanikov, Eurographics 2018. "
        f"Generated by `prodmaps report` from `{_show(results_dir)}` on "
        f"{_dt.datetime.now(_dt.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}, "
        f"code at commit `{_git_commit()}`.")
    d.p(f"Environment: Python {platform.python_version()} on {platform.system()} {platform.machine()}; "
        + ", ".join(_installed_versions()) + ".")

    d.h(2, "Runs")
    rows = []
    for i in infos:
        n_tab = len(_entries_of(i))
        rows.append([f"`{i.name}`", i.reproduces, i.status,
                     "" if i.seconds is None else f"{i.seconds:.1f}", len(i.figures), n_tab or ""])
    d.table(["run", "reproduces", "status", "time (s)", "figures", "table values"], rows)
    failed = [i.name for i in infos if i.status not in ("ok",)]
    if failed:
        d.p("**Not reproduced (failed or not run):** " + ", ".join(f"`{n}`" for n in failed)
            + ". A failed run keeps `error.txt` and `executed.ipynb` in its folder.")

    if published_rows:
        d.h(2, "Tables: published vs ours")
        d.p("Relative errors (the paper's area-weighted normalised L2). Difference = ours − published; "
            "the paper prints two decimals, so |difference| ≤ 0.005 is as published.")
        by_key = {tuple(r[k] for k in TABLE_KEYS): e for r, e in matches}
        for t in sorted({r["table"] for r in published_rows}, key=int):
            prow = [r for r in published_rows if r["table"] == t]
            got = [(r, by_key.get(tuple(r[k] for k in TABLE_KEYS))) for r in prow]
            n_got = sum(e is not None for _, e in got)
            settings = sorted({(r["fmap"], r["k_M"], r["k_N"]) for r in prow})
            d.h(3, f"Table {t}")
            desc = "; ".join(f"{f}, k_M = {a}, k_N = {b}" for f, a, b in settings)
            diffs = [abs(e["value"] - r["value"]) for r, e in got if e is not None]
            stat = (f" Mean |difference| {sum(diffs) / len(diffs):.3f}, max {max(diffs):.3f}; "
                    f"{sum(x <= 0.005 for x in diffs)} of {len(diffs)} as published.") if diffs else ""
            d.p(f"{desc}. {n_got} of {len(prow)} published values reproduced.{stat}")
            multi = len(settings) > 1
            header = (["k_M", "k_N"] if multi else []) + ["function", "stage", "method", "published", "ours",
                                                          "difference", "run"]
            trows = []
            for r, e in got:
                trows.append(([r["k_M"], r["k_N"]] if multi else []) + [
                    r["function"], r["stage"], r["method"], f"{r['value']:.2f}",
                    _num(e["value"]) if e else "—", _num(e["value"] - r["value"], True) if e else "",
                    e["run"] if e else ""])
            d.table(header, trows)
    if unmatched:
        d.h(3, "Table values that match no published number")
        d.table(["run", "entry", "reason"],
                [[e.get("run", "") if isinstance(e, dict) else "",
                  "`" + json.dumps({k: v for k, v in e.items() if k != "run"} if isinstance(e, dict) else e) + "`",
                  why] for e, why in unmatched])

    d.h(2, "Figures and runs")
    for i in infos:
        d.h(3, f"{i.name}" + (f" — {i.reproduces}" if i.reproduces else ""))
        if i.title:
            d.p(i.title)
        if i.status == "missing":
            d.p(f"No outputs in `{_show(i.folder)}`: run `prodmaps reproduce --only {i.name}`.")
            continue
        line = f"Status **{i.status}**"
        if i.seconds is not None:
            line += f", {i.seconds:.1f} s"
        if i.manifest.get("finished"):
            line += f", finished {i.manifest['finished']}"
        d.p(line + f"; outputs in `{_rel(i.folder, base)}`.")
        if i.status == "failed":
            err = (i.folder / "error.txt")
            if err.is_file():
                d.code("\n".join(err.read_text().splitlines()[:15]))
        for fig in i.figures:
            d.p(f"`{fig.name}`")
            if copy_figures:
                dest = base / "report_figures" / i.name / fig.name
                dest.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(fig, dest)
                fig = dest
            d.img(_rel(fig, base), f"{i.name} {fig.stem}")
        res = i.doc.get("results", {})
        nums = [(k, v) for k, v in _flatten(res).items()
                if not k.startswith("table.") and isinstance(v, (int, float)) and not isinstance(v, bool)]
        if nums:
            shown = nums[:_MAX_NUMBERS]
            d.p("Numbers" + (f" (first {_MAX_NUMBERS} of {len(nums)}; all in `results.json`)"
                             if len(nums) > _MAX_NUMBERS else "") + ":")
            d.table(["result", "value"], [[f"`{k}`", f"{v:.6g}" if isinstance(v, float) else v] for k, v in shown])
        params = i.doc.get("parameters", i.manifest.get("inputs", {}).get("parameters", {}))
        if params:
            d.p("Parameters:")
            d.table(["parameter", "value"],
                    [[f"`{k}`", f"`{json.dumps(v, default=str)}`"] for k, v in sorted(params.items())])
        vers = dict(i.doc.get("versions", {}))
        if i.doc.get("prodmaps_version"):
            vers["prodmaps"] = i.doc["prodmaps_version"]
        if i.manifest.get("python"):
            vers["python"] = i.manifest["python"]
        if vers:
            d.p("Versions: " + ", ".join(f"{k} {v}" for k, v in sorted(vers.items())) + ".")
        ds = params.get("dataset") if isinstance(params, dict) else None
        fp = i.manifest.get("inputs", {}).get("data")
        if fp == "none" and not ds:
            d.p("Data: none (synthetic domain, no dataset files).")
        elif ds or fp:
            d.p(f"Data: `{ds or '(notebook default)'}`" + (f", fingerprint `{fp[:40]}`" if fp else "")
                + f" (hash of `data/{ds or '<dataset>'}/SHA256SUMS`; provenance in `data/{ds or '<dataset>'}/SOURCE.md`).")

    out.parent.mkdir(parents=True, exist_ok=True)
    html_out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(d.markdown(), encoding="utf-8")
    os.replace(tmp, out)
    tmp = html_out.with_name(html_out.name + ".tmp")
    tmp.write_text(d.html("prodmaps reproduction report"), encoding="utf-8")
    os.replace(tmp, html_out)
    return out, html_out
