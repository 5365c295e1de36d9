"""The claims ledger: the paper's qualitative claims, judged by rules on the notebooks' results.

The ledger (``claims.toml`` beside this module, package data) has one entry per claim::

    [claims."tab01.products_improve_transfer"]
    where = "Table 1"                       # figure / table / section of the paper
    quote = "for all functions except hk k ... our approach produces a significant improvement"
    runs = ["tab01"]                        # the runs whose results.json decide it
    notebook = "tables_transfer"
    settings = "ground-truth maps, k_M = k_N = 9, 20 pairs"
    subsets = ["all", "intra", "inter"]     # optional: judged over all pairs and per pair kind
    smoke_verdict = "does not hold"         # what the smoke profile gives (asserted by the claim tests)
    [claims."tab01.products_improve_transfer".values]   # name -> "<run>:<dotted key>" ('*' expands)
    ours = "tab01:errors{subset}.k9_9.transfer.{method}.*"
    std = "tab01:errors{subset}.k9_9.transfer.std.*"
    [claims."tab01.products_improve_transfer".rule]
    holds = "all(ours[f] < std[f] for f in std if f != 'hk k')"
    margin = "max(ours[f] / std[f] for f in std if f != 'hk k')"
    evidence = "worst ours/std {margin:.2f} (ratio of transfer errors, all families but hk k)"

Values are read from the results of the named runs (``results.json``'s ``"results"``): a key
with ``*`` becomes a dict keyed by what ``*`` matched. Placeholders: ``{method}`` is the product
method being judged (below), ``{subset}`` is ``""`` (all pairs), ``"_intra"`` or ``"_inter"``.

Every claim is judged in up to three **settings**: ``paper`` (the paper's method, e.g.
Approach B at ``rtol = 1e-3``: ``{method}`` is the entry's ``method``, default ``our_B``),
``rule`` (Approach B with the threshold chosen by ``select_rtol(method="gain")``:
``method_rule``, default ``our_B_gainrule``) and ``default`` (the library's default extended
transfer: ``method_default``, default ``our_default``; reported beside the verdict, it does not
enter it). A setting whose keys are absent is "not measured here". The verdict combines the
first two:

* ``holds`` — the rule holds at the paper's settings;
* ``holds with the threshold rule`` — it does not at the paper's settings but does with the
  gain rule;
* ``does not hold`` — measured, and it holds neither at the paper's settings nor with the rule;
* ``not measured here`` — the results needed are missing (e.g. FAUST/TOSCA not prepared);
* ``not demonstrable in this setting`` — the entry has a ``rule.demonstrable`` (e.g. "an oracle,
  exact product-preserving transfer through the ground-truth point map, beats ``C``") and it
  fails on the results: the setting cannot show a product effect at all, so the claim is not
  judged there (the paper/rule/default columns are still computed and shown). The gate's
  ``rule.demonstrable_evidence`` (oracle and no-map numbers) leads the evidence; its outcome is in
  ``settings["oracle"]``.

The first two carry the suffix ``" within rounding"`` when the rule's outcome hinges on a
comparison whose margin is so thin that floating-point rounding (another BLAS kernel, another
machine) could flip it, see below.

Rules are Python expressions over the values (and ``all``, ``any``, ``min``, ``max``, ``abs``,
``len``, ``sum``, ``sorted``, ``mean``, and ``lower(a, b)`` / ``not_higher(a, b)``: ``<`` / ``<=``
with the tie rule of :mod:`prodmaps.experiments.shared.compare`), evaluated without builtins; the ledger
is part of the package, not user input. Every comparison of two measured numbers in a rule goes
through ``lower`` / ``not_higher`` (never a bare ``<``), and rules are monotone in them (no
``not``), so that each rule is judged three ways:

* *exact*: ties within ``TIE_REL`` (1e-5) relative are ties, everything else compares as is;
* *pessimistic*: in addition, every comparison whose relative margin is within ``ROUNDING_REL``
  (1e-3) goes against the claim;
* *optimistic*: every such comparison goes for the claim.

A rule that holds pessimistically holds whatever rounding does; one that fails optimistically
fails whatever rounding does; one in between is decided by margins under ``ROUNDING_REL``, and
the verdict says "… within rounding" on every machine instead of flipping between them. The
"holds" of a setting (the *paper* / *rule* / *default* columns) is the optimistic one, and
``within_rounding`` records whether the pessimistic one disagrees.
"""

from __future__ import annotations

import fnmatch
import importlib.resources
from dataclasses import dataclass, field
from pathlib import Path

from ...files import parse_toml, read_json
from . import compare
from .compare import ROUNDING_REL
from .results import flatten

__all__ = ["Claim", "Verdict", "load_ledger", "evaluate", "evaluate_folder", "verdicts_for_run",
           "format_table", "setting_mark", "reading_verdicts", "LEDGER", "VERDICTS"]

LEDGER = Path(str(importlib.resources.files("prodmaps.experiments.shared") / "claims.toml"))
NOT_DEMONSTRABLE = "not demonstrable in this setting"
VERDICTS = ("holds", "holds within rounding", "holds with the threshold rule",
            "holds with the threshold rule within rounding", "does not hold", NOT_DEMONSTRABLE, "not measured here")
SUBSET_SUFFIX = {"all": "", "intra": "_intra", "inter": "_inter"}
def _mean(values) -> float:
    values = list(values)
    return sum(values) / len(values)


def _comparators(mode: str) -> dict:
    """``lower`` / ``not_higher`` for one way of judging (``exact``, ``pessimistic``, ``optimistic``)."""
    if mode == "exact":  # the one tie rule of prodmaps.experiments.shared.compare
        return {"lower": compare.lower, "not_higher": compare.not_higher}

    def decide(a, b, strict: bool) -> bool:
        if compare.is_tie(a, b):
            return not strict  # a tie: never lower, always not higher
        if compare.is_tie(a, b, ROUNDING_REL):  # a margin rounding could flip: for or against the claim
            return mode == "optimistic"
        return compare.lower(a, b)

    return {"lower": lambda a, b: decide(a, b, True), "not_higher": lambda a, b: decide(a, b, False)}


_FUNCS = {"all": all, "any": any, "min": min, "max": max, "abs": abs, "len": len, "sum": sum,
          "sorted": sorted, "round": round, "range": range, "zip": zip, "mean": _mean}
_MODES = ("exact", "pessimistic", "optimistic")


@dataclass(frozen=True)
class Claim:
    """One ledger entry (see the module doc)."""

    id: str
    where: str
    quote: str
    runs: tuple
    values: dict
    holds: str
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


@dataclass
class Verdict:
    """The judgement of one claim on one subset of pairs."""

    claim: Claim
    subset: str
    verdict: str
    settings: dict = field(default_factory=dict)  # setting -> {"holds": bool | None, "margin": ..., "evidence": str}

    def __post_init__(self):
        # a measured claim whose setting cannot show it (its oracle does not beat C) is not judged
        if self.settings.get("oracle", {}).get("holds") is False and self.verdict != "not measured here":
            self.verdict = NOT_DEMONSTRABLE

    @property
    def evidence(self) -> str:
        """The evidence of the first judged setting (paper, rule, default), after the oracle's if it was judged."""
        oracle = self.settings.get("oracle", {})
        gate = oracle.get("evidence") if oracle.get("holds") is not None else None  # missing: said once below
        for s in ("paper", "rule", "default"):
            e = self.settings.get(s, {}).get("evidence")
            if e:
                return f"{gate}; {e}" if gate else e
        return gate or "results not found"

    def to_dict(self) -> dict:
        """The verdict as a JSON-ready dict: claim id, where, subset, verdict and settings."""
        return {"id": self.claim.id, "where": self.claim.where, "subset": self.subset, "verdict": self.verdict,
                "settings": {k: {kk: vv for kk, vv in v.items()} for k, v in self.settings.items()}}


def load_ledger(path=None) -> dict[str, Claim]:
    """The claims of the ledger, in file order."""
    doc = parse_toml(Path(path or LEDGER).read_text(encoding="utf-8"))
    out = {}
    for cid, e in doc.get("claims", {}).items():
        rule = e.get("rule", {})
        missing = [k for k in ("where", "quote", "runs", "values") if k not in e]
        missing += [] if "holds" in rule else ["rule.holds"]
        if missing:
            raise ValueError(f"claims ledger: claim {cid!r} lacks {missing}")
        out[cid] = Claim(
            id=cid, runs=tuple(e["runs"]), values=dict(e["values"]), subsets=tuple(e.get("subsets", ("all",))),
            smoke_verdict=_per_subset(cid, e.get("smoke_verdict", {})),
            **{k: e[k] for k in ("where", "quote", "notebook", "settings", "method", "method_rule", "method_default",
                                 "note") if k in e},
            **{k: rule[k] for k in ("holds", "margin", "evidence", "demonstrable", "demonstrable_margin",
                                    "demonstrable_evidence") if k in rule})
    return out


def _per_subset(cid: str, v) -> dict:
    out = {"all": v} if isinstance(v, str) else dict(v)
    bad = {k: x for k, x in out.items() if x not in VERDICTS or k not in SUBSET_SUFFIX}
    if bad:
        raise ValueError(f"claims ledger: claim {cid!r}: smoke_verdict {bad} (verdicts: {VERDICTS})")
    return out


def _gate(claim: Claim, results: dict, subset: str) -> dict:
    """``rule.demonstrable`` (can the setting show the claim?) on the values not naming ``{method}``, exact ties."""
    try:
        env = {**_FUNCS, **_values(claim, results, subset)}
    except _Missing as exc:
        return {"holds": None, "evidence": f"not measured: {exc}"}
    try:
        holds = bool(_eval(claim.demonstrable, env))
        margin = _eval(claim.demonstrable_margin, env) if claim.demonstrable_margin else None
    except _RULE_ERRORS as exc:
        return {"holds": None, "evidence": f"not measured: rule.demonstrable failed ({type(exc).__name__}: {exc})"}
    return {"holds": holds, "margin": margin, "evidence": _evidence(claim.demonstrable_evidence, margin, env)}


_RULE_ERRORS = (KeyError, NameError, TypeError, ZeroDivisionError, ValueError)


def _values(claim: Claim, results: dict, subset: str, method: str | None = None) -> dict:
    """The claim's values for one subset and product ``method`` (None: those not naming ``{method}``)."""
    return {name: _lookup(path.replace("{method}", method or "").replace("{subset}", SUBSET_SUFFIX[subset]), results)
            for name, path in claim.values.items() if method is not None or "{method}" not in path}


def _eval(expr: str, env: dict, mode: str = "exact"):
    """A rule's expression on the values ``env``, with the comparators of one way of judging."""
    return eval(expr, {"__builtins__": {}, **env, **_comparators(mode)})  # noqa: S307 - the ledger is package data


class _Missing(LookupError):
    pass


def _lookup(path: str, results: dict):
    """The value of ``"<run>:<dotted key>"`` in ``{run: flattened results or None}``."""
    run, _, key = path.partition(":")
    flat = results.get(run)
    if flat is None:
        raise _Missing(f"run {run!r} not available")
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
    fmt = {k: v for k, v in env.items() if k not in _FUNCS}
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


def _judge(claim: Claim, results: dict, method: str, subset: str, reading: str | None = None) -> dict:
    try:
        looked, found = _reading_rows(_values(claim, results, subset, method), reading)
    except _Missing as exc:
        return {"holds": None, "evidence": f"not measured: {exc}"}
    if reading is not None and reading not in found:
        return {"holds": None, "evidence": f"not measured: no family under the {reading} reading"}
    env = {**_FUNCS, **looked}
    try:
        ways = {mode: bool(_eval(claim.holds, env, mode)) for mode in _MODES}  # one namespace: generators see env
        margin = _eval(claim.margin, env) if claim.margin else None
    except _RULE_ERRORS as exc:
        return {"holds": None, "evidence": f"not measured: rule failed on these results ({type(exc).__name__}: {exc})"}
    holds = ways["optimistic"]
    within_rounding = ways["optimistic"] != ways["pessimistic"]
    ev = _evidence(claim.evidence, margin, env)
    if within_rounding:
        ev += f" (decided by a margin under {ROUNDING_REL:g} relative: within rounding)"
    return {"holds": holds, "margin": margin, "evidence": ev, "within_rounding": within_rounding,
            "readings": sorted(found)}


def evaluate(claim: Claim, results: dict) -> list[Verdict]:
    """Verdicts of ``claim`` (one per subset) from ``{run: results document or None}``."""
    prepared = {r: (flatten(d.get("results", d), number_lists=True) if d else None) for r, d in results.items()}
    out = []
    for subset in claim.subsets:
        settings = {"paper": _judge(claim, prepared, claim.method, subset)}
        if claim.demonstrable:  # the setting's oracle first: a claim is judged only where it can show
            settings["oracle"] = _gate(claim, prepared, subset)
        uses_method = any("{method}" in p for p in claim.values.values())
        if uses_method:
            settings["rule"] = _judge(claim, prepared, claim.method_rule, subset)
            settings["default"] = _judge(claim, prepared, claim.method_default, subset)
        verdict = _combine(settings["paper"], settings.get("rule"))
        for reading in settings["paper"].get("readings", []):  # e.g. the textbook HKS beside the published one
            paper = _judge(claim, prepared, claim.method, subset, reading=reading)
            rule = _judge(claim, prepared, claim.method_rule, subset, reading=reading) if uses_method else None
            settings[f"reading:{reading}"] = {**paper, "verdict": _combine(paper, rule)}
        out.append(Verdict(claim, subset, verdict, settings))
    return out


def _combine(paper: dict, rule: dict | None) -> str:
    """The verdict from the paper's setting and the threshold rule's (see the module doc)."""
    if paper["holds"] is None and (rule is None or rule["holds"] is None):
        return "not measured here"
    if paper["holds"]:
        return "holds" + (" within rounding" if paper["within_rounding"] else "")
    if rule is not None and rule.get("holds"):
        return "holds with the threshold rule" + (" within rounding" if rule["within_rounding"] else "")
    return "does not hold"


def reading_verdicts(v: "Verdict") -> dict:
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


def setting_mark(v: Verdict, setting: str) -> str:
    """``yes`` / ``no`` / ``—`` (not measured) for one setting of a verdict."""
    h = v.settings.get(setting, {}).get("holds")
    return "—" if h is None else ("yes" if h else "no")


def format_table(verdicts: list[Verdict]) -> str:
    """A plain-text table of verdicts (for notebooks and the ``prodmaps claims`` command)."""
    if not verdicts:
        return "(no claim of the ledger is judged on this run alone; see the report)"
    rows = [("claim", "pairs", "verdict", "paper", "rule", "default", "evidence")]
    for v in verdicts:
        verdict = v.verdict + "".join(f" ({r} reading: {x})" for r, x in reading_verdicts(v).items())
        rows.append((v.claim.id, v.subset if len(v.claim.subsets) > 1 else "", verdict, setting_mark(v, "paper"),
                     setting_mark(v, "rule"), setting_mark(v, "default"), v.evidence))
    w = [max(len(r[i]) for r in rows) for i in range(6)]
    return "\n".join("  ".join(f"{c:<{w[i]}}" for i, c in enumerate(r[:6])) + "  " + r[6] for r in rows)
