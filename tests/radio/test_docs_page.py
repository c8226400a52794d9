"""docs/guides/radio-measured.md shows what ``fleet radio fit kolakowski-ble-2021`` gives: its generated part is
the tool's report, and its figures carry that report's digest (``python docs/radio_measured.py`` rewrites both).
The site is fetched through a mirror of the measurements kept beside the repository."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest

from fleet_emu.launch.radio_plots import HISTOGRAM, SCATTER, carried_digest, digest
from tests.harness.docs import load_script
from tests.radio.mirror import fetched

ROOT = Path(__file__).resolve().parents[2]


def _generator() -> ModuleType:
    return load_script(ROOT / "docs" / "radio_measured.py", "radio_measured")


@pytest.mark.slow  # the whole fit of 22,277 readings: about 12 s of CPU
def test_the_page_and_its_figures_are_what_the_tool_gives(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    gen = _generator()
    text = gen.PAGE.read_text()
    site, body = gen.block_of(text)
    assert site == fetched(tmp_path, monkeypatch)
    report, _, _ = gen.fitted(site)
    assert body == report.strip(), "docs/guides/radio-measured.md is out of date: run `python docs/radio_measured.py`"
    assert "| wall (eq. 4) |" in body and "wall vs log-distance (one P0)" in body
    for name in (SCATTER, HISTOGRAM):
        assert f"../performance/img/{name}" in text
        assert carried_digest(gen.IMG / name) == digest(report), f"docs/performance/img/{name} is out of date"
    assert "doi:10.3390/s21186270" in text and "CC BY 4.0" in text


def test_the_page_is_linked_from_the_radio_guide_and_in_the_nav() -> None:
    assert "(radio-measured.md)" in (ROOT / "docs" / "guides" / "radio.md").read_text()
    assert "guides/radio-measured.md" in (ROOT / "mkdocs.yml").read_text()
