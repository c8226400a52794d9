"""The guide's trainer (docs/examples/train_policy.py): ``--tiny`` says it is a smoke test, not a policy, and a
table in which every run missed the target is called out."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest

from tests.harness.docs import load_script

pytest.importorskip("pettingzoo")

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "examples" / "train_policy.py"


def _example() -> ModuleType:
    return load_script(EXAMPLE, "train_policy_example")


@pytest.mark.slow  # trains a tiny policy; the policy allocator by default
def test_tiny_says_it_is_a_smoke_test_first_and_last(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    example = _example()
    assert example.main(["--tiny", "--eval", "", "--robots", "2", "--out", str(tmp_path / "p.npz")]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == lines[-1] == example.SMOKE and "smoke test" in example.SMOKE
    assert (tmp_path / "p.npz").is_file()


def test_a_table_of_runs_that_all_missed_is_called_out() -> None:
    example = _example()
    assert example.compares_nothing([["office", *["150 ± 0"] * 5]], 150)
    assert not example.compares_nothing([["office", "150 ± 0", "150 ± 0", "120 ± 4", "150 ± 0", "150 ± 0"]], 150)
