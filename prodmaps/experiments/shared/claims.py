"""The claims ledger: every claim of the paper (and the package's own, apart), judged on the results.

Contract (the criteria, the ledger's format and worked examples: ``docs/guide/claims.md``):

* ``claims.toml`` (package data) holds one entry per claim: ``where``, ``quote``, ``source``
  (``"paper"``: the paper's words, captions and "Please see the Appendix" included; ``"package"``:
  a claim of this package's settings), ``kind`` (``"measured"``, or ``"not empirical"`` /
  ``"not reproducible"`` with a ``reason``), and for a measured claim the ``runs``, ``values``
  (``"<run>:<dotted key>"``, ``*`` one level, ``**`` the nested dict below), ``rule.holds`` and,
  for a comparison, a practical ``margin`` with its ``why``.
* A **comparison** is paired over its units (pairs, or functions, or cells) by :func:`paired`:
  the mean improvement ``d``, its standard error ``SE = sd/√n`` and ``d`` relative to the
  reference. :meth:`Paired.outcome`: **holds** when the improvement exceeds both ``2·SE`` and the
  margin, **does not hold** when the opposite does, else **inconclusive**; one unit is a
  *single case* (no SE: the margin alone decides, and the verdict says so).
* Rules combine comparisons (``better``, ``improves``, ``improves_most``, ``similar``, ``below``;
  ``lower`` / ``not_higher`` for plain numbers, a margin under ``ROUNDING_REL`` being inconclusive)
  monotonely; a rule is evaluated with every inconclusive comparison against the claim and then
  for it: it holds if it holds the first way, does not hold if it fails the second, else is
  inconclusive (:data:`VERDICTS` adds "not measured here", "not demonstrable in this setting",
  "not empirical", "not reproducible").
* ``rule.ties`` (an expression giving ``{unit: reason}``) excludes ties by construction, e.g.
  :func:`span_ties`: a family in the span of the source basis, where every extended transfer
  equals the standard one up to its truncation; they count neither way and the verdict lists them.
* ``sensitivity`` (margins): the verdict at each, for margins read off the paper's own numbers.
* Settings: the verdict is the **paper's setting** alone (``{method}`` = ``method``); the threshold
  rule (``method_rule``) and the default transfer (``method_default``) are judged apart, as the
  package's columns ``rule`` / ``default`` of the verdict, never merged into it.
* :func:`verdict_counts` counts one verdict per claim by source; the report's totals use it.

Rules are Python expressions over the values, evaluated without builtins (the ledger is package
data, not user input).
"""

from __future__ import annotations

import fnmatch
import importlib.resources
import math
from dataclasses import dataclass, field
from pathlib import Path

from ...files import parse_toml, read_json
from . import compare
from .compare import ROUNDING_REL
from .results import flatten, to_jsonable

__all__ = ["Claim", "Verdict", "Paired", "paired", "span_ties", "load_ledger", "evaluate", "evaluate_folder",
           "verdicts_for_run", "verdicts_on_results", "verdict_counts", "format_table", "setting_mark",
           "reading_verdicts", "LEDGER", "VERDICTS", "SOURCES", "KINDS", "SPAN_TOL"]

LEDGER = Path(str(importlib.resources.files("prodmaps.experiments.shared") / "claims.toml"))
HOLDS, INCONCLUSIVE, NOT_HOLD = "holds", "inconclusive", "does not hold"
NOT_DEMONSTRABLE = "not demonstrable in this setting"
NOT_MEASURED = "not measured here"
NOT_EMPIRICAL, NOT_REPRODUCED = "not empirical", "not reproducible"
VERDICTS = (HOLDS, INCONCLUSIVE, NOT_HOLD, NOT_DEMONSTRABLE, NOT_MEASURED, NOT_EMPIRICAL, NOT_REPRODUCED)
SOURCES = ("paper", "package")
KINDS = ("measured", NOT_EMPIRICAL, NOT_REPRODUCED)
SUBSET_SUFFIX = {"all": "", "intra": "_intra", "inter": "_inter"}
SPAN_TOL = 1e-8  # a family whose standard approximation error is below this lies in the span of the basis
_Z = 2.0  # standard errors an improvement must exceed


# ------------------------------------------------------------------------------ paired comparisons
@dataclass(frozen=True)
class Paired:
    """A paired comparison of errors ``ours`` against ``ref`` over ``n`` units (lower is better).

    ``mean_diff``: the mean improvement ``ref − ours`` (positive: ours lower); ``se``: its standard
    error ``sd/√n`` (None for a single unit); ``rel``: ``mean_diff / mean(ref)``, the improvement
    relative to the reference; ``rel_opposite``: ``−mean_diff / mean(ours)``, the reference's
    improvement over ours relative to ours.
    """

    n: int
    ours: float
    ref: float
    mean_diff: float
    se: float | None
    rel: float
    rel_opposite: float

    @property
    def single_case(self) -> bool:
        """One unit: no standard error, the margin alone decides."""
        return self.n < 2

    def outcome(self, margin: float) -> str:
        """``"holds"``, ``"does not hold"`` or ``"inconclusive"`` at the practical ``margin`` (relative).

        >>> paired([0.1, 0.11, 0.1], [0.2, 0.21, 0.2]).outcome(0.05)
        'holds'
        >>> paired([0.2, 0.21], [0.1, 0.1]).outcome(0.05)
        'does not hold'
        >>> paired([0.1, 0.2], [0.2, 0.1]).outcome(0.05)
        'inconclusive'
        """
        noise = 0.0 if self.se is None else _Z * self.se
        if self.mean_diff > noise and self.rel > margin:
            return HOLDS
        if -self.mean_diff > noise and self.rel_opposite > margin:
            return NOT_HOLD
        return INCONCLUSIVE

    def to_dict(self) -> dict:
        """The statistics as a JSON-ready dict."""
        return {"n": self.n, "ours": self.ours, "ref": self.ref, "mean_diff": self.mean_diff, "se": self.se,
                "rel": self.rel}


def _units(ours, ref) -> tuple[list, list]:
    """Aligned unit values: dicts by the reference's keys, sequences by position, numbers as one unit."""
    if isinstance(ref, dict):
        if not isinstance(ours, dict) or set(ours) != set(ref):
            raise ValueError(f"paired values must have the same units, got {sorted(ours)} and {sorted(ref)}"
                             if isinstance(ours, dict) else "paired values must both be dicts of units")
        keys = list(ref)
        return [float(ours[k]) for k in keys], [float(ref[k]) for k in keys]
    if isinstance(ref, (list, tuple)):
        if not isinstance(ours, (list, tuple)) or len(ours) != len(ref):
            raise ValueError("paired values must be sequences of the same length (one value per unit)")
        return [float(x) for x in ours], [float(x) for x in ref]
    return [float(ours)], [float(ref)]


def paired(ours, ref, *, higher: bool = False) -> Paired:
    """The paired comparison of ``ours`` against ``ref`` (per-unit values: lists, dicts or one number).

    ``higher=True``: larger values are better (areas under a curve): the improvement is ``ours − ref``.

    Raises
    ------
    ValueError
        If the units do not match, a value is not finite, or there is no unit.

    Examples
    --------
    >>> p = paired([0.10, 0.12], [0.20, 0.24])
    >>> round(p.mean_diff, 12), round(p.se, 12), p.n, round(p.rel, 12)
    (0.11, 0.01, 2, 0.5)
    """
    a, b = _units(ours, ref)
    if not a:
        raise ValueError("paired needs at least one unit")
    if not all(math.isfinite(x) for x in a + b):
        raise ValueError("paired values must be finite")
    d = [(x - y) if higher else (y - x) for x, y in zip(a, b)]  # improvements
    n = len(d)
    mean_d = sum(d) / n
    se = math.sqrt(sum((x - mean_d) ** 2 for x in d) / (n - 1) / n) if n > 1 else None
    ma, mb = sum(a) / n, sum(b) / n
    scale_ref, scale_ours = abs(mb), abs(ma)
    rel = mean_d / scale_ref if scale_ref > 0 else (math.inf if mean_d > 0 else 0.0)
    rel_opp = -mean_d / scale_ours if scale_ours > 0 else (math.inf if mean_d < 0 else 0.0)
    return Paired(n, ma, mb, mean_d, se, rel, rel_opp)


def span_ties(approx_std: dict, tol: float = SPAN_TOL) -> dict:
    """``{family: reason}`` for the families whose standard approximation error is below ``tol``.

    Such a family lies in the span of the source basis: products cannot improve its representation,
    and every extended transfer equals the standard one up to its truncation (a tie by construction).

    >>> list(span_ties({"hk k": 3e-15, "HKS": 0.5}))
    ['hk k']
    """
    return {f: (f"in the span of the source basis (standard approximation error {float(e):.0e}): equal to the "
                "standard transfer by construction, up to the truncation")
            for f, e in approx_std.items() if abs(float(e)) < tol}


class _Judge:
    """The rule functions of one evaluation ``mode``.

    ``record`` collects every comparison (all true), ``pessimistic`` counts an inconclusive one
    against the claim, ``optimistic`` for it.
    """

    def __init__(self, mode: str, margin, ties: dict):
        self.mode, self.margin, self.ties, self.records = mode, margin, dict(ties), []

    def _as_bool(self, outcome: str) -> bool:
        if self.mode == "record":
            return True
        return outcome == HOLDS or (outcome == INCONCLUSIVE and self.mode == "optimistic")

    def _margin(self, margin):
        m = self.margin if margin is None else margin
        if m is None:
            raise ValueError("this rule compares but the claim states no margin (margin = ... and why = ...)")
        return float(m)

    def better(self, ours, ref, margin=None, label: str = "", higher: bool = False) -> bool:
        p = paired(ours, ref, higher=higher)
        out = p.outcome(self._margin(margin))
        if self.mode == "record":
            self.records.append({"label": str(label), **p.to_dict(), "outcome": out})
        return self._as_bool(out)

    def _per_unit(self, ours: dict, ref: dict, margin, higher: bool) -> list:
        if not isinstance(ref, dict):
            raise ValueError("improves/improves_most compare dicts of units (e.g. families)")
        return [self.better(ours[u], ref[u], margin, u, higher) for u in ref if u not in self.ties]

    def improves(self, ours, ref, margin=None, higher: bool = False) -> bool:
        return all(self._per_unit(ours, ref, margin, higher))  # every unit (the list is built first: no short cut)

    def improves_most(self, ours, ref, margin=None, higher: bool = False) -> bool:
        outs = self._per_unit(ours, ref, margin, higher)
        return 2 * sum(outs) > len(outs)

    def similar(self, a, b, tol=None, label: str = "") -> bool:
        """Equivalence: ``|mean(a − b)| ± 2·SE`` within ``tol·|mean(b)|`` holds, beyond it does not."""
        p = paired(a, b)
        bound = self._margin(tol) * abs(p.ref)
        noise = 0.0 if p.se is None else _Z * p.se
        out = HOLDS if abs(p.mean_diff) + noise <= bound else NOT_HOLD if abs(p.mean_diff) - noise > bound \
            else INCONCLUSIVE
        if self.mode == "record":
            self.records.append({"label": str(label), **p.to_dict(), "outcome": out, "test": f"within ±{bound:.3g}"})
        return self._as_bool(out)

    def below(self, values, bound=None, label: str = "") -> bool:
        """The mean of ``values`` below ``bound``: ``mean + 2·SE < bound`` holds, ``mean − 2·SE > bound`` does not."""
        v = [float(x) for x in (values.values() if isinstance(values, dict) else
                                values if isinstance(values, (list, tuple)) else [values])]
        n, bound = len(v), self._margin(bound)
        m = sum(v) / n
        se = math.sqrt(sum((x - m) ** 2 for x in v) / (n - 1) / n) if n > 1 else None
        noise = 0.0 if se is None else _Z * se
        out = HOLDS if m + noise < bound else NOT_HOLD if m - noise > bound else INCONCLUSIVE
        if self.mode == "record":
            self.records.append({"label": str(label), "n": n, "mean": m, "se": se, "bound": bound, "outcome": out})
        return self._as_bool(out)

    def _compare(self, a, b, strict: bool) -> bool:
        if compare.is_tie(a, b):
            return not strict
        if compare.is_tie(a, b, ROUNDING_REL):  # a margin rounding could flip: inconclusive
            return self.mode != "pessimistic"
        return compare.lower(a, b)

    def functions(self) -> dict:
        return {"better": self.better, "improves": self.improves, "improves_most": self.improves_most,
                "similar": self.similar, "below": self.below, "MARGIN": self.margin,
                "lower": lambda a, b: self._compare(a, b, True), "not_higher": lambda a, b: self._compare(a, b, False)}


def _mean(values) -> float:
    values = list(values.values() if isinstance(values, dict) else values)
    return sum(values) / len(values)


_FUNCS = {"all": all, "any": any, "min": min, "max": max, "abs": abs, "len": len, "sum": sum, "sorted": sorted,
          "round": round, "range": range, "zip": zip, "list": list, "next": next, "iter": iter, "mean": _mean,
          "paired": paired, "span_ties": span_ties}


# ------------------------------------------------------------------------------ the ledger
@dataclass(frozen=True)
class Claim:
    """One ledger entry (see the module doc).

    ``margin`` is the rule's shown number (``rule.margin``); ``practical_margin`` and ``why`` the
    claim's criterion (``margin`` and ``why`` at the top of the entry).
    """

    id: str
    where: str
    quote: str
    runs: tuple = ()
    values: dict = field(default_factory=dict)
    holds: str = ""
    margin: str = ""
    evidence: str = ""
    notebook: str = ""
    settings: str = ""
    subsets: tuple = ("all",)
    method: str = "our_B"
    method_rule: str = "our_B_gainrule"
    method_default: str = "our_default"
    note: str = ""
    demonstrable: str = ""  # rule.demonstrable: can the setting show the claim at all (an oracle beats C)?
    demonstrable_margin: str = ""
    demonstrable_evidence: str = ""
    smoke_verdict: dict = field(default_factory=dict)  # subset -> the verdict expected on the smoke results
    source: str = "paper"
    kind: str = "measured"
    reason: str = ""
    practical_margin: float | None = None
    why: str = ""
    sensitivity: tuple = ()
    ties: str = ""

    @property
    def measured(self) -> bool:
        """Whether the claim is judged on results (else it is listed with its reason)."""
        return self.kind == "measured"


@dataclass
class Verdict:
    """The judgement of one claim on one subset of pairs.

    ``settings[name]`` (``paper``, ``rule``, ``default``, ``oracle``, ``reading:<r>``): ``verdict``,
    ``holds`` (None: not measured), ``evidence``, ``comparisons`` (each paired comparison's
    statistics and outcome), ``excluded`` (``{unit: reason}``), ``single_case``, ``sensitivity``.
    """

    claim: Claim
    subset: str
    verdict: str
    settings: dict = field(default_factory=dict)

    def __post_init__(self):
        # a measured claim whose setting cannot show it (its oracle does not beat C) is not judged
        if self.settings.get("oracle", {}).get("verdict") in (NOT_HOLD, INCONCLUSIVE) and self.verdict != NOT_MEASURED:
            self.verdict = NOT_DEMONSTRABLE

    @property
    def source(self) -> str:
        """``"paper"`` or ``"package"``."""
        return self.claim.source

    @property
    def paper(self) -> dict:
        """The paper's setting (the verdict's)."""
        return self.settings.get("paper", {})

    @property
    def excluded(self) -> dict:
        """``{unit: reason}``: ties by construction left out of the paper setting's verdict."""
        return dict(self.paper.get("excluded", {}))

    @property
    def single_case(self) -> bool:
        """Whether the paper setting's verdict rests on a single case (one pair, one function)."""
        return bool(self.paper.get("single_case"))

    @property
    def comparisons(self) -> list:
        """The paired comparisons of the paper's setting."""
        return list(self.paper.get("comparisons", []))

    @property
    def evidence(self) -> str:
        """The evidence of the paper's setting (after the oracle's if it was judged), or the reason."""
        if not self.claim.measured:
            return self.claim.reason
        oracle = self.settings.get("oracle", {})
        gate = oracle.get("evidence") if oracle.get("holds") is not None else None
        e = self.paper.get("evidence")
        if e:
            return f"{gate}; {e}" if gate else e
        return gate or "results not found"

    def to_dict(self) -> dict:
        """The verdict as a JSON-ready dict: claim id, where, source, subset, verdict and settings."""
        return {"id": self.claim.id, "where": self.claim.where, "source": self.claim.source, "kind": self.claim.kind,
                "subset": self.subset, "verdict": self.verdict, "margin": self.claim.practical_margin,
                "why": self.claim.why, "evidence": self.evidence,
                "settings": {k: dict(v) for k, v in self.settings.items()}}


def load_ledger(path=None) -> dict[str, Claim]:
    """The claims of the ledger, in file order.

    Raises
    ------
    ValueError
        If an entry lacks a field its kind needs, or names an unknown source, kind or verdict.
    """
    doc = parse_toml(Path(path or LEDGER).read_text(encoding="utf-8"))
    out = {}
    for cid, e in doc.get("claims", {}).items():
        rule = e.get("rule", {})
        kind, source = e.get("kind", "measured"), e.get("source", "paper")
        if kind not in KINDS or source not in SOURCES:
            raise ValueError(f"claims ledger: claim {cid!r}: kind must be one of {KINDS} and source one of {SOURCES}")
        need = ("where", "quote", "runs", "values") if kind == "measured" else ("where", "quote", "reason")
        missing = [k for k in need if k not in e] + ([] if "holds" in rule or kind != "measured" else ["rule.holds"])
        if "margin" in e and "why" not in e:
            missing.append("why (the reason for its margin)")
        if missing:
            raise ValueError(f"claims ledger: claim {cid!r} lacks {missing}")
        out[cid] = Claim(
            id=cid, runs=tuple(e.get("runs", ())), values=dict(e.get("values", {})),
            subsets=tuple(e.get("subsets", ("all",))), smoke_verdict=_per_subset(cid, e.get("smoke_verdict", {})),
            practical_margin=None if e.get("margin") is None else float(e["margin"]),
            sensitivity=tuple(float(x) for x in e.get("sensitivity", ())),
            **{k: e[k] for k in ("where", "quote", "notebook", "settings", "method", "method_rule", "method_default",
                                 "note", "source", "kind", "reason", "why") if k in e},
            **{k: rule[k] for k in ("holds", "margin", "evidence", "demonstrable", "demonstrable_margin",
                                    "demonstrable_evidence", "ties") if k in rule})
    return out


def _per_subset(cid: str, v) -> dict:
    out = {"all": v} if isinstance(v, str) else dict(v)
    bad = {k: x for k, x in out.items() if x not in VERDICTS or k not in SUBSET_SUFFIX}
    if bad:
        raise ValueError(f"claims ledger: claim {cid!r}: smoke_verdict {bad} (verdicts: {VERDICTS})")
    return out


_RULE_ERRORS = (KeyError, NameError, TypeError, ZeroDivisionError, ValueError)


class _Missing(LookupError):
    pass


def _values(claim: Claim, results: dict, subset: str, method: str | None = None) -> dict:
    """The claim's values for one subset and product ``method`` (None: those not naming ``{method}``)."""
    return {name: _lookup(path.replace("{method}", method or "").replace("{subset}", SUBSET_SUFFIX[subset]), results)
            for name, path in claim.values.items() if method is not None or "{method}" not in path}


def _lookup(path: str, results: dict):
    """The value of ``"<run>:<dotted key>"`` in ``{run: flattened results or None}``."""
    run, _, key = path.partition(":")
    flat = results.get(run)
    if flat is None:
        raise _Missing(f"run {run!r} not available")
    if key.endswith(".**"):  # the nested dict below the prefix
        pre = key[:-2]
        hits = {k[len(pre):]: v for k, v in flat.items() if k.startswith(pre)}
        if not hits:
            raise _Missing(f"{run}:{key} matches nothing in the results")
        nested: dict = {}
        for k, v in hits.items():
            *head, last = k.split(".")
            d = nested
            for h in head:
                d = d.setdefault(h, {})
            d[last] = v
        return nested
    if "*" not in key:
        if key not in flat:
            raise _Missing(f"{run}:{key} not in the results")
        return flat[key]
    pre, _, post = key.partition("*")
    hits = {k[len(pre): len(k) - len(post) if post else None]: v for k, v in flat.items()
            if fnmatch.fnmatchcase(k, key) and "." not in k[len(pre): len(k) - len(post) if post else None]}
    if not hits:
        raise _Missing(f"{run}:{key} matches nothing in the results")
    return hits


def _evidence(template: str, margin, env: dict) -> str:
    """``template`` filled with the margin, the values and ``n_<name>`` (their sizes)."""
    fmt = {k: v for k, v in env.items() if k not in _FUNCS and not callable(v)}
    fmt.update({f"n_{k}": len(v) for k, v in fmt.items() if isinstance(v, dict)})
    try:
        return template.format(margin=margin, **fmt) if template else ""
    except (KeyError, IndexError, ValueError, TypeError) as exc:
        return f"(evidence template failed: {exc})"


def _reading_rows(values: dict, reading: str | None) -> tuple[dict, set]:
    """Family rows of one reading: the values and the set of readings found.

    Rows labelled ``"HKS (textbook)"`` (a family under a reading other than the run's) are dropped, or,
    for ``reading="textbook"``, take the place of ``"HKS"``.
    """
    from .families import PAPER_LABELS

    labels = set(PAPER_LABELS.values())
    found, out = set(), {}
    for key, v in values.items():
        if not isinstance(v, dict):
            out[key] = v
            continue
        rows, alt = {}, {}
        for label, x in v.items():
            base, sep, rest = str(label).partition(" (")
            if sep and base in labels and rest.endswith(")"):
                found.add(rest[:-1])
                if rest[:-1] == reading:
                    alt[base] = x
            else:
                rows[label] = x
        out[key] = {**rows, **alt}
    return out, found


def _rule_verdict(expr: str, env: dict, margin, ties: dict) -> tuple[str, list]:
    """The three-way verdict of ``expr`` (module doc) and the comparisons it made."""
    rec = _Judge("record", margin, ties)
    eval(expr, {"__builtins__": {}, **env, **rec.functions()})  # noqa: S307 - the ledger is package data
    ways = {}
    for mode in ("pessimistic", "optimistic"):
        ways[mode] = bool(eval(expr, {"__builtins__": {}, **env, **_Judge(mode, margin, ties).functions()}))  # noqa: S307
    verdict = HOLDS if ways["pessimistic"] else NOT_HOLD if not ways["optimistic"] else INCONCLUSIVE
    return verdict, rec.records


def _summary(records: list, excluded: dict) -> str:
    """``"3 of 5 comparisons hold, 2 inconclusive (paired over 2 units); excluded: hk k"``."""
    if not records:
        return ""
    counts = {o: sum(r["outcome"] == o for r in records) for o in (HOLDS, INCONCLUSIVE, NOT_HOLD)}
    ns = sorted({r["n"] for r in records})
    txt = (f"{counts[HOLDS]} of {len(records)} comparisons hold" + (f", {counts[INCONCLUSIVE]} inconclusive"
                                                                      if counts[INCONCLUSIVE] else "")
           + (f", {counts[NOT_HOLD]} do not" if counts[NOT_HOLD] else "")
           + (" (single case)" if ns == [1] else f" (paired over {'/'.join(map(str, ns))} units)"))
    return txt + (f"; excluded as ties by construction: {', '.join(excluded)}" if excluded else "")


def _judge(claim: Claim, results: dict, method: str, subset: str, reading: str | None = None) -> dict:
    """One setting of a claim: its verdict, comparisons, exclusions and evidence."""
    try:
        looked, found = _reading_rows(_values(claim, results, subset, method), reading)
    except _Missing as exc:
        return {"verdict": NOT_MEASURED, "holds": None, "evidence": f"not measured: {exc}"}
    if reading is not None and reading not in found:
        return {"verdict": NOT_MEASURED, "holds": None,
                "evidence": f"not measured: no family under the {reading} reading"}
    env = {**_FUNCS, **looked}
    try:
        ties = dict(eval(claim.ties, {"__builtins__": {}, **env})) if claim.ties else {}  # noqa: S307
        verdict, records = _rule_verdict(claim.holds, env, claim.practical_margin, ties)
        sens = {f"{m:g}": _rule_verdict(claim.holds, env, m, ties)[0] for m in claim.sensitivity}
        margin = eval(claim.margin, {"__builtins__": {}, **env, **_Judge("optimistic", claim.practical_margin,  # noqa: S307
                                                                          ties).functions()}) if claim.margin else None
    except _RULE_ERRORS as exc:
        return {"verdict": NOT_MEASURED, "holds": None,
                "evidence": f"not measured: rule failed on these results ({type(exc).__name__}: {exc})"}
    ev = "; ".join(x for x in (_evidence(claim.evidence, margin, env), _summary(records, ties)) if x)
    if sens:
        ev += "; margin sensitivity: " + ", ".join(f"{m}: {v}" for m, v in sens.items())
    return {"verdict": verdict, "holds": verdict == HOLDS, "margin": margin, "evidence": ev, "comparisons": records,
            "excluded": ties, "single_case": bool(records) and all(r["n"] < 2 for r in records),
            "sensitivity": sens, "readings": sorted(found)}


def _gate(claim: Claim, results: dict, subset: str) -> dict:
    """``rule.demonstrable`` (can the setting show the claim?) on the values not naming ``{method}``."""
    try:
        env = {**_FUNCS, **_values(claim, results, subset)}
    except _Missing as exc:
        return {"verdict": NOT_MEASURED, "holds": None, "evidence": f"not measured: {exc}"}
    try:
        verdict, records = _rule_verdict(claim.demonstrable, env, claim.practical_margin, {})
        margin = eval(claim.demonstrable_margin, {"__builtins__": {}, **env, **_Judge(  # noqa: S307
            "optimistic", claim.practical_margin, {}).functions()}) if claim.demonstrable_margin else None
    except _RULE_ERRORS as exc:
        return {"verdict": NOT_MEASURED, "holds": None,
                "evidence": f"not measured: rule.demonstrable failed ({type(exc).__name__}: {exc})"}
    ev = _evidence(claim.demonstrable_evidence, margin, env) + (f" ({verdict})" if verdict != HOLDS else "")
    return {"verdict": verdict, "holds": verdict == HOLDS, "margin": margin, "evidence": ev, "comparisons": records}


def evaluate(claim: Claim, results: dict) -> list[Verdict]:
    """Verdicts of ``claim`` (one per subset) from ``{run: results document or None}``."""
    if not claim.measured:
        return [Verdict(claim, s, claim.kind, {"paper": {"verdict": claim.kind, "holds": None,
                                                          "evidence": claim.reason}}) for s in claim.subsets]
    prepared = {r: (flatten(to_jsonable(d.get("results", d)), number_lists=True) if d else None)
                for r, d in results.items()}  # numpy arrays (a notebook's own results) as lists
    uses_method = any("{method}" in p for p in claim.values.values())
    out = []
    for subset in claim.subsets:
        settings = {"paper": _judge(claim, prepared, claim.method, subset)}
        if claim.demonstrable:  # the setting's oracle first: a claim is judged only where it can show
            settings["oracle"] = _gate(claim, prepared, subset)
        for name, method in (("rule", claim.method_rule), ("default", claim.method_default)):
            if uses_method and method:
                settings[name] = _judge(claim, prepared, method, subset)
        for reading in settings["paper"].get("readings", []):  # e.g. the textbook HKS beside the published one
            settings[f"reading:{reading}"] = _judge(claim, prepared, claim.method, subset, reading=reading)
        out.append(Verdict(claim, subset, settings["paper"]["verdict"], settings))
    return out


def reading_verdicts(v: Verdict) -> dict:
    """``{reading: verdict}`` of the family readings judged beside the run's (e.g. ``"textbook"``)."""
    return {k.partition(":")[2]: s["verdict"] for k, s in v.settings.items() if k.startswith("reading:")}


def evaluate_folder(results_dir, ledger=None) -> list[Verdict]:
    """Verdicts of every ledger claim from a results folder (``results/paper``: one subfolder per run)."""
    results_dir = Path(results_dir)
    claims = load_ledger(ledger)
    runs = {r for c in claims.values() for r in c.runs}
    docs = {r: read_json(results_dir / r / "results.json") for r in runs}
    return [v for c in claims.values() for v in evaluate(c, docs)]


def verdicts_for_run(run: str, results: dict, ledger=None) -> list[Verdict]:
    """Verdicts of the claims judged on ``run`` alone, from its results (``results.json`` dict or its ``"results"``).

    Claims that also need other runs are listed as "not measured here" with the missing runs
    named; the report judges them on the whole results folder.
    """
    doc = results if "results" in results else {"results": results}
    claims = [c for c in load_ledger(ledger).values() if run in c.runs]
    return [v for c in claims for v in evaluate(c, {r: (doc if r == run else None) for r in c.runs})]


def verdicts_on_results(docs: dict, ledger=None, subset: str = "all") -> dict:
    """``{claim id: verdict}`` of every measured claim whose runs are all in ``docs`` (``{run: results}``).

    For results computed under another setting than the runs' own (a study's substituted values,
    e.g. the tables under a rejected normalisation): each document needs only the keys the
    claims read (``errors``, ``errors_per_pair``); claims reading other keys are "not measured here".
    """
    docs = {r: (d if "results" in d else {"results": d}) for r, d in docs.items()}
    out = {}
    for c in load_ledger(ledger).values():
        if c.measured and c.runs and set(c.runs) <= set(docs):
            vs = {v.subset: v for v in evaluate(c, docs)}
            if subset in vs:
                out[c.id] = vs[subset].verdict
    return out


def verdict_counts(verdicts) -> dict:
    """``{source: {verdict: number of claims}}`` (every verdict of :data:`VERDICTS`, zeros included).

    One verdict per claim: its subset ``"all"`` (else its first). ``verdicts`` is a list of
    :class:`Verdict` or a ``{claim id: verdict string}`` dict with the ledger's sources.

    >>> ledger = load_ledger()
    >>> counts = verdict_counts({cid: "holds" for cid in ledger})
    >>> counts["paper"]["holds"] + counts["package"]["holds"] == len(ledger)
    True
    """
    out = {s: dict.fromkeys(VERDICTS, 0) for s in SOURCES}
    if isinstance(verdicts, dict):
        ledger = load_ledger()
        for cid, verdict in verdicts.items():
            out[ledger[cid].source][verdict] += 1
        return out
    seen: dict = {}
    for v in verdicts:
        if v.claim.id not in seen or v.subset == "all":
            seen[v.claim.id] = v
    for v in seen.values():
        out[v.claim.source][v.verdict] += 1
    return out


def setting_mark(v: Verdict, setting: str) -> str:
    """``yes`` (holds) / ``no`` (does not hold) / ``inconclusive`` / ``—`` (not measured) for one setting."""
    s = v.settings.get(setting, {}).get("verdict", NOT_MEASURED)
    return {HOLDS: "yes", NOT_HOLD: "no", INCONCLUSIVE: "inconclusive"}.get(s, "—")


def format_table(verdicts: list[Verdict]) -> str:
    """A plain-text table of verdicts (for notebooks and the ``prodmaps claims`` command)."""
    if not verdicts:
        return "(no claim of the ledger is judged on this run alone; see the report)"
    rows = [("claim", "source", "pairs", "verdict", "rule", "default", "evidence")]
    for v in verdicts:
        verdict = v.verdict + (" (single case)" if v.single_case else "") + "".join(
            f" ({r} reading: {x})" for r, x in reading_verdicts(v).items())
        rows.append((v.claim.id, v.claim.source, v.subset if len(v.claim.subsets) > 1 else "", verdict,
                     setting_mark(v, "rule"), setting_mark(v, "default"), v.evidence))
    w = [max(len(r[i]) for r in rows) for i in range(6)]
    return "\n".join("  ".join(f"{c:<{w[i]}}" for i, c in enumerate(r[:6])) + "  " + r[6] for r in rows)
