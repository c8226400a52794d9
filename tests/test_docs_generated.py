"""The reference pages' generated parts (CLI help, the Python API, the messages) are written into the pages, so
that they read on the repository as on the site, and are current: ``python docs/hooks.py`` rewrites them."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType

import pytest

from tests.harness.docs import load_script

ROOT = Path(__file__).resolve().parents[1]


def _hooks() -> ModuleType:
    return load_script(ROOT / "docs" / "hooks.py", "docs_hooks")


HOOKS = _hooks()


@pytest.mark.parametrize("page", HOOKS.PAGES)
def test_a_reference_page_holds_its_generated_parts_and_they_are_current(page: str) -> None:
    text = (ROOT / "docs" / page).read_text()
    assert "<!-- /" in text and "\n::: " not in text  # generated into the page: no placeholder nor directive
    assert HOOKS.refresh(text) == text, f"docs/{page} is out of date: run `python docs/hooks.py`"


def test_docstrings_render_as_markdown() -> None:
    doc = """Uses :class:`~fleet_emu.core.radio.RadioConfig` and :meth:`to_dict`, ``literal``::

        waf: float = setting(3.1)

    The end."""
    md = HOOKS.markdown_of(doc)
    assert "``fleet_emu.core.radio.RadioConfig``" in md and "``to_dict``" in md and ":meth:" not in md
    assert "```text\nwaf: float = setting(3.1)\n```" in md and "literal``:\n" in md
    api = HOOKS.api_page()
    assert ":meth:" not in api and ":class:" not in api and "### `fleet_emu.Scenario`" in api


def test_the_result_schema_s_scenario_is_written_from_the_declared_settings() -> None:
    """``result.schema.json``'s ``$defs.scenario`` is the scenario's and the radio's settings as declared (a field
    declared once is in it, with its range), and the file is current: ``python docs/hooks.py`` rewrites it."""
    assert HOOKS.SCHEMA.read_text() == HOOKS.result_schema_text(), "run `python docs/hooks.py`"
    scenario = json.loads(HOOKS.SCHEMA.read_text())["$defs"]["scenario"]
    assert scenario["properties"]["robots"] == {"type": "integer", "minimum": 1, "maximum": 256}
    assert scenario["properties"]["radio"]["properties"]["loss"] == {"type": "number", "minimum": 0.0, "maximum": 1.0}
