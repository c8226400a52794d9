"""MkDocs hooks of the documentation site (mkdocs.yml ``hooks``).

- ``<!-- cli-help: run -->`` in a page becomes the help text of ``fleet run`` (``<!-- cli-help: -->``: of
  ``fleet``), from the parser itself, so that the CLI reference cannot drift from the code.
- ``<!-- api -->`` becomes a section per name of ``fleet_emu.__all__``, grouped as its source groups them
  (a comment line per group), each rendered by mkdocstrings from where the name is defined.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
CLI_HELP = re.compile(r"<!--\s*cli-help:\s*(?P<cmd>[\w-]*)\s*-->")
API = re.compile(r"<!--\s*api\s*-->")


def cli_help(command: str) -> str:
    """The ``--help`` text of ``fleet COMMAND`` (of ``fleet`` for an empty one), 100 columns wide."""
    from fleet_emu.cli import build_parser

    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"
    try:
        parser = build_parser()
        if command:
            sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
            parser = sub.choices[command]
        with contextlib.redirect_stdout(io.StringIO()):
            text = parser.format_help()
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return text


def api_groups(root: Path = ROOT) -> list[tuple[str, list[str]]]:
    """``fleet_emu.__all__`` as its source lists it: (group comment, names) in order."""
    text = (root / "fleet_emu" / "__init__.py").read_text()
    body = text[text.index("__all__ = [") + len("__all__ = ["):]
    body = body[:body.index("]")]
    groups: list[tuple[str, list[str]]] = [("", [])]
    for line in body.splitlines():
        line = line.strip()
        if line.startswith("#"):
            groups.append((line.lstrip("# ").strip(), []))
        else:
            groups[-1][1].extend(re.findall(r'"([^"]+)"', line))
    return [(title, names) for title, names in groups if names]


def api_page() -> str:
    """A section per public name, rendered from the module that defines it."""
    import fleet_emu

    out = []
    for title, names in api_groups():
        out.append(f"## {(title or 'package').capitalize()}\n")
        for name in names:
            module = fleet_emu._LAZY.get(name, "fleet_emu")
            if name.startswith("__"):
                out.append(f"### `fleet_emu.{name}`\n\nThe package's version, `{fleet_emu.__version__}`.\n")
                continue
            out.append(f"::: {module}.{name}\n    options:\n      heading_level: 3\n")
    return "\n".join(out)


def on_page_markdown(markdown: str, **_: Any) -> str:
    markdown = CLI_HELP.sub(lambda m: f"```text\n{cli_help(m['cmd']).rstrip()}\n```", markdown)
    return API.sub(lambda m: api_page(), markdown)
