"""The documentation's fenced blocks, read with the ``docs-test`` markers of the comments above each (what the
markers mean: ``tests/test_docs.py``)."""

from __future__ import annotations

import dataclasses
import importlib.util
import re
from pathlib import Path
from types import ModuleType

from tests.harness.cli import ROOT

FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>```+|~~~+)[ \t]*(?P<lang>[\w+-]*)[^\n]*$")
MARK = re.compile(r"<!--\s*docs-test:\s*(?P<what>skip|slow|pending|file|exit)\b\s*(?P<arg>.*?)\s*-->")


@dataclasses.dataclass(frozen=True)
class Block:
    """One fenced block of a page: its language, its text (the fence's indent removed), the line of its opening
    fence and the markers of the comments just before it."""

    page: Path
    line: int
    lang: str
    code: str
    marks: tuple[tuple[str, str], ...] = ()

    def mark(self, what: str) -> str | None:
        return next((arg for kind, arg in self.marks if kind == what), None)

    @property
    def id(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of a page, with the ``docs-test`` markers of the comment lines just above each."""
    lines = page.read_text().splitlines()
    out: list[Block] = []
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence = m["indent"], m["fence"]
        body, j = [], i + 1
        while j < len(lines) and not (lines[j].strip().startswith(fence) and lines[j].strip().strip(fence[0]) == ""):
            body.append(lines[j][len(indent):] if lines[j].startswith(indent) else lines[j].lstrip())
            j += 1
        marks, k = [], i - 1
        while k >= 0 and (lines[k].strip() == "" or MARK.search(lines[k])):
            marks += [(x["what"], x["arg"]) for x in MARK.finditer(lines[k])]
            k -= 1
        out.append(Block(page, i + 1, m["lang"].lower(), "\n".join(body) + "\n", tuple(reversed(marks))))
        i = j + 1
    return out


def load_script(path: Path, name: str) -> ModuleType:
    """A script shipped with the docs (``docs/hooks.py``, an example) imported as the module ``name``, without
    running its ``__main__`` block."""
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
