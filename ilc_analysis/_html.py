"""The HTML of the results' Jupyter displays (``_repr_html_``), one look for all of them.

Following pandas and xarray: a compact block with a header line (what the object is, in bold,
and its one-line headline), plain tables of the numbers, and the longer parts (meanings, notes,
what was judged) in collapsible ``<details>`` sections that start closed. Every text is
escaped here (:func:`text`); the markup is well-formed XML (no void tags, quoted attributes,
no named entities), so a test can parse it. The style is scoped to the block's class and uses
colours readable on light and dark notebook themes.
"""

from __future__ import annotations

import html
from collections.abc import Iterable, Sequence

__all__ = ["text", "block", "table", "details", "verdict", "paragraph", "items", "Markup",
           "VERDICT_COLOURS", "CLASS"]

#: The class of every display's outer ``<div>`` (the scoped style's selector).
CLASS = "ilc-repr"

#: The colour of each verdict (:data:`ilc_analysis.analysis.VERDICTS`) in the tables.
VERDICT_COLOURS = {"holds": "#1a7f37", "marginal": "#bc4c00", "fails": "#cf222e",
                   "degenerate": "#9a6700", "not applicable": "#6e7781", "unknown": "#8250df"}

_STYLE = (f"<style>.{CLASS} table {{border-collapse: collapse; margin: 0.3em 0;}} "
          f".{CLASS} th, .{CLASS} td {{padding: 0.15em 0.6em; text-align: left; "
          f"vertical-align: top;}} "
          f".{CLASS} th {{border-bottom: 1px solid currentColor;}} "
          f".{CLASS} td.num {{text-align: right; font-variant-numeric: tabular-nums;}} "
          f".{CLASS} summary {{cursor: pointer;}} "
          f".{CLASS} .sub {{opacity: 0.75; font-size: 0.9em;}}</style>")


class Markup(str):
    """A string of markup made here (inserted as it is by :func:`table`)."""


def text(value) -> str:
    """``str(value)``, escaped for HTML (quotes included)."""
    return html.escape(str(value), quote=True)


def verdict(name: str) -> Markup:
    """A verdict in its colour, bold."""
    colour = VERDICT_COLOURS.get(name, "inherit")
    return Markup(f'<b style="color: {colour}">{text(name)}</b>')


def table(header: Sequence[str], rows: Iterable[Sequence], *, numeric: Sequence[int] = (),
          titles: Sequence[str] | None = None) -> Markup:
    """A ``<table>``: a header row, then one row per item.

    Parameters
    ----------
    header : sequence of str
        The column names (escaped).
    rows : iterable of sequence
        The cells; a cell that is a :class:`Markup` is inserted as it is, any other value is
        escaped.
    numeric : sequence of int
        Columns aligned right (numbers).
    titles : sequence of str, optional
        A tooltip per row (escaped), e.g. what the row means.
    """
    head = "".join(f"<th>{text(h)}</th>" for h in header)
    body = []
    for k, row in enumerate(rows):
        cells = "".join(
            ('<td class="num">' if j in numeric else "<td>") + _cell(c) + "</td>"
            for j, c in enumerate(row))
        title = f' title="{text(titles[k])}"' if titles is not None and titles[k] else ""
        body.append(f"<tr{title}>{cells}</tr>")
    return Markup(f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody>"
                  f"</table>")


def _cell(value) -> str:
    return str(value) if isinstance(value, Markup) else text(value)


def details(summary: str, body: str, *, open: bool = False) -> Markup:
    """A collapsible section: ``summary`` (escaped) over ``body`` (markup)."""
    start = '<details open="open">' if open else "<details>"
    return Markup(f"{start}<summary>{text(summary)}</summary>{body}</details>")


def block(kind: str, title: str, *parts: str, headline: str = "") -> Markup:
    """The whole display: the header line ``kind`` (bold) ``title``, the ``headline`` below it
    (both escaped), then ``parts`` (markup, in order)."""
    head = f'<div><b>{text(kind)}</b> {text(title)}</div>'
    line = f'<div class="sub">{text(headline)}</div>' if headline else ""
    return Markup(f'<div class="{CLASS}">{_STYLE}{head}{line}{"".join(parts)}</div>')


def paragraph(body: str) -> Markup:
    """A ``<p>`` of escaped text."""
    return Markup(f"<p>{text(body)}</p>")


def items(lines: Iterable[str]) -> Markup:
    """A ``<ul>`` of escaped lines."""
    return Markup("<ul>" + "".join(f"<li>{text(line)}</li>" for line in lines) + "</ul>")
