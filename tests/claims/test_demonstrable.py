"""The ledger's "not demonstrable in this setting" verdict: a claim is judged only where its oracle beats C.

Synthetic results (no notebook run): the gate ``rule.demonstrable`` of an entry compares an oracle
(for Figure 14, the consistency through the exact point-map transfer) with ``C``; where it fails
the verdict is "not demonstrable in this setting" whatever the products do, and the evidence leads
with the oracle and no-map numbers.
"""

import pytest

from prodmaps.experiments.shared import claims

CELLS = ("a|k5", "b|k5", "c|k5")


def _claim() -> claims.Claim:
    return claims.Claim(
        id="t.fig", where="Figure 0", quote="q", runs=("r",),
        values={"ext": "r:cells.{method}.*", "std": "r:cells.std.*", "oracle": "r:cells.p2p.*",
                "nomap": "r:cells.no_map.*"},
        holds="2 * sum(1 for c in std if lower(ext[c], std[c])) > len(std)",
        margin="sum(1 for c in std if lower(ext[c], std[c]))", evidence="products better on {margin} of {n_std}",
        method="ext", demonstrable="2 * sum(1 for c in std if lower(oracle[c], std[c])) > len(std)",
        demonstrable_margin="(sum(1 for c in std if lower(oracle[c], std[c])), "
                            "sum(1 for c in std if lower(nomap[c], std[c])))",
        demonstrable_evidence="oracle better on {margin[0]} of {n_std}, no map on {margin[1]}")


def _doc(ext, std, oracle, nomap):
    cells = {name: dict(zip(CELLS, v)) for name, v in
             (("ext", ext), ("std", std), ("p2p", oracle), ("no_map", nomap))}
    return {"r": {"results": {"cells": cells}}}


@pytest.mark.parametrize("ext, oracle, verdict, gate", [
    ((1, 1, 1), (1, 1, 3), "holds", True),                                 # oracle and products beat C
    ((3, 3, 1), (1, 1, 3), "does not hold", True),                         # oracle does, products do not
    ((1, 1, 1), (3, 3, 1), claims.NOT_DEMONSTRABLE, False),                # oracle does not: not judged
    ((1, 1, 1), (2, 2, 2), claims.NOT_DEMONSTRABLE, False),                # a tie with C is no win
])
def test_claim_is_judged_only_where_the_oracle_beats_C(ext, oracle, verdict, gate):
    v = claims.evaluate(_claim(), _doc(ext, (2, 2, 2), oracle, (3, 1, 3)))[0]
    assert v.verdict == verdict and v.verdict in claims.VERDICTS
    assert v.settings["oracle"]["holds"] is gate
    assert v.evidence.startswith("oracle better on ") and "no map on 1" in v.evidence
    # the products' own outcome is still computed and shown
    assert v.settings["paper"]["holds"] == (sum(e < 2 for e in ext) > 1.5)


def test_missing_results_are_not_measured_not_undemonstrable():
    v = claims.evaluate(_claim(), {"r": None})[0]
    assert v.verdict == "not measured here"


def test_figure14_claims_carry_the_oracle_gate():
    ledger = claims.load_ledger()
    fig14 = [c for c in ledger.values() if c.id.startswith("fig14.")]
    assert {c.id for c in fig14} >= {"fig14.products_more_consistent", "fig14.products_more_consistent_map_only",
                                     "fig14.quad_meshes_more_consistent"}
    for c in fig14:
        assert c.demonstrable and "oracle" in c.values and "{method}" not in c.values["oracle"], c.id
        assert "oracle" in c.demonstrable_evidence and "no map" in c.demonstrable_evidence, c.id
