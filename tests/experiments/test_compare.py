"""The one comparison rule (prodmaps.experiments.shared.compare), the ledger's rounding band, the printed ±0.02 rule."""

import math

import numpy as np
import pytest

from prodmaps.experiments.shared import claims, compare


def test_two_equal_errors_are_a_tie_not_a_win():
    a = 0.0671234
    for b in (a, a * (1 + 1e-13), a * (1 - 1e-9), a * (1 + 0.9 * compare.TIE_REL)):
        assert compare.outcome(a, b) == "tie"
        assert compare.outcome(b, a) == "tie"
        assert not compare.lower(a, b) and not compare.lower(b, a)
        assert compare.not_higher(a, b) and compare.not_higher(b, a)
    assert compare.count_outcomes([(a, a)] * 3) == {"better": 0, "tie": 3, "worse": 0}


def test_outside_the_tie_band_the_lower_error_wins():
    a = 0.2
    b = a * (1 + 3 * compare.TIE_REL)
    assert compare.outcome(a, b) == "better" and compare.outcome(b, a) == "worse"
    assert compare.lower(a, b) and not compare.not_higher(b, a)
    assert compare.outcome(0.0, 0.0) == "tie"
    assert compare.outcome(0.0, 1e-300) == "better"  # relative: any non-zero against zero
    assert compare.count_outcomes([(1, 2), (2, 1), (1, 1)]) == {"better": 1, "tie": 1, "worse": 1}


def test_relative_difference_is_scale_free_and_refuses_nan():
    for s in (1e-8, 1.0, 1e8):
        assert math.isclose(compare.relative_difference(1.0 * s, 2.0 * s), -0.5)
    with pytest.raises(ValueError, match="non-finite"):
        compare.outcome(float("nan"), 1.0)
    with pytest.raises(ValueError, match="non-finite"):
        compare.outcome(1.0, float("inf"))


def _claim(holds: str) -> claims.Claim:
    return claims.Claim(id="t.x", where="Table 0", quote="q", runs=("r",), values={"ours": "r:ours", "std": "r:std"},
                        holds=holds, evidence="{ours} vs {std}")


@pytest.mark.parametrize("ours, std, verdict", [
    (0.10, 0.20, "holds"),                                  # a clear win
    (0.20, 0.10, "does not hold"),                          # a clear loss
    (0.10, 0.10, "does not hold"),                          # a tie is no win
    (0.10, 0.10 * (1 + 1e-4), "inconclusive"),              # a win by a margin rounding could flip
    (0.10 * (1 + 1e-4), 0.10, "inconclusive"),              # a thin loss: the same, on every machine
    (0.10 * (1 + 2e-3), 0.10, "does not hold"),             # a loss beyond the rounding band
])
def test_ledger_verdicts_with_ties_and_thin_margins(ours, std, verdict):
    v = claims.evaluate(_claim("lower(ours, std)"), {"r": {"results": {"ours": ours, "std": std}}})[0]
    assert v.verdict == verdict, (ours, std, v.evidence)
    assert v.verdict in claims.VERDICTS
    assert v.settings["paper"]["verdict"] == verdict


def test_not_higher_accepts_a_tie_on_every_reading():
    v = claims.evaluate(_claim("not_higher(ours, std)"), {"r": {"results": {"ours": 0.3, "std": 0.3 * (1 + 1e-12)}}})
    assert v[0].verdict == "holds"


def test_the_ledger_compares_measured_numbers_only_through_the_tie_rule():
    """No bare ``<``/``>`` between two looked-up values: every rule goes through lower/not_higher."""
    import re

    for c in claims.load_ledger().values():
        names = set(c.values)
        for a, b in re.findall(r"(\w+)\[[^\]]*\]\s*[<>]=?\s*(\w+)\[", c.holds):
            assert not ({a, b} <= names), f"{c.id}: bare comparison in {c.holds!r}"
        assert not re.search(r"\bnot\s+(?!in\b)", c.holds), f"{c.id}: rules must be monotone (no 'not')"


def test_explain_cell_separates_reproduced_data_and_unexplained():
    from prodmaps.experiments.study_normalization import explain_cell

    assert explain_cell(0.23, 0.257, 0.29, 0.287).startswith("reproduced")
    why = explain_cell(0.09, 0.133, 0.46, 0.566)  # our std is itself 0.106 off: the family differs
    assert "control differs" in why and "+0.106" in why
    why = explain_cell(0.25, 0.217, 0.47, 0.451)  # the control matches: not explained by the data
    assert "not explained" in why and "-0.033" in why and "-0.019" in why
    assert "not explained" in explain_cell(0.25, 0.2, None, 0.45)


def test_tie_mask_is_is_tie_elementwise():
    """The vectorised rule equals the scalar one on random pairs, at the tie boundary, and at 0."""
    from prodmaps.experiments.shared import compare as cmp

    rng = np.random.default_rng(0)
    a = rng.random(2000)
    b = a * (1 + rng.choice([0.0, 1e-12, 5e-6, 2e-5, -3e-5, 0.5], size=a.size))
    a[:3], b[:3] = 0.0, [0.0, 1e-300, 0.0]
    mask = cmp.tie_mask(a, b)
    assert mask.shape == a.shape and mask.dtype == bool
    assert mask.tolist() == [cmp.is_tie(x, y) for x, y in zip(a, b)]
    assert 0 < mask.sum() < a.size


# ------------------------------------------------------------------------------ comparisons with the paper
def test_within_published_and_within_draw_noise():
    from prodmaps.experiments.shared import published as P

    assert P.within_published(0.02) and P.within_published(-0.02) and not P.within_published(0.0206)
    assert P.within_published(0.0201)  # printed +0.020: what is printed is counted
    band = P.WITHIN + P.DRAW_Z * np.sqrt(2) * 0.01  # 0.0483
    assert P.within_draw_noise(0.048, 0.01) and P.within_draw_noise(-0.048, 0.01)
    assert not P.within_draw_noise(0.049, 0.01) and 0.048 < band < 0.049
    assert P.within_draw_noise(0.02, 0.0) and not P.within_draw_noise(0.021, 0.0)  # no spread: the printed band
    assert P.within_draw_noise(0.02049, 0.0002)  # se printed 0.000: the band is 0.02, the difference printed +0.020
    with pytest.raises(ValueError, match="se must be"):
        P.within_draw_noise(0.01, -0.1)
    with pytest.raises(ValueError, match="se must be"):
        P.within_draw_noise(0.01, float("nan"))


def test_table_entries_keep_their_standard_error():
    from prodmaps.experiments.shared.published import load_published, match_entries, normalize_entry

    e = {"table": 1, "function": "HKS", "stage": "transfer", "method": "std", "value": 0.5, "se": 0.01}
    assert normalize_entry(e)["se"] == 0.01
    assert "se" not in normalize_entry({**e, "se": None})
    (m,), _ = match_entries([e], load_published())
    assert m[1]["se"] == 0.01 and m[0]["value"] == 0.54  # Table 1, HKS transfer std
    with pytest.raises(ValueError, match="se must be"):
        normalize_entry({**e, "se": -1})
