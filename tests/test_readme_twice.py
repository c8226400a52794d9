"""The README's Python snippet runs twice in one folder, as a reader trying it again would: its runs replace the
first ones' folders (``overwrite=True``) instead of refusing them."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.harness.cli import ROOT
from tests.harness.docs import blocks


@pytest.mark.slow  # the README's snippet again (test_docs runs it once)
def test_the_readme_snippet_runs_a_second_time(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    snippet = next(b for b in blocks(ROOT / "README.md") if b.lang == "python")
    monkeypatch.chdir(tmp_path)
    ticks = []
    for _ in range(2):
        namespace: dict[str, object] = {"__name__": "__readme__"}
        exec(compile(snippet.code, "README.md", "exec"), namespace)
        ticks.append(namespace["result"]["ticks"])  # type: ignore[index]
    assert ticks[0] == ticks[1] and (tmp_path / "runs" / "minpos" / "result.json").is_file()
