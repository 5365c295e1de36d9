"""prodmaps.pipeline.report: the claims-first reproduction report from a synthetic results folder.

The results folder and the registry are written here, as ``prodmaps reproduce`` writes them
(``results.json``, ``manifest.json``, PNGs, ``executed.html``, ``error.txt``): no notebook runs.
The claims are the package's ledger; the runs below cover a few of its claims and leave the
others "not measured here".
"""

from __future__ import annotations

import html as html_lib
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from prodmaps.experiments.shared.claims import VERDICTS, evaluate_folder, load_ledger
from prodmaps.experiments.shared.published import load_published, published_values
from prodmaps.pipeline import execute
from prodmaps.pipeline.document import anchor, words
from prodmaps.pipeline.forking import EXPECTED as READING_ROWS
from prodmaps.pipeline.publishing import PublishError, publish
from prodmaps.pipeline.registry import load_registry
from prodmaps.pipeline.report import ReportSettings, build_document, build_report
from prodmaps.pipeline.report_data import (
    DATASET_NAMES,
    ClaimResult,
    DatasetReport,
    Figure,
    Study,
    TableSummary,
    collect_runs,
)

TEXT = Path(__file__).resolve().parents[2] / "paper" / "report_text"  # the paper's prose, read at build time
PUB1 = published_values("T1", "ground_truth")  # {(k_M, k_N, stage, method, function): value}
PUB2 = published_values("T2", "computed_NO17")
N_PUB = {t: sum(r["table"] == t for r in load_published()) for t in "123456"}

REGISTRY = """
[runs.fig02]
notebook = "notebooks/fig02.ipynb"
reproduces = "Figure 2"
title = "Fourier functions and products"
[runs.fig03]
notebook = "notebooks/fig03.ipynb"
reproduces = "Figure 3"
[runs.fig04]
notebook = "notebooks/fig04.ipynb"
reproduces = "Figure 4"
[runs.tab01]
notebook = "notebooks/tables.ipynb"
reproduces = "Table 1"
title = "Transfer errors, ground-truth maps, 9/9"
[runs.tab01.params.paper]
table = "T1"
[runs.study_truncation]
notebook = "notebooks/study.ipynb"
reproduces = "Study"
report = "prodmaps.experiments.study_truncation"
"""

FAMS = ("hk k", "HKS", "XYZ")


def _fam(*values):
    return dict(zip(FAMS, values))


STD_T = _fam(0.06, 0.5, 0.3)
STD_A = _fam(0.0, 0.54, 0.29)
APPROX = {"std": STD_A, "our_B": _fam(0.01, 0.6, 0.3), "our_B_gainrule": _fam(0.01, 0.6, 0.3),
          "our_default": _fam(0.0, 0.1, 0.1)}
TRANSFER = {  # subset -> method -> family -> error
    "": {"std": STD_T, "our_B": _fam(0.07, 0.2, 0.25), "our_B_gainrule": _fam(0.05, 0.3, 0.2),
         "our_default": _fam(0.06, 0.4, 0.28), "p2p_transfer": _fam(0.1, 0.6, 0.4)},
    "_intra": {"std": STD_T, "our_B": _fam(0.07, 0.6, 0.25), "our_B_gainrule": _fam(0.07, 0.4, 0.2),
               "our_default": _fam(0.06, 0.45, 0.29)},
    "_inter": {"std": STD_T, "our_B": _fam(0.07, 0.6, 0.35), "our_B_gainrule": _fam(0.07, 0.55, 0.29),
               "our_default": _fam(0.06, 0.5, 0.3)},
}
SPREAD = (0.99, 1.01, 1.0)  # three pairs around each mean: a small standard error


def _tab01_results() -> dict:
    """tab01's results: means and per-pair errors (all, intra, inter pairs), the table values, per-column times."""
    out = {}
    for sub, tr in TRANSFER.items():
        out[f"errors{sub}"] = {"k9_9": {"approx": APPROX, "transfer": tr}}
        out[f"errors_per_pair{sub}"] = {"k9_9": {st: {m: {f: [v * s for s in SPREAD] for f, v in fams.items()}
                                                      for m, fams in by_m.items()}
                                                 for st, by_m in (("approx", APPROX), ("transfer", tr))}}
    out["table"] = TABLE1
    out["seconds"] = {"per_column": {"k9_9": {"std": [0.01] * 3, "our_B": [0.02] * 3, "our_l1": [0.5] * 3}}}
    return out


# our table values: published + delta (|delta| = 0.010, 0.050, 0.100, 0.004: 2 within 0.02, mean 0.041, max 0.100)
DELTAS = {("transfer", "std", "HKS"): 0.010, ("transfer", "our_B", "HKS"): -0.050,
          ("transfer", "our_B", "XYZ"): 0.100, ("approx", "std", "Indicator"): -0.004}
TABLE1 = [
    {"table": 1, "fmap": "ground_truth", "k_M": 9, "k_N": 9, "function": "HKS", "stage": "transfer", "method": "std",
     "value": PUB1[(9, 9, "transfer", "std", "HKS")] + 0.010, "se": 0.004},
    # missed by 0.05, within draw noise: 0.05 <= 0.02 + 2·√2·0.012 = 0.054
    {"table": "T1", "function": "HKS", "stage": "transfer", "method": "our_B",
     "value": PUB1[(9, 9, "transfer", "our_B", "HKS")] - 0.050, "se": 0.012},
    # missed by 0.10, beyond it: 0.10 > 0.02 + 2·√2·0.01 = 0.048
    {"table": "Table 1", "function": "XYZ", "column": "transfer_our_B",
     "value": PUB1[(9, 9, "transfer", "our_B", "XYZ")] + 0.100, "se": 0.01},
    {"table": 1, "function": "Indicator", "stage": "approx", "method": "std",
     "value": PUB1[(9, 9, "approx", "std", "Indicator")] - 0.004},
    {"table": 1, "function": "Nope", "stage": "transfer", "method": "std", "value": 0.5},  # matches nothing
]

# what the ledger's rules give on these numbers: claim -> (verdict of "all", marks rule/default, intra/inter, evidence)
# tab01: hk k's standard approximation is 0 (in the span of the basis): a tie by construction, excluded; Approach B
# transfers HKS 0.2 vs 0.5 and XYZ 0.25 vs 0.3 (17 % > the 5 % margin, SE tiny): holds; on intra/inter pairs its HKS
# is worse (0.6 vs 0.5): does not hold; the point-map transfer is worse than std for every family: holds
NM = "not measured here"
EXPECTED = {
    "fig01.transfer_example": ("not reproducible", ("—", "—"), "", "The figure names no shapes"),
    "theorem1.np_hard": ("not empirical", ("—", "—"), "", "A complexity result"),
    "abstract.cost_map_fixed": ("not empirical", ("—", "—"), "", "A property of the construction"),
    "fig02.rank": ("holds", ("—", "—"), "", "rank 9 of the extended basis = 2k+1 = 9"),
    "fig02.dependency": ("does not hold", ("—", "—"), "", "residual 1.0e-03 with λ = -0.797885"),
    "fig02.higher_frequencies": ("holds", ("—", "—"), "", "products reach frequency 8, the basis 4"),
    "tab01.products_improve_transfer": (
        "holds", ("yes", "yes"), "intra: does not hold; inter: does not hold",
        "2 of 2 comparisons hold (paired over 3 units); excluded as ties by construction: hk k"),
    "tab01.all_approaches_improve.our_l1": (NM, ("—", "—"), f"intra: {NM}; inter: {NM}", "not measured"),
    "tab01.all_approaches_improve.our_l2": (NM, ("—", "—"), f"intra: {NM}; inter: {NM}", "not measured"),
    "tab01.all_approaches_improve.our_B": (
        "does not hold", ("no", "yes"), "intra: does not hold; inter: does not hold", "Approach B; 2 of 4 comparisons"),
    "tab01.l1_performs_similarly": (NM, ("—", "—"), "", "not measured"),
    "tab01.l1_more_time_consuming": (NM, ("—", "—"), "", "not measured"),
    "tab01.point_map_transfer_worse": ("holds", ("—", "—"), f"intra: {NM}; inter: {NM}", "3 of 3 comparisons hold"),
}
PRESENT_WITH_RESULTS = {"fig02", "tab01", "study_truncation", "extra_run"}


def _doc(results, **params):
    return {"parameters": {"profile": "paper", **params}, "results": results, "prodmaps_version": "0.1.0",
            "versions": {"numpy": "2", "scipy": "1"}}


def _manifest(name, status, seconds):
    return {"run": name, "profile": "paper", "status": status, "hash": "0" * 64, "inputs": {},
            "notebook": f"notebooks/{name}.ipynb", "seconds": seconds, "finished": "2026-01-01T00:00:00+00:00",
            "python": "3.11.0", "outputs": {}}


def _png(path: Path, seed: int):
    rng = np.random.default_rng(seed)
    Image.fromarray(rng.integers(0, 256, size=(6, 5, 3), dtype=np.uint8)).save(path)


def _run(results_dir: Path, name, doc=None, manifest=None, pngs=(), html=True, error=None):
    d = results_dir / name
    d.mkdir(parents=True)
    if doc is not None:
        (d / "results.json").write_text(json.dumps(doc, indent=2, sort_keys=True, ensure_ascii=False))
    if manifest is not None:
        (d / "manifest.json").write_text(json.dumps(manifest))
    for i, p in enumerate(pngs):
        _png(d / p, i)
    if html:
        (d / "executed.ipynb").write_text("{}")
        (d / "executed.html").write_text(f"<html><body>{name}</body></html>")
    if error is not None:
        (d / "error.txt").write_text(error)
    return d


def _report_text(res, root, reg) -> str:
    return build_report(res, root / "paper" / "REPORT.md", ReportSettings(registry=reg))[0].read_text(encoding="utf-8")


def make_project(root: Path) -> tuple[Path, Path]:
    """``root/paper/runs.toml``, the paper's report texts and ``root/results/<run>/``: (registry, results folder)."""
    (root / "paper").mkdir(parents=True)
    shutil.copytree(TEXT, root / "paper" / "report_text")
    reg = root / "paper" / "runs.toml"
    reg.write_text(REGISTRY)
    res = root / "results"
    res.mkdir()
    fig02 = {"rank_extended": 9, "rank_expected": 9, "dependency_lambda": -0.7978845608,
             "dependency_residual": 1e-3, "max_frequency": {"φ0": 0, "φ1": 1, "φ4": 4, "φ1⊙φ4": 5, "φ4⊙φ4": 8}}
    _run(res, "fig02", _doc(fig02), pngs=["fourier.png"])  # no manifest: status from results.json
    _run(res, "fig03", None, _manifest("fig03", "failed", 1.5),
         error="\n".join(f"error line {i}" for i in range(1, 21)))
    tab01 = _tab01_results()
    _run(res, "tab01", _doc(tab01, table="T1"), _manifest("tab01", "ok", 12.34), pngs=["table.png"])
    study = {
        "median_max_gain_of_kept_directions": {"gt_9_9": {"0.001": 123.44, "0.01": 5.62}},
        "summary": {"gt_9_9": {
            "HKS": {"chosen": {"gain": {"transfer": 0.2}, "paper": {"transfer": 0.3}, "oracle": {"transfer": 0.19}},
                    "std_transfer": 0.25},
            "XYZ": {"chosen": {"gain": {"transfer": 0.4}, "paper": {"transfer": 0.35}, "oracle": {"transfer": 0.3}},
                    "std_transfer": 0.5},
            "SHOT": {"chosen": {"gain": {"transfer": 0.4}}, "std_transfer": 0.5},  # incomplete: not counted
        }},
    }
    _run(res, "study_truncation", _doc(study), _manifest("study_truncation", "ok", 4.0), pngs=["gains.png"])
    # not registered; its table values sit at the top level of results.json
    _run(res, "extra_run", {"table": [{"table": 2, "function": "HKS", "stage": "transfer", "method": "std",
                                       "value": PUB2[(29, 39, "transfer", "std", "HKS")] + 0.03}]}, html=False)
    _run(res, ".hidden", _doc({}), html=False)  # hidden: ignored
    (res / "junk").mkdir()  # neither results.json nor manifest.json: ignored
    (res / "stray.png").write_bytes(b"")  # a file, not a run
    return reg, res


@pytest.fixture(scope="module")
def project(tmp_path_factory):
    root = tmp_path_factory.mktemp("proj")
    reg, res = make_project(root)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PRODMAPS_RUNS", str(reg))  # the report's own project-root look-ups find this project
        md, html = build_report(res, root / "paper" / "REPORT.md", ReportSettings(registry=reg))
    return {"root": root, "registry": reg, "results": res, "md": md, "html": html,
            "text": md.read_text(encoding="utf-8"), "html_text": html.read_text(encoding="utf-8")}


# ------------------------------------------------------------------------------ helpers
def _section(text: str, heading: str, level: int = 2) -> str:
    """The text of a ``## heading`` section (``level`` #'s), up to the next heading of that level or higher."""
    hashes = "#" * level
    m = re.search(rf"^{hashes} {re.escape(heading)}.*?$(.*?)(?=^#{{1,{level}}} |\Z)", text, flags=re.M | re.S)
    assert m, f"no section {heading!r}"
    return m.group(1)


def _cells(line: str) -> list[str]:
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line.strip()[1:-1])]


def _tables(section: str) -> list[list[list[str]]]:
    """Markdown tables of a section: header row first, without the ``|---|`` line."""
    out, cur = [], None
    for line in section.splitlines():
        if line.startswith("|"):
            if cur is None:
                cur = []
                out.append(cur)
            if not re.fullmatch(r"\|(---\|)+", line.strip()):
                cur.append(_cells(line))
        else:
            cur = None
    return out


CLAIMS = "Claims of the paper, judged on each dataset"


def _claim_rows(text: str, datasets=("embedded humans",)) -> dict[str, dict]:
    """The main claims table: one verdict column per dataset."""
    (table,) = _tables(_section(text, CLAIMS))
    header, rows = table[0], table[1:]
    assert header == ["claim", "where", "the paper's words", *datasets, "notebook"]
    out = {}
    for r in rows:
        assert len(r) == len(header), r
        cid = r[0].strip("`")
        assert cid not in out, f"claim {cid} listed twice"
        out[cid] = dict(zip(header, r))
    return out


APPENDIX_CLAIMS = ["claim", "verdict", "rule", "default", "intra / inter", "other readings", "paired comparison",
                   "margin", "left out", "evidence"]


def _appendix_claims(text: str, name: str = "embedded humans") -> dict[str, dict]:
    """A dataset appendix's claims table: verdict, settings, pair kinds, evidence."""
    (table,) = _tables(_section(text, f"Claims on {name}", 3))
    assert table[0] == APPENDIX_CLAIMS
    return {r[0].strip("`"): dict(zip(APPENDIX_CLAIMS, r)) for r in table[1:]}


def _summary_counts(text: str) -> dict:
    """The summary's verdict table: ``{dataset: {verdict: n}}``."""
    (table,) = _tables(_section(text, "Summary"))[:1]
    header = table[0]
    return {ds: {r[0]: int(r[i]) for r in table[1:]} for i, ds in enumerate(header) if i}


def _paragraphs(text: str) -> list[str]:
    """The paragraphs of a Markdown text: blank-line separated chunks that are not tables, headings, images or code."""
    chunks = [c.strip() for c in re.split(r"\n\s*\n", re.sub(r"```.*?```", "", text, flags=re.S))]
    return [c for c in chunks if c and not c.startswith(("|", "#", "![", "- "))]


# ------------------------------------------------------------------------------ collect_runs
def test_collect_runs_registry_order_then_other_folders(project):
    infos = collect_runs(project["results"], project["registry"])
    assert [i.name for i in infos] == ["fig02", "fig03", "fig04", "tab01", "study_truncation", "extra_run"]
    by = {i.name: i for i in infos}
    assert (by["fig02"].status, by["fig02"].seconds) == ("ok", None)  # results.json without manifest
    assert (by["fig03"].status, by["fig03"].seconds) == ("failed", 1.5)
    assert (by["fig04"].status, by["fig04"].doc, by["fig04"].figures) == ("missing", {}, [])
    assert (by["tab01"].status, by["tab01"].seconds) == ("ok", 12.34)
    assert (by["extra_run"].status, by["extra_run"].reproduces) == ("ok", "")
    assert (by["tab01"].reproduces, by["tab01"].title) == ("Table 1", "Transfer errors, ground-truth maps, 9/9")
    assert by["tab01"].doc["parameters"]["table"] == "T1"
    assert by["tab01"].manifest["status"] == "ok"
    assert [p.name for p in by["study_truncation"].figures] == ["gains.png"]
    assert by["fig02"].folder == project["results"] / "fig02"


def test_collect_runs_without_registry(tmp_path):
    _, res = make_project(tmp_path)
    infos = collect_runs(res, tmp_path / "no-such-registry.toml")  # unreadable registry: folders only, sorted
    assert [i.name for i in infos] == ["extra_run", "fig02", "fig03", "study_truncation", "tab01"]
    assert all(i.reproduces == "" for i in infos)
    assert collect_runs(tmp_path / "nothing", tmp_path / "no-such-registry.toml") == []


# ------------------------------------------------------------------------------ the summary first
def test_report_files_and_return_value(project):
    assert project["md"] == (project["root"] / "paper" / "REPORT.md").resolve()
    assert project["html"] == project["md"].with_suffix(".html")
    assert project["md"].is_file() and project["html"].is_file()
    assert not list(project["md"].parent.glob("*.tmp"))  # written atomically


MAIN_SECTIONS = ["## Summary", "## Glossary", f"## {CLAIMS}", "## Beyond the paper: this package's own claims",
                 "## Tables 1–6 beside the published values",
                 "## Forking paths: readings chosen on one dataset, checked on the others",
                 "## What differs from the paper, and why"]


def test_the_summary_comes_first_then_the_main_text_then_the_appendices(project):
    text = project["text"]
    headings = [ln for ln in text.splitlines() if ln.startswith("#")]
    assert headings[0] == "# Reproduction report: Improved Functional Mappings via Product Preservation"
    level2 = [h for h in headings if h.startswith("## ")]
    assert level2 == MAIN_SECTIONS + ["## Appendix A: figure gallery", "## Appendix B: studies",
                                      "## Appendix C1: embedded humans", "## Appendix D: runs"]
    # the title's paragraph of provenance, then a line of links to every section
    between = text.split(headings[0], 1)[1].split(headings[1], 1)[0].strip().split("\n\n")
    assert len(between) == 2 and between[0].startswith("Nogneng, Melzi") and "`results`" in between[0]
    assert between[1] == "Contents: " + " · ".join(f"[{h[3:]}](#{anchor(h[3:])})" for h in level2) + "."
    summary = _section(text, "Summary")
    assert summary.strip().startswith("**Scope.** The 41 claims of the paper in the claims ledger")
    assert "the **embedded humans**" in summary and "**Not reproduced, and why:**" in summary
    assert "prodmaps reproduce --only fig04 --profile paper" in summary and "**Rerun one figure.**" in summary
    assert "Status **" not in text and "outputs in `" not in text  # no per-run status boilerplate


def test_every_ledger_claim_has_a_verdict(project):
    ledger = load_ledger()
    rows, app = _claim_rows(project["text"]), _appendix_claims(project["text"])
    paper = [c for c, x in ledger.items() if x.source == "paper"]
    assert list(rows) == paper and list(app) == list(ledger)  # ledger order: the paper's claims, all in the appendix
    package = _tables(_section(project["text"], "Beyond the paper"))[0]
    assert [r[0].strip("`") for r in package[1:]] == [c for c in ledger if c not in paper]
    for cid, a in app.items():
        claim = ledger[cid]
        assert a["verdict"].strip("*") in VERDICTS, (cid, a["verdict"])
        if cid in rows:
            assert rows[cid]["embedded humans"] == a["verdict"] and rows[cid]["where"] == claim.where
        if cid in EXPECTED:
            continue
        # a claim whose runs' results are absent here is not measured
        assert not set(claim.runs) <= PRESENT_WITH_RESULTS, f"{cid}: add it to EXPECTED"
        assert a["verdict"] == "not measured here", cid
        assert (a["rule"], a["default"]) == ("—", "—"), cid
        m = re.fullmatch(r"not measured: run '(\w+)' not available", a["evidence"])
        assert m and m.group(1) in set(claim.runs) - PRESENT_WITH_RESULTS, (cid, a["evidence"])


def test_verdicts_of_the_measured_claims(project):
    rows = _appendix_claims(project["text"])
    for cid, (verdict, marks, kinds, evidence) in EXPECTED.items():
        row = rows[cid]
        shown = f"**{verdict}**" if verdict == "does not hold" else verdict
        assert row["verdict"] == shown, cid
        assert (row["rule"], row["default"]) == marks, cid
        assert row["intra / inter"] == (kinds or "—"), cid
        assert row["evidence"].startswith(evidence), (cid, row["evidence"])
    c = rows["tab01.products_improve_transfer"]  # the criterion behind the verdict
    assert c["left out"].startswith("hk k: in the span of the source basis")
    assert c["margin"].startswith("0.05 ('significant improvement'")
    assert re.fullmatch(r"(\S.*: )?\+0\.\d+ ± [\d.e-]+, n = 3, \+\d+%.*", c["paired comparison"].split("; ")[0])


def test_summary_counts_are_the_ledgers_counts_and_quotes_are_the_papers(project):
    text, ledger = project["text"], load_ledger()
    rows = _claim_rows(text)
    paper = {c for c, x in ledger.items() if x.source == "paper"}
    expected = {}
    for cid in paper:
        v = EXPECTED[cid][0] if cid in EXPECTED else NM
        expected[v] = expected.get(v, 0) + 1
    assert expected["holds"] == 4 and expected["does not hold"] == 2 and expected["not empirical"] == 2
    counts = _summary_counts(text)
    assert counts == {"embedded humans": expected}
    assert _section(text, "Summary").strip().startswith(f"**Scope.** The {len(paper)} claims of the paper")
    # the ledger's own count of the same verdicts (claims.verdict_counts)
    verdicts = evaluate_folder(project["results"])
    assert {k: v for k, v in _ledger_counts(verdicts).items() if v} == counts["embedded humans"]
    weak = _section(text, "Summary").split("**Does not hold, or inconclusive**", 1)[1].split("\n\n")[1]
    expected = [(c, v[3]) for c, v in EXPECTED.items() if v[0] == "does not hold"]  # with the evidence's start
    assert len(weak.splitlines()) == len(expected) and all(
        line.startswith(f"- `{c}` ({ledger[c].where}): does not hold on embedded humans. embedded humans: {ev}")
        for line, (c, ev) in zip(weak.splitlines(), expected))
    for cid, row in rows.items():
        q = ledger[cid].quote
        shown = row["the paper's words"]
        assert shown == f"“{q}”" if len(q) <= 70 else (shown.startswith(f"“{q[:40]}") and shown.endswith(" …”")
                                                       and len(shown) <= 75), (cid, shown)


def _ledger_counts(verdicts) -> dict:
    """``{verdict: n}`` of the paper's claims (one verdict per claim), as the ledger counts them."""
    from prodmaps.experiments.shared import claims

    return claims.verdict_counts(verdicts)["paper"]


def test_no_count_of_reproduced_values(project):
    for text in (project["text"], project["html_text"]):
        assert not re.search(r"\d+\s+of\s+\d+\s+published values reproduced", text)


# ------------------------------------------------------------------------------ tables
SUMMARY_HEADER = ["table", "cells compared", "within ±0.02", "missed, within draw noise", "mean |diff|",
                  "largest |diff|", "products beat std: paper B (all · intra · inter)", "gain rule", "default"]
CELL_HEADER = ["function", "stage", "method", "published", "ours", "SE", "difference", "within ±0.02",
               "within draw noise", "run"]


def _summary_rows(text, name="embedded humans"):
    table = _tables(_section(text, f"Tables on {name}", 3))[0]  # then the cells, under level-4 headings
    assert table[0][0] == "table"  # (the header row itself: see test_markdown_table_headers_escape_pipes)
    assert all(len(r) == len(SUMMARY_HEADER) for r in table[1:])
    return {r[0]: r for r in table[1:]}


def test_markdown_table_headers_escape_pipes(project):
    section = _section(project["text"], "Tables on embedded humans", 3)
    table = _tables(section)[0]
    assert table[0] == SUMMARY_HEADER
    header_line = next(ln for ln in section.splitlines() if ln.startswith("|"))
    assert len(re.findall(r"(?<!\\)\|", header_line)) == len(SUMMARY_HEADER) + 1


def test_table_summaries_count_mean_and_largest_difference(project):
    rows = _summary_rows(project["text"])
    assert list(rows) == [f"Table {t}" for t in range(1, 7)]
    diffs = sorted(abs(d) for d in DELTAS.values())
    assert sum(d <= 0.02 for d in diffs) == 2 and abs(np.mean(diffs) - 0.041) < 1e-12
    t1 = rows["Table 1"]
    assert t1[1:6] == [f"4 of {N_PUB['1']}", "2", "1 of 2", "0.041", "0.100"]
    # products beat std, per method, over all · intra · inter pairs (3 families, one size)
    # hk k (in the span of the basis: a tie by construction) counts neither way
    assert t1[6:] == ["2/2 · 1/2 · 0/2", "2/2 · 2/2 · 1/2", "2/2 · 2/2 · 0/2"]
    # Table 2: one value from an unregistered run (top-level "table", no standard error: no noise count),
    # no tab02 run for the product columns
    assert rows["Table 2"][1:] == [f"1 of {N_PUB['2']}", "0", "—", "0.030", "0.030", "— · — · —", "— · — · —",
                                   "— · — · —"]
    for t in "3456":
        assert rows[f"Table {t}"][1:6] == [f"0 of {N_PUB[t]}", "—", "—", "—", "—"]
    # the main text: within ±0.02 · within draw noise, of the cells compared
    (main,) = _tables(_section(project["text"], "Tables 1–6 beside the published values"))
    assert main[0] == ["table", "published cells", "embedded humans"]
    assert main[1] == ["Table 1", str(N_PUB["1"]), "2 · 3 of 4"]
    assert main[2] == ["Table 2", str(N_PUB["2"]), "0 · — of 1"]  # a value without SE: no draw-noise count
    assert [r[2] for r in main[3:]] == ["—"] * 4


def test_table_summaries_against_a_custom_published_csv(tmp_path):
    _, res = make_project(tmp_path)
    csv = tmp_path / "pub.csv"
    csv.write_text("table,fmap,k_M,k_N,function,stage,method,value\n"
                   "1,ground_truth,9,9,HKS,transfer,std,0.50\n"  # ours 0.55: diff 0.05
                   "1,ground_truth,9,9,HKS,transfer,our_B,0.11\n"  # ours 0.10: diff 0.01
                   "1,ground_truth,9,9,WKS,transfer,std,0.20\n"  # not measured by us
                   "3,ground_truth,6,7,HKS,transfer,std,0.40\n")
    md, _ = build_report(res, tmp_path / "out" / "R.md",
                         ReportSettings(registry=tmp_path / "paper" / "runs.toml", published=csv))
    text = md.read_text(encoding="utf-8")
    rows = _summary_rows(text)
    assert list(rows) == ["Table 1", "Table 3"]
    # HKS std is off by 0.05 with SE 0.004: beyond 0.02 + 2·√2·0.004 = 0.031
    assert rows["Table 1"][1:6] == ["2 of 3", "1", "0 of 1", "0.030", "0.050"]
    assert rows["Table 3"][1:6] == ["0 of 1", "—", "—", "—", "—"]
    app = _section(text, "Appendix C1")
    assert "| HKS | transfer | std | 0.50 | 0.550 | 0.004 | +0.050 | no | no | tab01 |" in app
    assert "| HKS | transfer | our_B | 0.11 | 0.100 | 0.012 | -0.010 | yes | yes | tab01 |" in app
    assert "| WKS | transfer | std | 0.20 | — | — |  |  |  |  |" in app


def test_no_published_csv_means_no_table_sections(tmp_path):
    _, res = make_project(tmp_path)
    md, _ = build_report(res, tmp_path / "R.md", ReportSettings(registry=tmp_path / "paper" / "runs.toml",
                                                                published=tmp_path / "missing.csv"))
    text = md.read_text(encoding="utf-8")
    assert "## Tables 1–6" not in text and "### Tables on" not in text and "#### Table" not in text
    assert text.index(f"## {CLAIMS}") < text.index("## Appendix D: runs")


def test_the_dataset_appendix_lists_every_published_value(project):
    app = _section(project["text"], "Appendix C1: embedded humans")
    heads = re.findall(r"^#### (.*)$", app, flags=re.M)
    assert heads[0] == "Table 1 on embedded humans: ground_truth, k_M = 9, k_N = 9" and len(heads) == 6
    tables = _tables(app)[2:]  # after the claims and the table summaries
    assert len(tables) == 6
    t1 = tables[0]
    assert t1[0] == CELL_HEADER
    assert len(t1) - 1 == N_PUB["1"]
    by = {(r[1], r[2], r[0]): r for r in t1[1:]}
    for key, delta in DELTAS.items():
        pub = PUB1[(9, 9) + key]
        se = next(e.get("se") for e in TABLE1 if e["value"] == pytest.approx(pub + delta))
        within = abs(delta) <= 0.02
        noise = "—" if se is None else ("yes" if abs(delta) <= 0.02 + 2 * 2 ** 0.5 * se else "no")
        assert by[key][3:] == [f"{pub:.2f}", f"{pub + delta:.3f}", "—" if se is None else f"{se:.3f}",
                               f"{delta:+.3f}", "yes" if within else "no", noise, "tab01"], key
    assert by[("transfer", "std", "WKS")][4:] == ["—", "—", "", "", "", ""]
    assert tables[2][0][:3] == ["k_M", "k_N", "function"]  # Table 3 has two settings
    t2 = {(r[1], r[2], r[0]): r for r in tables[1][1:]}
    assert t2[("transfer", "std", "HKS")][9] == "extra_run"
    unmatched = _tables(_section(project["text"], "Appendix D: runs"))[-1]
    assert unmatched[0] == ["run", "entry", "reason"]
    assert len(unmatched) == 2
    assert unmatched[1][0] == "tab01" and '"function": "Nope"' in unmatched[1][1]
    assert unmatched[1][2] == "no published value with these keys"


def test_what_is_printed_is_what_is_counted(project):
    """The appendix's within columns are the counts of the summaries, cell by cell (the ±0.02 boundary included)."""
    text = project["text"]
    summary = _summary_rows(text)
    app = _section(text, "Appendix C1: embedded humans")
    for t, table in zip(range(1, 7), _tables(app)[2:]):
        i = table[0].index("within ±0.02")
        rows = [r for r in table[1:] if r[i]]
        row = summary[f"Table {t}"]
        if not rows:
            assert row[2] == "—"
            continue
        assert row[2] == str(sum(r[i] == "yes" for r in rows))
        missed = [r for r in rows if r[i] == "no"]
        noise = row[3] if row[3] == "—" else int(row[3].split(" of ")[0])
        assert noise == "—" or noise == sum(r[i + 1] == "yes" for r in missed)


# ------------------------------------------------------------------------------ studies, runs, figures
def test_studies_appendix(project):
    study = _section(project["text"], "Appendix B: studies")
    assert "### Study: Approach B's threshold, transfer gains, and a rule that does not need ground truth" in study
    assert ("- `gt_9_9`: median over pairs of the largest transfer gain kept at rtol = 1e-3: 123.4; at 1e-2: 5.6"
            in study)
    # HKS: gain 0.2 <= paper 0.3, <= 1.1 oracle, <= std; XYZ: gain 0.4 > paper 0.35, > 1.1 * 0.3, <= std 0.5
    assert ("- `gt_9_9`: the gain rule is at least as good as the paper's 1e-3 for 1 of 2 families, within 10 % of "
            "the oracle threshold for 1, and below the standard transfer for 2") in study
    assert "![gains on embedded humans](../results/study_truncation/gains.png)" in study
    assert "**The question:** how Approach B's threshold rtol" in study  # its caption
    assert project["text"].count("gains.png") == 1  # not repeated in the gallery


def test_runs_appendix_status_time_and_links(project):
    runs = _section(project["text"], "Appendix D: runs")
    table = _tables(runs)[0]
    assert table[0] == ["run", "reproduces", "embedded humans (s)", "read"]
    by = {r[0].strip("`"): r for r in table[1:]}
    assert list(by) == ["fig02", "fig03", "fig04", "tab01", "study_truncation", "extra_run"]
    assert by["tab01"][1:] == ["Table 1", "12.3", "[executed notebook](../results/tab01/executed.html)"]
    assert by["fig03"][1:] == ["Figure 3", "failed", "[executed notebook](../results/fig03/executed.html)"]
    assert by["fig04"][1:] == ["Figure 4", "—", "executed notebook"]  # no file: no link
    assert by["extra_run"][1:] == ["", "ok", "executed notebook"]
    assert "**Failed or not run** on the embedded humans: `fig03`, `fig04`." in runs
    # the failed run shows the first 15 lines of its error.txt
    block = re.search(r"```\n(.*?)\n```", runs, flags=re.S).group(1).splitlines()
    assert block == [f"error line {i}" for i in range(1, 16)]


def test_figure_gallery_with_captions(project):
    figs = _section(project["text"], "Appendix A: figure gallery")
    heads = re.findall(r"^### (.*)$", figs, flags=re.M)
    assert heads == ["Figure 2 (`fig02`)", "Table 1 (`tab01`)"]
    assert "![fourier](../results/fig02/fourier.png)" in figs
    assert "![table](../results/tab01/table.png)" in figs
    fig02 = _section(figs, "Figure 2 (`fig02`)", 3)
    assert fig02.strip().startswith("**The paper's Figure 2:** the first five 1D Fourier functions")
    assert "**Look at:**" in fig02 and "**Ours:**" in fig02
    assert _section(figs, "Table 1 (`tab01`)", 3).strip().startswith("**Look at:**")


def test_links_to_executed_notebooks_are_relative(project):
    base = project["md"].parent
    text = project["text"]
    links = re.findall(r"\]\(([^)\s]+)\)", text)
    assert links, "no links in the report"
    anchors = {anchor(h) for h in re.findall(r"^#+ (.*)$", text, flags=re.M)}
    for link in links:
        assert not link.startswith("/") and "://" not in link and not re.match(r"^[A-Za-z]:", link), link
        if link.startswith("#"):
            assert link[1:] in anchors, link
        else:
            assert (base / link).resolve().is_file(), link
    executed = {lk for lk in links if lk.endswith("executed.html")}
    assert executed == {f"../results/{r}/executed.html" for r in ("fig02", "fig03", "tab01", "study_truncation")}
    rows = _claim_rows(text)
    assert rows["tab01.products_improve_transfer"]["notebook"] == "[tables_transfer](../results/tab01/executed.html)"
    assert rows["fig02.rank"]["notebook"] == "[fig02_fourier_products](../results/fig02/executed.html)"
    assert rows["fig04.products_improve"]["notebook"] == "fig04_coordinate_reconstruction"  # no run: no link
    assert str(project["results"]) not in text  # no absolute paths to the results


def test_html_report(project):
    h = project["html_text"]
    assert h.startswith("<!DOCTYPE html>") and h.rstrip().endswith("</body></html>")
    assert "<title>prodmaps reproduction report</title>" in h
    h2 = re.findall(r'<h2 id="([^"]+)">(.*?)</h2>', h)
    assert [t for _, t in h2][:3] == ["Summary", "Glossary", CLAIMS]
    assert all(i == anchor(html_lib.unescape(t)) for i, t in h2)
    assert h.index("<h1") < h.index('<h2 id="summary">')
    assert '<a href="../results/tab01/executed.html">tables_transfer</a>' in h
    assert '<img src="../results/tab01/table.png" alt="table">' in h
    assert "<b>Scope.</b>" in h and "**" not in h
    hrefs = re.findall(r'(?:href|src)="([^"]+)"', h)
    assert hrefs and all(not x.startswith("/") and "://" not in x for x in hrefs)
    ids = set(re.findall(r' id="([^"]+)"', h))
    assert all(x[1:] in ids for x in hrefs if x.startswith("#"))
    assert h.count("<table>") == len(_tables(project["text"]))


def test_html_written_where_requested_and_figures_copied(tmp_path, monkeypatch):
    reg, res = make_project(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    out = tmp_path / "paper" / "R.md"
    html_out = tmp_path / "paper" / "site.html"
    md, html = build_report(res, out, ReportSettings(registry=reg, copy_figures=True), html_out=html_out)
    assert (md, html) == (out.resolve(), html_out)
    assert html_out.is_file() and not out.with_suffix(".html").exists()
    text = md.read_text(encoding="utf-8")
    assert "![table](report_figures/tab01/table.png)" in text
    copied = tmp_path / "paper" / "report_figures" / "tab01" / "table.png"
    assert copied.read_bytes() == (res / "tab01" / "table.png").read_bytes()
    assert (tmp_path / "paper" / "report_figures" / "study_truncation" / "gains.png").is_file()
    assert 'src="report_figures/study_truncation/gains.png"' in html_out.read_text(encoding="utf-8")


def test_explicit_registry_works_from_any_working_directory(tmp_path, monkeypatch):
    reg, res = make_project(tmp_path / "proj")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    monkeypatch.delenv("PRODMAPS_RUNS", raising=False)
    md, _ = build_report(res, tmp_path / "proj" / "paper" / "R.md", ReportSettings(registry=reg))
    assert f"## {CLAIMS}" in md.read_text(encoding="utf-8")


def test_html_links_resolve_from_the_html_folder(tmp_path, monkeypatch):
    reg, res = make_project(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    _, html = build_report(res, tmp_path / "paper" / "R.md", ReportSettings(registry=reg),
                           html_out=tmp_path / "paper" / "R2.html")
    links = [x for x in re.findall(r'(?:href|src)="([^"]+)"', html.read_text(encoding="utf-8"))
             if not x.startswith("#")]
    assert links
    for link in links:
        assert (html.parent / link).resolve().is_file(), link
    # the links are shared by both files: an HTML report in another folder is refused, not broken
    with pytest.raises(ValueError, match="html_out must be in the folder"):
        build_report(res, tmp_path / "paper" / "R.md", ReportSettings(registry=reg),
                     html_out=tmp_path / "site" / "R.html")


def test_default_output_is_beside_the_results_never_the_committed_report(tmp_path, monkeypatch):
    reg, res = make_project(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    md, html = build_report(res)  # registry from $PRODMAPS_RUNS; the report beside the results it reads
    assert md == (res / "REPORT.md").resolve()
    assert html == md.with_suffix(".html") and html.is_file()
    assert not (tmp_path / "paper" / "REPORT.md").exists()
    assert _runs_names(md.read_text(encoding="utf-8")) == ["fig02", "fig03", "fig04", "tab01", "study_truncation",
                                                            "extra_run"]
    assert len(load_registry(reg)) == 5


def _runs_names(text):
    table = _tables(_section(text, "Appendix D: runs"))[0]
    return [r[0].strip("`") for r in table[1:]]


def test_cli_report_never_writes_the_committed_report(tmp_path, monkeypatch, capsys):
    from prodmaps.pipeline import cli

    reg, res = make_project(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    for profile in ("smoke", "paper"):
        folder = tmp_path / "out" / profile
        folder.parent.mkdir(exist_ok=True)
        res.rename(folder)
        assert cli.main(["report", str(folder)]) == 0
        assert (folder / "REPORT.md").is_file() and not (tmp_path / "paper" / "REPORT.md").exists()
        res = folder


def test_cli_claims_and_report_refuse_a_folder_without_runs(tmp_path, monkeypatch, capsys):
    from prodmaps.pipeline import cli

    reg, res = make_project(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    assert cli.main(["claims", str(tmp_path / "missing")]) == 2
    assert "no such results folder" in capsys.readouterr().err
    out = tmp_path / "out"
    out.mkdir()
    res.rename(out / "paper")
    for cmd in ("claims", "report"):
        assert cli.main([cmd, str(out)]) == 2  # the --out root, not OUT/<profile>
        err = capsys.readouterr().err
        assert "no run results here" in err and str(out / "paper") in err, err
    assert cli.main(["claims", str(out / "paper")]) == 0


def _faust_tab01(folder: Path, pairs) -> None:
    tab01 = _tab01_results()
    tab01["pairs"] = pairs
    _run(folder, "tab01", _doc(tab01, table="T1"), _manifest("tab01", "ok", 3.0), pngs=["table.png"])


def test_a_prepared_dataset_gets_a_verdict_column_and_an_appendix(tmp_path):
    reg, res = make_project(tmp_path)
    faust = res.with_name(res.name + "-faust")  # what `prodmaps reproduce --dataset faust` writes
    _faust_tab01(faust, [["tr_reg_000", "tr_reg_001"], ["tr_reg_010", "tr_reg_025"]])
    md, _ = build_report(res, tmp_path / "paper" / "REPORT.md", ReportSettings(registry=reg))
    text = md.read_text(encoding="utf-8")
    rows = _claim_rows(text, ("embedded humans", "FAUST"))
    cell = rows["tab01.products_improve_transfer"]["FAUST"]
    assert cell.startswith(("holds", "**does not hold**")) and cell != "not measured here"
    assert rows["fig02.rank"]["FAUST"] == "not measured here"
    assert list(_summary_counts(text)) == ["embedded humans", "FAUST"]
    faust_sec = _section(text, "Appendix C2: FAUST")
    assert "tr_reg_000→tr_reg_001" in faust_sec and "4 shapes and 2 ordered" in faust_sec
    assert "### Tables on FAUST" in faust_sec and "#### Table 1 on FAUST" in faust_sec
    assert _appendix_claims(text, "FAUST")["tab01.products_improve_transfer"]["verdict"] == cell
    (main,) = _tables(_section(text, "Tables 1–6 beside the published values"))
    assert main[0] == ["table", "published cells", "embedded humans", "FAUST"] and main[1][3] == "2 · 3 of 4"
    runs = _tables(_section(text, "Appendix D: runs"))[0]
    assert runs[0] == ["run", "reproduces", "embedded humans (s)", "FAUST (s)", "read"]
    assert {r[0]: r[3] for r in runs[1:]}["`tab01`"] == "3.0"
    assert execute.profile_folder(tmp_path, "paper", "faust") == (tmp_path / "paper-faust").resolve()
    assert execute.profile_folder(tmp_path, "paper", "anny_humans") == (tmp_path / "paper").resolve()


def test_html_verdicts_are_badges_left_aligned_and_quotes_folded(project):
    page, ledger = project["html_text"], load_ledger()
    body = page.split(f'<h2 id="{anchor(CLAIMS)}">', 1)[1]
    table = body.split("<table>", 1)[1].split("</table>", 1)[0]
    rows = table.split("<tr>")[2:]
    assert len(rows) == sum(c.source == "paper" for c in ledger.values())  # the package's own: a table apart
    for row in rows:  # every verdict cell is a badge of its verdict's colour
        cells = re.findall(r"<td[^>]*>(.*?)</td>", row, flags=re.S)
        m = re.fullmatch(r'<span class="badge (v-\w+)">([a-z ]+)</span>', cells[3])
        assert m, cells[3]
        assert m.group(1) == {"holds": "v-holds", "does not hold": "v-not", "not measured here": "v-none",
                              "not empirical": "v-none", "not reproducible": "v-none"}[m.group(2)]
        quote = cells[2]
        if len(quote) > 60:
            assert quote.startswith("<details><summary>"), quote  # long quotes folded away
    style = page.split("<style>", 1)[1].split("</style>", 1)[0]
    assert "text-align:left" in style and "text-align:right" not in style.replace("td.num{text-align:right", "")
    assert '<td class="num">' in page  # numbers, and only numbers, right-aligned


# ------------------------------------------------------------------------------ publish
def _complete_paper_run(root: Path) -> tuple[Path, Path]:
    """A project whose five registered runs all ran, ok, in the paper profile (``root/results/paper``)."""
    reg, res = make_project(root)
    res.rename(root / "moving")
    res.mkdir()
    paper = (root / "moving").rename(res / "paper")
    for name in ("fig02", "fig03", "fig04"):
        folder = paper / name
        folder.mkdir(exist_ok=True)
        (folder / "error.txt").unlink(missing_ok=True)
        if not (folder / "results.json").is_file():
            (folder / "results.json").write_text(json.dumps(_doc({"x": 1})))
        if not list(folder.glob("*.png")):
            _png(folder / f"{name}.png", 3)
    for name in ("fig02", "fig03", "fig04", "tab01", "study_truncation"):
        (paper / name / "manifest.json").write_text(json.dumps(_manifest(name, "ok", 1.0)))
    for name in ("fig02", "fig03", "fig04", "tables", "study"):
        (root / "notebooks").mkdir(exist_ok=True)
        (root / "notebooks" / f"{name}.ipynb").write_text("{}")
    return reg, paper


def _local_links(path: Path) -> list[str]:
    text = path.read_text(encoding="utf-8")
    pattern = r"\]\(([^)\s]+)\)" if path.suffix == ".md" else r'(?:href|src)="([^"]+)"'
    links = re.findall(pattern, text)
    return [x for x in links if "://" not in x and not x.startswith("#")]


def test_reproduce_writes_its_report_beside_the_results_and_leaves_the_committed_one(tmp_path, monkeypatch, capsys):
    from prodmaps.pipeline import cli

    reg, paper = _complete_paper_run(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    committed = tmp_path / "paper" / "REPORT.md"
    committed.write_text("# the committed report\n")
    monkeypatch.setattr(execute, "reproduce", lambda **kw: [])  # nothing to run: the report step only
    assert cli.main(["reproduce", "--out", str(tmp_path / "results"), "--no-progress"]) == 0
    assert committed.read_text() == "# the committed report\n"
    assert (paper / "REPORT.md").is_file() and (paper / "REPORT.html").is_file()
    assert "make publish" in capsys.readouterr().out
    for link in _local_links(paper / "REPORT.md"):  # beside its results: every link resolves
        assert (paper / link).is_file(), link
    assert cli.main(["reproduce", "--out", str(tmp_path / "results"), "--report", str(committed)]) == 2
    assert "prodmaps publish" in capsys.readouterr().err
    assert committed.read_text() == "# the committed report\n"


def test_publish_refuses_a_partial_run_and_says_what_is_partial(tmp_path, monkeypatch, capsys):
    from prodmaps.pipeline import cli

    reg, res = make_project(tmp_path)  # fig03 failed, fig04 missing, no manifests for some
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    committed = tmp_path / "paper" / "REPORT.md"
    committed.write_text("# the committed report\n")
    with pytest.raises(PublishError, match=r"fig04.*failed: fig03.*--allow-partial"):
        publish(res, registry=reg)
    assert cli.main(["publish", str(res)]) == 2
    assert "refusing to publish" in capsys.readouterr().err
    assert committed.read_text() == "# the committed report\n"
    assert cli.main(["publish", str(res), "--allow-partial"]) == 0
    text = committed.read_text(encoding="utf-8")
    assert "**Partial publication:**" in text and "fig04" in text.split("## Summary")[0]


def test_publish_shows_overridden_parameters_and_refuses_them_by_default(tmp_path, monkeypatch):

    reg, paper = _complete_paper_run(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    man = dict(_manifest("fig03", "ok", 1.0), overrides={"k_values": [4, 8, 12, 16]})
    (paper / "fig03" / "manifest.json").write_text(json.dumps(man))
    md, _ = build_report(paper, settings=ReportSettings(registry=reg))  # every report shows them
    assert "`fig03`: `k_values=[4, 8, 12, 16]`" in md.read_text(encoding="utf-8")
    with pytest.raises(PublishError, match=r"parameters overridden: fig03 k_values=\[4, 8, 12, 16\]"):
        publish(paper, registry=reg)


def test_published_report_links_resolve_in_a_fresh_clone(tmp_path, monkeypatch):
    """Every local link of the published report points into paper/ or the committed notebooks."""
    reg, paper = _complete_paper_run(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    stale = tmp_path / "paper" / "report_figures" / "old_run" / "gone.png"
    stale.parent.mkdir(parents=True)
    stale.write_bytes(b"")
    md, html, problems = publish(paper, registry=reg)
    assert problems == [] and md == (tmp_path / "paper" / "REPORT.md").resolve()
    assert not stale.exists() and not stale.parent.exists()  # figures no longer shown are removed
    shutil.rmtree(tmp_path / "results")  # a fresh clone has no results/
    for f in (md, html):
        links = _local_links(f)
        assert links and not [x for x in links if "results/" in x], links
        for link in links:
            assert (f.parent / link).is_file(), link
    text = md.read_text(encoding="utf-8")
    assert "Generated by `prodmaps publish`" in text and "[notebook](../notebooks/tables.ipynb)" in text
    assert "Results `results/paper`" in text  # the results folder named relative to the project


def test_publishing_a_run_kept_outside_the_project_writes_no_machine_path(tmp_path, monkeypatch):
    # `make reproduce OUT=/scratch/res` then `make publish OUT=/scratch/res`: the committed report names
    # the results folder `<out>/paper`, not /scratch/res/paper or ../../scratch/res/paper
    reg, paper = _complete_paper_run(tmp_path / "project")
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    elsewhere = tmp_path / "scratch" / "res"
    elsewhere.mkdir(parents=True)
    paper = paper.rename(elsewhere / "paper")
    md, html, problems = publish(paper, registry=reg)
    assert problems == []
    for f in (md, html):
        text = f.read_text(encoding="utf-8")
        assert "scratch" not in text and str(tmp_path) not in text
    text = md.read_text(encoding="utf-8")
    assert "from `<out>/paper`" in text and "Results `<out>/paper`" in text
    local, _ = build_report(paper, settings=ReportSettings(registry=reg))  # a local report: the paths on this machine
    assert f"Results `{paper}`" in local.read_text(encoding="utf-8")


def test_publish_keeps_the_faust_section_when_faust_was_not_rerun(tmp_path, monkeypatch):
    reg, paper = _complete_paper_run(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    faust = paper.with_name("paper-faust")
    _faust_tab01(faust, [["tr_reg_000", "tr_reg_001"]])
    md, html, _ = publish(paper, registry=reg)  # with the FAUST runs: a fresh section and its figures
    first = md.read_text(encoding="utf-8")
    first_html = html.read_text(encoding="utf-8")
    faust_png = tmp_path / "paper" / "report_figures" / "faust" / "tab01" / "table.png"
    assert "## Appendix C2: FAUST" in first and not faust_png.exists()  # tab01 is not a figure run on FAUST
    (tmp_path / "paper" / "report_figures" / "faust" / "fig08").mkdir(parents=True)
    kept_png = tmp_path / "paper" / "report_figures" / "faust" / "fig08" / "curves.png"
    _png(kept_png, 7)
    stored = tmp_path / "paper" / "report_data" / "faust.json"  # FAUST's report data, beside the report
    assert json.loads(stored.read_text(encoding="utf-8"))["dataset"] == "faust"
    shutil.rmtree(faust)  # FAUST not rerun: its column and sections come from the stored report data
    k = DatasetReport.load(tmp_path / "paper", "faust")
    assert k is not None and list(k.verdicts) == list(load_ledger())
    assert k.verdicts["tab01.products_improve_transfer"].verdict in VERDICTS
    assert [t.table for t in k.tables] == ["1"] and k.pairs == [["tr_reg_000", "tr_reg_001"]]
    assert len(k.cells) == N_PUB["1"] and k.run_times == {"tab01": ["ok", 3.0]}  # every cell of its tables
    (tmp_path / "paper" / "REPORT.md").write_text("# edited by hand: not a data store\n")  # never read back
    md, html, _ = publish(paper, registry=reg)
    second = md.read_text(encoding="utf-8")

    def faust_part(text):  # FAUST's appendix, but for the note saying that it is kept
        part = "".join(s for s in re.split(r"(?m)^(?=## )", text) if "FAUST" in s.splitlines()[0])
        return part.replace(" (kept from that publication: not rerun for this report)", "")

    assert faust_part(second) == faust_part(first) != ""
    rows_first = {r[0]: r for r in _tables(_section(first, CLAIMS))[0][1:]}
    rows_second = {r[0]: r for r in _tables(_section(second, CLAIMS))[0][1:]}
    head = _tables(_section(second, CLAIMS))[0][0]
    col = head.index("FAUST")
    assert {c: r[col] for c, r in rows_second.items()} == {c: r[col] for c, r in rows_first.items()}
    assert "kept from the report published at commit" in second
    assert re.search(r"code at commit `[^`]+` \(kept from that publication: not rerun for this report\)", second)
    assert _summary_counts(second)["FAUST"] == _summary_counts(first)["FAUST"]
    assert kept_png.is_file()  # a kept dataset's figures stay
    first_commit = k.commit
    md, _, _ = publish(paper, registry=reg)  # kept again: still names the commit of the FAUST run's report
    assert DatasetReport.load(md.parent, "faust").commit == first_commit
    assert faust_part(md.read_text(encoding="utf-8")) == faust_part(first)
    h2 = '<h2 id="appendix-c2-faust">Appendix C2: FAUST</h2>'
    assert h2 in html.read_text(encoding="utf-8") and h2 in first_html


def test_a_run_with_a_report_module_gets_its_section_in_the_report_and_each_dataset(tmp_path, monkeypatch):
    (tmp_path / "owned_section.py").write_text(
        "def report_blocks(results, dataset, *, main=True):\n"
        "    if not results.get('n'):\n"
        "        return []\n"
        "    return [('h', 2 if main else 3, f\"Study: owned, on {dataset}\"), ('p', f\"n = {results['n']}\"),\n"
        "            ('table', ['a', 'b'], [[1, 2]])]\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    reg, res = make_project(tmp_path)
    reg.write_text(REGISTRY + '[runs.owned]\nnotebook = "notebooks/owned.ipynb"\nreproduces = "Study"\n'
                   'report = "owned_section"\n[runs.empty]\nnotebook = "notebooks/owned.ipynb"\n'
                   'report = "owned_section"\n')
    _run(res, "owned", _doc({"n": 7, "dataset": "anny_humans"}), _manifest("owned", "ok", 1.0), pngs=["o.png"])
    _run(res, "empty", _doc({}), _manifest("empty", "ok", 1.0), pngs=["e.png"])  # no blocks: no section
    faust = res.with_name(res.name + "-faust")
    _run(faust, "owned", _doc({"n": 8}), _manifest("owned", "ok", 1.0), pngs=["o.png"])
    text = _report_text(res, tmp_path, reg)
    owned = _section(text, "Study: owned, on embedded humans", 3)
    assert "n = 7" in owned and "![o on embedded humans](../results/owned/o.png)" in owned
    assert text.index("\n### Study: Approach B's threshold") < text.index("\n### Study: owned")  # registry order
    faust = _section(text, "Study: owned, on FAUST", 3)  # each dataset's blocks, one after the other
    assert "n = 8" in faust and text.index("Study: owned, on embedded humans") < text.index("Study: owned, on FAUST")
    figs = _section(text, "Appendix A: figure gallery")
    assert "(`owned`)" not in figs and "![e](../results/empty/e.png)" in figs  # shown once, in its section


def test_a_main_study_run_on_a_prepared_dataset_is_not_repeated_beside_its_dataset_section(tmp_path, monkeypatch):
    """The main run's studies run on FAUST when it is prepared: shown once, in FAUST's section."""
    (tmp_path / "owned_section2.py").write_text(
        "def report_blocks(results, dataset, *, main=True):\n"
        "    return [('h', 2 if main else 3, f\"Study: owned2, on {dataset}\"), ('p', f\"n = {results['n']}\")]\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    reg, res = make_project(tmp_path)
    reg.write_text(REGISTRY + '[runs.owned]\nnotebook = "notebooks/owned.ipynb"\nreproduces = "Study"\n'
                   'report = "owned_section2"\n')
    _run(res, "owned", _doc({"n": 7, "dataset": "faust"}), _manifest("owned", "ok", 1.0), pngs=["o.png"])
    faust = res.with_name(res.name + "-faust")
    text = _report_text(res, tmp_path, reg)
    assert text.count("Study: owned2, on FAUST") == 1  # no FAUST folder: the main run's section
    _run(faust, "owned", _doc({"n": 8, "dataset": "faust"}), _manifest("owned", "ok", 1.0), pngs=["o.png"])
    text = _report_text(res, tmp_path, reg)
    assert text.count("Study: owned2, on FAUST") == 1 and "n = 8" in _section(text, "Appendix B: studies")
    assert "n = 7" not in text


def test_a_published_report_quotes_a_failed_run_without_machine_paths(tmp_path, monkeypatch):
    # `prodmaps publish --allow-partial` quotes a failed run's error.txt: no absolute path of this machine
    reg, res = make_project(tmp_path / "proj")
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    root = (tmp_path / "proj").resolve()
    (res / "fig03" / "error.txt").write_text(
        f'  File "{root}/.venv/lib/python3.11/site-packages/nbclient/client.py", line 10, in run\n'
        f'  File "{root}/prodmaps/experiments/howto.py", line 5, in f\n'
        f"MeshError: {tmp_path}/alice/scans/spot_03.off: no such file (see https://example.org/a/b/c)\n")
    published, _ = build_report(res, tmp_path / "pub.md", ReportSettings(registry=reg, machine_paths=False))
    text = published.read_text(encoding="utf-8")
    assert str(tmp_path) not in text
    assert '"<site-packages>/nbclient/client.py"' in text and '"prodmaps/experiments/howto.py"' in text
    assert "MeshError: …/spot_03.off: no such file (see https://example.org/a/b/c)" in text  # URLs stay
    local, _ = build_report(res, tmp_path / "local.md", ReportSettings(registry=reg))  # a local report keeps them
    assert f"{tmp_path}/alice/scans/spot_03.off" in local.read_text(encoding="utf-8")


# ------------------------------------------------------------------------------ the parts: data, text, document
def test_the_report_data_is_built_from_the_results_without_rendering(project):
    from prodmaps.pipeline.document import Document
    from prodmaps.pipeline.report import build_document, read_inputs

    settings = ReportSettings(registry=project["registry"])
    inputs = read_inputs(project["results"], settings, project["root"] / "paper")
    main = inputs.main
    assert (main.dataset, main.name, inputs.datasets, inputs.kept) == ("anny_humans", "embedded humans", [], [])
    assert list(main.verdicts) == list(load_ledger())
    for cid, (verdict, marks, kinds, evidence) in EXPECTED.items():
        c = main.verdicts[cid]
        assert (c.verdict, (c.rule, c.default)) == (verdict, marks), cid
        assert "; ".join(f"{k}: {v}" for k, v in c.subsets.items()) == kinds and c.evidence.startswith(evidence)
    assert main.counts()["holds"] == 4 and sum(main.counts().values()) == len(load_ledger())
    assert main.counts_by_source()["package"] == {**dict.fromkeys(VERDICTS, 0), "not measured here": 1}
    assert [c["function"] for c in main.cells[:3]] == ["hk k"] * 3 and len(main.cells) == sum(N_PUB.values())
    assert main.run_times["tab01"] == ["ok", 12.34] and "fig04" not in main.run_times  # nothing there
    assert [f.run for f in main.figures] == ["fig02", "tab01"]  # the figures of every run but the studies
    t1 = main.tables[0]
    assert (t1.table, t1.compared, t1.published, t1.within, t1.missed, t1.in_noise) == ("1", 4, N_PUB["1"], 2, 2, 1)
    assert t1.mean_diff == pytest.approx(0.041) and t1.largest_diff == pytest.approx(0.1)
    assert t1.beats["our_B"] == [[2, 2], [1, 2], [0, 2]] and main.tables[1].in_noise is None  # no SE: no count
    assert [(s.run, s.dataset) for s in main.studies] == [("study_truncation", "anny_humans")]
    assert main.studies[0].blocks[0] == ("h", 2, "Study: Approach B's threshold, transfer gains, and a rule that "
                                               "does not need ground truth")
    doc = build_document(inputs, settings, project["root"] / "paper")
    assert isinstance(doc, Document) and doc.blocks[0][:2] == ("h", 1)
    assert [b[2] for b in doc.blocks if b[:2] == ("h", 2)] == [h[3:] for h in MAIN_SECTIONS] + [
        "Appendix A: figure gallery", "Appendix B: studies", "Appendix C1: embedded humans", "Appendix D: runs"]
    def undated(text):
        return re.sub(r" on \d{4}-\d\d-\d\d \d\d:\d\d UTC,", " on DATE,", text)

    assert undated(doc.markdown()) == undated(project["text"])  # what build_report wrote, rendered


def test_one_datasets_report_data_round_trips_through_its_json(tmp_path):
    paper = tmp_path / "paper"
    img = paper / "report_figures" / "faust" / "fig08" / "curves.png"
    img.parent.mkdir(parents=True)
    _png(img, 1)
    data = DatasetReport("faust", "results/paper-faust", "abc123", ["fig08", "study_x"], ["tr_reg_000", "tr_reg_001"],
                         [["tr_reg_000", "tr_reg_001"]],
                         {"fig08.products_above_std": ClaimResult("holds", {"textbook": "does not hold"}, "yes", "no",
                                                                  "yes", {"intra": "holds"}, "area +0.01")},
                         [TableSummary("1", 54, 54, 44, 10, 8, 0.012, 0.062, {"our_B": [[10, 10], None, [9, 10]]})],
                         [Figure("fig08", "Figure 8", [img])],
                         [Study("study_x", "faust", [("h", 3, "Study: x on FAUST"), ("table", ["a"], [["1"]])], [img])])
    path = data.save(paper)
    assert path == paper.resolve() / "report_data" / "faust.json"
    stored = json.loads(path.read_text(encoding="utf-8"))
    assert stored["figures"][0]["images"] == ["report_figures/faust/fig08/curves.png"]  # relative to the report
    back = DatasetReport.load(paper, "faust")
    assert back == DatasetReport(**{**data.__dict__, "figures": [Figure("fig08", "Figure 8", [img.resolve()])],
                                    "studies": [Study("study_x", "faust", data.studies[0].blocks, [img.resolve()])]})
    assert back.counts()["holds"] == 1 and back.name == "FAUST" and back.images() == [img.resolve()] * 2
    assert DatasetReport.load(paper, "tosca") is None
    outside = tmp_path / "elsewhere.png"
    _png(outside, 2)
    data.figures[0].images = [outside]
    with pytest.raises(ValueError, match="not in the report's folder"):
        data.save(paper)
    path.write_text(json.dumps({"format": 0, "dataset": "faust"}))
    with pytest.raises(ValueError, match="not the report data of 'faust'"):
        DatasetReport.load(paper, "faust")


def test_the_committed_report_data_of_faust_loads_and_is_what_the_committed_report_shows():
    paper = TEXT.parent
    data = DatasetReport.load(paper, "faust")
    assert data is not None and data.verdicts and set(data.verdicts) & set(load_ledger())
    assert data.images() and all(p.is_file() and paper.resolve() in p.parents for p in data.images())
    text = (paper / "REPORT.md").read_text(encoding="utf-8")
    if "## Summary" in text:  # the report's structure since the summary came first: FAUST's summary column
        assert {k: v for k, v in data.counts_by_source()["paper"].items() if v} == _summary_counts(text)["FAUST"]
        assert "## Appendix C2: FAUST" in text and all(f"`{r}`" in text for r in data.runs)
    else:  # the report published before (at the commit faust.json names): its "On FAUST" counts
        shown = re.search(r"^On FAUST(?: \(kept from [^)]*\))?: (.*)\.$", text, flags=re.M).group(1)
        assert shown == ", ".join(f"{n} {v}" for v in ("holds", "holds within rounding", "does not hold",
                                                       "not demonstrable in this setting", "not measured here")
                                  if (n := sum(c.verdict == v for c in data.verdicts.values())))
        assert f"## On {data.name}" in text and all(f"`{r}`" in text for r in data.runs)


def test_a_stored_file_of_the_first_format_is_migrated_on_load(tmp_path):
    from prodmaps.pipeline.report_data import migrate

    stored = json.loads((TEXT.parent / "report_data" / "faust.json").read_text(encoding="utf-8"))
    first = {k: v for k, v in stored.items() if k not in ("cells", "run_times", "readings")}
    first["format"] = 1
    first["verdicts"] = {c: {k: x for k, x in v.items() if k in ("verdict", "readings", "paper", "rule", "default",
                                                                 "subsets", "evidence")}
                         for c, v in stored["verdicts"].items()}
    (tmp_path / "report_data").mkdir()
    (tmp_path / "report_data" / "faust.json").write_text(json.dumps(first), encoding="utf-8")
    shutil.copytree(TEXT.parent / "report_figures" / "faust", tmp_path / "report_figures" / "faust")
    old = DatasetReport.load(tmp_path, "faust")
    assert (old.cells, old.run_times, old.readings) == (None, {}, {})  # not stored then: the report says so
    assert {c: (v.verdict, v.source, v.excluded, v.comparisons) for c, v in old.verdicts.items()} == {
        c: (v["verdict"], "paper", {}, []) for c, v in first["verdicts"].items()}
    assert [t.table for t in old.tables] == [t["table"] for t in stored["tables"]]
    assert migrate(migrate(first)) == migrate(first) and migrate(first)["format"] == 2
    with pytest.raises(ValueError, match="formats 1 and 2"):
        migrate({**first, "format": 7})
    # saved again, it is the current format, and loads to the same data
    for img in old.images():
        assert img.is_file()
    old.save(tmp_path)
    again = json.loads((tmp_path / "report_data" / "faust.json").read_text(encoding="utf-8"))
    assert again["format"] == 2 and again["cells"] is None and DatasetReport.load(tmp_path, "faust") == old
    doc = build_document(*_inputs_with(tmp_path, kept=old))
    text = doc.markdown()
    assert "The cells of FAUST's tables were not stored by the publication at commit" in text


def test_the_papers_texts_fill_every_placeholder_and_a_missing_text_folder_leaves_a_bare_report(tmp_path):
    from prodmaps.pipeline.prose import TEXT_FILES, report_text
    from prodmaps.pipeline.report_data import CRITERIA

    values = dict(CRITERIA, ledger_file="prodmaps/experiments/claims.toml", provenance="Generated by a test.",
                  seconds={"fig04": "12"}, n_paper=30, n_package=0, data="the embedded humans")
    for name in TEXT_FILES:
        blocks = report_text(TEXT, name, **values)
        assert blocks, name
        assert not re.search(r"[{}]|<!--", json.dumps(blocks, ensure_ascii=False)), name
    assert report_text(TEXT, "title.md", **values)[0] == (
        "h", 1, "Reproduction report: Improved Functional Mappings via Product Preservation")
    (tmp_path / "t.md").write_text("A {typo} here.\n")
    with pytest.raises(ValueError, match=r"t\.md: placeholder 'typo' is not one the report fills"):
        report_text(tmp_path, "t.md", **values)
    assert report_text(tmp_path, "absent.md", **values) == []
    reg, res = make_project(tmp_path / "proj")
    md, _ = build_report(res, settings=ReportSettings(registry=reg, text=tmp_path / "no-texts"))
    text = md.read_text(encoding="utf-8")
    assert text.startswith("# Reproduction report\n\nGenerated by `prodmaps report`")
    assert "## What differs from the paper" not in text and "## Glossary" not in text and f"## {CLAIMS}" in text
    assert "**Caption missing**: add an entry to `report_text/captions.toml`." in text


def test_document_blocks_are_checked_when_added():
    from prodmaps.pipeline.document import Document

    with pytest.raises(ValueError, match="not a document block"):
        Document([("h", "no level")])
    with pytest.raises(ValueError, match="not a document block"):
        Document().extend([("chart", "a.png")])
    with pytest.raises(ValueError, match="not a document block"):
        Document().extend([("figure", [[["a.png", "FAUST"]]])])  # a figure's caption is its second argument


# ------------------------------------------------------------------------------ the report as a referee reads it
PAPER = TEXT.parent
FULL = ("anny_humans", "faust", "faust_r", "tosca_r")  # the four datasets the paper's claims are judged on


def _inputs_with(folder: Path, main=None, datasets=(), kept=None):
    """``(inputs, settings, base)`` for :func:`build_document` from report data (no results folder read)."""
    from prodmaps.pipeline.report import ReportInputs

    main = main or DatasetReport("anny_humans", "results/paper", "abc1234",
                                 verdicts={c: ClaimResult("not measured here") for c in load_ledger()})
    inputs = ReportInputs(Path(folder), main.folder, main.commit, [], main, list(datasets),
                          [kept] if kept is not None else [], load_published(), [], [])
    return inputs, ReportSettings(text=TEXT, notebooks={}), Path(folder)


def _full_report_data(folder: Path) -> list:
    """Four datasets' report data at the size of a paper publication, written as a publication stores it.

    Every claim judged (verdicts in turn, a reading verdict, paired statistics, long evidence),
    every published cell with a value and an SE (differences at and around the ±0.02 boundary),
    every reading scored, every registered figure run with two images, every study with a
    paragraph that is the same on every dataset.
    """
    from prodmaps.pipeline.report_data import table_summaries

    runs, ledger, rows = load_registry(PAPER / "runs.toml"), load_ledger(), load_published()
    deltas = (0.0, 0.02, -0.02, 0.0204, 0.0206, 0.05, -0.3)  # at, around and far beyond the ±0.02 boundary
    out = []
    for n, ds in enumerate(FULL):
        verdicts = {cid: ClaimResult(VERDICTS[(i + n) % 3], {"textbook": VERDICTS[i % 3]}, "yes", "no", "yes",
                                     {"intra": "holds", "inter": "does not hold"},
                                     f"transfer error ours/std at most 0.9{i} over the families but hk k; " * 2,
                                     c.source, "measured", 0.05, "'significant improvement': 5 % of std's error",
                                     False, {"hk k": "in the span of the source basis"} if "tab" in cid else {},
                                     {"0.1": "inconclusive"},
                                     [{"label": "HKS", "n": 20, "ours": 0.2, "ref": 0.25, "mean_diff": 0.05,
                                       "se": 0.004, "rel": 0.2, "outcome": "holds"},
                                      {"label": "mean |std - ours|", "n": 20, "mean": 0.143, "se": 0.01,
                                       "bound": 0.15, "outcome": "inconclusive"}])
                    for i, (cid, c) in enumerate(ledger.items())}
        entries = [{**{k: r[k] for k in ("table", "fmap", "k_M", "k_N", "function", "stage", "method")},
                    "value": r["value"] + deltas[(i + n) % len(deltas)], "se": 0.01, "run": f"tab0{r['table']}"}
                   for i, r in enumerate(rows)]
        from prodmaps.pipeline.report_data import RunInfo, match_published, table_cells

        matches = match_published(entries, rows)[0]
        infos = [RunInfo(f"tab0{t}", folder, reproduces=f"Table {t}", doc={"results": {}}) for t in "123456"]
        tables = table_summaries(infos, rows, matches)
        figures, studies = [], []
        for run, r in runs.items():
            imgs = []
            for stem in (f"{run}_a", f"{run}_b"):
                p = folder / "report_figures" / ds / run / f"{stem}.png"
                p.parent.mkdir(parents=True, exist_ok=True)
                _png(p, n)
                imgs.append(p)
            if r.report:
                name = DATASET_NAMES[ds]
                studies.append(Study(run, ds, [("h", 2, f"Study: {run}, judged on {name}"),
                                               ("p", f"Every plausible reading run by `{run}` (the same text on "
                                                     "every dataset)."),
                                               ("table", ["reading", "cells"], [["a", "3/8"], ["b", "5/8"]]),
                                               ("p", f"Conclusion of {run} on {name}: b.")], imgs))
            else:
                figures.append(Figure(run, r.reproduces, imgs))
        readings = {label: {"label": label, "alternatives": 5 + k, "cells": "16 published std cells (T1, T3, T5, "
                            "T6)", "frozen": "t=5e-4", "choice": "t=5e-4" if n < 2 else "t=2e-3", "n": 16,
                            "within": 9 + n, "in_noise": 13 + n if label != "Approach B's normalisation" else None}
                    for k, label in enumerate(READING_ROWS)}
        readings["Section 4.4's heat time"] |= {"n": 0, "within": None, "in_noise": None, "frozen_error": 0.0131}
        out.append(DatasetReport(ds, f"results/paper-{ds}", "abc1234", list(runs),
                                 [f"s{i}" for i in range(40)], [[f"s{i}", f"s{i + 1}"] for i in range(20)],
                                 verdicts, tables, figures, studies, table_cells(rows, matches),
                                 {r: ["ok", 12.5] for r in runs}, readings))
    return out


@pytest.fixture(scope="module")
def full(tmp_path_factory):
    """The report of four datasets at full size, as Markdown, HTML and blocks."""
    from prodmaps.pipeline.report import build_document, write_document

    folder = tmp_path_factory.mktemp("full")
    main, *others = _full_report_data(folder)
    doc = build_document(*_inputs_with(folder, main, others))
    md, html = folder / "REPORT.md", folder / "REPORT.html"
    write_document(doc, md, html)
    return {"doc": doc, "text": md.read_text(encoding="utf-8"), "md": md, "html": html, "data": [main, *others]}


@pytest.fixture(scope="module")
def baselines_report(tmp_path_factory):
    """The report of the committed smoke baselines: every registered run's real results, published settings."""
    folder = tmp_path_factory.mktemp("baselines")
    md, html = build_report(PAPER / "baselines" / "smoke", folder / "REPORT.md",
                            ReportSettings(registry=PAPER / "runs.toml", strict_captions=True))
    return {"md": md, "html": html, "text": md.read_text(encoding="utf-8")}


def test_the_report_of_the_real_smoke_results(baselines_report):
    """Every registered run's results as committed (the smoke baselines): the report's rules on real data."""
    text = baselines_report["text"]
    assert words(_section(text, "Summary")) <= 600 and words(_main_text(text)) <= 4000
    paragraphs = _paragraphs(text)
    assert not {p for p in paragraphs if paragraphs.count(p) > 1}
    verdicts = evaluate_folder(PAPER / "baselines" / "smoke")
    assert {k: v for k, v in _ledger_counts(verdicts).items() if v} == _summary_counts(text)["embedded humans"]
    gallery = _section(text, "Appendix A: figure gallery")
    heads = re.findall(r"^### .*\(`(\w+)`\)$", gallery, flags=re.M)
    runs = load_registry(PAPER / "runs.toml")
    assert set(heads) == {r for r, x in runs.items() if not x.report}  # every figure run, captioned (strict)
    assert "Caption missing" not in text
    sec = _section(text, "Forking paths: readings chosen on one dataset, checked on the others")
    rows = {r[0]: r for r in _tables(sec)[0][1:]}
    assert {"hk k parameters", "Approach B's normalisation", "NO17 recipe", "Section 4.4's heat time"} <= set(rows)
    defined = _glossary_terms(text)
    rest = re.sub(r"!\[[^\]]*\]\([^)]*\)", "", text.replace(_section(text, "Glossary"), ""))
    assert {term for term, pattern in JARGON.items() if re.search(pattern, rest)} <= defined


def _main_text(text: str) -> str:
    return text.split("\n## Appendix", 1)[0]


def test_the_summary_fits_on_one_page_and_the_main_text_in_4000_words(full, project):
    for text in (full["text"], project["text"]):
        assert words(_section(text, "Summary")) <= 600
        assert words(_main_text(text)) <= 4000
    assert words(full["text"]) > 3 * words(_main_text(full["text"]))  # the rest is in the appendices
    paper = {ds.name: ds.counts_by_source()["paper"] for ds in full["data"]}
    assert _summary_counts(full["text"]) == {name: {k: v for k, v in c.items() if any(x[k] for x in paper.values())}
                                             for name, c in paper.items()}


def test_no_paragraph_is_repeated(full, project):
    for text in (full["text"], project["text"]):
        paragraphs = _paragraphs(text)
        repeated = {p for p in paragraphs if paragraphs.count(p) > 1}
        assert not repeated, repeated
        images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
        assert len(images) == len(set(images))
    shared = "Every plausible reading run by `study_default` (the same text on every dataset)."
    assert full["text"].count(shared) == 1  # a study's text, the same on four datasets, is shown once
    assert all(full["text"].count(f"Conclusion of {r} on {ds.name}: b.") == 1 for ds in full["data"]
               for r in ("study_default", "study_truncation"))  # what differs stays


JARGON = {  # the glossary's term -> how the report uses it (a term used must be defined)
    "reading": r"\breadings?\b", "textbook": r"\btextbook\b", "default": r"\bdefault\b", "OFP": r"\bOFP\b",
    "oracle": r"\boracle\b", "gain rule": r"\bgain rule\b", "pair-k cell": r"\bpair-k cells?\b",
    "embedded humans": r"\bembedded humans\b", "within draw noise": r"\bwithin draw noise\b", "SE": r"\bSE\b",
    "std": r"\bstd\b", "Approach A": r"\bApproach A\b", "Approach B": r"\bApproach B\b", "NO17": r"\bNO17\b",
    "AWFT": r"\bAWFT\b", "HKS": r"\bHKS\b", "WKS": r"\bWKS\b", "SHOT": r"\bSHOT\b", "hk k": r"\bhk k\b",
    "hk K": r"\bhk K\b", "C~": r"C~", "k_M": r"\bk_M\b", "k_N": r"\bk_N\b", "rtol": r"\brtol\b",
    "intra": r"\bintra\b", "inter": r"\binter\b", "within rounding": r"\bwithin rounding\b",
    "inconclusive": r"\binconclusive\b", "not empirical": r"\bnot empirical\b",
    "not demonstrable in this setting": r"\bnot demonstrable in this setting\b", "control": r"\bcontrol\b",
    "frozen reading": r"\bfrozen reading\b", "FAUST_r": r"\bFAUST_r\b", "TOSCA_r": r"\bTOSCA_r\b",
    "ACBCO17": r"\bACBCO17\b", "LMH": r"\bLMH\b", "paired comparison": r"\bpaired comparison\b",
    "claims ledger": r"\bclaims ledger\b", "profile": r"\bprofile\b", "holds with the threshold rule":
    r"\bholds with the threshold rule\b", "not measured here": r"\bnot measured here\b",
    "our_B": r"\bour_B\b", "our_l1": r"\bour_l1\b", "our_A": r"\bour_A\b", "approx": r"\bapprox\b",
    "ground_truth": r"\bground_truth\b", "computed_NO17": r"\bcomputed_NO17\b",
}


def _glossary_terms(text: str) -> set:
    (table,) = _tables(_section(text, "Glossary"))
    assert table[0] == ["term", "meaning"]
    return {t.strip() for r in table[1:] for t in re.split(r",\s*|\s+/\s+", r[0])}


def test_the_glossary_defines_every_term_the_report_uses(full, project):
    for text in (full["text"], project["text"]):
        defined = _glossary_terms(text)
        rest = re.sub(r"!\[[^\]]*\]\([^)]*\)", "", text.replace(_section(text, "Glossary"), ""))  # no images
        used = {term for term, pattern in JARGON.items() if re.search(pattern, rest)}
        assert used - defined == set(), used - defined
        studies = {r for r in load_registry(PAPER / "runs.toml") if r.startswith("study_")
                   and re.search(rf"\b{r}\b", rest)}
        assert studies and studies <= defined, studies - defined
    assert {"reading", "textbook", "OFP", "oracle", "pair-k cell", "SE"} <= _glossary_terms(full["text"])


def test_every_run_has_a_caption_and_a_missing_one_is_refused_in_a_publication(tmp_path):
    from prodmaps.pipeline.prose import report_captions
    from prodmaps.pipeline.report import build_document

    captions, runs = report_captions(TEXT), load_registry(PAPER / "runs.toml")
    assert set(captions) == set(runs), (set(runs) - set(captions), set(captions) - set(runs))
    for run, c in captions.items():
        assert c.get("ours") and (c.get("look") or c.get("paper")), run
    main, *others = _full_report_data(tmp_path)
    main.figures.append(Figure("new_run", "Figure 99", [main.figures[0].images[0]]))
    inputs, settings, base = _inputs_with(tmp_path, main, others)
    text = build_document(inputs, settings, base).markdown()
    assert "### Figure 99 (`new_run`)\n\n**Caption missing**" in text
    strict = ReportSettings(text=TEXT, notebooks={}, strict_captions=True)
    with pytest.raises(ValueError, match=r"no caption for the runs new_run: add an entry .*captions\.toml"):
        build_document(inputs, strict, base)
    bad = tmp_path / "texts"
    shutil.copytree(TEXT, bad)
    (bad / "captions.toml").write_text('[fig02]\nshows = "x"\n')
    with pytest.raises(ValueError, match=r"\[fig02\] needs text under paper, look, ours"):
        report_captions(bad)


def test_figures_are_laid_out_like_the_papers(full):
    gallery = _section(full["text"], "Appendix A: figure gallery")
    fig12 = _section(gallery, "Figures 12 and 13 (`fig12_13`)", 3)
    tables = _tables(fig12)
    # FAUST_r left and the centaur's TOSCA_r right, as the paper's FAUST and TOSCA panels; then the others
    assert tables[0][0] == ["FAUST_r", "TOSCA_r"] and tables[1][0] == ["embedded humans", "FAUST"]
    assert tables[0][1] == ["![FAUST_r](report_figures/faust_r/fig12_13/fig12_13_a.png)",
                            "![TOSCA_r](report_figures/tosca_r/fig12_13/fig12_13_a.png)"]
    assert fig12.strip().startswith("**The paper's Figures 12 and 13:**") and "`fig12_13_b`" in fig12
    fig07 = _tables(_section(gallery, "Figure 7 (`fig07`)", 3))
    assert fig07[0][0] == ["embedded humans", "TOSCA_r"]  # Figure 7 on TOSCA beside the humans' version
    html = full["html"].read_text(encoding="utf-8")
    row = '<div class="row"><div class="panel"><img src="report_figures/faust_r/fig12_13/fig12_13_a.png"'
    assert row in html


def test_each_dataset_has_an_appendix_of_every_cell(full):
    text = full["text"]
    for n, ds in enumerate(full["data"], 1):
        app = _section(text, f"Appendix C{n}: {ds.name}")
        tables = _tables(app)[2:]
        assert [len(t) - 1 for t in tables] == [N_PUB[t] for t in "123456"]
        assert all("within draw noise" in t[0] and "SE" in t[0] for t in tables)
        claims = _appendix_claims(text, ds.name)
        assert list(claims) == list(load_ledger())
        c = claims["tab01.products_improve_transfer"]
        assert c["paired comparison"] == ("HKS: +0.05 ± 0.004, n = 20, +20% (holds); "
                                          "mean |std - ours|: 0.143 ± 0.01, n = 20, bound 0.15 (inconclusive)")
        assert c["margin"] == "0.05 ('significant improvement': 5 % of std's error); at 0.1: inconclusive"
        assert c["left out"] == "hk k: in the span of the source basis"
        # the boundary: the printed difference decides (0.0204 prints +0.020: within; 0.0206 prints +0.021: not)
        rows = [r for t in tables for r in t[1:]]
        shown = {(r[-4], r[-3]) for r in rows}
        assert {("+0.020", "yes"), ("-0.020", "yes"), ("+0.021", "no")} <= shown
        assert all((r[-3] == "yes") == (abs(float(r[-4])) <= 0.02) for r in rows)
        summary = _summary_rows(text, ds.name)
        for t, table in zip("123456", tables):
            assert summary[f"Table {t}"][2] == str(sum(r[-3] == "yes" for r in table[1:]))


def test_forking_paths_show_the_chosen_and_the_held_out_data(full):
    sec = _section(full["text"], "Forking paths: readings chosen on one dataset, checked on the others")
    table = _tables(sec)[0]
    assert table[0] == ["reading", "readings scored", "cells that judge it", "frozen reading", "embedded humans",
                        "FAUST (chosen here)", "FAUST_r", "TOSCA_r"]
    rows = {r[0]: r for r in table[1:]}
    hk = rows["hk k parameters"]
    assert hk[1:5] == ["5", "16 published std cells (T1, T3, T5, T6)", "t=5e-4", "13 of 16; same choice"]
    assert hk[5:] == ["14 of 16", "15 of 16; would choose t=2e-3", "16 of 16; would choose t=2e-3"]
    assert rows["Approach B's normalisation"][5] == "10 of 16 within ±0.02 (no SE)"
    assert rows["Section 4.4's heat time"][5:] == ["error 0.0131", "error 0.0131; would choose t=2e-3",
                                                   "error 0.0131; would choose t=2e-3"]
    assert list(rows) == list(READING_ROWS) and "Not scored" not in sec
    assert "Readings another dataset would choose: hk k parameters: t=2e-3;" in sec
    claims = _tables(sec)[1]
    # the humans' and TOSCA_r's verdicts are the same under the textbook families here: no column of theirs
    assert claims[0] == ["claim", "FAUST", "FAUST_r"]
    by = {r[0]: r for r in claims[1:]}
    changed = [cid for cid, c in load_ledger().items() if c.where.startswith("Table") and any(
        ds.verdicts[cid].readings["textbook"] != ds.verdicts[cid].verdict for ds in full["data"])]
    assert [r.strip("`") for r in by] == changed
    c = full["data"][1].verdicts["tab01.products_improve_transfer"]
    assert by["`tab01.products_improve_transfer`"][1] == f"{c.verdict}; textbook families: {c.readings['textbook']}"


def _reading_runs():
    """Results of the runs that score the frozen readings (the experiments' own keys), with numbers to count."""
    pub1 = published_values("T1", "ground_truth")
    frozen = "uniform, ordered, unit_area"
    family = {"scores": {"Random": {"textbook": {"std": {"cells": 2, "within": 0, "mean_abs": 0.1}},
                                    frozen: {"std": {"cells": 2, "within": 1, "mean_abs": 0.03}}}},
              "published_readings": {"Random": frozen}, "chosen": {"Random": "textbook"}, "agrees": {"Random": False},
              "groups": {"T1": [[9, 9]]},
              "errors": {"Random": {frozen: {"k9_9": {
                  "approx": {"std": pub1[(9, 9, "approx", "std", "Random")] + 0.01},
                  "transfer": {"std": pub1[(9, 9, "transfer", "std", "Random")] + 0.05}}}}},
              "standard_errors": {"Random": {frozen: {"k9_9": {"approx": {"std": 0.001}, "transfer": {"std": 0.02}}}}}}
    # the tables on the same dataset: Random's std cells off by +0.03 (SE 0.001: beyond the draw) and 0.0
    table = [{"table": 1, "fmap": "ground_truth", "k_M": 9, "k_N": 9, "function": "Random", "stage": st,
              "method": "std", "value": pub1[(9, 9, st, "std", "Random")] + d, "se": 0.001}
             for st, d in (("approx", 0.03), ("transfer", 0.0))]
    tab01 = {"table_name": "T1", "fmap": "ground_truth", "table": table}
    norm = {"scores": {"metres": {"our_B": {"cells": 4, "within": 1, "mean_abs": 0.2}},
                       "unit Euclidean eigenvectors": {"our_B": {"cells": 4, "within": 3, "mean_abs": 0.01}}},
            "tables": {"T1": [[9, 9]]},
            "claim_verdicts": {"metres": {"tab01.products_improve_transfer": "does not hold"},
                               "unit Euclidean eigenvectors": {"tab01.products_improve_transfer": "holds"}},
            "chosen_reading": "unit Euclidean eigenvectors"}
    no17 = {"default_recipe": "authors_200",
            "comparison": {"rows": [{"recipe": r, "family": f, "ours": 0.1, "published": 0.1 + d, "diff": -d}
                                    for r, d in (("authors_200", 0.01), ("pyfm", 0.05)) for f in ("hk_k", "XYZ")],
                           "summary": {"gt": {"mean_abs": 0.0}, "authors_200": {"mean_abs": 0.01},
                                       "pyfm": {"mean_abs": 0.05}}}}
    p2p = {"sweep": {"rows": [{"size": [40, 30], "setting": "extended t x1", "mean_error": 0.013},
                              {"size": [40, 30], "setting": "extended t x2", "mean_error": 0.012},
                              {"size": [40, 30], "setting": "std", "mean_error": 0.02}]}}
    return {"study_family_readings": family, "tab01": tab01, "study_normalization": norm, "study_no17": no17,
            "fig12_13": p2p}


def test_reading_scores_from_the_runs_results():
    from prodmaps.pipeline.report_data import RunInfo, reading_scores

    infos = [RunInfo(n, Path("."), doc={"results": r}) for n, r in _reading_runs().items()]
    got = reading_scores(infos)
    assert list(got) == ["Random parameters", "Approach B's normalisation", "NO17 recipe", "Section 4.4's heat time"]
    # the tables' counts (their pairs, with SE): +0.03 beyond 0.02 + 2·√2·0.001, 0.0 within; the study's choice
    assert got["Random parameters"] == {"label": "Random parameters", "alternatives": 2,
                                        "cells": "published std cells (T1, T3, T5, T6)",
                                        "frozen": "uniform, ordered, unit_area", "choice": "textbook", "n": 2,
                                        "within": 1, "in_noise": 1}
    assert got["Approach B's normalisation"] == {  # the study's alone: the tables hold no Approach B cell here
        "label": "Approach B's normalisation", "alternatives": 2, "cells": "4 published Approach B cells (T1)",
        "frozen": "unit Euclidean eigenvectors", "choice": "unit Euclidean eigenvectors", "n": 4, "within": 3,
        "in_noise": None}
    assert (got["NO17 recipe"]["frozen"], got["NO17 recipe"]["choice"], got["NO17 recipe"]["n"],
            got["NO17 recipe"]["within"]) == ("authors_200", "authors_200", 2, 2)
    heat = got["Section 4.4's heat time"]
    assert (heat["n"], heat["frozen_error"], heat["choice"], heat["alternatives"]) == (0, 0.013, "extended t x2", 2)
    lead = {"Section 4.4's heat time": {"label": "Section 4.4's heat time", "alternatives": 3}}
    infos.append(RunInfo("extra", Path("."), doc={"results": {"forking_paths": lead}}))
    assert reading_scores(infos)["Section 4.4's heat time"] == lead["Section 4.4's heat time"]  # a run's own rows


def test_a_datasets_readings_and_its_verdicts_under_the_rejected_normalisation(tmp_path):
    reg, res = make_project(tmp_path)
    faust = res.with_name(res.name + "-faust")
    _faust_tab01(faust, [["tr_reg_000", "tr_reg_001"]])
    for run, results in _reading_runs().items():
        if run != "tab01":
            _run(faust, run, _doc(results), _manifest(run, "ok", 1.0))
    md, _ = build_report(res, tmp_path / "paper" / "R.md", ReportSettings(registry=reg))
    text = md.read_text(encoding="utf-8")
    sec = _section(text, "Forking paths: readings chosen on one dataset, checked on the others")
    rows = {r[0]: r for r in _tables(sec)[0][1:]}
    assert _tables(sec)[0][0][4:] == ["FAUST (chosen here)"]  # the humans' folder has no such run here
    assert rows["Section 4.4's heat time"][4] == "error 0.013; would choose extended t x2"
    assert rows["Approach B's normalisation"][4] == "3 of 4 within ±0.02 (no SE)"
    assert rows["Random parameters"][4] == "2 of 2; would choose textbook"  # the study's: no Random cell in tab01
    # the table claim under the metre normalisation, beside its verdict as chosen
    claims = _tables(sec)[1]
    assert claims[0] == ["claim", "FAUST"]
    by = {r[0]: r for r in claims[1:]}
    verdict = _appendix_claims(text, "FAUST")["tab01.products_improve_transfer"]["verdict"]
    assert by["`tab01.products_improve_transfer`"][1].startswith(f"{verdict}; metres normalisation: does not hold")


# ------------------------------------------------------------------------------ in a real browser
_CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)), None)
_CHECK = """<script>window.addEventListener("load", () => {
  const out = document.createElement("pre");
  out.id = "render-check";
  out.textContent = JSON.stringify({
    images: [...document.images].map(i => [i.getAttribute("src"), i.complete && i.naturalWidth > 0]),
    links: [...document.querySelectorAll("a[href]")].map(a => [a.getAttribute("href"), a.href]),
    ids: [...document.querySelectorAll("[id]")].map(e => e.id)});
  document.body.appendChild(out);
});</script>"""


def _render(page: Path, tmp: Path) -> dict:
    """What headless Chromium makes of ``page``: its images (loaded or not), its links (resolved), its ids.

    A copy of the page in ``tmp`` with a ``<base>`` at the page's folder (so every relative link
    resolves as from the page) and a script that records, once the page has loaded, every image's
    ``naturalWidth`` and every link as the browser resolves it.
    """
    import html as html_lib
    import subprocess

    text = page.read_text(encoding="utf-8")
    text = text.replace("<head>", f'<head><base href="{page.parent.resolve().as_uri()}/">', 1)
    tmp.mkdir(parents=True, exist_ok=True)
    copy = tmp / "render-check.html"
    copy.write_text(text.replace("</body>", _CHECK + "</body>", 1), encoding="utf-8")
    cmd = [_CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={tmp / 'chromium-profile'}", "--virtual-time-budget=30000",
           "--run-all-compositor-stages-before-draw", "--dump-dom", copy.as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    m = re.search(r'<pre id="render-check">(.*?)</pre>', proc.stdout, flags=re.S)
    assert m, f"Chromium did not run the page's check (exit {proc.returncode}): {proc.stderr[-1500:]}"
    return json.loads(html_lib.unescape(m.group(1)))


def _assert_renders(page: Path, tmp: Path) -> int:
    """Every image of ``page`` loaded in Chromium and every link resolving (a file that exists, an anchor that does)."""
    from urllib.parse import unquote, urlparse

    got = _render(page, tmp)
    source = page.read_text(encoding="utf-8")
    assert len(got["images"]) == source.count("<img ") > 0
    assert [src for src, ok in got["images"] if not ok] == []
    ids = set(got["ids"])
    for href, resolved in got["links"]:
        if href.startswith("#"):
            assert href[1:] in ids, href
        else:
            url = urlparse(resolved)
            assert url.scheme == "file" and Path(unquote(url.path)).is_file(), (href, resolved)
    return len(got["images"])


@pytest.mark.skipif(_CHROMIUM is None, reason="Chromium is not installed: apt-get install chromium "
                                              "(.ci/run installs it where apt is available)")
def test_the_html_report_renders_in_chromium_with_every_figure_and_link(full, project, baselines_report, tmp_path):
    assert _assert_renders(full["html"], tmp_path / "full") == len(re.findall(r"!\[", full["text"]))
    assert _assert_renders(baselines_report["html"], tmp_path / "baselines") == len(
        re.findall(r"!\[", baselines_report["text"]))
    assert _assert_renders(project["html"], tmp_path / "project") == 3
    assert _assert_renders(PAPER / "REPORT.html", tmp_path / "committed") > 20  # the committed report
    # a broken figure is caught
    broken = full["md"].parent / "BROKEN.html"
    broken.write_text(full["html"].read_text(encoding="utf-8").replace('src="report_figures/faust/fig07/',
                                                                       'src="report_figures/faust/nothing/'))
    with pytest.raises(AssertionError):
        _assert_renders(broken, tmp_path / "broken")


def test_a_held_out_choice_is_compared_with_that_datasets_name_of_the_frozen_reading():
    from types import SimpleNamespace as R

    from prodmaps.pipeline.forking import forking_blocks, forking_paths

    row = {"label": "NO17 recipe", "alternatives": 3, "cells": "T2 std", "n": 5, "within": 2, "in_noise": 4}
    reports = [R(dataset="faust", readings={"NO17 recipe": {**row, "frozen": "authors_200", "choice": "authors_200"}}),
               R(dataset="faust_r", readings={"NO17 recipe": {**row, "frozen": "a200", "choice": "a200"}}),
               R(dataset="tosca_r", readings={"NO17 recipe": {**row, "frozen": "a200", "choice": "pyfm"}})]
    paths = forking_paths(reports)
    (table, note) = forking_blocks(paths, {}, ["faust", "faust_r", "tosca_r"])[:2]
    assert table[2][0][4:] == ["4 of 5", "4 of 5; same choice", "4 of 5; would choose pyfm"]
    assert note[1].startswith("Not scored by the studies in these results: hk k parameters;")
    assert "Readings another dataset would choose: NO17 recipe: pyfm." in forking_blocks(paths, {}, ["faust"])[2][1]
