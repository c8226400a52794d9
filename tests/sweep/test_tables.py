"""``fleet sweep report``'s tables fit the terminal without cutting a cell, print whole when piped, and come as
CSV or Markdown; allocator variants stay apart."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest
from rich.console import Console

from fleet_emu.sweep.execute import write_tables
from fleet_emu.sweep.report import _summary_table, report, summary
from fleet_emu.sweep.tables import show
from tests.harness.sweep import row

VARIANTS = ["spread(crowd=15.0,stale=40)", "spread(crowd=5.0,stale=40)", "spread(crowd=15.0,stale=10)"]
ROWS = [row(a, n, t) | {"param.seed": s, "id": f"{a}{n}{s}"} for a in ["greedy", *VARIANTS]
        for n in (2, 10) for s, t in ((0, 200 + n), (1, 230 + n))]


def _column(text: str, header: str) -> str:
    """The cells of one column of a rendered rich table, their lines joined (a wrapped cell comes back whole)."""
    lines = text.splitlines()
    top = next(i for i, ln in enumerate(lines) if ln.startswith("┃") and header in ln)
    index = [c.strip() for c in lines[top].split("┃")].index(header)
    body = [ln for ln in lines[top + 2:] if ln.startswith("│")]
    return "".join(ln.split("│")[index].strip() for ln in body)


@pytest.mark.parametrize("width", [80, 120])
def test_a_terminal_table_fits_and_cuts_no_cell(width: int) -> None:
    console = Console(file=io.StringIO(), width=width, force_terminal=True, color_system=None)
    show(console, _summary_table(summary(ROWS, "greedy"), "greedy"))
    text = console.file.getvalue()  # type: ignore[attr-defined]
    assert max(len(ln) for ln in text.splitlines()) <= width and "…" not in text
    lines = summary(ROWS, "greedy")
    assert _column(text, "allocator") == "".join(str(ln["allocator"]) for ln in lines)  # every variant whole
    assert "map: office" in text  # a constant column, moved to the legend


def test_piped_whole_and_as_csv_or_markdown(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    write_tables(ROWS, tmp_path)
    report(tmp_path, baseline="greedy", plots=False)
    out = capsys.readouterr().out
    assert "…" not in out and all(v in out for v in VARIANTS)  # each on one line: not cut to 180 columns
    report(tmp_path, baseline="greedy", plots=False, fmt="csv")
    got = capsys.readouterr()
    table = [r for r in csv.reader(io.StringIO(got.out.split("\n", 1)[1])) if r]
    assert table[0][:4] == ["map", "radio", "robots", "allocator"] and len(table) == 1 + 8
    assert {r[3] for r in table[1:]} == {"greedy", *VARIANTS} and "runs, 0 failed" in got.err
    report(tmp_path, baseline="greedy", plots=False, fmt="markdown")
    md = capsys.readouterr().out
    assert "| map | radio | robots | allocator |" in md and "| spread(crowd=5.0,stale=40) |" in md
