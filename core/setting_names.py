"""How an error names a setting: the flag (``--max-ticks``) when the user typed a ``fleet`` command, the Python
keyword (``max_ticks``) when they called the library, the key (``[fleet] robots``) when the value came from a
scenario or study file. One setting has all three names; which one the user knows depends on where the value
came from, so the CLI says so once (:func:`cli_spelling`, around a command), a file's reader says so around its
checks (:func:`file_spelling`), and every message asks :func:`option` instead of writing any name in its text.

:func:`near` adds "did you mean" to an error naming an unknown name (an allocator, a map, a study, a flag)."""

from __future__ import annotations

import contextlib
import difflib
from collections.abc import Iterable, Iterator, Mapping
from contextvars import ContextVar

_CLI: ContextVar[bool] = ContextVar("fleet_emu.cli_spelling", default=False)
#: Within :func:`file_spelling`: each setting's key as the file writes it (``robots``: ``[fleet] robots``).
_FILE: ContextVar[Mapping[str, str] | None] = ContextVar("fleet_emu.file_spelling", default=None)


def option(name: str, value: str = "", flag: str = "") -> str:
    """The setting ``name`` (a field or keyword name, ``max_ticks``) as the user wrote it: ``--max-ticks`` from
    the CLI (``flag`` when the flag is not the name's: ``--realtime`` for ``realtime_hz``); ``max_ticks`` from
    Python, or ``max_ticks=VALUE`` when ``value`` is given (``overwrite=True`` for a switch, whose flag takes no
    value); its key (``[fleet] robots``) within :func:`file_spelling`, whatever the caller."""
    keys = _FILE.get()
    if keys is not None:
        return keys.get(name, name)
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


@contextlib.contextmanager
def file_spelling(keys: Mapping[str, str]) -> Iterator[None]:
    """Within it, :func:`option` names each setting by its key in the file being read (``keys``: a setting's
    name to its key, ``robots`` to ``[fleet] robots``; a name not in it is its own key); the reader puts the
    file's name in front of the message (``scenario s.toml: [fleet] robots must be ...``)."""
    token = _FILE.set(keys)
    try:
        yield
    finally:
        _FILE.reset(token)


def near(name: object, known: Iterable[str]) -> str:
    """``; did you mean 'minpos'?`` when ``name`` is close to one of ``known`` (difflib's ratio, 0.6 and up), else
    "": it follows the name in an "unknown X" message (``unknown allocator 'minpoz'; did you mean 'minpos'?
    (known: ...)``)."""
    if not isinstance(name, str) or not name:
        return ""
    close = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def plural(count: int, noun: str, nouns: str = "") -> str:
    """``1 job``, ``2 jobs``, ``0 jobs``: ``count`` and the noun in its number (``nouns``: an irregular plural,
    else ``noun + "s"``)."""
    return f"{count} {noun if count == 1 else nouns or noun + 's'}"
