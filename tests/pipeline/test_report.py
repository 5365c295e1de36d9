"""prodmaps.pipeline.report: the claims-first reproduction report from a synthetic results folder.

The results folder and the registry are written here, as ``prodmaps reproduce`` writes them
(``results.json``, ``manifest.json``, PNGs, ``executed.html``, ``error.txt``): no notebook runs.
The claims are the package's ledger; the runs below cover a few of its claims and leave the
others "not measured here".
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from prodmaps.experiments.shared.claims import VERDICTS, load_ledger
from prodmaps.experiments.shared.published import load_published, published_values
from prodmaps.pipeline import execute
from prodmaps.pipeline.publishing import PublishError, publish
from prodmaps.pipeline.registry import load_registry
from prodmaps.pipeline.report import ReportSettings, build_report
from prodmaps.pipeline.report_data import ClaimResult, DatasetReport, Figure, Study, TableSummary, collect_runs

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

# what the ledger's rules give on these numbers: claim -> (verdict of "all", marks paper/rule/default, intra/inter)
EXPECTED = {
    "fig02.rank": ("holds", ("yes", "—", "—"), "", "rank 9 of the extended basis = 2k+1 = 9"),
    "fig02.dependency": ("does not hold", ("no", "—", "—"), "", "residual 1.0e-03 with λ = -0.797885"),
    "fig02.higher_frequencies": ("holds", ("yes", "—", "—"), "", "products reach frequency 8, the basis 4"),
    "tab01.products_improve_transfer": (
        "holds", ("yes", "yes", "yes"), "intra: holds with the threshold rule; inter: does not hold",
        "transfer error ours/std at most 0.83 over the families but hk k"),
    "tab01.products_improve_approximation": (
        "does not hold", ("no", "no", "yes"), "intra: does not hold; inter: does not hold",
        "approximation error ours/std at most 1.11"),
    "tab01.point_map_transfer_worse": (
        "holds", ("yes", "—", "—"), "intra: not measured here; inter: not measured here",
        "point-map transfer worse than std for 3 of 3 families"),
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
    tab01 = {f"errors{sub}": {"k9_9": {"approx": APPROX, "transfer": tr}} for sub, tr in TRANSFER.items()}
    tab01["table"] = TABLE1
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
def _section(text: str, heading: str) -> str:
    """The text of a ``## heading`` section, up to the next ``## `` heading."""
    m = re.search(rf"^## {re.escape(heading)}.*?$(.*?)(?=^## |\Z)", text, flags=re.M | re.S)
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


def _claim_rows(text: str) -> dict[str, dict]:
    (table,) = _tables(_section(text, "Claims of the paper"))
    header, rows = table[0], table[1:]
    assert header == ["claim", "where", "the paper's words", "verdict", "paper", "rule", "default", "intra / inter",
                      "evidence", "notebook"]
    out = {}
    for r in rows:
        assert len(r) == len(header), r
        cid = r[0].strip("`")
        assert cid not in out, f"claim {cid} listed twice"
        out[cid] = dict(zip(header, r))
    return out


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


# ------------------------------------------------------------------------------ claims first
def test_report_files_and_return_value(project):
    assert project["md"] == (project["root"] / "paper" / "REPORT.md").resolve()
    assert project["html"] == project["md"].with_suffix(".html")
    assert project["md"].is_file() and project["html"].is_file()
    assert not list(project["md"].parent.glob("*.tmp"))  # written atomically


def test_claims_section_comes_first(project):
    text = project["text"]
    headings = [ln for ln in text.splitlines() if ln.startswith("#")]
    assert headings[0] == "# Reproduction report: Improved Functional Mappings via Product Preservation"
    assert headings[1] == "## Claims of the paper, judged on these results"
    level2 = [h for h in headings if h.startswith("## ")]
    assert [h.split(":")[0] for h in level2] == [
        "## Claims of the paper, judged on these results", "## Tables 1–6",
        "## Study", "## Runs", "## Figures", "## Appendix"]
    # nothing but the one paragraph of provenance between the title and the claims
    between = text.split(headings[0], 1)[1].split(headings[1], 1)[0].strip()
    assert "\n" not in between and between.startswith("Nogneng, Melzi")
    assert "`results`" in between  # the results folder, shown relative to the project


def test_every_ledger_claim_has_a_verdict(project):
    ledger = load_ledger()
    rows = _claim_rows(project["text"])
    assert list(rows) == list(ledger)  # one row per claim, ledger order
    for cid, row in rows.items():
        claim = ledger[cid]
        assert row["verdict"].strip("*") in VERDICTS, (cid, row["verdict"])
        assert row["where"] == claim.where
        if cid in EXPECTED:
            continue
        # a claim whose runs' results are absent here is not measured
        assert not set(claim.runs) <= PRESENT_WITH_RESULTS, f"{cid}: add it to EXPECTED"
        assert row["verdict"] == "not measured here", cid
        assert (row["paper"], row["rule"], row["default"]) == ("—", "—", "—"), cid
        m = re.fullmatch(r"not measured: run '(\w+)' not available", row["evidence"])
        assert m and m.group(1) in set(claim.runs) - PRESENT_WITH_RESULTS, (cid, row["evidence"])


def test_verdicts_of_the_measured_claims(project):
    rows = _claim_rows(project["text"])
    for cid, (verdict, marks, kinds, evidence) in EXPECTED.items():
        row = rows[cid]
        shown = f"**{verdict}**" if verdict == "does not hold" else verdict
        assert row["verdict"] == shown, cid
        assert (row["paper"], row["rule"], row["default"]) == marks, cid
        assert row["intra / inter"] == kinds, cid
        assert row["evidence"].startswith(evidence), (cid, row["evidence"])


def test_claims_totals_and_quotes(project):
    text, ledger = project["text"], load_ledger()
    rows = _claim_rows(text)
    n_holds = sum(v[0] == "holds" for v in EXPECTED.values())
    n_not = sum(v[0] == "does not hold" for v in EXPECTED.values())
    n_unmeasured = len(ledger) - len(EXPECTED)
    assert (n_holds, n_not) == (4, 2)
    totals = (f"Totals over {len(ledger)} claims: {n_holds} holds, {n_not} does not hold, "
              f"{n_unmeasured} not measured here.")
    assert totals in _section(text, "Claims of the paper")
    for cid, row in rows.items():
        q = ledger[cid].quote
        assert row["the paper's words"] == f"“{q[:110]}{'…' if len(q) > 110 else ''}”"


def test_no_reproduced_wording(project):
    for text in (project["text"], project["html_text"]):
        assert not re.search(r"\d+\s+of\s+\d+\s+published values reproduced", text)
        assert "reproduced" not in text.lower()


# ------------------------------------------------------------------------------ tables
SUMMARY_HEADER = ["table", "cells compared", "within ±0.02", "missed, within draw noise", "mean |diff|",
                  "largest |diff|", "products beat std: paper B (all · intra · inter)", "gain rule", "default"]


def _summary_rows(text):
    (table,) = _tables(_section(text, "Tables 1–6"))
    assert table[0][0] == "table"  # (the header row itself: see test_markdown_table_headers_escape_pipes)
    assert all(len(r) == len(SUMMARY_HEADER) for r in table[1:])
    return {r[0]: r for r in table[1:]}


def test_markdown_table_headers_escape_pipes(project):
    (table,) = _tables(_section(project["text"], "Tables 1–6"))
    assert table[0] == SUMMARY_HEADER
    header_line = next(ln for ln in _section(project["text"], "Tables 1–6").splitlines() if ln.startswith("|"))
    assert len(re.findall(r"(?<!\\)\|", header_line)) == len(SUMMARY_HEADER) + 1


def test_table_summaries_count_mean_and_largest_difference(project):
    rows = _summary_rows(project["text"])
    assert list(rows) == [f"Table {t}" for t in range(1, 7)]
    diffs = sorted(abs(d) for d in DELTAS.values())
    assert sum(d <= 0.02 for d in diffs) == 2 and abs(np.mean(diffs) - 0.041) < 1e-12
    t1 = rows["Table 1"]
    assert t1[1:6] == [f"4 of {N_PUB['1']}", "2", "1 of 2", "0.041", "0.100"]
    # products beat std, per method, over all · intra · inter pairs (3 families, one size)
    assert t1[6:] == ["2/3 · 1/3 · 0/3", "3/3 · 2/3 · 1/3", "2/3 · 2/3 · 0/3"]
    # Table 2: one value from an unregistered run (top-level "table", no standard error: no noise count),
    # no tab02 run for the product columns
    assert rows["Table 2"][1:] == [f"1 of {N_PUB['2']}", "0", "—", "0.030", "0.030", "— · — · —", "— · — · —",
                                   "— · — · —"]
    for t in "3456":
        assert rows[f"Table {t}"][1:6] == [f"0 of {N_PUB[t]}", "—", "—", "—", "—"]
    assert "Systematic differences (stated once):" in _section(project["text"], "Tables 1–6")


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
    app = _section(text, "Appendix")
    assert "| HKS | transfer | std | 0.50 | 0.550 | +0.050 | 0.004 | tab01 |" in app
    assert "| HKS | transfer | our_B | 0.11 | 0.100 | -0.010 | 0.012 | tab01 |" in app
    assert "| WKS | transfer | std | 0.20 | — |  |  |  |" in app


def test_no_published_csv_means_no_table_sections(tmp_path):
    _, res = make_project(tmp_path)
    md, _ = build_report(res, tmp_path / "R.md", ReportSettings(registry=tmp_path / "paper" / "runs.toml",
                                                                published=tmp_path / "missing.csv"))
    text = md.read_text(encoding="utf-8")
    assert "## Tables 1–6" not in text and "## Appendix" not in text
    assert text.index("## Claims of the paper") < text.index("## Runs")


def test_appendix_lists_every_published_value(project):
    app = _section(project["text"], "Appendix")
    heads = re.findall(r"^### (.*)$", app, flags=re.M)
    assert heads[0] == "Table 1: ground_truth, k_M = 9, k_N = 9"
    assert heads[-1] == "Table values that match no published number"
    tables = _tables(app)
    assert len(tables) == 7  # six paper tables and the unmatched values
    t1 = tables[0]
    assert t1[0] == ["function", "stage", "method", "published", "ours", "difference", "SE of ours", "run"]
    assert len(t1) - 1 == N_PUB["1"]
    by = {(r[1], r[2], r[0]): r for r in t1[1:]}
    for key, delta in DELTAS.items():
        pub = PUB1[(9, 9) + key]
        se = next(e.get("se") for e in TABLE1 if e["value"] == pytest.approx(pub + delta))
        assert by[key][3:] == [f"{pub:.2f}", f"{pub + delta:.3f}", f"{delta:+.3f}",
                               "—" if se is None else f"{se:.3f}", "tab01"], key
    assert by[("transfer", "std", "WKS")][4:] == ["—", "", "", ""]
    assert tables[2][0][:3] == ["k_M", "k_N", "function"]  # Table 3 has two settings
    t2 = {(r[1], r[2], r[0]): r for r in tables[1][1:]}
    assert t2[("transfer", "std", "HKS")][7] == "extra_run"
    unmatched = tables[-1]
    assert unmatched[0] == ["run", "entry", "reason"]
    assert len(unmatched) == 2
    assert unmatched[1][0] == "tab01" and '"function": "Nope"' in unmatched[1][1]
    assert unmatched[1][2] == "no published value with these keys"


# ------------------------------------------------------------------------------ study, runs, figures
def test_study_section_conclusions(project):
    study = _section(project["text"], "Study")
    assert ("- `gt_9_9`: median over pairs of the largest transfer gain kept at rtol = 1e-3: 123.4; at 1e-2: 5.6"
            in study)
    # HKS: gain 0.2 <= paper 0.3, <= 1.1 oracle, <= std; XYZ: gain 0.4 > paper 0.35, > 1.1 * 0.3, <= std 0.5
    assert ("- `gt_9_9`: the gain rule is at least as good as the paper's 1e-3 for 1 of 2 families, within 10 % of "
            "the oracle threshold for 1, and below the standard transfer for 2") in study
    assert "![study_truncation gains](../results/study_truncation/gains.png)" in study
    assert project["text"].count("gains.png") == 1  # not repeated under Figures


def test_runs_table_status_time_and_links(project):
    runs = _section(project["text"], "Runs")
    (table,) = _tables(runs)
    assert table[0] == ["run", "reproduces", "status", "time (s)", "figures", "read"]
    by = {r[0].strip("`"): r for r in table[1:]}
    assert list(by) == ["fig02", "fig03", "fig04", "tab01", "study_truncation", "extra_run"]
    assert by["tab01"][1:] == ["Table 1", "ok", "12.3", "1", "[executed notebook](../results/tab01/executed.html)"]
    assert by["fig03"][1:] == ["Figure 3", "failed", "1.5", "0", "[executed notebook](../results/fig03/executed.html)"]
    assert by["fig04"][1:] == ["Figure 4", "missing", "", "0", "executed notebook"]  # no file: no link
    assert by["extra_run"][1:] == ["", "ok", "", "0", "executed notebook"]
    assert "**Failed or not run:** `fig03`, `fig04`." in runs


def test_figures_section(project):
    figs = _section(project["text"], "Figures")
    assert re.findall(r"^### (.*)$", figs, flags=re.M) == ["fig02 — Figure 2", "fig03 — Figure 3", "tab01 — Table 1"]
    assert "![fig02 fourier](../results/fig02/fourier.png)" in figs
    assert "![tab01 table](../results/tab01/table.png)" in figs
    assert "Status **ok**, 12.3 s; outputs in `results/tab01`;" in figs  # relative to the project
    # the failed run shows the first 15 lines of its error.txt
    block = re.search(r"```\n(.*?)\n```", figs, flags=re.S).group(1).splitlines()
    assert block == [f"error line {i}" for i in range(1, 16)]


def test_links_to_executed_notebooks_are_relative(project):
    base = project["md"].parent
    text = project["text"]
    links = re.findall(r"\]\(([^)\s]+)\)", text)
    assert links, "no links in the report"
    for link in links:
        assert not link.startswith("/") and "://" not in link and not re.match(r"^[A-Za-z]:", link), link
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
    h2 = re.findall(r"<h2>(.*?)</h2>", h)
    assert h2[0] == "Claims of the paper, judged on these results"
    assert h.index("<h1>") < h.index("<h2>Claims")
    assert '<a href="../results/tab01/executed.html">tables_transfer</a>' in h
    assert '<img src="../results/tab01/table.png" alt="tab01 table">' in h
    assert "<b>does not hold</b>" in h and "**" not in h
    hrefs = re.findall(r'(?:href|src)="([^"]+)"', h)
    assert hrefs and all(not x.startswith("/") and "://" not in x for x in hrefs)
    md_tables = sum(len(_tables(_section(project["text"], s))) for s in ("Claims", "Tables", "Runs", "Appendix"))
    assert h.count("<table>") == md_tables == 10


def test_html_written_where_requested_and_figures_copied(tmp_path, monkeypatch):
    reg, res = make_project(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    out = tmp_path / "paper" / "R.md"
    html_out = tmp_path / "paper" / "site.html"
    md, html = build_report(res, out, ReportSettings(registry=reg, copy_figures=True), html_out=html_out)
    assert (md, html) == (out.resolve(), html_out)
    assert html_out.is_file() and not out.with_suffix(".html").exists()
    text = md.read_text(encoding="utf-8")
    assert "![tab01 table](report_figures/tab01/table.png)" in text
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
    assert "## Claims of the paper" in md.read_text(encoding="utf-8")


def test_html_links_resolve_from_the_html_folder(tmp_path, monkeypatch):
    reg, res = make_project(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    _, html = build_report(res, tmp_path / "paper" / "R.md", ReportSettings(registry=reg),
                           html_out=tmp_path / "paper" / "R2.html")
    links = re.findall(r'(?:href|src)="([^"]+)"', html.read_text(encoding="utf-8"))
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
    (table,) = _tables(_section(text, "Runs"))
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


def test_a_prepared_dataset_gets_a_verdict_column_and_a_section(tmp_path):
    reg, res = make_project(tmp_path)
    faust = res.with_name(res.name + "-faust")  # what `prodmaps reproduce --dataset faust` writes
    tab01 = {f"errors{sub}": {"k9_9": {"approx": APPROX, "transfer": tr}} for sub, tr in TRANSFER.items()}
    tab01["table"] = TABLE1
    tab01["pairs"] = [["tr_reg_000", "tr_reg_001"], ["tr_reg_010", "tr_reg_025"]]
    _run(faust, "tab01", _doc(tab01, table="T1"), _manifest("tab01", "ok", 3.0), pngs=["table.png"])
    md, _ = build_report(res, tmp_path / "paper" / "REPORT.md", ReportSettings(registry=reg))
    text = md.read_text(encoding="utf-8")
    claims = _section(text, "Claims of the paper, judged on these results")
    (table,) = _tables(claims)
    head = [h.strip() for h in table[0]]
    assert head.index("FAUST") == head.index("default") + 1
    row = {r[0].strip("`"): r for r in table[1:]}["tab01.products_improve_transfer"]
    assert row[head.index("FAUST")].strip().startswith(("holds", "**does not hold**"))
    assert row[head.index("FAUST")] != "not measured here"
    assert "On FAUST:" in claims
    faust_sec = _section(text, "On FAUST")
    assert "`tr_reg_000`" in faust_sec and "tr_reg_010→tr_reg_025" in faust_sec and "2 ordered" in faust_sec
    assert "Tables on FAUST" in faust_sec
    assert execute.profile_folder(tmp_path, "paper", "faust") == (tmp_path / "paper-faust").resolve()
    assert execute.profile_folder(tmp_path, "paper", "anny_humans") == (tmp_path / "paper").resolve()


def test_html_leads_with_verdict_badges_left_aligned_and_quotes_folded(project):
    text, page, ledger = project["text"], project["html_text"], load_ledger()
    claims_md = _section(text, "Claims of the paper")
    assert claims_md.strip().startswith(f"Totals over {len(ledger)} claims:")  # the counts lead the section
    body = page.split('<h2>Claims of the paper', 1)[1]
    counts = body.split("</p>", 1)[0]
    assert 'class="counts"' in counts
    assert re.findall(r'<span class="badge (v-\w+)">(\d+) ([a-z ]+)</span>', counts) == [
        ("v-holds", "4", "holds"), ("v-not", "2", "does not hold"),
        ("v-none", str(len(ledger) - len(EXPECTED)), "not measured here")]
    table = body.split("<table>", 1)[1].split("</table>", 1)[0]
    rows = table.split("<tr>")[2:]
    assert len(rows) == len(ledger)
    for row in rows:  # every verdict cell is a badge of its verdict's colour
        cells = re.findall(r"<td[^>]*>(.*?)</td>", row, flags=re.S)
        m = re.fullmatch(r'<span class="badge (v-\w+)">([a-z ]+)</span>', cells[3])
        assert m, cells[3]
        assert m.group(1) == {"holds": "v-holds", "does not hold": "v-not", "not measured here": "v-none"}[m.group(2)]
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
    assert "**Partial publication:**" in text and "fig04" in text.split("## Claims")[0]


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
    assert "outputs in `results/paper/tab01`" in text  # the run folder named relative to the project


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
    assert "from `<out>/paper`" in text and "outputs in `<out>/paper/tab01`" in text
    local, _ = build_report(paper, settings=ReportSettings(registry=reg))  # a local report: the paths on this machine
    assert "outputs in `tab01`" in local.read_text(encoding="utf-8")


def test_publish_keeps_the_faust_section_when_faust_was_not_rerun(tmp_path, monkeypatch):
    reg, paper = _complete_paper_run(tmp_path)
    monkeypatch.setenv("PRODMAPS_RUNS", str(reg))
    faust = paper.with_name("paper-faust")
    tab01 = {f"errors{sub}": {"k9_9": {"approx": APPROX, "transfer": tr}} for sub, tr in TRANSFER.items()}
    tab01["table"] = TABLE1
    tab01["pairs"] = [["tr_reg_000", "tr_reg_001"]]
    _run(faust, "tab01", _doc(tab01, table="T1"), _manifest("tab01", "ok", 3.0), pngs=["table.png"])
    md, html, _ = publish(paper, registry=reg)  # with the FAUST runs: a fresh section and its figures
    first = md.read_text(encoding="utf-8")
    first_html = html.read_text(encoding="utf-8")
    faust_png = tmp_path / "paper" / "report_figures" / "faust" / "tab01" / "table.png"
    assert "## On FAUST" in first and not faust_png.exists()  # tab01 is not a figure run on FAUST
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
    (tmp_path / "paper" / "REPORT.md").write_text("# edited by hand: not a data store\n")  # never read back
    md, html, _ = publish(paper, registry=reg)
    second = md.read_text(encoding="utf-8")

    def faust_part(text):
        return "".join(s for s in re.split(r"(?m)^(?=## )", text) if "FAUST" in s.splitlines()[0])

    assert faust_part(second) == faust_part(first) != ""
    rows_first = {r[0]: r for r in _tables(_section(first, "Claims of the paper"))[0][1:]}
    rows_second = {r[0]: r for r in _tables(_section(second, "Claims of the paper"))[0][1:]}
    head = _tables(_section(second, "Claims of the paper"))[0][0]
    col = head.index("FAUST")
    assert {c: r[col] for c, r in rows_second.items()} == {c: r[col] for c, r in rows_first.items()}
    assert "kept from the report published at commit" in second
    assert re.search(r"On FAUST \(kept from the report published at commit `[^`]+`\): \d+ ", second)
    assert kept_png.is_file()  # a kept dataset's figures stay
    first_commit = k.commit
    md, _, _ = publish(paper, registry=reg)  # kept again: still names the commit of the FAUST run's report
    assert DatasetReport.load(md.parent, "faust").commit == first_commit
    assert faust_part(md.read_text(encoding="utf-8")) == faust_part(first)
    assert "<h2>On FAUST</h2>" in html.read_text(encoding="utf-8") and "<h2>On FAUST</h2>" in first_html


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
    owned = _section(text, "Study: owned, on embedded humans")
    assert "n = 7" in owned and "![owned o](../results/owned/o.png)" in owned
    assert text.index("\n## Study: Approach B's threshold") < text.index("\n## Study: owned")  # registry order
    assert "### Study: owned, on FAUST" in _section(text, "On FAUST") and "n = 8" in _section(text, "On FAUST")
    figs = _section(text, "Figures")
    assert "owned o" not in figs and "![empty e](../results/empty/e.png)" in figs  # shown once, in its section


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
    assert text.count("Study: owned2, on FAUST") == 1 and "n = 8" in _section(text, "On FAUST")
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
        assert (c.verdict, (c.paper, c.rule, c.default)) == (verdict, marks), cid
        assert "; ".join(f"{k}: {v}" for k, v in c.subsets.items()) == kinds and c.evidence.startswith(evidence)
    assert main.counts()["holds"] == 4 and sum(main.counts().values()) == len(load_ledger())
    t1 = main.tables[0]
    assert (t1.table, t1.compared, t1.published, t1.within, t1.missed, t1.in_noise) == ("1", 4, N_PUB["1"], 2, 2, 1)
    assert t1.mean_diff == pytest.approx(0.041) and t1.largest_diff == pytest.approx(0.1)
    assert t1.beats["our_B"] == [[2, 3], [1, 3], [0, 3]] and main.tables[1].in_noise is None  # no SE: no count
    assert [(s.run, s.dataset) for s in main.studies] == [("study_truncation", "anny_humans")]
    assert main.studies[0].blocks[0] == ("h", 2, "Study: Approach B's threshold, transfer gains, and a rule that "
                                               "does not need ground truth")
    doc = build_document(inputs, settings, project["root"] / "paper")
    assert isinstance(doc, Document) and doc.blocks[0][:2] == ("h", 1)
    assert [b[2] for b in doc.blocks if b[:2] == ("h", 2)][:2] == ["Claims of the paper, judged on these results",
                                                                  "Tables 1–6: our values beside the published ones"]
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


def test_the_committed_report_data_of_faust_is_what_the_committed_report_shows():
    paper = TEXT.parent
    data = DatasetReport.load(paper, "faust")
    assert data is not None and list(data.verdicts) == list(load_ledger())
    text = (paper / "REPORT.md").read_text(encoding="utf-8")
    shown = re.search(r"^On FAUST(?: \(kept from [^)]*\))?: (.*)\.$", text, flags=re.M).group(1)
    assert shown == ", ".join(f"{n} {v}" for v, n in data.counts().items() if n)
    assert data.images() and all(p.is_file() and paper.resolve() in p.parents for p in data.images())
    assert f"## On {data.name}" in text and all(f"`{r}`" in text for r in data.runs)


def test_the_papers_texts_fill_every_placeholder_and_a_missing_text_folder_leaves_a_bare_report(tmp_path):
    from prodmaps.pipeline.report import TEXT_FILES, report_text
    from prodmaps.pipeline.report_data import CRITERIA

    values = dict(CRITERIA, ledger_file="prodmaps/experiments/claims.toml", provenance="Generated by a test.")
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
    assert "Systematic differences" not in text and "## Claims of the paper" in text


def test_document_blocks_are_checked_when_added():
    from prodmaps.pipeline.document import Document

    with pytest.raises(ValueError, match="not a document block"):
        Document([("h", "no level")])
    with pytest.raises(ValueError, match="not a document block"):
        Document().extend([("figure", "a.png")])
