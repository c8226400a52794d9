"""Bounds on what a user's file may hold, checked before it is parsed or copied anywhere: its size, how deeply
its brackets nest and how long its strings are.

A scenario is a few levels deep and a few hundred bytes long; a file far past that is a mistake or an attack, and
Python's own parsers (``tomllib``, ``json``) recurse once per level, so a few thousand nested brackets would end in
a ``RecursionError`` deep inside them. :func:`check_text` finds such a file with one linear scan of its brackets
(outside strings and comments) and refuses it with one line, before any parser runs.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

from fleet_emu.core.errors import ConfigError

#: The most hops a relayed message may still take (an envelope's ``ttl``), and the largest payload an envelope
#: carries: bus limits, kept here so that the scenario can name them without loading the codec.
MAX_TTL = 16
MAX_PAYLOAD_BYTES = 16 * 1024 * 1024

#: The largest scenario (or study) file read: a shipped scenario is under 2 KB.
MAX_FILE_BYTES = 1 << 20
#: The deepest nesting of brackets (``[``, ``{``) a file may have; a scenario uses 3.
MAX_NESTING = 32
#: The longest string a scenario may hold (a map path is at most PATH_MAX, 4096 bytes on Linux).
MAX_TEXT = 4096
#: The longest run name (it is copied into ``scenario.json``, ``result.json`` and the recording).
MAX_NAME = 200

#: Strings (TOML's four kinds; JSON's is the basic one), comments, and the brackets between them.
_TOKENS = re.compile(r'"""[\s\S]*?"""|\'\'\'[\s\S]*?\'\'\'|"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'|#[^\n]*|[\[\]{}]')


def nesting(text: str) -> int:
    """The deepest nesting of ``[``/``{`` in ``text``, outside strings and comments (a linear scan, no
    recursion). A malformed file may be misjudged; its parser then refuses it."""
    depth = deepest = 0
    for m in _TOKENS.finditer(text):
        c = m.group()
        if c in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif c in "]}":
            depth = max(0, depth - 1)
    return deepest


def check_size(size: int, where: str) -> None:
    """A ConfigError when a file of ``size`` bytes is larger than :data:`MAX_FILE_BYTES`."""
    if size > MAX_FILE_BYTES:
        raise ConfigError(f"{where} is {size} bytes, more than the {MAX_FILE_BYTES} a scenario may have")


def check_text(text: str, where: str) -> None:
    """A ConfigError when ``text`` is larger than :data:`MAX_FILE_BYTES` or nests deeper than
    :data:`MAX_NESTING`."""
    check_size(len(text), where)
    depth = nesting(text)
    if depth > MAX_NESTING:
        raise ConfigError(f"{where} nests {depth} levels of brackets deep, more than the {MAX_NESTING} allowed")


def _walk(value: Any, depth: int = 0) -> Iterator[tuple[Any, int]]:
    """Every value inside ``value`` (dicts' keys and values, lists' items) with its depth, without recursion."""
    todo = [(value, depth)]
    while todo:
        v, d = todo.pop()
        yield v, d
        if isinstance(v, dict):
            todo.extend((x, d + 1) for kv in v.items() for x in kv)
        elif isinstance(v, list | tuple):
            todo.extend((x, d + 1) for x in v)


def check_values(value: Any, where: str) -> None:
    """A ConfigError when ``value`` (a scenario's table) nests deeper than :data:`MAX_NESTING` or holds a string
    longer than :data:`MAX_TEXT`."""
    for v, depth in _walk(value):
        if depth > MAX_NESTING:
            raise ConfigError(f"{where} nests deeper than the {MAX_NESTING} levels allowed")
        if isinstance(v, str) and len(v) > MAX_TEXT:
            raise ConfigError(f"{where} holds a string of {len(v)} characters, more than the {MAX_TEXT} allowed "
                              f"(it begins {v[:20]!r})")
