"""The first study of the sweeps guide compares something: its baseline reaches the target in every run, so
that the report's comparison columns (the % difference and the paired difference to the baseline) hold numbers,
not ``-``. The docs' own test runs the block; this one reads its output."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest

from fleet_emu.sweep.execute import read_rows
from tests.harness.cli import ROOT, run_cli
from tests.harness.docs import blocks

GUIDE = ROOT / "docs" / "guides" / "sweeps.md"


@pytest.mark.slow  # the guide's study in full; study rows by default (test_sweep)
def test_the_guides_first_study_fills_its_comparison_columns(tmp_path: Path) -> None:
    study = next(b for b in blocks(GUIDE) if b.mark("file") == "tiny.toml")
    (tmp_path / "tiny.toml").write_text(study.code)
    out = tmp_path / "runs" / "tiny"
    run_cli(["sweep", "tiny.toml", "--out", str(out), "--jobs", "1", "--quiet"], cwd=tmp_path, check=True)
    rows = read_rows(out)
    assert len(rows) >= 6 and all(r["status"] == "ok" for r in rows)
    baseline = [r for r in rows if r["param.allocator"] == "nearest"]
    assert len(baseline) >= 3 and all(r["completed"] for r in baseline), [r["coverage"] for r in baseline]
    code, text, _ = run_cli(["sweep", "report", str(out), "--no-plots", "--format", "csv"], cwd=tmp_path)
    assert code == 0
    lines = [line for line in text.splitlines() if not line.startswith("#")]
    table = list(csv.DictReader(io.StringIO("\n".join(lines))))
    others = [r for r in table if r.get("allocator") == "minpos"]
    columns = [c for c in table[0] if c.startswith("vs nearest") or c.startswith("paired")]
    assert others and len(columns) == 2, (list(table[0]), others)
    for row in others:
        assert all(row[c].strip() not in ("", "-") for c in columns), row


def test_the_guides_study_table_lists_every_shipped_study() -> None:
    from fleet_emu.sweep.study import shipped

    text = GUIDE.read_text()
    assert [name for name in shipped() if f"| `{name}` |" not in text] == []
