"""The paper-specific prose of the report: text files, figure captions and dataset scopes, read at build time.

The prose is not in code: it lives in ``report_text/`` beside the run registry
(``paper/report_text/``, see ``docs/guide/report.md``).

* :data:`TEXT_FILES`: Markdown files of ``#`` headings, paragraphs, ``- `` bullet lists and fenced
  code separated by blank lines (:func:`text_blocks`); :func:`report_text` reads one with its
  ``{name}`` placeholders filled (``{{`` for a literal brace, HTML comments dropped; an absent file
  contributes nothing, an unknown placeholder is a ``ValueError`` naming the file).
* :data:`CAPTIONS` (``captions.toml``): one entry per run, ``paper``, ``look``, ``ours`` and an
  optional ``layout`` (:func:`report_captions`).
* ``datasets.toml``: how the summary names each dataset (:func:`dataset_scope`).
"""

from __future__ import annotations

import re
from pathlib import Path

from ..files import parse_toml

__all__ = ["TEXT_FILES", "CAPTIONS", "text_blocks", "report_text", "report_captions", "dataset_scope"]

TEXT_FILES = ("title.md", "summary.md", "not_reproduced.md", "rerun.md", "glossary.md", "claims.md",
              "beyond_the_paper.md", "tables.md", "forking_paths.md", "systematic_differences.md", "gallery.md")
CAPTIONS = "captions.toml"  # the figures' captions, one entry per run


def text_blocks(text: str) -> list:
    r"""Blocks of a report text: ``#`` headings, bullet lists (``- `` items), fenced code and paragraphs.

    Chunks are separated by blank lines; a paragraph's or an item's lines are joined with spaces; a
    chunk fenced by lines of three backticks is code, kept as it is.

    Examples
    --------
    >>> text_blocks("# Title\n\nOne paragraph\nwrapped.\n\n- an item\n  wrapped\n- another\n")
    [('h', 1, 'Title'), ('p', 'One paragraph wrapped.'), ('ul', ['an item wrapped', 'another'])]
    >>> text_blocks("```\nmake reproduce\n```")
    [('code', 'make reproduce')]
    """
    blocks = []
    for chunk in re.split(r"\n\s*\n", text.strip()):
        fenced = re.fullmatch(r"```[^\n]*\n(.*?)\n?```", chunk.strip(), flags=re.S)
        if fenced:
            blocks.append(("code", fenced.group(1)))
            continue
        lines = [ln.strip() for ln in chunk.strip().splitlines()]
        if not lines or not lines[0]:
            continue
        if lines[0].startswith("#"):
            level = len(lines[0]) - len(lines[0].lstrip("#"))
            blocks.append(("h", level, " ".join([lines[0][level:].strip(), *lines[1:]])))
        elif lines[0].startswith("- "):
            items = []
            for ln in lines:
                if ln.startswith("- "):
                    items.append(ln[2:])
                else:
                    items[-1] += " " + ln
            blocks.append(("ul", items))
        else:
            blocks.append(("p", " ".join(lines)))
    return blocks


def report_text(folder, name: str, **values) -> list:
    """The blocks of the text file ``folder/name`` with its ``{placeholders}`` filled; ``[]`` if absent."""
    path = Path(folder) / name if folder is not None else None
    if path is None or not path.is_file():
        return []
    text = re.sub(r"<!--.*?-->", "", path.read_text(encoding="utf-8"), flags=re.S)
    try:
        text = text.format_map(values)
    except (KeyError, ValueError, IndexError) as exc:
        raise ValueError(f"{path}: placeholder {exc} is not one the report fills ({', '.join(sorted(values))}); "
                         "write a literal brace as {{ or }}") from None
    return text_blocks(text)


def _read_toml(folder, name: str) -> dict:
    path = Path(folder) / name if folder is not None else None
    return parse_toml(path.read_text(encoding="utf-8")) if path is not None and path.is_file() else {}


def report_captions(folder) -> dict:
    """``{run: {"paper", "look", "ours", "layout"}}`` of ``folder/captions.toml`` (``{}`` without the file).

    ``paper``: what the paper's figure shows; ``look``: what to look at; ``ours``: what our panel
    shows; ``layout`` (optional): rows of datasets, the panels' arrangement in the gallery
    (e.g. ``[["faust_r", "tosca_r"]]``: FAUST_r left, TOSCA_r right, as the paper's FAUST and
    centaur). Raises ``ValueError`` for an entry with other keys or without text.
    """
    doc = _read_toml(folder, CAPTIONS)
    for run, entry in doc.items():
        bad = set(entry) - {"paper", "look", "ours", "layout"} if isinstance(entry, dict) else {"(not a table)"}
        if bad or not any(entry.get(k) for k in ("paper", "look", "ours")):
            raise ValueError(f"{Path(folder) / CAPTIONS}: [{run}] needs text under paper, look, ours "
                             f"(and optionally layout); unknown keys {sorted(bad)}")
    return doc


def dataset_scope(folder, ds) -> str:
    """How the summary names a dataset: its ``scope`` in ``report_text/datasets.toml``, else its name."""
    entry = _read_toml(folder, "datasets.toml").get(ds.dataset, {})
    return entry.get("scope", ds.name)
