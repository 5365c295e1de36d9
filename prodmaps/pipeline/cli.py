"""Command line: ``prodmaps reproduce | diff | report`` (also ``python -m prodmaps ...``).

Examples::

    prodmaps reproduce                                   # every run, paper profile, into results/
    prodmaps reproduce --profile smoke --jobs 2          # fast versions, two at a time
    prodmaps reproduce --only fig04 tab02 -p seed=3 --force
    prodmaps reproduce --dataset faust --out results_faust
    prodmaps reproduce --scheduler tcp://host:8786       # one task per run on a Dask cluster
    prodmaps reproduce --profile smoke --update-baselines   # refresh paper/baselines/smoke/
    prodmaps diff results/smoke/fig03 paper/baselines/smoke/fig03
    prodmaps diff results/smoke paper/baselines/smoke   # every run; a profile folder against one run folder: that run
    prodmaps report results/paper                        # results/paper/REPORT.md and .html
    prodmaps publish                                     # results/paper -> the committed paper/REPORT.md
    prodmaps claims results/paper                        # the verdicts of the claims ledger
    prodmaps --version

Exit status: 0 on success; 1 if a run failed or a diff found drift; 2 for usage errors.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from .. import __version__, datasets
from ..experiments.shared import claims
from ..experiments.shared.parallel import default_workers
from . import baselines, execute, registry
from .diffing import DEFAULT_PNG_THRESHOLD, diff_runs
from .publishing import publish
from .report import ReportSettings, build_report

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    """The ``prodmaps`` command-line parser, one subcommand per action."""
    p = argparse.ArgumentParser(prog="prodmaps", description="Reproduce the paper's figures and tables.")
    p.add_argument("--version", action="version", version=f"prodmaps {_version()}")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("reproduce", help="run the registered notebooks (resumable, parallel)",
                       description="Run the notebooks of paper/runs.toml with papermill. Unchanged runs "
                                   "whose outputs exist are skipped; failures are isolated and summarised.")
    r.add_argument("--only", nargs="+", action="extend", metavar="RUN",
                   help="run only these registry entries (repeatable: every --only adds runs)")
    r.add_argument("--profile", choices=("smoke", "paper"), default="paper",
                   help="smoke: small and fast (CI); paper: the paper's sizes (default)")
    r.add_argument("--dataset", help="set the notebooks' `dataset` parameter (e.g. anny_humans, faust)")
    r.add_argument("-p", "--param", action="append", default=[], metavar="KEY=VALUE",
                   help="override a notebook parameter; VALUE is read as JSON/TOML, else a string (repeatable)")
    r.add_argument("--jobs", "-j", type=int, default=1, help="notebooks run at once in a local process pool")
    r.add_argument("--out", default="results", help="output root; runs go to OUT/<profile>/<run>/ (default results/)")
    r.add_argument("--force", action="store_true", help="rerun even if inputs are unchanged")
    r.add_argument("--scheduler", metavar="ADDRESS", help="Dask distributed scheduler address (needs prodmaps[dask])")
    r.add_argument("--update-baselines", action="store_true",
                   help="copy results.json and PNGs of the runs into paper/baselines/<profile>/<run>/ (smoke only)")
    r.add_argument("--registry", help="run registry file (default $PRODMAPS_RUNS or paper/runs.toml)")
    r.add_argument("--timeout", type=_positive_seconds, default=None,
                   help="per-cell timeout in seconds (> 0; rounded up to whole seconds)")
    r.add_argument("--kernel", default="python3", help="Jupyter kernel name (default python3)")
    r.add_argument("--report", metavar="PATH", help="where to write the report (default: OUT/<profile>/REPORT.md, "
                   "beside the results; the committed paper/REPORT.md changes only by `prodmaps publish`)")
    r.add_argument("--no-report", action="store_true", help="do not write the report")
    r.add_argument("--copy-figures", action="store_true",
                   help="copy the PNGs next to the report (report_figures/) instead of linking into OUT")
    r.add_argument("--no-progress", action="store_true", help="plain lines instead of a progress bar")
    r.add_argument("--list", action="store_true", help="list the registered runs and exit")

    d = sub.add_parser("diff", help="compare a run folder with a baseline folder",
                       description="Compare results.json (per-key tolerances) and PNGs (pixel RMS).")
    d.add_argument("run_dir")
    d.add_argument("baseline_dir")
    d.add_argument("--run", help="registry entry whose [tolerances] apply (default: the baseline folder's name)")
    d.add_argument("--registry", help="run registry file")
    d.add_argument("--png-threshold", type=_png_threshold, default=None,
                   help="pixel RMS threshold (0-255, default 2.0)")
    d.add_argument("--diff-dir", help="where side-by-side images go (default RUN_DIR/diff)")

    c = sub.add_parser("claims", help="print the verdicts of the claims ledger on a results folder",
                       description="Judge every claim of prodmaps/experiments/claims.toml on the runs in a "
                                   "results folder (e.g. results/paper) and print the table.")
    c.add_argument("results_dir", nargs="?", default="results/paper", help="e.g. results/paper (default)")
    c.add_argument("--json", action="store_true", help="print the verdicts as JSON")

    rp = sub.add_parser("report", help="write RESULTS_DIR/REPORT.md and REPORT.html from a results folder")
    rp.add_argument("results_dir", nargs="?", default="results/paper", help="e.g. results/paper (default)")
    rp.add_argument("--out", help="Markdown path (default: RESULTS_DIR/REPORT.md; the committed paper/REPORT.md "
                    "is written only by `prodmaps publish`); HTML goes beside it")
    rp.add_argument("--registry", help="run registry file")
    rp.add_argument("--published", help="published tables CSV (default: the one shipped with the package)")
    rp.add_argument("--copy-figures", action="store_true",
                    help="copy the PNGs into <report folder>/report_figures/ and link those")
    pb = sub.add_parser("publish", help="regenerate the committed paper/REPORT.md from a complete paper run",
                        description="Write paper/REPORT.md and .html from RESULTS_DIR (default results/paper), "
                                    "copy the figures it shows into paper/report_figures/ and link the committed "
                                    "notebooks, so every local link resolves in a fresh clone. Refuses a partial "
                                    "run (missing, failed, other profile, overridden parameters) unless "
                                    "--allow-partial. A prepared dataset's runs (RESULTS_DIR-faust) are reported "
                                    "when present; otherwise its column and sections are kept from the committed "
                                    "report.")
    pb.add_argument("results_dir", nargs="?", default=None, help="default: results/paper of the project")
    pb.add_argument("--allow-partial", action="store_true", help="publish anyway; the report says what is partial")
    pb.add_argument("--registry", help="run registry file")
    pb.add_argument("--published", help="published tables CSV (default: the one shipped with the package)")
    return p


def _version() -> str:
    return execute.package_versions(["prodmaps"]).get("prodmaps", __version__)  # a source tree: not installed


def _positive_seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds") from None
    if not v > 0 or v != v or v == float("inf"):
        raise argparse.ArgumentTypeError(f"{text!r}: the per-cell timeout must be a positive number of seconds")
    return v


def _png_threshold(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0 <= v <= 255:  # also refuses nan
        raise argparse.ArgumentTypeError(f"{text!r}: the pixel RMS threshold must be a number in [0, 255]")
    return v


def _check_dataset(name: str) -> None:
    """Refuse an unknown or unprepared dataset before anything runs (and before any folder is made)."""
    if name not in datasets.names():
        raise ValueError(f"unknown dataset {name!r}; registered datasets: {', '.join(datasets.names())}")
    if name not in datasets.prepared():
        raise ValueError(f"dataset {name!r} is not prepared under {datasets.data_root()}: prepare it with "
                         f"`python -m prodmaps.prepare {name} --archive ...` (or set PRODMAPS_DATA)")


def _cmd_reproduce(a) -> int:
    if a.list:
        root = registry.project_root(a.registry)
        for name, run in registry.load_registry(a.registry).items():
            nb = run.notebook.relative_to(root) if root in run.notebook.parents else run.notebook
            print(f"{name:<28} {run.reproduces:<14} {nb}")
        return 0
    if a.jobs < 1:
        raise ValueError("--jobs must be >= 1")
    if a.update_baselines and a.profile != "smoke":
        raise ValueError("--update-baselines refreshes the smoke baselines: add --profile smoke")
    try:
        root = registry.project_root(a.registry)
    except ValueError:  # no project (RegistryError): nothing to keep relative to
        root = None
    execute.require_modules("prodmaps reproduce")  # a library-only install: name the extra, before anything runs
    overrides = execute.absolute_param_files(registry.parse_params(a.param), root)
    default_workers()  # a bad PRODMAPS_WORKERS is refused here, not in every notebook that computes pairs
    if a.dataset is not None:
        _check_dataset(a.dataset)
    if a.report and not a.no_report:
        root = registry.project_root(a.registry)
        if Path(a.report).resolve() == (root / "paper" / "REPORT.md").resolve():
            raise ValueError("the committed paper/REPORT.md is written only by `prodmaps publish` (make publish), "
                             "which refuses partial runs; drop --report to write OUT/<profile>/REPORT.md")
    t0 = time.perf_counter()
    results = execute.reproduce(registry=a.registry, only=a.only, profile=a.profile, dataset=a.dataset,
                           overrides=overrides, out=a.out, jobs=a.jobs, force=a.force,
                           scheduler=a.scheduler, kernel_name=a.kernel, timeout=a.timeout,
                           progress=not a.no_progress)
    wall = time.perf_counter() - t0
    print(execute.summary(results))
    out_root = execute.profile_folder(a.out, a.profile, a.dataset)
    print(f"wall time {wall:.1f} s; outputs in {out_root}")
    if a.update_baselines:
        dest = baselines.baselines_dir(a.registry, a.profile)
        done = baselines.update_baselines(results, dest)
        print(f"baselines updated for {len(done)} run(s) in {dest}: {' '.join(done)}")
    if not a.no_report:
        main_root = execute.profile_folder(a.out, a.profile)  # the embedded data's runs; other datasets beside
        if not main_root.is_dir():
            main_root = out_root
        md = Path(a.report) if a.report else main_root / "REPORT.md"
        md, html = build_report(main_root, md, ReportSettings(registry=a.registry, copy_figures=a.copy_figures))
        print(f"report: {md} and {html}")
        if a.profile == "paper":
            print("the committed paper/REPORT.md is unchanged; publish this run with `make publish` "
                  "(prodmaps publish)")
    return 1 if any(r.status == "failed" for r in results) else 0


def _is_run_folder(folder: Path) -> bool:
    return (folder / "results.json").is_file()


def _is_profile_folder(folder: Path) -> bool:
    return folder.is_dir() and not _is_run_folder(folder) and any(folder.glob("*/results.json"))


def _pair_folders(new: Path, base: Path, run: str | None) -> tuple[Path, Path]:
    """One run's folders: a profile folder (``results/smoke``) given against a run folder, or with ``--run``.

    ``results/smoke paper/baselines/smoke/fig02`` compares ``results/smoke/fig02`` with that baseline,
    ``results/smoke/fig02 paper/baselines/smoke`` with ``paper/baselines/smoke/fig02``; two profile
    folders and ``--run NAME`` compare that run of each. Anything else is returned as given.
    """
    def pick(profile: Path, name: str, side: str) -> Path:
        if not _is_run_folder(profile / name):
            have = sorted(p.parent.name for p in profile.glob("*/results.json"))
            raise FileNotFoundError(f"{profile} is a profile folder without the run {name!r} ({side}; it holds "
                                    f"{', '.join(have)}): pass two run folders (e.g. {profile / have[0]}), or two "
                                    "profile folders to compare every run")
        return profile / name

    if _is_profile_folder(new) and (_is_run_folder(base) or (run and _is_profile_folder(base))):
        name = run or base.resolve().name
        return pick(new, name, "the results"), base if _is_run_folder(base) else pick(base, name, "the baselines")
    if _is_run_folder(new) and _is_profile_folder(base):
        return new, pick(base, run or new.resolve().name, "the baselines")
    return new, base


def _cmd_diff(a) -> int:
    try:
        runs = registry.load_registry(a.registry)
    except registry.RegistryError as exc:
        if a.registry or os.environ.get(registry.RUNS_ENV):  # a registry the user named must be read, not skipped
            raise
        print(f"prodmaps diff: note: {exc}; comparing with the default tolerances", file=sys.stderr)
        runs = {}
    new, base = _pair_folders(Path(a.run_dir), Path(a.baseline_dir), a.run)
    if (new, base) != (Path(a.run_dir), Path(a.baseline_dir)):
        print(f"prodmaps diff: comparing the run folder {new} with {base}", file=sys.stderr)
    thr = DEFAULT_PNG_THRESHOLD if a.png_threshold is None else a.png_threshold
    if not (new / "results.json").is_file() and new.is_dir() and not a.run:  # two profile folders
        names = sorted(p.parent.name for p in new.glob("*/results.json"))
        if not names:
            raise FileNotFoundError(f"{new}: neither a run folder (results.json) nor a profile folder "
                                    "(<run>/results.json)")
        missing = [n for n in names if not (base / n / "results.json").is_file()]
        absent = sorted(p.parent.name for p in base.glob("*/results.json") if p.parent.name not in names)
        ok = not missing and not absent
        for n in names:
            if n not in missing:
                rep = diff_runs(new / n, base / n, runs[n].tolerances if n in runs else {}, png_threshold=thr,
                                diff_dir=(Path(a.diff_dir) / n) if a.diff_dir else None)
                print(rep.to_markdown())
                ok &= rep.ok
        print(f"{len(names) - len(missing)} run(s) compared" + (f"; no baseline for {missing}" if missing else "")
              + (f"; no results in {new} for {absent} (in the baseline only; diff one run's folder to compare "
                 "that run alone)" if absent else ""))
        return 0 if ok else 1
    if new.name != base.resolve().name and not a.run and new.name in runs and base.resolve().name in runs:
        raise ValueError(f"refusing to diff run {new.name!r} against the baseline of another run "
                         f"{base.resolve().name!r}; pass --run NAME if that is what you mean")
    name = a.run or base.resolve().name
    if a.run and name not in runs:
        raise ValueError(f"run {a.run!r} is not in the registry")
    rep = diff_runs(new, base, runs[name].tolerances if name in runs else {}, png_threshold=thr,
                    diff_dir=a.diff_dir)
    print(rep.to_markdown())
    return 0 if rep.ok else 1


def _cmd_claims(a) -> int:
    _check_results_folder(Path(a.results_dir), {r for c in claims.load_ledger().values() for r in c.runs})
    verdicts = claims.evaluate_folder(a.results_dir)
    if a.json:
        print(json.dumps([v.to_dict() for v in verdicts], indent=1, default=str))
    else:
        print(claims.format_table(verdicts))
    return 0


def _check_results_folder(folder: Path, runs) -> None:
    """Refuse a folder holding no run of ``runs`` (a typo, or the ``--out`` root), naming the folder expected."""
    if not folder.is_dir():
        raise FileNotFoundError(f"{folder}: no such results folder; expected OUT/<profile>, e.g. results/paper")
    if not any((folder / r / "results.json").is_file() for r in runs):
        inner = [p.name for p in sorted(folder.iterdir()) if p.is_dir() and any((p / r / "results.json").is_file()
                                                                              for r in runs)]
        hint = (f"; it holds the profile folder(s) {inner}: pass {folder / inner[0]}" if inner
                else "; expected OUT/<profile> (e.g. results/paper) with one subfolder per run")
        raise FileNotFoundError(f"{folder}: no run results here (no <run>/results.json){hint}")


def _cmd_report(a) -> int:
    folder = Path(a.results_dir)
    _check_results_folder(folder, set(registry.load_registry(a.registry)))
    out = a.out if a.out is not None else folder / "REPORT.md"  # beside the results; paper/: `publish`
    md, html = build_report(a.results_dir, out, ReportSettings(registry=a.registry, published=a.published,
                                                             copy_figures=a.copy_figures))
    print(f"report: {md} and {html}")
    return 0


def _cmd_publish(a) -> int:
    md, html, problems = publish(a.results_dir, registry=a.registry, allow_partial=a.allow_partial,
                                 published=a.published)
    print(f"published: {md} and {html} (figures in {md.parent / 'report_figures'})")
    for p in problems:
        print(f"partial: {p}")
    return 0


def main(argv=None) -> int:
    """Entry point of the ``prodmaps`` command; returns the exit status."""
    parser = build_parser()
    a = parser.parse_args(argv)
    try:
        return {"reproduce": _cmd_reproduce, "diff": _cmd_diff, "report": _cmd_report,
                "claims": _cmd_claims, "publish": _cmd_publish}[a.command](a)
    except ModuleNotFoundError as exc:  # an optional package of an extra (papermill, matplotlib, dask)
        print(f"prodmaps {a.command}: error: {execute.install_hint(exc)}", file=sys.stderr)
        return 2
    except (ValueError, FileNotFoundError) as exc:  # incl. RegistryError, ParameterError
        print(f"prodmaps {a.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
