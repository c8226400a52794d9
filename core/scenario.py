"""Scenario: everything that defines a run, from a TOML file, a dict or the ``scenario.json`` a run wrote, with
CLI flags (or keyword arguments) on top.

Every value is checked for type, finiteness and range before any process starts; a bad one is a
:class:`ConfigError` whose message is one line naming the field and what it accepts.

``[hosts]`` (:class:`HostPlan`, docs/guides/hosts.md) says where the robots run, not what they do:
a lockstep run gives the same result wherever its robots are, so a run without it keeps its ``scenario.json``
as before, and ``recording.result.deterministic`` leaves it out.
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
from fleet_emu.core.fields import Setting, check_all, merge, setting, settings
from fleet_emu.core.files import read_regular
from fleet_emu.core.host_plan import MAX_HOSTS, MAX_ROBOTS, HostPlan
from fleet_emu.core.limits import MAX_FILE_BYTES, MAX_NAME, MAX_TTL, check_size, check_text, check_values
from fleet_emu.core.radio import RadioConfig, radio_settings
from fleet_emu.core.radio_profile import radio_of_profile
from fleet_emu.core.scenario_checks import check_names
from fleet_emu.core.setting_names import file_spelling, option

RELAY_POLICIES = ("none", "flood", "tree")
#: Allocators that plan at the base station: a run with one needs ``base``, the base joins
#: netem's lockstep as a sender (``radio/tx/base``), and the robots relay (``tree`` by default, below).
BASE_PLANNERS = frozenset({"mhm"})
DEFAULT_STALL = 30
#: Seconds of simulated time per tick: one 0.5 m cell a second is 0.5 m/s, a typical indoor ground robot.
DEFAULT_TICK_S = 1.0
BASE_PLANNER_STALL = 200  # a base planner's runs: robots hold while the base waits (Scenario.__post_init__)
#: Where the shipped scenarios are (``Scenario.load("default")``): ``launch/scenarios`` of the package, found by
#: path, not imported (core imports nothing above it).
SHIPPED_SCENARIOS = Path(__file__).resolve().parents[1] / "launch" / "scenarios"


def _cell(value: Any, low: float = -math.inf) -> bool:
    """Whether ``value`` is a cell: two whole numbers (row, column), each at least ``low``."""
    return isinstance(value, tuple) and len(value) == 2 and all(
        isinstance(v, int) and not isinstance(v, bool) and v >= low for v in value)


def _start_ok(value: Any) -> bool:
    """A start: a cell, or ``"random"`` (None, the map's own, is the field's ``optional``)."""
    return value == "random" or _cell(value)


def _base_ok(value: Any) -> bool:
    """A base station: true, false, or a cell on the map's side of the origin."""
    return isinstance(value, bool) or _cell(value, 0)


def start_arg(text: str) -> tuple[int, int] | str:
    """``--start``'s reader: ``ROW,COL`` as a cell, or ``random``."""
    if text == "random":
        return text
    try:
        row, col = (int(v) for v in text.split(","))
    except ValueError:
        import argparse

        raise argparse.ArgumentTypeError(f"expected ROW,COL or 'random', got {text!r}") from None
    return (row, col)


class _DefaultCellSize(float):
    """The cell size of a scenario that names none: 0.5 m, equal to 0.5 in every use, but told apart from a cell
    size the user gave (:attr:`Scenario.cell_size_given`): a bare bitmap map is read one pixel per cell, so it
    needs the user's cell size (``world.maps.load_map``)."""

    __slots__ = ()


DEFAULT_CELL_SIZE: float = _DefaultCellSize(0.5)


@dataclasses.dataclass(frozen=True)
class Scenario:
    """A run's full definition; :meth:`to_dict` is what ``scenario.json``, the recording's metadata and
    ``result.json`` carry, and :meth:`from_dict` reads it back.

    Every field is declared once with :func:`~fleet_emu.core.fields.setting` (type, unit, range, flag, help,
    its key in a scenario file): that declaration makes it a ``fleet run`` flag, a key of a scenario file and of
    a study's ``[grid]`` and ``[fleet]``, an :meth:`override` keyword, and checks it (:meth:`validate`) the same
    way in all of them (docs/guides/scenarios.md, "Every key")."""

    name: str = setting("default", low=1, high=MAX_NAME, metavar="NAME",
                        help="the run's name, in result.json and the tables")
    map: str = setting("office", low=1, section="map", key="name", metavar="MAP",
                       help="a built-in or registry map's name (see `fleet maps`), or a ROS map YAML or a PNG/PGM "
                            "path (a bare bitmap needs --cell-size: one pixel per cell)")
    cell_size: float = setting(DEFAULT_CELL_SIZE, unit="m", low=1e-3, high=1e3, section="map", metavar="M",
                               help="metres per cell (one cell = one robot)")
    robots: int = setting(4, low=1, high=MAX_ROBOTS, section="fleet", metavar="N", help="robots in the fleet")
    sensor_range: float = setting(4.0, unit="m", low=0.0, low_open=True, section="fleet", metavar="M",
                                  help="sensor range (360 degrees), at least one cell")
    start: tuple[int, int] | str | None = setting(
        None, optional=True, unset="the map's own start", shape=_start_ok, accepts="ROW,COL or 'random'",
        parse=start_arg, section="fleet", metavar="ROW,COL",
        help="the fleet's start cell ('random': drawn from the seed)")
    allocator: dict[str, Any] = setting(factory=lambda: {"type": "minpos"}, table=True, section="allocator",
                                        key="type", help="the allocator and its parameters (`fleet allocators`)")
    radio: RadioConfig = setting(factory=RadioConfig, table=True, section="radio",
                                 help="the radio (core/radio.py: a setting each)")
    seed: int = setting(0, low=0, high=2**63 - 1, help="the run's seed: a seed reproduces a run exactly")
    max_ticks: int = setting(2000, low=1, high=10**9, metavar="N", help="ticks after which the run ends unfinished")
    tick_s: float = setting(DEFAULT_TICK_S, unit="s", low=0.0, high=3600.0, low_open=True, metavar="S", quiet=True,
                            help="simulated time per tick: a robot moves one cell per tick, and the radio's "
                                 "--bandwidth is per second of it")
    target_coverage: float = setting(0.99, low=0.0, high=1.0, low_open=True, metavar="F",
                                     help="fraction of the free cells at which the run is done")
    stall_ticks: int = setting(DEFAULT_STALL, low=1, high=10**9, metavar="N",
                               help="ticks without a move nor a new cell sensed that end the run as a stall "
                                    f"({BASE_PLANNER_STALL} for a base-station planner left at the default)")
    coverage_stall_ticks: int = setting(500, low=1, high=10**9, metavar="N",
                                        help="the least belief stall window: ticks in which no robot's own belief "
                                             "gained a known cell that end the run as a stall")
    barrier_timeout: float = setting(10.0, unit="s", low=0.0, high=86400.0, low_open=True, metavar="S",
                                     help="seconds a robot may stay silent (after the tick's last answer) before "
                                          "it is failed")
    belief_every: int = setting(10, low=0, high=10**9, metavar="K",
                                help="ticks between the robots' belief snapshots in the recording (0: none)")
    base: bool | tuple[int, int] = setting(False, shape=_base_ok, accepts="true, false or a cell [ROW, COL]",
                                           section="fleet", cli=False, quiet=True,
                                           help="a base station: false (none), true (at the start cell) or a cell")
    relay: str = setting("none", choices=RELAY_POLICIES, quiet=True,
                         help="multi-hop relaying in the robots (agents/relay.py; flood: every robot forwards)")
    relay_ttl: int = setting(0, low=0, high=MAX_TTL, metavar="K", quiet=True,
                             help="hops left after the first on the messages a robot makes (0: one hop)")
    map_sync: bool = setting(True, quiet=True,
                             help="repair map deltas lost on a lossy radio (agents/mapsync.py); off: a lost delta is "
                                  "lost (docs/guides/radio.md#map-sync)")
    hosts: HostPlan | None = setting(None, optional=True, table=True, section="hosts", cli=False, quiet=True,
                                     help="robots on other machines (`fleet host`); none: all here")
    faults: tuple[Fault, ...] = setting((), table=True, cli=False, quiet=True,
                                        help="robot failures at given ticks ([[faults]], core/faults.py)")

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
                _move(m, flat, _IN["map"], "map")
            elif k == "fleet":
                _move(dict(v), flat, _IN["fleet"], "fleet")
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
        """The scenario as ``scenario.json`` holds it: the fields declared ``quiet`` (a base station, relaying,
        hosts, faults, simulated time, map sync, the radio's airtime and shadowing) left out at their defaults,
        so that runs without them keep the scenario.json they always had."""
        d = dataclasses.asdict(self)
        for config, out, specs in ((self, d, scenario_settings()), (self.radio, d["radio"], radio_settings())):
            for s in specs:
                if s.quiet and getattr(config, s.name) == s.default:
                    del out[s.name]
        d["start"] = list(self.start) if isinstance(self.start, tuple) else self.start
        if "base" in d:
            d["base"] = list(self.base) if isinstance(self.base, tuple) else self.base
        if self.hosts is not None:
            d["hosts"] = self.hosts.to_dict()
        if "faults" in d:
            d["faults"] = [f.to_dict() for f in self.faults]
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
        """Raise ConfigError on the first bad value; return self. Each field is checked against its declaration
        (:func:`scenario_settings`); what is left here is what relates fields or checks a table."""
        check_all(self)
        check_values([self.map, self.allocator, self.start], "the scenario")
        check_all(self.radio)
        if self.sensor_range / self.cell_size < 1:
            raise ConfigError(f"{option('sensor_range')} {self.sensor_range} m is less than one cell "
                              f"({self.cell_size} m)")
        if not isinstance(self.allocator, dict) or not isinstance(self.allocator.get("type"), str):
            raise ConfigError("allocator needs a 'type' name")
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


def scenario_settings() -> tuple[Setting, ...]:
    """The declaration of every :class:`Scenario` field, in order: its flag, its key in a scenario file, its
    check (:mod:`fleet_emu.core.fields`)."""
    return settings(Scenario)


def _named(exc: ConfigError | MapError, where: str) -> ConfigError | MapError:
    """``exc`` with ``where`` (the file) in front, once; a MapError stays one."""
    text = str(exc)
    return exc if text.startswith(where) else type(exc)(f"{where}: {text}")


#: A scenario TOML's key of each setting, as :func:`fleet_emu.core.setting_names.option` names it in an error.
_TOML_KEYS = {**{s.name: s.file_key for s in scenario_settings() if s.section and (s.key or not s.table)},
              **{s.name: f"[radio] {s.name}" for s in radio_settings()}}

#: The keys a scenario file writes at its top level (``base`` there too, as in ``[fleet]``) and in each section.
_TOP = {s.name for s in scenario_settings() if not s.section} | {"base"}
_SECTIONS = tuple(dict.fromkeys(s.section for s in scenario_settings() if s.section))
_IN = {section: tuple(s.name for s in scenario_settings() if s.section == section and not s.key)
       for section in ("map", "fleet")}


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
