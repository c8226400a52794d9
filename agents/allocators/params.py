"""An allocator's parameters, declared once: type (from the default), default and accepted range.

``Param(0.4, ge=0)`` is a finite number >= 0 defaulting to 0.4; ``Param(2, ge=1)`` an integer >= 1;
``Param(False)`` true or false; ``Param("full", choices=("full", "stop"))`` one of the names. A bool is not an
integer and a string is not a number; an integer is accepted where a number is (and becomes a float). Every
rejection is a :class:`ConfigError` of one line naming the allocator, the parameter and the accepted range.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from typing import Any

from fleet_emu.core.errors import ConfigError

_KINDS = {bool: "true or false", int: "an integer", float: "a number", str: "a string"}


@dataclasses.dataclass(frozen=True)
class Param:
    """One parameter: ``default`` fixes its type (bool, int, float or str); bounds are inclusive (``ge``,
    ``le``) or strict (``gt``); ``choices`` lists the accepted strings."""

    default: bool | int | float | str
    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    choices: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if type(self.default) not in _KINDS:
            raise TypeError(f"a parameter's default must be a bool, int, float or str, not {self.default!r}")

    @property
    def kind(self) -> type:
        return type(self.default)

    def accepted(self) -> str:
        """The accepted values in words: ``a number in [0, 1]``, ``an integer >= 1``, ``one of 'a', 'b'``."""
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        text = _KINDS[self.kind]
        low = f"[{self.ge:g}" if self.ge is not None else f"({self.gt:g}" if self.gt is not None else None
        if low is not None and self.le is not None:
            return f"{text} in {low}, {self.le:g}]"
        if self.ge is not None:
            return f"{text} >= {self.ge:g}"
        if self.gt is not None:
            return f"{text} > {self.gt:g}"
        return f"{text} <= {self.le:g}" if self.le is not None else text

    def check(self, value: Any) -> bool | int | float | str:
        """``value`` as this parameter's type, or ValueError when it is not accepted."""
        kind = self.kind
        if kind is bool or kind is str:
            ok = isinstance(value, kind)
        else:
            number = numbers.Integral if kind is int else numbers.Real
            ok = isinstance(value, number) and not isinstance(value, bool)
            if ok:
                value = kind(value)
                ok = math.isfinite(value) and ((self.ge is None or value >= self.ge)
                                               and (self.gt is None or value > self.gt)
                                               and (self.le is None or value <= self.le))
        if ok and self.choices:
            ok = value in self.choices
        if not ok:
            raise ValueError(self.accepted())
        return value


def check_params(allocator: str, spec: Mapping[str, Param], given: Mapping[str, Any]) -> dict[str, Any]:
    """Every parameter of ``spec``, from ``given`` or its default, checked; ConfigError on an unknown name or
    a value out of its range."""
    unknown = sorted(set(given) - set(spec))
    if unknown:
        takes = f"its parameters: {', '.join(spec)}" if spec else "it takes none"
        raise ConfigError(f"allocator {allocator!r} has no parameter {unknown[0]!r} ({takes})")
    out: dict[str, Any] = {}
    for name, param in spec.items():
        value = given.get(name, param.default)
        try:
            out[name] = param.check(value)
        except ValueError as exc:
            raise ConfigError(f"allocator {allocator!r}: {name} must be {exc} (got {value!r})") from None
    return out
