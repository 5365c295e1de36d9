"""Every claim of the ledger, judged on the smoke results, gives the verdict the ledger records.

A change that flips a verdict fails here and has to update ``smoke_verdict`` in
``prodmaps/experiments/shared/claims.toml`` on purpose (the paper-profile verdicts are in the report).
Also: the ledger is well formed, and its rules are calibrated on the paper's own numbers (each
table claim holds on the published table it quotes, where the paper's table supports it).
"""

import pytest

from prodmaps.experiments.shared import claims
from prodmaps.experiments.shared.published import load_published

LEDGER = claims.load_ledger()

pytestmark = pytest.mark.notebook


def test_ledger_is_well_formed_and_covers_the_papers_claims():
    where = " ".join(c.where for c in LEDGER.values())
    for item in ["Figure 2", "Figure 3", "Figure 4", "Figure 5", "Figure 6", "Figure 7", "Figure 8", "Figure 9",
                 "Figure 10", "Figure 11", "Figure 12", "Figure 13", "Figure 14", "Table 1", "Table 2", "Table 3",
                 "Table 4", "Table 5", "Table 6", "Section 4.2", "Section 5.1"]:
        assert item in where, f"no ledger entry for {item}"
    for c in LEDGER.values():
        assert c.quote and c.smoke_verdict, f"{c.id}: record the smoke verdict (smoke_verdict = ...)"
        assert (c.settings and c.runs and c.values and c.holds) if c.measured else c.reason, c.id
        assert set(c.smoke_verdict) <= set(c.subsets), c.id


@pytest.mark.parametrize("cid", list(LEDGER))
def test_smoke_verdict_is_the_recorded_one(cid, smoke_results):
    claim = LEDGER[cid]
    docs = {}
    for run in claim.runs:
        d, res = smoke_results(run)
        docs[run] = {"results": res}
    got = {v.subset: v for v in claims.evaluate(claim, docs)}
    timed = "seconds" in str(claim.values)  # wall times: a loaded machine may widen their SE, never flip them
    for subset, expected in claim.smoke_verdict.items():
        v = got[subset]
        assert v.verdict == expected or (timed and v.verdict == "inconclusive"), (
            f"{cid} [{subset}]: the smoke results give '{v.verdict}' ({v.evidence}), the ledger records "
            f"'{expected}'; if the change is intended, update smoke_verdict in claims.toml")


def _published_results(table: int) -> dict:
    """The paper's own table as a results document (our keys): each cell a single case (one 'pair')."""
    errors: dict = {}
    for r in load_published():
        if int(r["table"]) == table:
            size = f"k{r['k_M']}_{r['k_N']}"
            by_method = errors.setdefault(size, {}).setdefault(r["stage"], {})
            by_method.setdefault(r["method"], {})[r["function"]] = r["value"]
    if table == 3:  # no approximation column: hk k is built from k_M + 1 = 28 functions, in the span at 27/35 only
        for z in errors:
            errors[z]["approx"] = {"std": {f: 0.0 if (z, f) == ("k27_35", "hk k") else 0.5
                                           for f in errors[z]["transfer"]["std"]}}
    per_pair = {z: {st: {m: {f: [v] for f, v in by_f.items()} for m, by_f in by_m.items()} for st, by_m in s.items()}
                for z, s in errors.items()}
    return {"results": {"errors": errors, "errors_per_pair": per_pair}}


ON_THE_TABLE = [c for c in LEDGER if c.startswith("tab") and LEDGER[c].measured
                and "seconds" not in str(LEDGER[c].values) and "p2p_transfer" not in str(LEDGER[c].values)
                and not c.endswith((".our_l2", ".our_B"))]  # the published T1 has no approximation by A-L2 or B


@pytest.mark.parametrize("cid", ON_THE_TABLE)
def test_table_rules_never_refute_the_published_tables(cid):
    """Judged on the paper's own numbers (single cases: the margin decides), no table claim fails.

    Some are inconclusive there (e.g. Table 1's SHOT, 0.84 to 0.82, is below the 5 % margin of
    "significant"): the criteria are not calibrated on the paper's tables.
    """
    claim = LEDGER[cid]
    docs = {run: _published_results(int(run[3:5])) for run in claim.runs}
    v = {x.subset: x for x in claims.evaluate(claim, docs)}["all"]
    assert v.verdict in ("holds", "inconclusive"), f"{cid}: the rule refutes the paper's own table: {v.evidence}"
    assert v.single_case or cid == "tab03.std_more_close_to_ours_fewer", cid
