"""Declared settings: one declaration per field of a frozen config dataclass (its unit, range, flag and help)
that every way of setting it reads, so that a field declared once is a ``fleet run`` flag, a key of its
scenario table, a sweepable grid or ``[fleet]`` key, a :meth:`Scenario.override` keyword, and checked the same
way everywhere. :class:`~fleet_emu.core.radio.RadioConfig` declares its fields with :func:`setting`::

    waf: float = setting(3.1, unit="dB", low=0.0, high=1000.0, metavar="DB", help="attenuation per wall")

The kind of value (a whole number, a number, one of ``choices``) is the field's annotation (``int``, ``float``,
``str``), else its default's type.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, TypeVar

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.spelling import option

T = TypeVar("T")
_KEY = "fleet_emu.setting"
_KINDS: dict[str, type] = {"int": int, "float": float, "str": str}


@dataclasses.dataclass(frozen=True)
class Setting:
    """One field's declaration: ``default``, ``unit`` (shown in help and errors; "" for none), the accepted
    range ``low``..``high`` (``low_open``: ``low`` itself refused) or ``choices``, the flag's ``metavar`` and
    ``help``; ``name`` and ``kind`` (``int``, ``float`` or ``str``) are the field's, filled by :func:`settings`."""

    default: Any
    unit: str = ""
    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    choices: tuple[str, ...] = ()
    metavar: str | None = None
    help: str = ""
    name: str = ""
    kind: type = object

    @property
    def flag(self) -> str:
        """The ``fleet run`` flag: ``--max-walls`` for ``max_walls``."""
        return "--" + self.name.replace("_", "-")

    def span(self) -> str:
        """The accepted range (or choices), as help texts and errors say it: ``within [0, 1000] dB``."""
        if self.choices:
            return "one of " + ", ".join(self.choices)
        unit = f" {self.unit}" if self.unit else ""
        if self.kind is int:
            return f"from {_num(self.low)} to {_num(self.high)}{unit}"
        if math.isinf(self.high):
            return f"{'>' if self.low_open else '>='} {_num(self.low)}{unit}"
        return f"within {'(' if self.low_open else '['}{_num(self.low)}, {_num(self.high)}]{unit}"

    def check(self, value: Any) -> None:
        """A ConfigError of one line when ``value`` is not what the field accepts, naming the flag from the CLI
        and the keyword from Python (:func:`fleet_emu.core.spelling.option`)."""
        name = option(self.name)
        if self.choices:
            if value not in self.choices:
                raise ConfigError(f"{name} must be {self.span()} (got {value!r})")
            return
        whole = self.kind is int
        if whole:
            typed = isinstance(value, int) and not isinstance(value, bool)
        else:
            typed = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        if not typed:
            what = "a whole number" if whole else "a finite number"
            raise ConfigError(f"{name} must be {what} {self.span()} (got {value!r})")
        if not (self.low < value if self.low_open else self.low <= value) or value > self.high:
            raise ConfigError(f"{name} must be {self.span()} (got {value!r})")


def _num(x: float) -> str:
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else f"{x:g}"


def setting(default: T, *, unit: str = "", low: float = -math.inf, high: float = math.inf, low_open: bool = False,
            choices: tuple[str, ...] = (), metavar: str | None = None, help: str = "") -> T:
    """A dataclass field with its :class:`Setting` (the field's default is ``default``)."""
    spec = Setting(default, unit, low, high, low_open, choices, metavar, help)
    return dataclasses.field(default=default, metadata={_KEY: spec})


def settings(cls: type) -> tuple[Setting, ...]:
    """Every declared field of the dataclass ``cls``, in order, each with its name; a field without a
    declaration is a programming error (every field of such a config must be settable)."""
    out = []
    for f in dataclasses.fields(cls):
        spec = f.metadata.get(_KEY)
        if spec is None:
            raise TypeError(f"{cls.__name__}.{f.name} has no setting(...) declaration")
        kind = _KINDS.get(f.type if isinstance(f.type, str) else getattr(f.type, "__name__", ""), type(spec.default))
        out.append(dataclasses.replace(spec, name=f.name, kind=kind))
    return tuple(out)


def check_all(config: Any) -> None:
    """Check every declared field of the dataclass instance ``config``; ConfigError on the first bad one."""
    for spec in settings(type(config)):
        spec.check(getattr(config, spec.name))


def merge(config: T, table: Any, section: str, where: str = "") -> T:
    """``config`` with the values of ``table`` (a mapping of field names, or an instance: replaces it) on top;
    a ConfigError (``where``: what the table came from, ``section``: its name) for a table that is not one or an
    unknown name. The values are checked later, with the whole config (:func:`check_all`)."""
    if isinstance(table, type(config)):
        return table
    prefix = f"{where}: " if where else ""
    if not isinstance(table, dict):
        raise ConfigError(f"{prefix}{section} must be a table of settings (got {table!r})")
    names = [s.name for s in settings(type(config))]
    bad = sorted(map(str, set(table) - set(names)))
    if bad:
        raise ConfigError(f"{prefix}unknown key(s) in {section}: {', '.join(bad)} (known: {', '.join(names)})")
    return dataclasses.replace(config, **table)  # type: ignore[type-var]
