"""The install lines the documentation shows: a user's (the product and the extras a user picks) is one line,
the same on every page; a contributor's (``dev``) and the test command are the README's, and CI runs exactly
them; every extra a line names exists, and ``dev`` holds the developer tools so that the user's does not."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
USER = "python3 -m pip install -e '.[sweep,rl,ros2]'"
DEV = "python3 -m pip install -e '.[dev]'"
TEST = "python3 -m pytest"
LINE = re.compile(r"pip install -e '\.\[([\w,-]+)\]'")
PAGES = [ROOT / "README.md", ROOT / "benchmarks" / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def _extras() -> dict[str, list[str]]:
    with open(ROOT / "pyproject.toml", "rb") as f:
        return tomllib.load(f)["project"]["optional-dependencies"]


def test_ci_runs_exactly_the_readme_s_install_and_test_lines() -> None:
    readme = ROOT / "README.md"
    script = (ROOT / ".ci" / "run").read_text().splitlines()
    commands = [ln for ln in script if ln and not ln.startswith(("#", "set ", "cd "))]
    assert commands[:2] == [DEV, TEST]
    blocks = re.findall(r"```bash\n(.*?)```", readme.read_text(), re.S)
    assert [USER] in [b.splitlines() for b in blocks] and [DEV] in [b.splitlines() for b in blocks]
    assert [TEST] in [b.splitlines() for b in blocks]


def test_every_page_shows_the_same_user_line_or_the_dev_line() -> None:
    seen = {}
    for page in PAGES:
        for m in LINE.finditer(page.read_text()):
            seen.setdefault(m.group(0), []).append(page.relative_to(ROOT).as_posix())
    assert set(seen) <= {USER.removeprefix("python3 -m "), DEV.removeprefix("python3 -m ")}, seen
    assert {"README.md", "docs/getting-started.md", "docs/guides/ros2.md", "docs/guides/learning.md"} <= \
        set(seen[USER.removeprefix("python3 -m ")])


def test_the_user_s_extras_hold_no_developer_tool_and_dev_holds_them_all() -> None:
    extras = _extras()
    named = {e for line in (USER, DEV) for e in LINE.search(line).group(1).split(",")}  # type: ignore[union-attr]
    assert named <= set(extras)
    tools = ("pytest", "ruff", "mypy", "mkdocs", "import-linter")
    user = [req for e in ("sweep", "rl", "ros2") for req in extras[e]]
    assert not [req for req in user if req.startswith(tools)], user
    assert all(any(req.startswith(t) for req in extras["dev"]) for t in tools)
    assert "fleet-emu[sweep,rl,ros2]" in extras["dev"]  # a contributor's install runs every test


def test_the_learning_guide_is_linked_from_the_readme_and_the_index() -> None:
    assert "(docs/guides/learning.md)" in (ROOT / "README.md").read_text()
    assert "(guides/learning.md)" in (ROOT / "docs" / "index.md").read_text()
