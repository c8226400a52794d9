"""Checks of a scenario's names that only the layers above core can make: that its allocator exists and takes
the parameters given (``agents``), that its map exists (``world``). :meth:`Scenario.override` runs them on the
fields it was given, so that ``override(allocator="nope")`` or ``override(map="nomap")`` fail where they are
written, not when the run starts.

Core imports nothing above it, so the checks are found as the entry points of the group :data:`GROUP`
(``pyproject.toml``; an editable install lists them once ``pip install -e .`` ran), each named after the field
it checks and loaded on first use. A check takes the scenario and raises :class:`ConfigError`; anything else
it raises becomes one.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from fleet_emu.core.errors import ConfigError, FleetError

GROUP = "fleet_emu.scenario_checks"

_checks: dict[str, Callable[[Any], None]] = {}
_entries: dict[str, EntryPoint] | None = None


def check_names(scenario: Any, fields: Iterable[str]) -> None:
    """Run the check of each of ``fields`` (those with one) on ``scenario``; a ConfigError on the first bad one."""
    for field in fields:
        check = _check(field)
        if check is None:
            continue
        try:
            check(scenario)
        except FleetError:
            raise
        except Exception as exc:  # a check's own failure is still the user's value it could not accept
            raise ConfigError(f"{field} {getattr(scenario, field, None)!r}: {type(exc).__name__}: {exc}") from None


def _check(field: str) -> Callable[[Any], None] | None:
    """The check of ``field``, loaded once; None when there is none."""
    global _entries
    if field not in _checks:
        if _entries is None:
            _entries = {ep.name: ep for ep in entry_points(group=GROUP)}
        ep = _entries.get(field)
        if ep is None:
            return None
        try:
            _checks[field] = ep.load()
        except Exception as exc:  # an installation problem, said in one line
            raise ConfigError(f"the {field} check {ep.value} does not load: {type(exc).__name__}: {exc}") from None
    return _checks[field]
