"""How ``fleet sweep report`` prints its tables: fitted to the terminal, at full width when piped, or as CSV or
Markdown (``--format``).

On a terminal a cell is never cut: a long cell (an allocator variant, ``spread(crowd=15.0,stale=40)``) wraps
within its column rather than ending in an ellipsis, so that variants can always be told apart; and when the table
is wider than the terminal, the columns whose every cell is the same (a study of one map, one radio) leave the
table for a legend under it. Piped to a file or another program, a table is printed at its natural width, whatever
the terminal's. ``csv`` and ``markdown`` print each table's title and rows only, with nothing cut nor wrapped,
and send every other line of the report to standard error.
"""

from __future__ import annotations

import csv
import io
from typing import Any

from rich.console import Console
from rich.table import Table
from rich.text import Text

#: The formats of ``fleet sweep report --format``.
FORMATS = ("table", "csv", "markdown")


def plain(table: Table) -> tuple[str, list[str], list[list[str]]]:
    """The table's title, column headers and rows as plain text (rich markup removed)."""
    def text(v: Any) -> str:
        return Text.from_markup(v).plain if isinstance(v, str) else Text(str(v)).plain if v is not None else ""

    headers = [text(c.header) for c in table.columns]
    cells = [[text(v) for v in c.cells] for c in table.columns]
    rows = [list(r) for r in zip(*cells, strict=True)] if cells else []
    return text(table.title), headers, rows


def to_csv(table: Table) -> str:
    """One table as CSV: a header line, then a line per row (the title is not part of it)."""
    _, headers, rows = plain(table)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(headers)
    writer.writerows(rows)
    return buf.getvalue()


def to_markdown(table: Table) -> str:
    """One table as a Markdown (GitHub) table under its title in bold."""
    title, headers, rows = plain(table)

    def line(cells: list[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    body = [line(headers), "| " + " | ".join("---" for _ in headers) + " |", *(line(r) for r in rows)]
    return (f"**{title}**\n\n" if title else "") + "\n".join(body) + "\n"


def fitted(table: Table, width: int) -> Table:
    """``table`` for a terminal ``width`` columns wide: no cell cut (long cells wrap in their column); when it is
    wider than that, its constant columns moved into a legend under it (the caption)."""
    for col in table.columns:
        col.overflow = "fold"
        col.no_wrap = False
    if Console(width=10_000).measure(table).maximum <= width or not table.rows:
        return table
    _, headers, rows = plain(table)
    constant = [i for i in range(len(headers)) if len({r[i] for r in rows}) == 1 and len(rows) > 1]
    if not constant or len(constant) == len(headers):
        return table
    out = Table(title=table.title, title_justify=table.title_justify,
                caption="; ".join(f"{headers[i]}: {rows[0][i]}" for i in constant), caption_justify="left")
    keep = [i for i in range(len(headers)) if i not in constant]
    for i in keep:
        col = table.columns[i]
        out.add_column(col.header, justify=col.justify, overflow="fold")
    for r in rows:
        out.add_row(*(r[i] for i in keep))
    return out


def show(console: Console, table: Table, fmt: str = "table") -> None:
    """Print ``table`` on ``console`` in ``fmt`` (:data:`FORMATS`): fitted to a terminal, at its natural width
    when the console is not one, or as CSV or Markdown."""
    if fmt == "csv":
        title = plain(table)[0]
        console.print((f"# {title}\n" if title else "") + to_csv(table), markup=False, highlight=False,
                      soft_wrap=True)
    elif fmt == "markdown":
        console.print(to_markdown(table), markup=False, highlight=False, soft_wrap=True)
    elif console.is_terminal:
        console.print(fitted(table, console.width))
    else:  # piped: the whole table, however wide
        for col in table.columns:
            col.overflow = "fold"
        natural = Console(width=10_000).measure(table).maximum
        Console(file=console.file, width=max(natural, 40), no_color=True).print(table)
