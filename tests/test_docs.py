"""Every example in the documentation runs: the fenced ``python`` and ``bash`` blocks of ``docs/**/*.md`` and
``README.md``, so that a page cannot drift from the code.

The blocks of one page run in order in one temporary folder (where ``docs/`` is this repository's, so that a path
from a clone's root holds), as a reader would type them: ``python`` blocks in this process, in one namespace per
page (a notebook: a later block uses an earlier one's names); ``bash`` blocks with ``bash -euo pipefail``,
``fleet`` being this environment's. The default selection keeps to small runs on the memory engine (about 25 s of
CPU in all). An HTML comment right before a block changes that (it does not show on the site):

- ``<!-- docs-test: skip REASON -->``: never run (it installs something, needs another machine, runs for
  minutes...); the reason is required;
- ``<!-- docs-test: slow -->``: run only with ``-m slow`` (a real fleet over Zenoh, or a long run); the blocks
  before it on its page run first, so a default block must not build on a slow one;
- ``<!-- docs-test: pending FEATURE -->``: a feature the documentation describes before it lands: expected to
  fail (strict), so that the block reports once it passes and the marker must go;
- ``<!-- docs-test: file NAME -->`` (any language): the block is written to ``NAME`` in the page's folder, for the
  blocks after it (a scenario file, a study);
- ``<!-- docs-test: exit N -->``: a ``bash`` block expected to end with exit code N (a run that ends without its
  target exits 3).

Other languages (``toml``, ``text``, ``json``...) are shown, not run, unless written to a file.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.harness.cli import ROOT
from tests.harness.docs import MARK, Block, blocks

PAGES = [*sorted((ROOT / "docs").rglob("*.md")), ROOT / "README.md"]
RUNNABLE = ("python", "bash")


def _params() -> list[Any]:
    params = []
    for page in PAGES:
        for b in blocks(page):
            if b.lang not in RUNNABLE and b.mark("file") is None:
                continue
            marks: list[Any] = []
            if b.mark("skip") is not None:
                marks.append(pytest.mark.skip(reason=b.mark("skip") or "no reason given"))
            if b.mark("slow") is not None:
                marks.append(pytest.mark.slow)
            if b.mark("pending") is not None:
                marks.append(pytest.mark.xfail(reason=f"pending: {b.mark('pending')}", strict=True))
            params.append(pytest.param(b, id=b.id, marks=marks))
    return params


class _Page:
    """What the blocks of one page share: a folder, a Python namespace, and the allocators, payload kinds and
    modules its examples registered or imported, which stay the page's: the rest of the suite (whose allocator
    tests list every registered allocator) and the other pages never see them."""

    def __init__(self, folder: Path) -> None:
        import fleet_emu.agents.allocators  # noqa: F401  (every built-in allocator and payload kind, registered first)
        from fleet_emu.agents.allocators import Allocator
        from fleet_emu.core.codec import Payload

        self.folder = folder
        (folder / "docs").symlink_to(ROOT / "docs")  # paths from a clone's root (docs/examples/...) hold
        self.namespace: dict[str, Any] = {"__name__": "__docs__"}
        self.allocators = dict(Allocator.registry)
        self.payloads = dict(Payload.REGISTRY)
        self.modules: dict[str, Any] = {}
        self.done: set[int] = set()  # the lines of the blocks that ran

    @contextlib.contextmanager
    def entered(self, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
        from fleet_emu.agents.allocators import Allocator
        from fleet_emu.core.codec import Payload

        suite = (Allocator.registry, Payload.REGISTRY)  # the suite's own, put back after the block
        monkeypatch.setattr(Allocator, "registry", self.allocators)
        monkeypatch.setattr(Payload, "REGISTRY", self.payloads)
        monkeypatch.setattr(sys, "path", list(sys.path))
        monkeypatch.chdir(self.folder)
        sys.modules.update(self.modules)
        try:
            yield
        finally:
            for name, mod in list(sys.modules.items()):
                if _in_docs(getattr(mod, "__file__", None)):
                    self.modules[name] = sys.modules.pop(name)
            for mine, theirs in zip((self.allocators, self.payloads), suite, strict=True):
                for kind, cls in mine.items():  # what the package registered on a first import stays registered
                    if kind not in theirs and cls.__module__ != self.namespace["__name__"] \
                            and cls.__module__ not in self.modules:
                        theirs[kind] = cls


def _in_docs(file: str | None) -> bool:
    """Whether a module's file is under ``docs/`` (followed through the page folder's link to it)."""
    return bool(file) and Path(file).resolve().is_relative_to((ROOT / "docs").resolve())


@pytest.fixture(scope="module")
def pages() -> dict[Path, _Page]:
    return {}


def _env(folder: Path) -> dict[str, str]:
    """This environment's ``fleet`` first on the PATH, and a cache of the page's own (``fleet maps fetch``)."""
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["COLUMNS"] = "120"
    env["XDG_CACHE_HOME"] = str(folder / ".cache")
    env.pop("FLEET_MAPS", None)
    return env


def _runs(b: Block) -> bool:
    """Whether a block runs in the default selection (a later block of its page may build on it)."""
    return (b.lang in RUNNABLE or b.mark("file") is not None) and not any(
        b.mark(m) is not None for m in ("skip", "slow", "pending"))


def _run(block: Block, page: _Page, monkeypatch: pytest.MonkeyPatch) -> None:
    page.done.add(block.line)
    name = block.mark("file")
    if name:
        (page.folder / name).parent.mkdir(parents=True, exist_ok=True)
        (page.folder / name).write_text(block.code)
        if block.lang not in RUNNABLE:
            return
    if block.lang == "python":
        monkeypatch.setenv("MPLBACKEND", "Agg")
        with page.entered(monkeypatch):
            exec(compile(block.code, block.id, "exec"), page.namespace)  # the page's own example
        return
    want = int(block.mark("exit") or 0)
    done = subprocess.run(["bash", "-euo", "pipefail", "-c", block.code], cwd=page.folder, env=_env(page.folder),
                          capture_output=True, text=True, timeout=170)
    assert done.returncode == want, (f"{block.id}: exit {done.returncode} (expected {want})\n--- stdout\n"
                                     f"{done.stdout[-3000:]}\n--- stderr\n{done.stderr[-3000:]}")


@pytest.mark.parametrize("block", _params())
def test_example(block: Block, pages: dict[Path, _Page], tmp_path_factory: pytest.TempPathFactory,
                 monkeypatch: pytest.MonkeyPatch) -> None:
    page = pages.get(block.page)
    if page is None:
        page = pages[block.page] = _Page(tmp_path_factory.mktemp(block.page.stem))
    for earlier in blocks(block.page):  # what a reader typed before, when a selection (-m slow, -k) left it out
        if earlier.line < block.line and earlier.line not in page.done and _runs(earlier):
            _run(earlier, page, monkeypatch)
    _run(block, page, monkeypatch)


def test_markers_are_known() -> None:
    """A misspelt marker would silently run (or not skip) a block: every ``docs-test`` comment is one of the five."""
    bad = [f"{p.relative_to(ROOT)}:{n}" for p in PAGES for n, line in enumerate(p.read_text().splitlines(), 1)
           if "docs-test" in line and not MARK.search(line)]
    assert not bad, f"unknown docs-test markers at {', '.join(bad)}"


def test_skips_say_why() -> None:
    """A skipped example names its reason."""
    bare = [b.id for p in PAGES for b in blocks(p) if b.mark("skip") == ""]
    assert not bare, f"docs-test: skip without a reason at {', '.join(bare)}"
