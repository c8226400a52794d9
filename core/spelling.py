"""How an error names a setting: the flag (``--max-ticks``) when the user typed a ``fleet`` command, the Python
keyword (``max_ticks``) when they called the library. One setting has both names; which one the user knows
depends on where the call came from, so the CLI says so once (:func:`cli_spelling`, around a command) and every
message asks :func:`option` instead of writing either name in its text."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from contextvars import ContextVar

_CLI: ContextVar[bool] = ContextVar("fleet_emu.cli_spelling", default=False)


def option(name: str, value: str = "", flag: str = "") -> str:
    """The setting ``name`` (a field or keyword name, ``max_ticks``) as the user wrote it: ``--max-ticks`` from
    the CLI (``flag`` when the flag is not the name's: ``--realtime`` for ``realtime_hz``); ``max_ticks`` from
    Python, or ``max_ticks=VALUE`` when ``value`` is given (``overwrite=True`` for a switch, whose flag takes no
    value)."""
    if _CLI.get():
        return flag or "--" + name.replace("_", "-")
    return f"{name}={value}" if value else name


@contextlib.contextmanager
def cli_spelling() -> Iterator[None]:
    """Within it, :func:`option` names flags: the ``fleet`` command's dispatcher runs each command inside."""
    token = _CLI.set(True)
    try:
        yield
    finally:
        _CLI.reset(token)
