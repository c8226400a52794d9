"""Scenario: everything that defines a run, loaded from TOML and overridden by CLI flags.

Validation turns bad input into :class:`ConfigError`, whose message is one line for the user.
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path
from typing import Any

from fleet_emu.core.errors import ConfigError


@dataclasses.dataclass(frozen=True)
class RadioConfig:
    """The radio (DESIGN.md radio model): ``comm`` is ``wall`` (eq. 4 + loss) or ``ideal``."""

    comm: str = "wall"
    loss: float = 0.1
    comm_range: float = 10.0
    path_loss: float = 2.0
    waf: float = 3.1
    max_walls: int = 4
    threshold: float = 0.0
    latency: int = 1


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A run's full definition; ``to_dict`` is what the recording's metadata and result.json carry."""

    name: str = "default"
    map: str = "office"
    cell_size: float = 0.5
    robots: int = 4
    sensor_range: float = 4.0
    start: tuple[int, int] | str | None = None  # a cell, "random" (drawn from the seed), or the map's own
    allocator: dict[str, Any] = dataclasses.field(default_factory=lambda: {"type": "minpos"})
    radio: RadioConfig = dataclasses.field(default_factory=RadioConfig)
    seed: int = 0
    max_ticks: int = 2000
    target_coverage: float = 0.99
    stall_ticks: int = 30
    barrier_timeout: float = 10.0
    map_delta_ttl: int = 0
    belief_every: int = 10

    def validate(self) -> Scenario:
        """Raise ConfigError on the first bad value; return self."""
        if self.robots < 1:
            raise ConfigError(f"--robots must be at least 1 (got {self.robots})")
        if self.robots > 64:
            raise ConfigError(f"--robots must be at most 64 (got {self.robots})")
        if not 0.0 <= self.radio.loss <= 1.0:
            raise ConfigError(f"--loss must be within [0, 1] (got {self.radio.loss})")
        for flag, value in (("--sensor-range", self.sensor_range), ("--comm-range", self.radio.comm_range),
                            ("cell_size", self.cell_size)):
            if not value > 0:
                raise ConfigError(f"{flag} must be positive (got {value})")
        if self.sensor_range / self.cell_size < 1:
            raise ConfigError(f"--sensor-range {self.sensor_range} m is less than one cell ({self.cell_size} m)")
        if self.radio.comm not in ("wall", "ideal"):
            raise ConfigError(f"--comm must be 'wall' or 'ideal' (got {self.radio.comm!r})")
        if not 0.0 < self.target_coverage <= 1.0:
            raise ConfigError(f"--target-coverage must be within (0, 1] (got {self.target_coverage})")
        if self.max_ticks < 1:
            raise ConfigError(f"--max-ticks must be at least 1 (got {self.max_ticks})")
        if self.seed < 0:
            raise ConfigError(f"--seed must be non-negative (got {self.seed})")
        if self.belief_every < 0:
            raise ConfigError(f"belief_every must be non-negative (got {self.belief_every})")
        if self.radio.latency < 1:
            raise ConfigError("radio.latency must be at least 1 tick")
        if isinstance(self.start, str) and self.start != "random":
            raise ConfigError(f"--start must be ROW,COL or 'random' (got {self.start!r})")
        if isinstance(self.start, tuple) and (len(self.start) != 2 or not all(isinstance(v, int) for v in self.start)):
            raise ConfigError(f"--start must be ROW,COL or 'random' (got {self.start!r})")
        if not isinstance(self.allocator.get("type"), str):
            raise ConfigError("allocator needs a 'type' name")
        return self

    @property
    def sensor_cells(self) -> float:
        """Sensor range in cells."""
        return self.sensor_range / self.cell_size

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["start"] = list(self.start) if isinstance(self.start, tuple) else self.start
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Scenario:
        d = dict(d)
        radio = RadioConfig(**d.pop("radio", {}))
        if isinstance(d.get("start"), list):
            d["start"] = tuple(d["start"])
        return cls(radio=radio, **d)


_TOP = {"name", "seed", "max_ticks", "target_coverage", "stall_ticks", "barrier_timeout", "map_delta_ttl",
        "belief_every"}


def load_scenario(path: str | Path) -> Scenario:
    """Read a scenario TOML (sections ``[map]``, ``[fleet]``, ``[radio]``, ``[allocator]``)."""
    p = Path(path)
    try:
        raw = tomllib.loads(p.read_text())
    except FileNotFoundError:
        raise ConfigError(f"scenario file not found: {p}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read scenario {p}: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"scenario {p} is not valid TOML: {exc}") from None
    kw: dict[str, Any] = {}
    try:
        for k, v in raw.items():
            if k in _TOP:
                kw[k] = v
            elif k == "map":
                m = dict(v)
                if "name" in m:
                    name = str(m.pop("name"))
                    rel = p.parent / name
                    kw["map"] = str(rel) if ("/" in name or "." in name) and rel.exists() else name
                if "cell_size" in m:
                    kw["cell_size"] = float(m.pop("cell_size"))
                _no_extra("map", m)
            elif k == "fleet":
                f = dict(v)
                for key in ("robots", "sensor_range", "start"):
                    if key in f:
                        kw[key] = f.pop(key)
                if isinstance(kw.get("start"), list):
                    kw["start"] = tuple(kw["start"])
                _no_extra("fleet", f)
            elif k == "radio":
                kw["radio"] = RadioConfig(**v)
            elif k == "allocator":
                kw["allocator"] = dict(v)
            else:
                raise ConfigError(f"scenario {p}: unknown key or section {k!r}")
        return Scenario(**kw)
    except TypeError as exc:
        raise ConfigError(f"scenario {p}: {exc}") from None


def _no_extra(section: str, rest: dict[str, Any]) -> None:
    if rest:
        raise ConfigError(f"unknown key(s) in [{section}]: {', '.join(sorted(rest))}")


def with_overrides(s: Scenario, **flags: Any) -> Scenario:
    """Apply CLI flags (None means not given) on top of a scenario."""
    top: dict[str, Any] = {}
    radio: dict[str, Any] = {}
    for k, v in flags.items():
        if v is None:
            continue
        if k in ("loss", "comm_range", "comm"):
            radio[k] = v
        elif k == "allocator":
            top["allocator"] = {"type": v} if v != s.allocator.get("type") else s.allocator
        else:
            top[k] = v
    if radio:
        top["radio"] = dataclasses.replace(s.radio, **radio)
    return dataclasses.replace(s, **top)
