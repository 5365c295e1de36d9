"""Rendering: a small document model written as Markdown and as one standalone HTML page.

A :class:`Document` is a list of blocks, each a tuple ``(kind, *args)``:

* ``("h", level, text)``: a heading (``level`` 1 is the title);
* ``("p", text)``: a paragraph;
* ``("table", header, rows)``: a table, ``header`` a list of cells and ``rows`` lists of as many;
* ``("img", src, alt)``: an image, ``src`` relative to the folder the files are written to;
* ``("code", text)``: preformatted text;
* ``("ul", items)``: a bullet list;
* ``("counts", label, {verdict: n})``: verdict counts, a sentence (a row of coloured badges in HTML);
* ``("figure", rows, caption)``: panels laid out in rows, each row a list of ``[src, label]``, under
  one caption (Markdown: a table of images, one column per panel; HTML: panels side by side).

Text may hold the inline Markdown the HTML renderer understands: ```code```, ``[text](link)``,
``**bold**`` and ``*italic*``. Blocks are plain data (lists from JSON become tuples), so a report's
parts can be stored (:mod:`.report_data`) and tested without rendering; the experiments'
``report_blocks`` return blocks of the same kinds.

The renderers are pure: the same blocks give the same bytes. Markdown escapes ``|`` inside table
cells; HTML shows verdict phrases (``holds``, ``does not hold``, ...) as coloured badges, folds long
quotes of the paper (the column ``the paper's words``), right-aligns cells that are numbers and
gives every heading the anchor GitHub gives it (:func:`anchor`), so ``[text](#anchor)`` links work
in both. :func:`words` counts a Markdown text's words as a reader sees them.
"""

from __future__ import annotations

import html
import re

__all__ = ["KINDS", "Document", "anchor", "words"]

KINDS = {"h": 2, "p": 1, "table": 2, "img": 2, "code": 1, "ul": 1, "counts": 2, "figure": 2}  # kind -> its arguments

# verdict -> badge class, longest phrases first so "holds with the threshold rule" is not "holds"
_BADGES = (("holds with the threshold rule within rounding", "v-rule"), ("holds with the threshold rule", "v-rule"),
           ("holds within rounding", "v-round"), ("does not hold", "v-not"), ("inconclusive", "v-round"),
           ("not measured here", "v-none"), ("not demonstrable in this setting", "v-none"), ("not empirical", "v-none"),
           ("not reproducible", "v-none"),
           ("holds", "v-holds"))
_NUMBER = re.compile(r"[-+−]?(\d[\d,]*\.?\d*(e[-+]?\d+)?|\.\d+)\s*(%|x|s)?", re.I)
_STYLE = (
    "body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;line-height:1.45;max-width:1400px;"
    "margin:2em auto;padding:0 1em;color:#222}h1{font-size:1.6em}h2{margin-top:1.6em;border-bottom:1px solid #ddd}"
    "table{border-collapse:collapse;margin:.6em 0;font-size:.9em}td,th{border:1px solid #ddd;padding:3px 8px;"
    "text-align:left;vertical-align:top;overflow-wrap:anywhere}th{background:#f3f4f6;position:sticky;top:0;overflow-wrap:normal}"
    "td:first-child code{white-space:normal}td:nth-child(n+2){min-width:4em}td.num{text-align:right;"
    "font-variant-numeric:tabular-nums;white-space:nowrap}tr:nth-child(even) td{background:#fafafa}"
    "img{max-width:100%;border:1px solid #ddd;margin:.3em 0}pre{background:#f6f6f6;padding:.5em;overflow-x:auto}"
    ".badge{display:inline-block;padding:1px 8px;border-radius:10px;font-size:.85em;font-weight:600;"
    "white-space:nowrap}.v-holds{background:#d1fadf;color:#05603a}.v-round{background:#e0f2fe;color:#075985}"
    ".v-rule{background:#fef0c7;color:#93370d}.v-not{background:#fee4e2;color:#b42318}"
    ".v-none{background:#eaecf0;color:#475467}.counts{font-size:1.05em}.counts .badge{font-size:1em;"
    "margin:0 .3em .3em 0;padding:3px 10px}details summary{cursor:pointer;color:#475467}"
    "details{max-width:22em}figure{margin:.8em 0}.row{display:flex;gap:.6em;align-items:flex-start}"
    ".panel{flex:1 1 0;min-width:0;text-align:center}.panel img{margin:0}.label{font-size:.85em;color:#475467}"
    "figcaption{font-size:.9em;color:#344054}")


class Document:
    r"""An ordered list of blocks (see the module doc), rendered by :meth:`markdown` and :meth:`html`.

    Examples
    --------
    >>> d = Document()
    >>> d.h(2, "Claims")
    >>> d.counts("Totals", {"holds": 2, "does not hold": 0, "not measured here": 1})
    >>> d.table(["claim", "verdict"], [["`a`", "holds"], ["`b|c`", "not measured here"]])
    >>> print(d.markdown())
    ## Claims
    <BLANKLINE>
    Totals: 2 holds, 1 not measured here.
    <BLANKLINE>
    | claim | verdict |
    |---|---|
    | `a` | holds |
    | `b\|c` | not measured here |
    <BLANKLINE>
    >>> Document([["p", "from JSON"]]).blocks
    [('p', 'from JSON')]
    """

    def __init__(self, blocks=()):
        self.blocks: list[tuple] = []
        self.extend(blocks)

    def extend(self, blocks) -> None:
        """Append blocks (tuples or lists ``[kind, *args]``); raises ``ValueError`` for an unknown kind or arity."""
        for b in blocks:
            b = tuple(b)
            if not b or b[0] not in KINDS or len(b) != KINDS[b[0]] + 1:
                raise ValueError(f"not a document block: {b!r}; kinds and their arguments: {KINDS}")
            self.blocks.append(b)

    def h(self, level: int, text: str) -> None:
        """A heading of ``level`` (1 is the title)."""
        self.blocks.append(("h", level, text))

    def p(self, text: str) -> None:
        """A paragraph."""
        self.blocks.append(("p", text))

    def table(self, header, rows) -> None:
        """A table: ``header`` a list of cells, ``rows`` lists of as many cells."""
        self.blocks.append(("table", list(header), [list(r) for r in rows]))

    def img(self, src: str, alt: str) -> None:
        """An image, ``src`` relative to the folder the document is written to."""
        self.blocks.append(("img", src, alt))

    def code(self, text: str) -> None:
        """Preformatted text."""
        self.blocks.append(("code", text))

    def ul(self, items) -> None:
        """A bullet list."""
        self.blocks.append(("ul", list(items)))

    def counts(self, label: str, counts: dict) -> None:
        """Verdict counts (``{verdict: n}``; zero counts are left out)."""
        self.blocks.append(("counts", label, {k: n for k, n in counts.items() if n}))

    def figure(self, rows, caption: str = "") -> None:
        """Panels in rows (each a list of ``[src, label]``) under one caption."""
        self.blocks.append(("figure", [[list(p) for p in r] for r in rows], caption))

    # ------------------------------------------------------------------------------ Markdown
    def markdown(self) -> str:
        """The blocks as Markdown, one blank line between blocks."""
        def row(r):
            return "| " + " | ".join(str(c).replace("|", "\\|") for c in r) + " |"

        lines = {"h": lambda level, text: ["#" * level + " " + text], "p": lambda text: [text],
                 "table": lambda header, rows: [row(header), "|" + "---|" * len(header), *map(row, rows)],
                 "img": lambda src, alt: [f"![{alt}]({src})"], "code": lambda text: ["```\n" + text.rstrip() + "\n```"],
                 "ul": lambda items: [f"- {i}" for i in items],
                 "counts": lambda label, n: [f"{label}: " + ", ".join(f"{c} {k}" for k, c in n.items()) + "."],
                 "figure": lambda rows, caption: _figure_markdown(rows, caption, row)}
        return "\n".join(x for kind, *args in self.blocks for x in [*lines[kind](*args), ""]).rstrip() + "\n"

    # ------------------------------------------------------------------------------ HTML
    def html(self, title: str) -> str:
        """The blocks as one standalone HTML page (its style inline) titled ``title``."""
        inline, esc = _inline, html.escape
        render = {
            "h": lambda level, text: f'<h{level} id="{esc(anchor(text))}">{inline(text)}</h{level}>',
            "p": lambda text: f"<p>{inline(text)}</p>",
            "table": lambda header, rows: "\n".join(
                ["<table><tr>" + "".join(f"<th>{inline(c)}</th>" for c in header) + "</tr>"]
                + ["<tr>" + "".join(_cell(c, str(h)) for c, h in zip(r, header)) + "</tr>" for r in rows]
                + ["</table>"]),
            "counts": lambda label, n: f'<p class="counts"><b>{inline(label)}:</b> '
                                       + "".join(_badge(k, f"{c} {k}") for k, c in n.items()) + "</p>",
            "img": lambda src, alt: f'<p><img src="{esc(src)}" alt="{esc(alt)}"></p>',
            "code": lambda text: f"<pre>{esc(text)}</pre>",
            "ul": lambda items: "<ul>" + "".join(f"<li>{inline(i)}</li>" for i in items) + "</ul>",
            "figure": lambda rows, caption: "<figure>" + "".join(
                '<div class="row">' + "".join(f'<div class="panel"><img src="{esc(src)}" alt="{esc(label)}">'
                                              f'<div class="label">{inline(label)}</div></div>' for src, label in r)
                + "</div>" for r in rows) + (f"<figcaption>{inline(caption)}</figcaption>" if caption else "")
            + "</figure>"}
        return "\n".join(["<!DOCTYPE html>", "<html><head><meta charset=\"utf-8\">", f"<title>{esc(title)}</title>",
                          f"<style>{_STYLE}</style></head><body>",
                          *(render[kind](*args) for kind, *args in self.blocks), "</body></html>"]) + "\n"


def _figure_markdown(rows, caption: str, row) -> list:
    """A figure block as Markdown lines: per row of panels a table (labels, then images), then the caption."""
    parts = []
    for r in rows:
        if len(r) == 1:
            parts.append([f"![{r[0][1]}]({r[0][0]})"])
        else:
            parts.append([row([label for _, label in r]), "|" + "---|" * len(r),
                          row([f"![{label}]({src})" for src, label in r])])
    if caption:
        parts.append([caption])
    return [line for i, p in enumerate(parts) for line in ([""] if i else []) + p]


def anchor(heading: str) -> str:
    """The anchor GitHub gives a Markdown heading: lower case, inline markup and punctuation dropped, spaces ``-``.

    Examples
    --------
    >>> anchor("Appendix C2: FAUST (eight registrations)")
    'appendix-c2-faust-eight-registrations'
    >>> anchor("Tables 1–6 beside the published values")
    'tables-16-beside-the-published-values'
    """
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", str(heading))  # a link's text
    text = re.sub(r"[`*]", "", text).strip().lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def words(markdown: str) -> int:
    r"""Words of a Markdown text as a reader counts them: link and image targets, table rules and lone symbols left out.

    Examples
    --------
    >>> words("## Claims\n\n| a | b |\n|---|---|\n| holds | 2 of 3 |\n\n![FAUST](x/y.png) See [the cells](#cells).")
    11
    """
    text = re.sub(r"\]\([^)\s]*\)", "] ", str(markdown))  # link and image targets
    return sum(1 for tok in text.split() if re.search(r"\w", tok))


def _inline(text) -> str:
    """Inline Markdown (code, links, bold, italic) as HTML, everything else escaped."""
    s = html.escape(str(text))
    s = re.sub(r"`([^`]+)`", r"<code>\1</code>", s)
    s = re.sub(r"\[([^\]]+)\]\(([^)\s]+)\)", r'<a href="\2">\1</a>', s)
    s = re.sub(r"\*\*([^*]+)\*\*", r"<b>\1</b>", s)
    return re.sub(r"(?<![\w*])\*([^*\s][^*]*)\*(?![\w*])", r"<i>\1</i>", s)


def _badge(verdict: str, text: str | None = None) -> str:
    for phrase, css in _BADGES:
        if verdict.startswith(phrase):
            return f'<span class="badge {css}">{html.escape(text or verdict)}</span>'
    return html.escape(text or verdict)


def _cell(text, header: str = "") -> str:
    """One table cell: verdicts as badges, quotes folded, numbers right-aligned.

    A cell is a verdict when it starts with a verdict phrase followed by nothing or by ``(``, ``;``,
    ``,``, ``.``, ``:`` (a verdict with its notes), not by more words ("holds with a rule" is text).
    """
    t = str(text)
    plain = t.strip("*")
    for phrase, _ in _BADGES:
        rest = plain[len(phrase):]
        if plain.startswith(phrase) and (not rest or rest.startswith((" (", ";", ",", ".", ":"))):
            return "<td>" + _badge(phrase) + _inline(rest.replace("**", "")) + "</td>"
    if header == "the paper's words" and len(t) > 48:
        short = t[:40].rsplit(" ", 1)[0] + " …"
        return f"<td><details><summary>{html.escape(short)}</summary>{_inline(t)}</details></td>"
    if _NUMBER.fullmatch(t.strip()):
        return f'<td class="num">{_inline(t)}</td>'
    return f"<td>{_inline(t)}</td>"
