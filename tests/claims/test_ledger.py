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
        assert c.quote and c.settings and c.runs and c.values and c.holds, c.id
        assert c.smoke_verdict, f"{c.id}: record the smoke verdict (smoke_verdict = ...)"
        assert set(c.smoke_verdict) <= set(c.subsets), c.id


@pytest.mark.parametrize("cid", list(LEDGER))
def test_smoke_verdict_is_the_recorded_one(cid, smoke_results):
    claim = LEDGER[cid]
    docs = {}
    for run in claim.runs:
        d, res = smoke_results(run)
        docs[run] = {"results": res}
    got = {v.subset: v for v in claims.evaluate(claim, docs)}
    for subset, expected in claim.smoke_verdict.items():
        v = got[subset]
        assert v.verdict == expected, (
            f"{cid} [{subset}]: the smoke results give '{v.verdict}' ({v.evidence}), the ledger records "
            f"'{expected}'; if the change is intended, update smoke_verdict in claims.toml")


def _published_results(table: int) -> dict:
    """The paper's own table as a results document (our keys), to check the rules encode the claim."""
    errors: dict = {}
    names = {"our_A": "our_B", "our_l2": "our_B"} if table in (1,) else {}
    for r in load_published():
        if int(r["table"]) != table:
            continue
        size = f"k{r['k_M']}_{r['k_N']}"
        m = names.get(r["method"], r["method"]) if r["method"] not in ("our_B",) else "our_B"
        errors.setdefault(size, {}).setdefault(r["stage"], {}).setdefault(m, {})[r["function"]] = r["value"]
    return {"results": {"errors": errors}}


@pytest.mark.parametrize("cid", [c for c in LEDGER if c.startswith(("tab01.products_improve_transfer",
                                                                     "tab02.products", "tab03.", "tab04.",
                                                                     "tab05.", "tab05_06.", "tab06."))])
def test_table_rules_hold_on_the_published_tables(cid):
    claim = LEDGER[cid]
    docs = {run: _published_results(int(run[3:5])) for run in claim.runs}
    v = {x.subset: x for x in claims.evaluate(claim, docs)}["all"]
    assert v.settings["paper"]["holds"], f"{cid}: the rule fails on the paper's own table: {v.evidence}"
