"""Publishing: a complete paper run into the committed report, ``paper/REPORT.md`` and ``.html``.

:func:`publish` builds the report (:mod:`.report`) of a results folder with the settings of a
committed report: the figures it shows copied into ``paper/report_figures/`` (stale ones
removed), links to the committed notebooks instead of executed ones, no path of this machine, and
a caption for every figure (``paper/report_text/captions.toml``; a run without one is refused).
It refuses (:class:`PublishError`) a results folder that is not a complete, failure-free run of
the paper profile at the registry's parameters (:func:`partial_problems`), unless
``allow_partial``: the report then says under its title what is partial.

Other datasets. A prepared dataset's runs beside the results (``<results>-<dataset>``, e.g.
``results/paper-faust``) are reported from their folder, and their report data is stored beside
the committed report as ``paper/report_data/<dataset>.json``
(:meth:`.report_data.DatasetReport.save`, figures under ``report_figures/<dataset>/``). A dataset
stored there but not rerun this time keeps its verdict column, its appendix and its gallery panels
from that JSON (an older format is migrated on load), with a note naming the commit of the
publication it came from; its figures stay. Nothing is read back from the committed Markdown.
"""

from __future__ import annotations

import json
from pathlib import Path

from .. import datasets
from .registry import load_registry, project_root
from .report import ReportSettings, build_document, copy_figures, read_inputs, write_document
from .report_data import DATA_FOLDER, DATASET_NAMES, DatasetReport, collect_runs, other_datasets, overridden_parameters

__all__ = ["PublishError", "partial_problems", "stored_datasets", "publish"]


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


def stored_datasets(report_folder, exclude=()) -> list[DatasetReport]:
    """The datasets whose report data is stored in ``report_folder/report_data/`` (registry order, then by name).

    ``exclude``: datasets not to load (those rerun this time).
    """
    folder = Path(report_folder) / DATA_FOLDER
    names = sorted(p.stem for p in folder.glob("*.json") if p.stem not in exclude) if folder.is_dir() else []
    order = [*datasets.names(), *DATASET_NAMES]
    names.sort(key=lambda n: (order.index(n) if n in order else len(order), n))
    return [DatasetReport.load(report_folder, n) for n in names]


def publish(results_dir=None, dest=None, *, registry=None, allow_partial: bool = False, published=None):
    """Regenerate the committed report (``paper/REPORT.md`` and ``.html``) from a paper run.

    ``results_dir`` defaults to ``results/paper`` of the project, ``dest`` to ``paper/REPORT.md``;
    ``published``: the published tables CSV (default: the package's). See the module doc for what
    is refused, copied and stored. Returns ``(md_path, html_path, problems)``.
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
    folder = dest.parent.resolve()
    fresh = other_datasets(results_dir)
    kept = stored_datasets(folder, exclude=fresh)
    notes = ["**Partial publication:** " + "; ".join(problems) + "."] if problems else []
    notes += [f"{k.name} was not rerun for this report (no `{results_dir.name}-{k.dataset}` folder): its "
              f"verdict column, appendix and figures are kept from the report published at commit `{k.commit}`."
              for k in kept]
    settings = ReportSettings(registry=registry, published=published, kept=tuple(kept), notes=tuple(notes),
                              notebooks={n: r.notebook for n, r in load_registry(registry).items()},
                              generated_by="prodmaps publish", machine_paths=False, copy_figures=True,
                              strict_captions=True)
    md, html_path = dest.resolve(), dest.resolve().with_suffix(".html")
    inputs = read_inputs(results_dir, settings, folder)
    keep = set(copy_figures(inputs, folder))
    write_document(build_document(inputs, settings, folder), md, html_path)
    for ds in inputs.datasets:
        ds.save(folder)
    figures = folder / "report_figures"
    for f in sorted(figures.rglob("*"), reverse=True) if figures.is_dir() else []:
        rel = f.relative_to(figures).parts
        if rel and rel[0] in {k.dataset for k in kept}:  # a carried-over dataset's figures stay
            continue
        if f.is_file() and f.resolve() not in keep:
            f.unlink()
        elif f.is_dir() and not any(f.iterdir()):
            f.rmdir()
    return md, html_path, problems
