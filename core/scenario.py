"""Scenario: everything that defines a run, from a TOML file, a dict or the ``scenario.json`` a run wrote, with
CLI flags (or keyword arguments) on top.

Every value is checked for type, finiteness and range before any process starts; a bad one is a
:class:`ConfigError` whose message is one line naming the field and what it accepts.

``[hosts]`` (:class:`HostPlan`, docs/guides/hosts.md) says where the robots run, not what they do:
a lockstep run gives the same result wherever its robots are, so a run without it keeps its ``scenario.json``
as before, and ``launch.result.deterministic`` leaves it out.
"""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib
from pathlib import Path
from typing import Any

from fleet_emu.core.errors import ConfigError, MapError
from fleet_emu.core.faults import Fault, check_faults, parse_faults
from fleet_emu.core.fields import check_all, merge
from fleet_emu.core.files import read_regular
from fleet_emu.core.keys import HOST_ID
from fleet_emu.core.limits import MAX_FILE_BYTES, MAX_NAME, check_size, check_text, check_values
from fleet_emu.core.messages import MAX_TTL
from fleet_emu.core.radio import RadioConfig, radio_settings
from fleet_emu.core.radio_profile import radio_of_profile
from fleet_emu.core.scenario_checks import check_names
from fleet_emu.core.spelling import file_spelling, option

MAX_ROBOTS = 256
MAX_HOSTS = 64
RELAY_POLICIES = ("none", "flood", "tree")
#: Allocators that plan at the base station: a run with one needs ``base``, the base joins
#: netem's lockstep as a sender (``radio/tx/base``), and the robots relay (``tree`` by default, below).
BASE_PLANNERS = frozenset({"mhm"})
DEFAULT_STALL = 30
#: Seconds of simulated time per tick: one 0.5 m cell a second is 0.5 m/s, a typical indoor ground robot.
DEFAULT_TICK_S = 1.0
#: The radio's airtime and shadowing fields (``RadioConfig``), left out of ``scenario.json`` at their defaults
#: (unlimited, no shadowing).
_RADIO_QUIET: dict[str, float] = {"bandwidth": 0.0, "queue_bytes": 1_000_000, "jitter": 0, "shadowing_db": 0.0,
                                   "shadowing_m": 1.0}
BASE_PLANNER_STALL = 200  # a base planner's runs: robots hold while the base waits (Scenario.__post_init__)
#: Where the shipped scenarios are (``Scenario.load("default")``): ``launch/scenarios`` of the package, found by
#: path, not imported (core imports nothing above it).
SHIPPED_SCENARIOS = Path(__file__).resolve().parents[1] / "launch" / "scenarios"


class _DefaultCellSize(float):
    """The cell size of a scenario that names none: 0.5 m, equal to 0.5 in every use, but told apart from a cell
    size the user gave (:attr:`Scenario.cell_size_given`): a bare bitmap map is read one pixel per cell, so it
    needs the user's cell size (``world.maps.load_map``)."""

    __slots__ = ()


DEFAULT_CELL_SIZE: float = _DefaultCellSize(0.5)


@dataclasses.dataclass(frozen=True)
class HostPlan:
    """The scenario's ``[hosts]``: robots on ``count`` other machines (``fleet host``), as ``fleet run --hosts
    count`` does. ``names``: which hosts (``hostK`` logins; default the first ``count`` that come, by number);
    ``robots``: how many robots each of them runs, in that order, the rest running here (default: robots dealt
    round-robin over this machine and the hosts). Placement is dealt one robot at a time round the machines that
    still have room (``launch.hosts.placement``)."""

    count: int
    names: tuple[str, ...] = ()
    robots: tuple[int, ...] = ()

    @classmethod
    def from_dict(cls, d: dict[str, Any], where: str) -> HostPlan | None:
        """``[hosts]``: ``count``, ``names``, ``robots`` (None for ``count = 0`` alone: no hosts)."""
        bad = set(d) - {"count", "names", "robots"}
        if bad:
            raise ConfigError(f"{where}: unknown key(s) in [hosts]: {', '.join(sorted(bad))} (count, names, robots)")
        lists = {}
        for key in ("names", "robots"):
            value = d.get(key, [])
            if not isinstance(value, list | tuple):
                raise ConfigError(f"{where}: [hosts] {key} must be a list (got {value!r})")
            lists[key] = tuple(value)
        if "count" not in d and not lists["names"]:
            raise ConfigError(f"{where}: [hosts] needs count = N or names = [\"host0\", ...]")
        count = d.get("count", len(lists["names"]))
        if count == 0 and not isinstance(count, bool) and not lists["names"] and not lists["robots"]:
            return None
        return cls(count, lists["names"], lists["robots"])

    def to_dict(self) -> dict[str, Any]:
        """The ``[hosts]`` table, with only the keys given."""
        return {"count": self.count, **({"names": list(self.names)} if self.names else {}),
                **({"robots": list(self.robots)} if self.robots else {})}

    def validate(self, fleet: int) -> None:
        """A ConfigError on the first bad value; ``fleet`` is the scenario's number of robots."""
        _integer("[hosts] count", self.count, 1, MAX_HOSTS)
        if self.names:
            if len(self.names) != self.count:
                raise ConfigError(f"[hosts] names lists {len(self.names)} host(s) but count is {self.count}")
            bad = [n for n in self.names if not isinstance(n, str) or not HOST_ID.fullmatch(n)]
            if bad:
                raise ConfigError(f"[hosts] names must be host0, host1, ... (the hosts' logins; got {bad[0]!r})")
            if len(set(self.names)) != len(self.names):
                raise ConfigError(f"[hosts] names lists a host twice ({', '.join(self.names)})")
        if self.robots:
            if len(self.robots) != self.count:
                raise ConfigError(f"[hosts] robots gives {len(self.robots)} number(s) for {self.count} host(s)")
            for n in self.robots:
                _integer("[hosts] robots (each host's)", n, 0, MAX_ROBOTS)
            if sum(self.robots) > fleet:
                raise ConfigError(f"[hosts] robots puts {sum(self.robots)} robots on hosts, more than the fleet's "
                                  f"{fleet} (--robots)")


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A run's full definition; :meth:`to_dict` is what ``scenario.json``, the recording's metadata and
    ``result.json`` carry, and :meth:`from_dict` reads it back."""

    name: str = "default"
    map: str = "office"
    cell_size: float = DEFAULT_CELL_SIZE
    robots: int = 4
    sensor_range: float = 4.0
    start: tuple[int, int] | str | None = None  # a cell, "random" (drawn from the seed), or the map's own
    allocator: dict[str, Any] = dataclasses.field(default_factory=lambda: {"type": "minpos"})
    radio: RadioConfig = dataclasses.field(default_factory=RadioConfig)
    seed: int = 0
    max_ticks: int = 2000
    tick_s: float = DEFAULT_TICK_S  # seconds of simulated time per tick: a robot moves one cell per tick
    target_coverage: float = 0.99
    stall_ticks: int = DEFAULT_STALL  # ticks without a move nor a new cell sensed that end the run
    coverage_stall_ticks: int = 500  # ticks without coverage growth that end the run as a stall
    barrier_timeout: float = 10.0
    belief_every: int = 10
    base: bool | tuple[int, int] = False  # a base station: False (none), True (at the start cell) or a cell
    relay: str = "none"  # multi-hop relaying in the robots (agents/relay.py): none, flood or tree
    relay_ttl: int = 0  # hops left after the first on the messages a robot makes (0: one hop)
    map_sync: bool = True  # repair lost map deltas on a lossy radio (agents/mapsync.py); False: a lost one is lost
    hosts: HostPlan | None = None  # robots on other machines (``fleet host``); None: all here
    faults: tuple[Fault, ...] = ()  # robot failures at given ticks (``[[faults]]``, core/faults.py)

    def __post_init__(self) -> None:
        """A base-station planner's orders must cross several hops: with ``relay = "none"`` (the default) it
        runs with ``tree`` relaying and, when ``relay_ttl`` is 0, the largest hop limit. And its robots hold
        while the base waits (orders crossing the tree, a robot slow to reach its hinge point, up to the
        planner's patience): at the default ``stall_ticks`` (30) it runs with :data:`BASE_PLANNER_STALL`
        (docs/guides/base-station.md)."""
        if self.plans_at_base and self.relay == "none":
            object.__setattr__(self, "relay", "tree")
            if self.relay_ttl == 0:
                object.__setattr__(self, "relay_ttl", MAX_TTL)
        if self.plans_at_base and self.stall_ticks == DEFAULT_STALL:
            object.__setattr__(self, "stall_ticks", BASE_PLANNER_STALL)

    # --- reading and writing ------------------------------------------------------------------------------

    @classmethod
    def load(cls, path: str | Path) -> Scenario:
        """A scenario file: TOML, or the ``scenario.json`` a run wrote (by suffix); or the name of a shipped
        scenario (:func:`shipped`: ``"default"``, ``"connectivity"``) when no such file exists."""
        p = Path(path)
        if not p.exists() and str(path) in shipped():
            p = SHIPPED_SCENARIOS / f"{path}.toml"
        return cls.from_json(p) if p.suffix.lower() == ".json" else cls.from_toml(p)

    @classmethod
    def from_toml(cls, path: str | Path) -> Scenario:
        """A scenario TOML: top-level keys and the sections ``[map]``, ``[fleet]``, ``[radio]``, ``[allocator]``."""
        p = Path(path)
        try:
            raw = tomllib.loads(_read(p))
        except RecursionError:  # a bound check_text did not see; never a traceback
            raise ConfigError(f"scenario {p} nests too deeply") from None
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"scenario {p} is not valid TOML: {exc}") from None
        flat: dict[str, Any] = {}
        for k, v in raw.items():
            if k in _SECTIONS and not isinstance(v, dict):
                raise ConfigError(f"scenario {p}: {k!r} must be a [{k}] section, not a value")
            if k == "map":
                m = dict(v)
                if "name" in m:
                    name = m.pop("name")
                    rel = p.parent / str(name)
                    is_path = isinstance(name, str) and ("/" in name or "." in name) and rel.exists()
                    flat["map"] = str(rel) if is_path else name
                _move(m, flat, ("cell_size",), "map")
            elif k == "fleet":
                _move(dict(v), flat, ("robots", "sensor_range", "start", "base"), "fleet")
            elif k == "radio":  # a measured profile (core/radio_profile.py): its path relative to the file
                flat[k] = radio_of_profile(dict(v), p.parent)
            elif k in ("allocator", "hosts"):
                flat[k] = dict(v)
            elif k in _TOP:
                flat[k] = v
            else:
                raise ConfigError(f"scenario {p}: unknown key or section {k!r}")
        where = f"scenario {p}"
        try:
            with file_spelling(_TOML_KEYS):  # an error names the key: ``scenario s.toml: [fleet] robots must ...``
                scenario = cls.from_dict(flat, where=where)
                # a file someone wrote: its allocator and map are checked now, as override's (a run's JSON is not)
                check_names(scenario, [k for k in ("allocator", "map") if k in flat])
        except (ConfigError, MapError) as exc:
            raise _named(exc, where) from None
        return scenario

    @classmethod
    def from_json(cls, path: str | Path) -> Scenario:
        """The ``scenario.json`` that ``fleet run`` writes beside every result (:meth:`to_dict`)."""
        p = Path(path)
        try:
            d = json.loads(_read(p))
        except RecursionError:
            raise ConfigError(f"scenario {p} nests too deeply") from None
        except json.JSONDecodeError as exc:
            raise ConfigError(f"scenario {p} is not valid JSON: {exc}") from None
        if not isinstance(d, dict):
            raise ConfigError(f"scenario {p} is not a JSON object")
        try:
            with file_spelling({s.name: f"radio.{s.name}" for s in radio_settings()}):
                return cls.from_dict(d, where=f"scenario {p}")
        except ConfigError as exc:
            raise _named(exc, f"scenario {p}") from None

    @classmethod
    def from_dict(cls, d: dict[str, Any], where: str = "scenario") -> Scenario:
        """The inverse of :meth:`to_dict`; unknown keys and wrong types are a ConfigError."""
        d = dict(d)
        unknown = set(d) - {f.name for f in dataclasses.fields(cls)}
        if unknown:
            raise ConfigError(f"{where}: unknown key(s) {', '.join(sorted(unknown))}")
        radio = merge(RadioConfig(), d.pop("radio", {}), "[radio]", where)
        for cell_key in ("start", "base"):
            if isinstance(d.get(cell_key), list):
                d[cell_key] = tuple(d[cell_key])
        alloc = d.get("allocator", {})
        if not isinstance(alloc, dict) or not isinstance(alloc.get("type", ""), str):
            raise ConfigError(f"{where}: allocator must be a table with a 'type' name (got {alloc!r})")
        if "faults" in d:
            d["faults"] = parse_faults(d["faults"])
        if isinstance(d.get("hosts"), dict):
            d["hosts"] = HostPlan.from_dict(d["hosts"], where)
        elif d.get("hosts") is not None and not isinstance(d["hosts"], HostPlan):
            raise ConfigError(f"{where}: hosts must be a [hosts] table (count, names, robots)")
        try:
            return cls(radio=radio, **d).validate()
        except ConfigError:  # the checks' own line (a ConfigError is a ValueError too)
            raise
        except (TypeError, ValueError, AttributeError) as exc:  # a value of a type no check above foresaw
            raise ConfigError(f"{where}: a value of the wrong type ({exc})") from None

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["start"] = list(self.start) if isinstance(self.start, tuple) else self.start
        if self.base is False:  # absent when there is no base: runs without one keep their scenario.json
            del d["base"]
        else:
            d["base"] = list(self.base) if isinstance(self.base, tuple) else self.base
        for k, default in (("relay", "none"), ("relay_ttl", 0)):  # absent at their defaults, as before relaying
            if d[k] == default:
                del d[k]
        if self.tick_s == DEFAULT_TICK_S:  # absent at its default, as are the radio's airtime fields
            del d["tick_s"]
        if self.map_sync is True:  # absent at its default (on): runs keep their scenario.json
            del d["map_sync"]
        for name, quiet in _RADIO_QUIET.items():
            if d["radio"][name] == quiet:
                del d["radio"][name]
        if self.hosts is None:  # absent without hosts: runs on one machine keep their scenario.json
            del d["hosts"]
        else:
            d["hosts"] = self.hosts.to_dict()
        if self.faults:  # absent without faults: runs without them keep their scenario.json
            d["faults"] = [f.to_dict() for f in self.faults]
        else:
            del d["faults"]
        return d

    def override(self, **flags: Any) -> Scenario:
        """Flags on top (None means not given): a radio field by its name (``waf=6.0``), or ``radio`` a table of
        them (or a :class:`RadioConfig`), the names winning over the table; ``allocator`` a name (its parameters
        kept when the name is unchanged) or a table with a ``type``; ``hosts`` a number (``--hosts N``: the
        robots dealt round-robin over this machine and any N hosts, replacing the scenario's ``[hosts]``; 0:
        every robot here); the rest by field name. Every value is checked, and an allocator or a map given is
        checked to exist (:mod:`fleet_emu.core.scenario_checks`), before this returns."""
        top: dict[str, Any] = {}
        names = {f.name for f in dataclasses.fields(self)}
        radio_names = {s.name for s in radio_settings()}
        table = flags.pop("radio", None)
        if isinstance(table, dict):  # ``profile`` in it: a measured profile's settings under the table's own
            table = radio_of_profile(table)
        radio = self.radio if table is None else merge(self.radio, table, "radio")
        for k, v in flags.items():
            if v is None:
                continue
            if k in radio_names:
                radio = dataclasses.replace(radio, **{k: v})
            elif k == "allocator":
                top["allocator"] = _allocator(v, self.allocator)
            elif k == "faults":
                top["faults"] = parse_faults(v)
            elif k == "hosts" and not isinstance(v, HostPlan):
                if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= MAX_HOSTS:
                    raise ConfigError(f"{option('hosts')} must be in 0..{MAX_HOSTS} (got {v!r})")
                top["hosts"] = HostPlan(v) if v else None
            elif k in names:
                top[k] = tuple(v) if k in ("start", "base") and isinstance(v, list) else v
            else:
                raise ConfigError(f"unknown scenario field {k!r}")
        if radio != self.radio:
            top["radio"] = radio
        out = dataclasses.replace(self, **top).validate()
        check_names(out, [k for k in ("allocator", "map") if k in top])
        return out

    @property
    def cell_size_given(self) -> bool:
        """Whether the cell size was given (a scenario file, a flag, an argument), not the default's."""
        return not isinstance(self.cell_size, _DefaultCellSize)

    @property
    def has_base(self) -> bool:
        """Whether the run has a base station (the ``base`` process, docs/guides/base-station.md)."""
        return self.base is not False

    @property
    def plans_at_base(self) -> bool:
        """Whether the allocator is a base-station planner (:data:`BASE_PLANNERS`): the base sends orders."""
        kind = self.allocator.get("type") if isinstance(self.allocator, dict) else None
        return isinstance(kind, str) and kind in BASE_PLANNERS

    @property
    def link_cells(self) -> float:
        """:attr:`RadioConfig.sure_range` in cells; 1e6 (no map is larger) where it is infinite."""
        r = self.radio.sure_range
        return r / self.cell_size if math.isfinite(r) else 1e6

    @property
    def sensor_cells(self) -> float:
        """Sensor range in cells."""
        return self.sensor_range / self.cell_size

    # --- checks -------------------------------------------------------------------------------------------

    def validate(self) -> Scenario:
        """Raise ConfigError on the first bad value; return self."""
        _text("name", self.name)
        if len(self.name) > MAX_NAME:
            raise ConfigError(f"name is {len(self.name)} characters long, more than the {MAX_NAME} allowed")
        _text(option("map"), self.map)
        check_values([self.map, self.allocator, self.start], "the scenario")
        _integer(option("robots"), self.robots, 1, MAX_ROBOTS)
        _integer(option("seed"), self.seed, 0, 2**63 - 1)
        _integer(option("max_ticks"), self.max_ticks, 1, 10**9)
        _integer("stall_ticks", self.stall_ticks, 1, 10**9)
        _integer("coverage_stall_ticks", self.coverage_stall_ticks, 1, 10**9)
        _integer("belief_every", self.belief_every, 0, 10**9)
        _number(option("cell_size"), self.cell_size, 1e-3, 1e3)
        _number(option("sensor_range"), self.sensor_range, 0.0, math.inf, low_open=True)  # the world clamps it
        _number(option("target_coverage"), self.target_coverage, 0.0, 1.0, low_open=True)
        _number("barrier_timeout", self.barrier_timeout, 0.0, 86400.0, low_open=True)
        _number("tick_s", self.tick_s, 0.0, 3600.0, low_open=True)
        check_all(self.radio)
        if self.sensor_range / self.cell_size < 1:
            raise ConfigError(f"{option('sensor_range')} {self.sensor_range} m is less than one cell "
                              f"({self.cell_size} m)")
        start_ok = self.start is None or self.start == "random" or (
            isinstance(self.start, tuple) and len(self.start) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) for v in self.start))
        if not start_ok:
            raise ConfigError(f"{option('start')} must be ROW,COL or 'random' (got {self.start!r})")
        base_ok = isinstance(self.base, bool) or (
            isinstance(self.base, tuple) and len(self.base) == 2
            and all(isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in self.base))
        if not base_ok:
            raise ConfigError(f"base must be true, false or a cell [ROW, COL] (--base-cell ROW,COL; got {self.base!r})")
        if not isinstance(self.allocator, dict) or not isinstance(self.allocator.get("type"), str):
            raise ConfigError("allocator needs a 'type' name")
        if self.relay not in RELAY_POLICIES:
            raise ConfigError(f"{option('relay')} must be one of {', '.join(RELAY_POLICIES)} (got {self.relay!r})")
        _integer(option("relay_ttl"), self.relay_ttl, 0, MAX_TTL)
        if not isinstance(self.map_sync, bool):
            raise ConfigError(f"{option('map_sync', flag='--map-sync / --no-map-sync')} must be true or false "
                              f"(got {self.map_sync!r})")
        if self.plans_at_base and not self.has_base:
            spelt = option("base")
            how = ("--base (or --base-cell ROW,COL; in a scenario [fleet] base = true)" if spelt.startswith("--")
                   else "[fleet] base = true (or base = [ROW, COL])" if spelt.startswith("[")
                   else "base=True (or base=(ROW, COL); in a scenario [fleet] base = true)")
            raise ConfigError(f"{option('allocator')} {self.allocator['type']} plans at the base station: it needs "
                              f"{how}")
        check_faults(self.faults, self.robots, self.max_ticks)
        if self.hosts is not None:
            if not isinstance(self.hosts, HostPlan):
                raise ConfigError(f"hosts must be a [hosts] table (count, names, robots; got {self.hosts!r})")
            self.hosts.validate(self.robots)
        return self


def _named(exc: ConfigError | MapError, where: str) -> ConfigError | MapError:
    """``exc`` with ``where`` (the file) in front, once; a MapError stays one."""
    text = str(exc)
    return exc if text.startswith(where) else type(exc)(f"{where}: {text}")


#: A scenario TOML's key of each setting, as :func:`fleet_emu.core.spelling.option` names it in an error.
_TOML_KEYS = {"map": "[map] name", "cell_size": "[map] cell_size", "allocator": "[allocator] type",
              **{k: f"[fleet] {k}" for k in ("robots", "sensor_range", "start", "base")},
              **{s.name: f"[radio] {s.name}" for s in radio_settings()}}

_TOP = {"name", "base", "seed", "max_ticks", "tick_s", "target_coverage", "stall_ticks", "coverage_stall_ticks",
        "barrier_timeout", "belief_every", "relay", "relay_ttl", "map_sync", "faults"}
_SECTIONS = ("map", "fleet", "radio", "allocator", "hosts")


def _allocator(value: Any, current: dict[str, Any]) -> dict[str, Any]:
    """An allocator override: a name (``current``'s parameters kept when it names the same allocator) or a table
    with a ``type`` name and parameters."""
    if isinstance(value, str):
        return current if value == current.get("type") else {"type": value}
    if isinstance(value, dict) and isinstance(value.get("type"), str):
        return dict(value)
    raise ConfigError(f"allocator must be a name or a table with a 'type' name (got {value!r})")


def shipped() -> list[str]:
    """The names of the scenarios shipped in the package (``launch/scenarios/*.toml``)."""
    return sorted(p.stem for p in SHIPPED_SCENARIOS.glob("*.toml"))


def _read(p: Path) -> str:
    """The file's text, once its size and nesting are within ``core/limits.py``'s bounds; only a regular file is
    opened (a FIFO or a device is refused at once, never waited on: :func:`read_regular`)."""
    try:
        if p.is_file():
            check_size(p.stat().st_size, f"scenario {p}")
        text = read_regular(p, MAX_FILE_BYTES).decode()
        check_text(text, f"scenario {p}")
        return text
    except FileNotFoundError:
        raise ConfigError(f"scenario file not found: {p} (a TOML file, a run's scenario.json, or a shipped "
                          f"scenario: {', '.join(shipped())})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read scenario {p}: {getattr(exc, 'strerror', None) or exc}") from None


def _move(section: dict[str, Any], flat: dict[str, Any], keys: tuple[str, ...], name: str) -> None:
    for key in keys:
        if key in section:
            flat[key] = section.pop(key)
    if section:
        raise ConfigError(f"unknown key(s) in [{name}]: {', '.join(sorted(section))}")


def _text(field: str, value: Any) -> None:
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{field} must be a non-empty string (got {value!r})")


def _integer(field: str, value: Any, low: int, high: int) -> None:
    if not isinstance(value, int) or isinstance(value, bool):
        raise ConfigError(f"{field} must be a whole number from {low} to {high} (got {value!r})")
    if not low <= value <= high:
        raise ConfigError(f"{field} must be from {low} to {high} (got {value})")


def _number(field: str, value: Any, low: float, high: float, low_open: bool = False) -> None:
    lo = "(" if low_open else "["
    span = f"{'>' if low_open else '>='} {low:g}" if math.isinf(high) else f"within {lo}{low:g}, {high:g}]"
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        raise ConfigError(f"{field} must be a finite number {span} (got {value!r})")
    if not (low < value if low_open else low <= value) or value > high:
        raise ConfigError(f"{field} must be {span} (got {value})")
