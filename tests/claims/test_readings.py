"""The ledger judges a claim under every family reading a run carries (e.g. the textbook HKS beside
the published one): rows labelled ``"HKS (textbook)"`` never enter the run's verdict, and replace
``"HKS"`` in the verdict of their reading."""

from prodmaps.experiments.shared import claims

CLAIM = claims.load_ledger()["tab01.products_improve_transfer"]


def _pairs(x):  # two pairs, 1 % apart: a small standard error
    return [x, 1.01 * x]


def _doc(hks_ours, hks_textbook_ours):
    std = {"hk k": 0.05, "HKS": 0.55, "HKS (textbook)": 0.01, "XYZ": 0.29}
    ours = {"hk k": 0.05, "HKS": hks_ours, "HKS (textbook)": hks_textbook_ours, "XYZ": 0.2}
    per_pair = {"k9_9": {"transfer": {"std": {f: _pairs(x) for f, x in std.items()},
                                      **{m: {f: _pairs(x) for f, x in ours.items()}
                                         for m in ("our_B", "our_B_gainrule", "our_default")}}}}
    span = {"k9_9": {"approx": {"std": {"hk k": 0.0, "HKS": 0.5, "HKS (textbook)": 0.01, "XYZ": 0.29}}}}
    return {"tab01": {"results": {"errors": span, "errors_per_pair": per_pair}}}


def test_textbook_rows_are_judged_apart():
    (v,) = [x for x in claims.evaluate(CLAIM, _doc(0.15, 0.02)) if x.subset == "all"]
    assert v.verdict == "holds"  # the published HKS improves; the textbook row does not enter
    assert claims.reading_verdicts(v) == {"textbook": "does not hold"}  # 0.02 > 0.01 for the textbook HKS
    (v,) = [x for x in claims.evaluate(CLAIM, _doc(0.6, 0.005)) if x.subset == "all"]
    assert v.verdict == "does not hold" and claims.reading_verdicts(v) == {"textbook": "holds"}
    assert "textbook reading: holds" in claims.format_table([v])


def test_runs_without_readings_have_no_reading_verdicts():
    doc = _doc(0.15, 0.02)
    for by in doc["tab01"]["results"]["errors_per_pair"]["k9_9"]["transfer"].values():
        by.pop("HKS (textbook)")
    doc["tab01"]["results"]["errors"]["k9_9"]["approx"]["std"].pop("HKS (textbook)")
    (v,) = [x for x in claims.evaluate(CLAIM, doc) if x.subset == "all"]
    assert v.verdict == "holds" and claims.reading_verdicts(v) == {}
