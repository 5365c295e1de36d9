"""The ledger's criteria on constructed data: the paired test, ties by construction, the printed ±0.02 rule,
the settings kept apart, the ledger's completeness and its verdict counts by source (no notebook run)."""

import math

import numpy as np
import pytest

from prodmaps.experiments.shared import claims
from prodmaps.experiments.shared import published as P
from prodmaps.pipeline import report_data

LEDGER = claims.load_ledger()


def _claim(holds="improves(ours, std)", margin=0.05, **kw) -> claims.Claim:
    return claims.Claim(id="t.paired", where="Table 0", quote="q", runs=("r",),
                        values={"ours": "r:ours.{method}.*", "std": "r:ours.std.*", "span": "r:span.*"},
                        holds=holds, practical_margin=margin, why="a test", method="B", method_rule="rule",
                        method_default="", **kw)


def _verdict(ours: dict, std: dict, span=None, rule=None, **kw) -> claims.Verdict:
    cols = {"B": ours, "std": std, **({"rule": rule} if rule is not None else {})}
    res = {"ours": cols, "span": span or {f: 0.5 for f in std}}
    return claims.evaluate(_claim(**kw), {"r": {"results": res}})[0]


# ------------------------------------------------------------------------------ the paired test
@pytest.mark.parametrize("ours, std, expected", [
    ([0.10, 0.11, 0.12], [0.20, 0.21, 0.22], "holds"),          # beyond 2·SE and the 5 % margin
    ([0.20, 0.21, 0.22], [0.10, 0.11, 0.12], "does not hold"),  # the opposite, by the same test
    ([0.10, 0.30, 0.10], [0.30, 0.10, 0.30], "inconclusive"),   # 2·SE (0.27) larger than the mean gain (0.067)
    ([0.196, 0.197, 0.198], [0.200, 0.201, 0.202], "inconclusive"),  # beyond 2·SE but 2 % < the 5 % margin
    ([0.20, 0.21, 0.22], [0.20, 0.21, 0.22], "inconclusive"),   # equal: neither shown
])
def test_paired_criterion_needs_both_two_se_and_the_margin(ours, std, expected):
    v = _verdict({"HKS": ours}, {"HKS": std})
    assert v.verdict == expected, v.evidence
    (c,) = v.comparisons
    assert c["n"] == 3 and c["outcome"] == expected
    d = np.array(std) - np.array(ours)
    assert math.isclose(c["mean_diff"], d.mean(), abs_tol=1e-15)
    assert math.isclose(c["se"], d.std(ddof=1) / np.sqrt(3), abs_tol=1e-15)
    assert math.isclose(c["rel"], d.mean() / np.mean(std), abs_tol=1e-12)
    assert not v.single_case


def test_margin_and_two_se_are_each_needed():
    p = claims.paired([0.10, 0.11, 0.12], [0.20, 0.21, 0.22])  # gain 0.1, SE 0, 48 % relative
    assert p.outcome(0.05) == "holds" and p.outcome(0.6) == "inconclusive"  # the margin alone can stop it
    q = claims.paired([0.10, 0.30], [0.30, 0.31])  # gain 0.105 (41 %), SE 0.095: 2·SE = 0.19 > gain
    assert q.outcome(0.05) == "inconclusive" and q.outcome(0.0) == "inconclusive"  # 2·SE alone stops it
    assert claims.paired([0.1, 0.1, 0.1], [0.2, 0.2, 0.2], higher=True).outcome(0.05) == "does not hold"
    with pytest.raises(ValueError, match="same length"):
        claims.paired([0.1, 0.2], [0.1])
    with pytest.raises(ValueError, match="finite"):
        claims.paired([float("nan")], [0.1])


def test_a_single_case_is_judged_by_the_margin_and_labelled():
    v = _verdict({"HKS": [0.10]}, {"HKS": [0.20]})
    assert v.verdict == "holds" and v.single_case and v.comparisons[0]["se"] is None
    assert "single case" in v.evidence and "single case" in claims.format_table([v])
    assert _verdict({"HKS": [0.199]}, {"HKS": [0.20]}).verdict == "inconclusive"  # 0.5 % < 5 %


def test_a_claim_over_families_is_the_three_valued_and():
    ok, unsure, bad = ([0.1, 0.11, 0.12], [0.2, 0.21, 0.22]), ([0.1, 0.3, 0.1], [0.3, 0.1, 0.3]), \
        ([0.3, 0.31, 0.32], [0.2, 0.21, 0.22])
    fam = lambda *xs: ({f"f{i}": x[0] for i, x in enumerate(xs)}, {f"f{i}": x[1] for i, x in enumerate(xs)})  # noqa: E731
    assert _verdict(*fam(ok, ok)).verdict == "holds"
    assert _verdict(*fam(ok, unsure)).verdict == "inconclusive"
    assert _verdict(*fam(ok, unsure, bad)).verdict == "does not hold"
    most = "improves_most(ours, std)"
    assert _verdict(*fam(ok, ok, bad), holds=most).verdict == "holds"
    assert _verdict(*fam(ok, unsure, bad), holds=most).verdict == "inconclusive"
    assert _verdict(*fam(ok, bad, bad), holds=most).verdict == "does not hold"


def test_the_verdict_is_the_papers_setting_alone():
    ours, rule = {"HKS": [0.3, 0.31, 0.32]}, {"HKS": [0.1, 0.11, 0.12]}
    v = _verdict(ours, {"HKS": [0.2, 0.21, 0.22]}, rule=rule)
    assert v.verdict == "does not hold"  # the threshold rule's success is the package's column, not the verdict
    assert v.settings["rule"]["verdict"] == "holds" and claims.setting_mark(v, "rule") == "yes"
    assert "default" not in v.settings and claims.setting_mark(v, "default") == "—"


def test_sensitivity_line_gives_the_verdict_at_each_margin():
    v = _verdict({"HKS": [0.17, 0.171, 0.172]}, {"HKS": [0.2, 0.201, 0.202]}, margin=0.1, sensitivity=(0.05, 0.1, 0.2))
    assert v.verdict == "holds"  # 15 % gain
    assert v.paper["sensitivity"] == {"0.05": "holds", "0.1": "holds", "0.2": "inconclusive"}
    assert "margin sensitivity" in v.evidence


# ------------------------------------------------------------------------------ ties by construction
def test_ties_by_construction_are_excluded_with_their_reason():
    ours = {"hk k": [0.053, 0.054], "HKS": [0.10, 0.11]}
    std = {"hk k": [0.053, 0.054], "HKS": [0.50, 0.52]}
    v = _verdict(ours, std, span={"hk k": 3e-15, "HKS": 0.5}, ties="span_ties(span)")
    assert v.verdict == "holds"
    assert list(v.excluded) == ["hk k"] and "span of the source basis" in v.excluded["hk k"]
    assert [c["label"] for c in v.comparisons] == ["HKS"]  # not counted as a win, a loss or a tie
    assert "excluded as ties by construction: hk k" in v.evidence
    v = _verdict(ours, std, span={"hk k": 3e-15, "HKS": 0.5})  # without rule.ties the tie makes it inconclusive
    assert v.verdict == "inconclusive" and not v.excluded


def test_products_beat_std_counts_leave_ties_by_construction_out():
    errors = {"k9_9": {"approx": {"std": {"hk k": 1e-15, "HKS": 0.5, "XYZ": 0.3}},
                       "transfer": {"std": {"hk k": 0.053, "HKS": 0.54, "XYZ": 0.29},
                                    "our_B": {"hk k": 0.0529, "HKS": 0.15, "XYZ": 0.23}}}}
    info = report_data.RunInfo("tab01", None, reproduces="Table 1", doc={"results": {"errors": errors}})
    (t,) = report_data.table_summaries([info], [{"table": "1"}], [])
    assert t.ties == ["k9_9 hk k"]
    assert t.beats["our_B"][0] == [2, 2]  # HKS and XYZ: hk k at 0.0529 vs 0.053 is neither win nor family


# ------------------------------------------------------------------------------ the printed ±0.02 rule
@pytest.mark.parametrize("diff, within", [(-0.020, True), (0.020, True), (-0.02004, True), (0.02049, True),
                                          (-0.0205, False), (0.0205, False), (-0.02051, False), (0.021, False)])
def test_within_is_decided_by_the_printed_difference(diff, within):
    shown = P.printed(diff, signed=True)
    assert P.within_published(diff) is within
    assert within == (shown in {f"{s}0.0{d:02d}" for s in "+-" for d in range(21)})  # the printed value decides
    assert P.within_published(abs(diff)) is within  # the studies count |diff| the same way


def test_table_counts_agree_with_the_printed_appendix():
    rows = [r for r in P.load_published() if r["table"] == "6" and r["stage"] == "transfer"][:6]
    diffs = [-0.020, 0.020, -0.02004, -0.0207, 0.0206, -0.0205]  # the last: whichever way its float prints
    entries = [{"table": 6, "function": r["function"], "stage": r["stage"], "method": r["method"],
                "k_M": int(r["k_M"]), "k_N": int(r["k_N"]), "fmap": r["fmap"], "value": r["value"] + d, "se": 0.001}
               for r, d in zip(rows, diffs)]
    matches, unmatched = P.match_entries(entries, rows)
    assert not unmatched
    info = report_data.RunInfo("tab06", None, reproduces="Table 6", doc={"results": {}})
    (t,) = report_data.table_summaries([info], rows, matches)
    printed_within = sum(abs(float(P.printed(e["value"] - r["value"], signed=True))) <= 0.02 for r, e in matches)
    assert t.within == printed_within and t.within + t.missed == 6 and 3 <= t.within <= 4


# ------------------------------------------------------------------------------ the ledger
ISSUE_CLAIMS = {
    "fig01.transfer_example": "not reproducible", "theorem1.np_hard": "not empirical",
    "abstract.cost_map_fixed": "not empirical", "lemma2.exact": "measured", "sec52.hks_wks_representable": "measured",
    "tab03.both_benefit_from_larger_basis": "measured", "tab03.improvement_grows_with_basis": "measured",
    "tab01.l1_performs_similarly": "measured", "tab01.l1_more_time_consuming": "measured",
    "tab01.all_approaches_improve.our_l1": "measured", "tab01.all_approaches_improve.our_l2": "measured",
    "tab01.all_approaches_improve.our_B": "measured", "conclusion.extended_basis_cost": "measured",
}
COMPARES = ("better(", "improves(", "improves_most(", "similar(", "below(")


def test_the_ledger_is_complete_and_says_whose_claim_each_is():
    for cid, kind in ISSUE_CLAIMS.items():
        assert cid in LEDGER and LEDGER[cid].kind == kind, cid
    where = " ".join(c.where for c in LEDGER.values())
    for item in ["Figure 1", "Theorem 1", "Lemma 2", "Section 5.2", "Section 6", "Abstract"] + \
            [f"Figure {i}" for i in range(2, 15)] + [f"Table {i}" for i in range(1, 7)]:
        assert item in where, f"no ledger entry for {item}"
    for c in LEDGER.values():
        assert c.source in claims.SOURCES and c.where and c.quote, c.id
        if not c.measured:
            assert c.reason and not c.runs, c.id
            continue
        if any(f in c.holds + c.demonstrable for f in COMPARES):
            assert c.practical_margin is not None and c.why, f"{c.id}: a comparison needs a margin and its why"
    package = {c.id for c in LEDGER.values() if c.source == "package"}
    assert package == {"fig14.products_more_consistent_map_only"}
    for cid in ("tab03.std_more_close_to_ours_fewer", "tab01.l1_performs_similarly"):  # margins read off the paper
        assert len(LEDGER[cid].sensitivity) >= 3 and "sensitivity" in LEDGER[cid].why, cid


def test_non_empirical_claims_are_listed_with_their_reason():
    for cid in ("fig01.transfer_example", "theorem1.np_hard"):
        (v,) = claims.evaluate(LEDGER[cid], {})
        assert v.verdict == LEDGER[cid].kind and v.evidence == LEDGER[cid].reason


def test_verdict_counts_by_source_and_the_reports_agree():
    results = {"tab01": {"results": {}}, "fig11": {"results": {"lemma2": {"max_relative_residual": 1e-16,
                                                                          "target_dim": 40}}}}
    verdicts = [v for c in LEDGER.values() for v in claims.evaluate(c, {r: results.get(r) for r in c.runs})]
    counts = claims.verdict_counts(verdicts)
    assert set(counts) == set(claims.SOURCES) and all(set(x) == set(claims.VERDICTS) for x in counts.values())
    assert sum(counts["paper"].values()) == sum(c.source == "paper" for c in LEDGER.values())
    assert sum(counts["package"].values()) == 1
    assert counts["paper"]["holds"] == 1 and counts["paper"]["not empirical"] == 2
    assert counts["paper"]["not reproducible"] == 1
    report = report_data.claim_results(verdicts)
    assert report_data.verdict_counts(report) == counts
    assert report["lemma2.exact"].source == "paper" and report["fig14.products_more_consistent_map_only"].source \
        == "package"
    assert claims.verdict_counts({cid: r.verdict for cid, r in report.items()}) == counts


def test_normalisation_study_judges_the_table_claims_per_reading():
    from prodmaps.experiments.study_normalization import claim_verdicts

    fams = ("hk k", "HKS", "XYZ")

    def table(ours):
        std = {"hk k": [0.05, 0.06], "HKS": [0.5, 0.52], "XYZ": [0.3, 0.31]}
        pp = {"k9_9": {"transfer": {"std": std, "our_B": ours},
                       "approx": {"std": {"hk k": [0.0, 0.0], "HKS": [0.5, 0.5], "XYZ": [0.3, 0.3]}}}}
        means = {z: {st: {m: {f: float(np.mean(v[f])) for f in fams} for m, v in by.items()} for st, by in s.items()}
                 for z, s in pp.items()}
        return means, pp

    good, bad = table({"hk k": [0.05, 0.06], "HKS": [0.1, 0.11], "XYZ": [0.2, 0.21]}), \
        table({"hk k": [0.05, 0.06], "HKS": [0.7, 0.72], "XYZ": [0.4, 0.41]})
    v_good = claim_verdicts({"T1": good[0]}, {"T1": good[1]})
    v_bad = claim_verdicts({"T1": bad[0]}, {"T1": bad[1]})
    assert v_good["tab01.products_improve_transfer"] == "holds"  # hk k: a tie by construction, left out
    assert v_bad["tab01.products_improve_transfer"] == "does not hold"
    assert v_good["tab01.point_map_transfer_worse"] == "not measured here"  # no point-map column in the study
    assert all(cid.startswith("tab01.") for cid in v_good)
