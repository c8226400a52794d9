"""Declared settings: one declaration per field of a frozen config dataclass (its unit, range, flag and help)
that every way of setting it reads, so that a field declared once is a ``fleet run`` flag, a key of its
scenario table, a sweepable grid or ``[fleet]`` key, a :meth:`Scenario.override` keyword, and checked the same
way everywhere. :class:`~fleet_emu.core.radio.RadioConfig` and :class:`~fleet_emu.core.scenario.Scenario` declare
their fields with :func:`setting`, and an allocator's parameters are settings too (``agents/allocators/params``)::

    waf: float = setting(3.1, unit="dB", low=0.0, high=1000.0, metavar="DB", help="attenuation per wall")

The kind of value (a whole number, a number, true or false, a string, one of ``choices``) is the field's
annotation (``int``, ``float``, ``bool``, ``str``), else ``kind`` given (an optional number, ``int | None``), else
its default's type. A value of another shape (a cell)
says so with ``shape`` (a test) and ``accepts`` (its words); a field that holds a table of its own (the radio,
the allocator, the hosts) is declared with ``table=True``: its key and help are declared here, its own code
checks it, and its flags are written by hand.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Callable
from typing import Any, TypeVar

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.setting_names import option

T = TypeVar("T")
_KEY = "fleet_emu.setting"
_KINDS: dict[str, type] = {"int": int, "float": float, "str": str, "bool": bool}


@dataclasses.dataclass(frozen=True)
class Setting:
    """One field's declaration: ``default``, ``unit`` (shown in help and errors; "" for none), the accepted
    range ``low``..``high`` (``low_open``: ``low`` itself refused; a string's length) or ``choices``, the flag's
    ``metavar`` and ``help``; ``optional``: None is accepted too (``unset`` says what it means, "the map's own");
    ``shape`` and ``accepts``: a test of a value of another shape and its words, ``parse`` its flag's reader;
    ``section`` and ``key``: where a scenario file writes it (``[map] name``; top level and the field's name by
    default); ``table``: a table checked by its own code, with flags of its own; ``cli``: a flag is made from
    it; ``quiet``: left out of ``scenario.json`` at its default (a field added later: older runs keep theirs).
    ``name`` and ``kind`` (``int``, ``float``, ``bool`` or ``str``) are the field's, filled by
    :func:`settings`."""

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
    optional: bool = False
    unset: str = ""
    shape: Callable[[Any], bool] | None = None
    accepts: str = ""
    parse: Callable[[str], Any] | None = None
    section: str = ""
    key: str = ""
    table: bool = False
    cli: bool = True
    quiet: bool = False

    @property
    def flag(self) -> str:
        """The ``fleet run`` flag: ``--max-walls`` for ``max_walls``."""
        return "--" + self.name.replace("_", "-")

    @property
    def file_key(self) -> str:
        """Its key in a scenario file, as an error names it: ``[fleet] robots``, ``[map] name``, ``seed``."""
        if self.table and not self.key:
            return f"[{self.section}]" if self.section else self.name
        key = self.key or self.name
        return f"[{self.section}] {key}" if self.section else key

    @property
    def checked(self) -> bool:
        """Whether :meth:`check` checks it (a table is checked by its own code)."""
        return not self.table and (self.shape is not None or self.kind in (int, float, bool, str))

    def span(self) -> str:
        """The accepted range (or choices), as help texts and errors say it: ``within [0, 1000] dB``."""
        if self.shape is not None or self.table:
            return self.accepts or "a table"
        if self.choices:
            return "one of " + ", ".join(self.choices)
        if self.kind is bool:
            return "true or false"
        if self.kind is str:
            most = f" of at most {_num(self.high)} characters" if math.isfinite(self.high) else ""
            return ("a non-empty string" if self.low >= 1 else "a string") + most
        unit = f" {self.unit}" if self.unit else ""
        if math.isinf(self.high):
            return f"{'>' if self.low_open else '>='} {_num(self.low)}{unit}"
        if self.kind is int:
            return f"from {_num(self.low)} to {_num(self.high)}{unit}"
        return f"within {'(' if self.low_open else '['}{_num(self.low)}, {_num(self.high)}]{unit}"

    def refusal(self, value: Any) -> str | None:
        """What follows the name in the one-line error when ``value`` is not accepted (``must be from 1 to 256
        (got 0)``), else None; a table is not checked here."""
        if (value is None and self.optional) or not self.checked:
            return None
        if self.shape is not None:
            return None if self.shape(value) else f"must be {self.accepts} (got {value!r})"
        if self.choices:
            return None if value in self.choices else f"must be {self.span()} (got {value!r})"
        if self.kind is bool:
            return None if isinstance(value, bool) else f"must be {self.span()} (got {value!r})"
        if self.kind is str:
            if not isinstance(value, str) or len(value) < self.low:
                return f"must be {self.span()} (got {value!r})"
            if len(value) > self.high:
                return f"is {len(value)} characters long, more than the {_num(self.high)} allowed"
            return None
        whole = self.kind is int
        if whole:
            typed = isinstance(value, int) and not isinstance(value, bool)
        else:
            typed = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
        if not typed:
            return f"must be {'a whole number' if whole else 'a finite number'} {self.span()} (got {value!r})"
        if not (self.low < value if self.low_open else self.low <= value) or value > self.high:
            return f"must be {self.span()} (got {value!r})"
        return None

    def check(self, value: Any) -> Any:
        """``value`` (an integer as a float where a number is declared), or a ConfigError of one line when it is
        not what the field accepts, naming the flag from the CLI, the keyword from Python and the key from a file
        (:func:`fleet_emu.core.setting_names.option`)."""
        refused = self.refusal(value)
        if refused is not None:
            flag = f"{self.flag} / --no-{self.flag[2:]}" if self.kind is bool else ""
            raise ConfigError(f"{option(self.name, flag=flag)} {refused}")
        return float(value) if self.kind is float and isinstance(value, int) and value is not None else value

    def shown(self) -> str:
        """The default as the help shows it: ``0.99``, ``on``, or what None means (``unset``)."""
        if self.default is None:
            return self.unset or "none"
        if isinstance(self.default, bool):
            return "on" if self.default else "off"
        return str(self.default)


def _num(x: float) -> str:
    if isinstance(x, int):
        return str(x)
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else f"{x:g}"


def setting(default: Any = None, *, factory: Callable[[], Any] | None = None, **declared: Any) -> Any:
    """A dataclass field with its :class:`Setting` (the field's default is ``default``, or ``factory()`` for a
    table); ``declared`` are :class:`Setting`'s other attributes (``unit``, ``low``, ``help``...)."""
    spec = Setting(default, **declared)
    if factory is not None:
        return dataclasses.field(default_factory=factory, metadata={_KEY: spec})
    return dataclasses.field(default=default, metadata={_KEY: spec})


def settings(cls: type) -> tuple[Setting, ...]:
    """Every declared field of the dataclass ``cls``, in order, each with its name; a field without a
    declaration is a programming error (every field of such a config must be settable). Read once per class."""
    if cls not in _SETTINGS:
        _SETTINGS[cls] = _declared(cls)
    return _SETTINGS[cls]


_SETTINGS: dict[type, tuple[Setting, ...]] = {}


def _declared(cls: type) -> tuple[Setting, ...]:
    out = []
    for f in dataclasses.fields(cls):
        spec = f.metadata.get(_KEY)
        if spec is None:
            raise TypeError(f"{cls.__name__}.{f.name} has no setting(...) declaration")
        kind = spec.kind if spec.kind is not object else _KINDS.get(
            f.type if isinstance(f.type, str) else getattr(f.type, "__name__", ""), type(spec.default))
        out.append(dataclasses.replace(spec, name=f.name, kind=kind))
    return tuple(out)


def json_schema(spec: Setting) -> dict[str, Any] | None:
    """The JSON Schema of a setting's values, from its declaration (its kind, range or choices); None for a
    table or a value of another shape, which its own code checks."""
    if spec.table or spec.shape is not None or spec.kind not in _KINDS.values():
        return None
    out: dict[str, Any]
    if spec.choices:
        out = {"enum": list(spec.choices)}
    elif spec.kind is bool:
        out = {"type": "boolean"}
    else:
        string = spec.kind is str
        out = {"type": "string" if string else "integer" if spec.kind is int else "number"}
        low, high = ("minLength", "maxLength") if string else ("exclusiveMinimum" if spec.low_open else "minimum",
                                                              "maximum")
        out |= {low: spec.low} if math.isfinite(spec.low) else {}
        out |= {high: spec.high} if math.isfinite(spec.high) else {}
        out = {k: int(v) if isinstance(v, float) and v.is_integer() and (string or spec.kind is int) else v
               for k, v in out.items()}
    return {"anyOf": [out, {"type": "null"}]} if spec.optional else out


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


def cell_arg(text: str) -> tuple[int, int]:
    """An argparse type: ``ROW,COL`` as a cell (here, not in the node shell, so that building a parser loads
    neither Zenoh nor numpy)."""
    try:
        row, col = (int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected ROW,COL, got {text!r}") from None
    if row < 0 or col < 0:
        raise argparse.ArgumentTypeError(f"expected ROW,COL, each a whole number >= 0, got {text!r}")
    return (row, col)
