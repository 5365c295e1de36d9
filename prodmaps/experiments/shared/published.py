"""The paper's published Tables 1–6 (package data) and how our values are matched to them.

Table values: how a notebook reports them
-----------------------------------------
A notebook that reproduces (part of) a paper table puts a list under ``"table"`` in its
results (``nbtools.write_results(out_dir, {"table": [...], ...}, params)``), one entry per
number, in the long format of ``paper/published_tables.csv``
(columns ``table,fmap,k_M,k_N,function,stage,method,value``)::

    {"table": 1, "function": "HKS", "stage": "transfer", "method": "std", "value": 0.5412,
     "fmap": "ground_truth", "k_M": 9, "k_N": 9}

* ``table``: the paper's table number (``1``, ``"1"``, ``"T1"`` and ``"Table 1"`` all work);
* ``function``: exactly as in the CSV (case matters: ``"hk k"`` and ``"hk K"`` differ):
  ``hk k``, ``hk K``, ``HKS``, ``WKS``, ``Random``, ``XYZ``, ``Indicator``, ``SHOT``, ``AWFT``;
* ``stage``: ``"approx"`` or ``"transfer"``; ``method``: ``std``, ``our_l1``, ``our_l2``,
  ``our_A``, ``our_B`` (as in the CSV); instead of ``stage`` and ``method`` a single
  ``"column": "transfer_our_B"`` (``<stage>_<method>``) is accepted;
* ``value``: our number (float, same normalisation as the paper: the relative error);
* ``fmap`` (``ground_truth`` / ``computed_NO17``), ``k_M``, ``k_N`` (the paper's k, constant
  not counted): optional, but needed where a table has several settings (Table 3 has both
  ``k_M=6, k_N=7`` and ``k_M=27, k_N=35``). Given values must agree with the CSV row.

An entry is matched to the CSV row that agrees on every field it gives (table, function,
stage, method and whichever of fmap, k_M, k_N are present). Entries matching no row, or
several, are listed in the report as unmatched. The difference is ``ours - published``;
the paper prints two decimals, so ``|difference| <= 0.005`` is "as published".

One rule for every count: the report prints values, differences and SEs with
:data:`PRINTED_DECIMALS` (3) decimals (:func:`printed`), and the printed difference decides
(``±0.020`` is within ±0.02, ``−0.021`` is not), so recounting the printed table gives the count.

An entry may also give ``se``, the standard error of our value over its pairs (a mean over
drawn pairs and functions). Comparisons with the paper (one home for the report and the studies):

* :func:`within_published`: ``|ours − published| <= WITHIN`` (0.02), printed: the cell is reproduced;
* :func:`within_draw_noise`: ``|ours − published| <= WITHIN + DRAW_Z·√2·se``, printed: the difference is
  within what two independent draws of as many pairs explain at about 95 % (``DRAW_Z = 2``),
  taking the paper's mean to be as noisy as ours (its pairs and functions are unknown). A miss
  beyond it is a difference of data or definition, not of the draw.
"""

from __future__ import annotations

import csv
import importlib.resources
import re
from pathlib import Path

import numpy as np

__all__ = ["PUBLISHED_CSV", "TABLE_KEYS", "WITHIN", "DRAW_Z", "PRINTED_DECIMALS", "printed", "load_published",
           "normalize_entry", "match_entries", "published_values", "within_published", "within_draw_noise",
           "score_cells"]

PUBLISHED_CSV = Path(str(importlib.resources.files("prodmaps.experiments.shared") / "published_tables.csv"))
TABLE_KEYS = ("table", "fmap", "k_M", "k_N", "function", "stage", "method")
_OPTIONAL = ("fmap", "k_M", "k_N")
WITHIN = 0.02  # the paper prints two decimals
DRAW_Z = 2.0  # standard errors of the band of within_draw_noise (about 95 %)
PRINTED_DECIMALS = 3  # the report prints ours, the difference and the SE with three decimals
_ROUND = 1e-12  # a printed difference of exactly 0.020 counts as within, whatever the float rounding


def printed(value: float, signed: bool = False) -> str:
    """``value`` as the report prints it: :data:`PRINTED_DECIMALS` decimals (``signed``: with its sign).

    >>> printed(0.14296), printed(-0.02004, signed=True), printed(0.0, signed=True)
    ('0.143', '-0.020', '+0.000')
    """
    return f"{float(value):+.{PRINTED_DECIMALS}f}" if signed else f"{float(value):.{PRINTED_DECIMALS}f}"


def within_published(diff: float) -> bool:
    """Whether ``ours − published`` reproduces the printed cell: ``|diff| <= WITHIN`` for ``diff`` as printed.

    The difference is rounded as :func:`printed` shows it, so the count and the printed table agree
    at the boundary.

    >>> within_published(-0.02004), within_published(0.0204), within_published(-0.0206)
    (True, True, False)
    """
    return abs(float(printed(diff, signed=True))) <= WITHIN + _ROUND


def within_draw_noise(diff: float, se: float) -> bool:
    """Whether ``|ours − published| <= WITHIN + DRAW_Z·√2·se`` (module doc), both as printed; ``se >= 0``.

    ``se`` is our value's standard error.

    >>> within_draw_noise(0.04, 0.01), within_draw_noise(0.05, 0.01)
    (True, False)
    """
    se = float(se)
    if not se >= 0:
        raise ValueError(f"se must be a standard error >= 0, got {se!r}")
    band = WITHIN + DRAW_Z * 2 ** 0.5 * float(printed(se))
    return abs(float(printed(diff, signed=True))) <= band + _ROUND


def load_published(path=None) -> list[dict]:
    """Rows of the published-tables CSV; ``value`` as float, the key columns as strings."""
    path = Path(path) if path is not None else PUBLISHED_CSV
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    missing = set(TABLE_KEYS + ("value",)) - set(rows[0] if rows else ())
    if missing:
        raise ValueError(f"{path}: missing columns {sorted(missing)}")
    for r in rows:
        r["value"] = float(r["value"])
    return rows


def _table_id(v) -> str:
    m = re.search(r"\d+", str(v))
    if not m:
        raise ValueError(f"table {v!r}: give the paper's table number, e.g. 1 or 'T1'")
    return str(int(m.group(0)))


def normalize_entry(entry: dict) -> dict:
    """Validate one ``table`` entry and bring it to the CSV's key format (strings)."""
    if not isinstance(entry, dict):
        raise ValueError(f"table entry {entry!r} must be a dict")
    e = dict(entry)
    if "column" in e and ("stage" not in e or "method" not in e):
        stage, _, method = str(e.pop("column")).partition("_")
        e.setdefault("stage", stage)
        e.setdefault("method", method)
    missing = [k for k in ("table", "function", "stage", "method", "value") if k not in e]
    if missing:
        raise ValueError(f"table entry {entry!r} misses {missing}")
    out = {"table": _table_id(e["table"]), "function": str(e["function"]),
           "stage": str(e["stage"]), "method": str(e["method"]), "value": float(e["value"])}
    out.update({k: str(int(e[k])) if k != "fmap" else str(e[k]) for k in _OPTIONAL if e.get(k) is not None})
    if e.get("se") is not None:
        se = float(e["se"])
        if not se >= 0:
            raise ValueError(f"table entry {entry!r}: se must be a standard error >= 0")
        out["se"] = se
    return out


def match_entries(entries: list[dict], published: list[dict]):
    """``(matches, unmatched)``: matches are ``(published_row, entry)``; unmatched ``(entry, reason)``."""
    matches, unmatched = [], []
    for raw in entries:
        try:
            e = normalize_entry(raw)
        except (ValueError, TypeError) as exc:
            unmatched.append((raw, str(exc)))
            continue
        keys = [k for k in TABLE_KEYS if k in e]
        cands = [r for r in published if all(r[k] == e[k] for k in keys)]
        if len(cands) == 1:
            matches.append((cands[0], dict(e, run=raw.get("run", ""))))
        elif not cands:
            unmatched.append((raw, "no published value with these keys"))
        else:
            unmatched.append((raw, f"{len(cands)} published values match; add fmap/k_M/k_N"))
    return matches, unmatched


def published_values(table: str, fmap: str, path=None) -> dict:
    """``{(k_M, k_N, stage, method, function): value}`` of one paper table (``"T1"`` or ``1``)."""
    t = _table_id(table)
    return {(int(r["k_M"]), int(r["k_N"]), r["stage"], r["method"], r["function"]): r["value"]
            for r in load_published(path) if r["table"] == t and r["fmap"] == fmap}


def score_cells(ours: dict, published: dict, methods=("std", "our_A", "our_l2", "our_B")) -> dict:
    """``{method: {"cells", "within", "mean_abs", "max_abs"}}`` over the published cells we measured.

    ``ours`` and ``published`` are keyed ``(k_M, k_N, stage, method, function)``; a cell counts as
    reproduced when :func:`within_published` (``|ours - published| <= 0.02`` as printed).
    """
    out = {}
    for m in methods:
        d = [abs(ours[c] - v) for c, v in published.items() if c[3] == m and c in ours]
        if d:
            out[m] = {"cells": len(d), "within": int(sum(map(within_published, d))),
                      "mean_abs": float(np.mean(d)), "max_abs": float(np.max(d))}
    return out
