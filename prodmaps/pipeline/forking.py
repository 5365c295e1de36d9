"""The report's forking paths: each reading the paper leaves open, chosen on one dataset, checked on the others.

A *reading* is one way of computing what the paper leaves open: a function family's parameters,
the heat-kernel time, AWFT's parameters, Approach B's normalisation, NO17's recipe, Section 4.4's
heat time. The library froze each reading where it was chosen, on FAUST's eight registrations
(:data:`CHOSEN_ON`), by published cells the product methods do not touch. Each dataset's report
data carries what its runs scored (:attr:`.report_data.DatasetReport.readings`, built by
:func:`.report_data.reading_scores` from the tables' ``held_out_rows`` and the studies'
``reading_summary``): per reading, ``{"label", "alternatives", "cells", "frozen", "choice", "n",
"within", "in_noise"}`` (and ``frozen_error`` where no published cell judges the reading).

:func:`forking_paths` gathers the datasets' rows into one structure, plain data a test can write::

    {label: {"alternatives": n, "cells": "published std cells of Tables 1, 3, 5 and 6",
             "frozen": "t=5e-4",
             "chosen_on": {dataset: score}, "held_out": {dataset: score, ...}}}

with ``score = {"n", "within", "in_noise", "choice"}`` (and ``frozen_error``): the frozen
reading's cells on that dataset (compared, within ±0.02, within draw noise or None without
standard errors) and the reading that dataset's own scores would choose. :func:`forking_blocks` renders it as one table
row per reading; readings of :data:`EXPECTED` that no dataset scored are named below the table.
:func:`reading_verdict_blocks` shows each table claim's verdict under the other readings the
ledger judged (``ClaimResult.readings``: the textbook families, a rejected normalisation, ...).
"""

from __future__ import annotations

__all__ = ["CHOSEN_ON", "EXPECTED", "forking_paths", "forking_blocks", "reading_verdict_blocks"]

CHOSEN_ON = "faust"  # where the library's readings were chosen (FAUST's eight registrations)
EXPECTED = (  # the readings the report expects scores for, in the report's order (the experiments' row names)
    "hk k parameters", "hk K parameters", "HKS parameters", "Random parameters", "Indicator parameters",
    "SHOT parameters", "AWFT parameters", "Approach B's normalisation", "NO17 recipe", "Section 4.4's heat time")


def forking_paths(reports, chosen_on: str = CHOSEN_ON) -> dict:
    """``{label: {"alternatives", "cells", "frozen", "chosen_on", "held_out"}}`` from the datasets' reading rows.

    ``reports``: :class:`.report_data.DatasetReport` objects (anything with ``dataset`` and
    ``readings``), in the report's dataset order. Rows are ordered as :data:`EXPECTED`, then as
    found. ``chosen_on`` and ``held_out`` map a dataset to ``{"n", "within", "in_noise", "choice"}``.

    Examples
    --------
    >>> from types import SimpleNamespace as R
    >>> row = {"label": "NO17: recipe", "alternatives": 3, "cells": "T2 std", "frozen": "a", "choice": "a",
    ...        "n": 5, "within": 2, "in_noise": 4}
    >>> fp = forking_paths([R(dataset="faust", readings={"no17": row}),
    ...                     R(dataset="faust_r", readings={"no17": {**row, "choice": "b", "in_noise": 3}})])
    >>> fp["NO17: recipe"]["chosen_on"]
    {'faust': {'n': 5, 'within': 2, 'in_noise': 4, 'choice': 'a'}}
    >>> fp["NO17: recipe"]["held_out"]["faust_r"]["choice"]
    'b'
    """
    ids = [*EXPECTED, *(k for r in reports for k in r.readings if k not in EXPECTED)]
    out = {}
    for rid in dict.fromkeys(ids):
        rows = [(r.dataset, r.readings[rid]) for r in reports if rid in r.readings]
        if not rows:
            continue
        first = next((x for ds, x in rows if ds == chosen_on), rows[0][1])
        entry = {"alternatives": first.get("alternatives"), "cells": first.get("cells", ""),
                 "frozen": first.get("frozen", ""), "chosen_on": {}, "held_out": {}}
        for ds, x in rows:
            score = {k: x.get(k) for k in ("n", "within", "in_noise", "choice", "frozen_error")
                     if k != "frozen_error" or x.get(k) is not None}
            if x.get("frozen") and x.get("frozen") != entry["frozen"]:
                score["frozen"] = x["frozen"]  # the frozen reading as this dataset's run names it
            entry["chosen_on" if ds == chosen_on else "held_out"][ds] = score
        out[first.get("label") or rid] = entry
    return out


def _score_cell(score: dict, frozen: str, chosen_here: bool) -> str:
    n, noise, within, choice = score.get("n"), score.get("in_noise"), score.get("within"), score.get("choice")
    frozen = score.get("frozen", frozen)
    if n:
        text = f"{noise} of {n}" if noise is not None else f"{within} of {n} within ±0.02 (no SE)"
    else:  # no published cell judges it (Section 4.4's heat time): the frozen reading's own error
        text = f"error {score['frozen_error']:.4g}" if score.get("frozen_error") is not None else "not scored"
    if choice and choice != frozen:
        text += f"; would choose {choice}"
    elif choice and not chosen_here:
        text += "; same choice"
    return text


def forking_blocks(paths: dict, names: dict, datasets: list, chosen_on: str = CHOSEN_ON) -> list:
    """The forking-paths table of :func:`forking_paths` as blocks, one column per dataset of ``datasets``.

    ``names``: ``{dataset: name shown}``; a dataset column holds the frozen reading's published
    cells within draw noise there (``k of n``) and, where that dataset's scores choose another
    reading, which.

    Examples
    --------
    >>> fp = {"NO17: recipe": {"alternatives": 3, "cells": "T2 std", "frozen": "a",
    ...       "chosen_on": {"faust": {"n": 5, "within": 2, "in_noise": 4, "choice": "a"}},
    ...       "held_out": {"faust_r": {"n": 5, "within": 1, "in_noise": 3, "choice": "b"}}}}
    >>> blocks = forking_blocks(fp, {"faust": "FAUST", "faust_r": "FAUST_r"}, ["faust", "faust_r"])
    >>> blocks[0][1]
    ['reading', 'readings scored', 'cells that judge it', 'frozen reading', 'FAUST (chosen here)', 'FAUST_r']
    >>> blocks[0][2][0][4:]
    ['4 of 5', '3 of 5; would choose b']
    """
    cols = [ds for ds in datasets if any(ds in e["chosen_on"] or ds in e["held_out"] for e in paths.values())]
    header = ["reading", "readings scored", "cells that judge it", "frozen reading"] + [
        names.get(ds, ds) + (" (chosen here)" if ds == chosen_on else "") for ds in cols]
    rows = []
    for label, e in paths.items():
        scores = {**e["chosen_on"], **e["held_out"]}
        rows.append([label, "—" if e["alternatives"] is None else str(e["alternatives"]), e["cells"], e["frozen"]]
                    + [_score_cell(scores[ds], e["frozen"], ds == chosen_on) if ds in scores else "—" for ds in cols])
    out = [("table", header, rows)] if rows else []
    missing = [lab for lab in EXPECTED if lab not in paths]
    if missing:
        out.append(("p", "Not scored by the studies in these results: " + "; ".join(missing) + "."))
    other = {label: sorted({s["choice"] for s in e["held_out"].values()
                            if s.get("choice") and s["choice"] != s.get("frozen", e["frozen"])})
             for label, e in paths.items()}
    other = {k: v for k, v in other.items() if v}
    if other:
        out.append(("p", "Readings another dataset would choose: " + "; ".join(
            f"{k}: {', '.join(v)}" for k, v in other.items()) + ". The frozen reading stays (no reading is chosen "
            "again on the data that judge it); the table claims under the other readings follow."))
    return out


def reading_verdict_blocks(reports, names: dict, claim_ids) -> list:
    """The claims of ``claim_ids`` (the table claims) whose verdict changes under another reading the ledger judged.

    One row per claim where, on some dataset, a verdict under another reading
    (``ClaimResult.readings``: the textbook families, a rejected normalisation, ...) differs from the
    verdict as chosen; one column per dataset: the verdict as chosen, then each reading that
    changes it. Then a sentence counting the verdicts that do not change; none when no dataset
    records a reading.

    Examples
    --------
    >>> from types import SimpleNamespace as R
    >>> same, other = R(verdict="holds", readings={"textbook": "holds"}), R(verdict="holds", readings={"metres": "x"})
    >>> blocks = reading_verdict_blocks([R(dataset="faust", verdicts={"tab01.a": same, "tab01.b": other})],
    ...                                 {"faust": "FAUST"}, ["tab01.a", "tab01.b"])
    >>> blocks[0][1:]
    (['claim', 'FAUST'], [['`tab01.b`', 'holds; metres: x']])
    >>> blocks[1][1]
    'Under every other reading judged, the other 1 verdict of the table claims is the same as under the chosen one.'
    """
    def changes(c) -> dict:
        return {k: v for k, v in (getattr(c, "readings", None) or {}).items() if v != c.verdict}

    judged = [(cid, r) for cid in claim_ids for r in reports
              if cid in r.verdicts and getattr(r.verdicts[cid], "readings", None)]
    if not judged:
        return []
    changed = [cid for cid in claim_ids if any(c == cid and changes(r.verdicts[c]) for c, r in judged)]
    cols = [r for r in reports if any(changes(r.verdicts[cid]) for cid in changed if cid in r.verdicts)]
    out = []
    if changed:
        def cell(r, cid):
            c = r.verdicts.get(cid)
            if c is None:
                return "—"
            return "; ".join([c.verdict] + [f"{'textbook families' if k == 'textbook' else k}: {v}"
                                            for k, v in changes(c).items()])

        out.append(("table", ["claim"] + [names.get(r.dataset, r.dataset) for r in cols],
                    [[f"`{cid}`"] + [cell(r, cid) for r in cols] for cid in changed]))
    rest = sum(1 for cid, r in judged if not changes(r.verdicts[cid]))
    if rest:
        out.append(("p", f"Under every other reading judged, the {'other ' if changed else ''}{rest} "
                         f"verdict{'s' if rest > 1 else ''} of the table claims "
                         f"{'are' if rest > 1 else 'is'} the same as under the chosen one."))
    return out
