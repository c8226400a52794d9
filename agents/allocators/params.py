"""An allocator's parameters, declared once as settings (:class:`fleet_emu.core.fields.Setting`, as the scenario's
and the radio's fields are): type (from the default), default and accepted range, from which the check, the
one-line error, ``fleet allocators``' listing and the docs' ranges all follow.

``Param(0.4, ge=0)`` is a finite number >= 0 defaulting to 0.4; ``Param(2, ge=1)`` a whole number >= 1;
``Param(False)`` true or false; ``Param("full", choices=("full", "stop"))`` one of the names. A bool is not an
integer and a string is not a number; an integer is accepted where a number is (and becomes a float). Every
rejection is a :class:`ConfigError` of one line naming the allocator, the parameter and the accepted range.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.fields import Setting

_KINDS = (bool, int, float, str)


class Param(Setting):
    """One parameter: ``default`` fixes its type (bool, int, float or str); bounds are inclusive (``ge``,
    ``le``) or strict (``gt``); ``choices`` lists the accepted strings; ``help`` says what it is."""

    def __init__(self, default: bool | int | float | str, ge: float | None = None, gt: float | None = None,
                 le: float | None = None, choices: tuple[str, ...] = (), help: str = "") -> None:
        if type(default) not in _KINDS:
            raise TypeError(f"a parameter's default must be a bool, int, float or str, not {default!r}")
        low = ge if ge is not None else gt if gt is not None else -math.inf
        super().__init__(default, low=low, high=le if le is not None else math.inf, low_open=gt is not None,
                         choices=choices, help=help, kind=type(default))

    def accepted(self) -> str:
        """The accepted values in words: ``within [0, 1]``, ``>= 1``, ``one of a, b``."""
        return self.span()


def check_params(allocator: str, spec: Mapping[str, Setting], given: Mapping[str, Any]) -> dict[str, Any]:
    """Every parameter of ``spec``, from ``given`` or its default, checked; ConfigError on an unknown name or
    a value out of its range."""
    unknown = sorted(set(given) - set(spec))
    if unknown:
        takes = f"its parameters: {', '.join(spec)}" if spec else "it takes none"
        raise ConfigError(f"allocator {allocator!r} has no parameter {unknown[0]!r} ({takes})")
    out: dict[str, Any] = {}
    for name, param in spec.items():
        value = given.get(name, param.default)
        refused = param.refusal(value)
        if refused is not None:
            raise ConfigError(f"allocator {allocator!r}: {name} {refused}")
        out[name] = float(value) if param.kind is float else value
    return out
