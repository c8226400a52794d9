"""docs/design/architecture.md names modules and classes by path: each one exists, so that a rename that forgets
the page fails here; and every step of its data path names the module that does it."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "design" / "architecture.md"
PACKAGES = ("core", "world", "netem", "agents", "launch", "recording", "sweep", "ros2", "rl", "fleet_emu")
_ANY, _SUB = "|".join(PACKAGES), "|".join(PACKAGES[:-1])
_PATH = re.compile(rf"`((?:{_ANY})/[\w/]+\.py)`")
_DOTTED = re.compile(rf"`((?:{_SUB})\.[\w.]+)`")


def test_every_module_path_on_the_page_exists() -> None:
    paths = set(_PATH.findall(PAGE.read_text()))
    assert len(paths) > 30, paths  # the page names its modules; an emptied list would pass vacuously
    assert sorted(p for p in paths if not (ROOT / p).is_file()) == []


def _resolves(dotted: str) -> bool:
    parts = ("fleet_emu." + dotted).split(".")
    for i in range(len(parts), 1, -1):
        try:
            obj: object = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def test_every_dotted_name_on_the_page_resolves() -> None:
    names = set(_DOTTED.findall(PAGE.read_text()))
    assert names, "the page names no module or class by its dotted name"
    assert sorted(n for n in names if not _resolves(n)) == []


def test_every_step_of_the_data_path_names_a_module() -> None:
    text = PAGE.read_text()
    section = text.split("## A run's data path", 1)[1].split("\n## ", 1)[0]
    steps = re.split(r"\n\d+\. ", section)[1:]
    assert len(steps) == 7, len(steps)  # scenario, launch, processes, recording, result, report, sweep
    assert all(_PATH.search(step) for step in steps)
