"""Robot failures as scenario events: a scenario's ``[[faults]]`` entries, each a robot, a tick and a kind, so
that a fault study is reproducible and needs no ``kill -9`` by hand (docs/guides/faults.md).

```toml
[[faults]]
robot = "r1"      # or its number, 1
tick = 30         # the first tick the robot misses: its last command is of tick 29
kind = "crash"    # the only kind: the robot stops for good, its body stays where it stood
```

The world applies a crash at its tick (``world/sim.py``: the robot leaves the run before the tick's readings,
as a robot whose process died does), in every engine alike, so that a seed gives one result; the processes
engine also kills the robot's process then (``launch/runner.py``). Pure: parsing and checks only.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Iterable
from typing import Any

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.setting_names import option

#: The kinds of fault a scenario may declare.
KINDS = ("crash",)
#: The keys of one ``[[faults]]`` entry.
KEYS = ("robot", "tick", "kind")
MAX_FAULTS = 256
_ROBOT = re.compile(r"r(0|[1-9][0-9]{0,2})")


@dataclasses.dataclass(frozen=True)
class Fault:
    """One scheduled failure: ``robot`` (its id, ``r1``) stops at ``tick`` (its last command is of the tick
    before) for good; ``kind`` is ``crash``."""

    robot: str
    tick: int
    kind: str = "crash"

    def to_dict(self) -> dict[str, Any]:
        """The ``[[faults]]`` entry, as ``scenario.json`` and ``result.json`` write it."""
        return {"robot": self.robot, "tick": self.tick, "kind": self.kind}


def parse_faults(value: Any) -> tuple[Fault, ...]:
    """A scenario's ``faults``: a list of tables (``robot``, ``tick``, ``kind``) or of :class:`Fault`; the
    robot by id (``"r1"``) or number (``1``). A ConfigError of one line naming the entry and the key; the
    ranges (the fleet's robots, the tick limit) are :func:`check_faults`'s."""
    name = option("faults", flag="--crash")
    if isinstance(value, Fault):
        value = [value]
    if not isinstance(value, list | tuple):
        raise ConfigError(f"{name} must be a list of tables with robot, tick and kind (got {value!r})")
    if len(value) > MAX_FAULTS:
        raise ConfigError(f"{name} holds {len(value)} entries, more than the {MAX_FAULTS} allowed")
    return tuple(_entry(v, f"{name}[{i}]") for i, v in enumerate(value))


def _entry(value: Any, where: str) -> Fault:
    if isinstance(value, Fault):
        value = value.to_dict()
    if not isinstance(value, dict):
        raise ConfigError(f"{where} must be a table with robot, tick and kind (got {value!r})")
    unknown = sorted(map(str, set(value) - set(KEYS)))
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(unknown)} (known: {', '.join(KEYS)})")
    missing = [k for k in ("robot", "tick") if k not in value]
    if missing:
        raise ConfigError(f"{where} needs {' and '.join(missing)} (robot = \"r1\", tick = 30, kind = \"crash\")")
    robot, tick, kind = value["robot"], value["tick"], value.get("kind", "crash")
    if isinstance(robot, int) and not isinstance(robot, bool) and robot >= 0:
        robot = f"r{robot}"
    if not isinstance(robot, str) or not _ROBOT.fullmatch(robot):
        raise ConfigError(f"{where}: robot must be a robot's id (\"r0\", \"r1\", ...) or number (got {robot!r})")
    if not isinstance(tick, int) or isinstance(tick, bool) or tick < 0:
        raise ConfigError(f"{where}: tick must be a whole number >= 0 (got {tick!r})")
    if kind not in KINDS:
        raise ConfigError(f"{where}: kind must be one of {', '.join(KINDS)} (got {kind!r})")
    return Fault(robot, tick, kind)


def check_faults(faults: Any, robots: int, max_ticks: int) -> None:
    """A ConfigError when an entry names a robot the fleet does not have, a tick past the tick limit, or a
    robot a second time (a robot crashes once)."""
    name = option("faults", flag="--crash")
    if not isinstance(faults, tuple) or not all(isinstance(f, Fault) for f in faults):
        raise ConfigError(f"{name} must be a list of tables with robot, tick and kind (got {faults!r})")
    seen: set[str] = set()
    for i, f in enumerate(faults):
        where = f"{name}[{i}]"
        if int(f.robot[1:]) >= robots:
            raise ConfigError(f"{where}: robot {f.robot} is not one of the fleet's {robots} (r0 to r{robots - 1})")
        if f.tick > max_ticks:
            raise ConfigError(f"{where}: tick {f.tick} is past the tick limit {max_ticks}")
        if f.robot in seen:
            raise ConfigError(f"{where}: robot {f.robot} already has a fault (a robot crashes once)")
        seen.add(f.robot)


def crashes(faults: Iterable[Fault]) -> tuple[tuple[str, int], ...]:
    """The crashes, as (robot, tick): what the world applies (``world.sim.WorldConfig.crashes``)."""
    return tuple((f.robot, f.tick) for f in faults if f.kind == "crash")


def applied(faults: Iterable[dict[str, Any]], ticks: int) -> list[dict[str, Any]]:
    """The ``[[faults]]`` entries (as ``scenario.json`` writes them) that a run of ``ticks`` ticks applied:
    those of a tick it reached (``result.json``'s ``faults``)."""
    return [dict(f) for f in faults if isinstance(f, dict) and isinstance(f.get("tick"), int) and f["tick"] <= ticks]
