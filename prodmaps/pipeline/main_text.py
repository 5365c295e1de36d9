"""The report's main text: the sections a reader with the paper and two minutes reads first.

Each builder appends its section to a :class:`.document.Document` ``d``; ``inputs`` is the
report's :class:`.report.ReportInputs`, ``settings`` its :class:`.report.ReportSettings`, ``text``
reads a text file of the paper's prose into blocks (:func:`.prose.report_text`, placeholders
filled) and ``all_ds`` lists every dataset's :class:`.report_data.DatasetReport` in the report's
order, one column each.

* :func:`summary_section`: the scope, the verdict counts of the paper's claims, what does not hold
  or is inconclusive (as detailed as keeps the summary within :data:`SUMMARY_WORDS`), what is not
  reproduced and why, one rerun command with its time;
* :func:`glossary_section`: every term the report uses, a table;
* :func:`claims_section`: one row per claim, one verdict column per dataset; the paper's claims,
  then this package's own apart;
* :func:`tables_section`: per published table and dataset, the cells within ±0.02 and within draw
  noise, of the cells compared;
* :func:`forking_section`: the readings the paper leaves open (:mod:`.forking`) and the table claims
  whose verdict changes under another reading.

The verdicts, counts and summaries come from the data, never written here.
"""

from __future__ import annotations

import re
from pathlib import Path

from .document import Document, words
from .forking import forking_blocks, forking_paths, reading_verdict_blocks
from .links import notebook_link
from .report_data import VERDICTS, load_claims

__all__ = ["SUMMARY_WORDS", "verdict_text", "summary_section", "glossary_section", "claims_section", "tables_section",
           "forking_section"]


def verdict_text(c) -> str:
    """The verdict, bold when it does not hold."""
    return f"**{c.verdict}**" if c.verdict == "does not hold" else c.verdict


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

    ``detail`` 3: per claim, its datasets and the evidence where it fails (else the first dataset's);
    2: the claims that do not hold with that evidence, the inconclusive ones as one line of ids;
    1: the same without evidence; 0: the claims' ids per verdict.
    """
    if not weak:
        return []
    weak = sorted(weak, key=lambda w: "does not hold" not in w[2])
    lead = ("p", "**Does not hold, or inconclusive**, on at least one dataset" + (
        ", with the evidence where it fails (each dataset's appendix gives all of it):" if detail >= 2 else
        " (each dataset's appendix gives the evidence):"))
    if detail == 0:
        verdicts = list(dict.fromkeys(v for _, _, by in weak for v in by))
        return [lead, ("ul", [f"{v}: " + ", ".join(f"`{cid}`" for cid, _, by in weak if v in by) for v in verdicts])]
    items, only_inconclusive = [], []
    for cid, where, by in weak:
        if detail < 3 and "does not hold" not in by:
            only_inconclusive.append(f"`{cid}`")
            continue
        item = f"`{cid}` ({where}): " + "; ".join(f"{v} on {', '.join(x.name for x in sets)}" for v, sets in by.items())
        first = (by.get("does not hold") or next(iter(by.values())))[0]
        if first.verdicts[cid].evidence and detail >= 2:
            item += f". {first.name}: {_short(first.verdicts[cid].evidence)}"
        items.append(item)
    if only_inconclusive:
        items.append("inconclusive (neither the claim nor its opposite shown beyond 2·SE and its margin) on at "
                     "least one dataset: " + ", ".join(only_inconclusive))
    return [lead, ("ul", items)]


def summary_section(d: Document, inputs, text, all_ds: list) -> None:
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


def glossary_section(d: Document, text) -> None:
    """The glossary: the items ``- **term**: meaning`` of ``glossary.md`` as a table (nothing without them)."""
    items = [i for kind, *args in text("glossary.md") if kind == "ul" for i in args[0]]
    if not items:
        return
    d.h(2, "Glossary")
    rows = []
    for item in items:
        m = re.match(r"\*\*(.+?)\*\*[:\s—–-]+(.*)", item)
        rows.append([m.group(1), m.group(2)] if m else ["", item])
    d.table(["term", "meaning"], rows)


def _claims_table(d: Document, inputs, settings, all_ds, base: Path, source: str):
    claims, rows = load_claims(), []
    for cid, c in inputs.main.verdicts.items():
        if cid not in claims or c.source != source:
            continue
        claim = claims[cid]
        links = ", ".join(notebook_link(inputs.results_dir / r, base,
                                        claim.notebook or r if len(claim.runs) == 1 else r, settings.notebooks)
                          for r in claim.runs)  # one notebook per run it is judged on
        rows.append([f"`{cid}`", claim.where, f"“{_short(claim.quote, 70)}”"]
                    + [verdict_text(ds.verdicts[cid]) if cid in ds.verdicts else "not measured here" for ds in all_ds]
                    + [links])
    d.table(["claim", "where", "the paper's words"] + [ds.name for ds in all_ds] + ["notebook"], rows)
    return len(rows)


def claims_section(d: Document, inputs, settings, text, all_ds, base: Path) -> None:
    """The claims of the paper, one verdict column per dataset; then this package's own claims, apart."""
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


def tables_section(d: Document, inputs, text, all_ds) -> None:
    """Per published table and dataset: the cells within ±0.02 · within draw noise, of the cells compared."""
    d.h(2, "Tables 1–6 beside the published values")
    d.extend(text("tables.md"))
    tables = sorted({t.table for ds in all_ds for t in ds.tables}, key=int)
    by = {(ds.dataset, t.table): t for ds in all_ds for t in ds.tables}
    n_pub = {t: sum(1 for r in inputs.published if r["table"] == t) for t in tables}
    d.table(["table", "published cells"] + [ds.name for ds in all_ds],
            [[f"Table {t}", str(n_pub[t])] + [_counted(by[(ds.dataset, t)]) if (ds.dataset, t) in by else "—"
                                              for ds in all_ds] for t in tables])


def forking_section(d: Document, text, all_ds) -> None:
    """The forking paths (:mod:`.forking`), then the table claims whose verdict changes under another reading."""
    paths = forking_paths(all_ds)
    table_claims = [cid for cid, c in load_claims().items() if c.where.startswith("Table")]
    verdicts = reading_verdict_blocks(all_ds, {ds.dataset: ds.name for ds in all_ds}, table_claims)
    d.h(2, "Forking paths: readings chosen on one dataset, checked on the others")
    d.extend(text("forking_paths.md"))
    d.extend(forking_blocks(paths, {ds.dataset: ds.name for ds in all_ds}, [ds.dataset for ds in all_ds]))
    if verdicts and verdicts[0][0] == "table":
        d.p("The table claims whose verdict changes under another reading the ledger judged (per dataset: the "
            "verdict as chosen, then each reading that changes it). The metres verdicts come from the "
            "normalisation study, whose pairs are not the tables'; where its verdict under the chosen reading "
            "differs from the tables', it is shown as *chosen reading, study's pairs*: compare the metres "
            "verdict with that one.")
    d.extend(verdicts)
