"""``fleet run``'s flags made from declared settings (:mod:`fleet_emu.core.fields`): one flag per field of the
scenario and of its radio, its type, choices, metavar, range and default all read from the declaration, so that
a field declared once is a flag with nothing else to write. Each flag defaults to None (not given: the scenario's
value)."""

from __future__ import annotations

import argparse
from collections.abc import Iterable
from typing import Any

from fleet_emu.core.fields import Setting

#: What a scenario's flag not given leaves: the scenario's own value.
SCENARIO_S = ", or the scenario's"


def setting_help(s: Setting, fallback: str = SCENARIO_S) -> str:
    """A flag's help from its declaration: what it is, the range it accepts (a switch's is plain) and its
    default, ``robots in the fleet; from 1 to 256 (default: 4, or the scenario's)`` (``fallback``: what follows
    the default)."""
    span = "" if s.kind is bool and s.shape is None else f"; {s.span()}"
    return f"{s.help}{span} (default: {s.shown()}{fallback})".replace("%", "%%")


def add_setting_flags(group: Any, specs: Iterable[Setting], fallback: str = SCENARIO_S) -> None:
    """A flag on ``group`` (a parser or an argument group) for each of ``specs`` that makes one (``cli``, not a
    table): ``--x/--no-x`` for a switch, the choices for a choice, else the value's reader and metavar; its help
    from :func:`setting_help`."""
    for s in specs:
        if not s.cli or s.table:
            continue
        extra: dict[str, Any]
        if s.kind is bool and s.shape is None:
            extra = {"action": argparse.BooleanOptionalAction}
        elif s.choices:
            extra = {"choices": s.choices}
        else:
            extra = {"type": s.parse or s.kind, "metavar": s.metavar}
        group.add_argument(s.flag, dest=s.name, default=None, help=setting_help(s, fallback), **extra)


def given(args: argparse.Namespace, specs: Iterable[Setting]) -> dict[str, Any]:
    """The flags made from ``specs`` (:func:`add_setting_flags`) given on the command line, by field name (for
    :meth:`Scenario.override`)."""
    return {s.name: getattr(args, s.name) for s in specs
            if s.cli and not s.table and getattr(args, s.name, None) is not None}
