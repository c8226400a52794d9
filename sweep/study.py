"""A study: a grid of runs (allocators with parameters, robot counts, losses, radio models, maps, seeds, any
scenario field), read from a TOML file, expanded into points with stable ids (so that a sweep can resume).

```toml
[study]
name = "tiny"
engine = "memory"          # or "processes": each point a real fleet over Zenoh
seeds = 2                  # seeds 0..1, or a list [0, 5, 7]
baseline = "nearest"       # the allocator `fleet sweep report` compares the others with
replicates = []            # grid keys whose values are repetitions, like seeds: the report pools them
# more = {start = [[3, 4]]}  # further values of a replicates key that `--until-decided` may add
record = "failed"          # keep the recordings of the runs that failed or missed the target; "all"; "none"
[grid]                     # every key a list; the points are their product
allocator = ["nearest", {type = "minpos", wavefront = "stop"}]
robots = [2, 3]
loss = [0.0]
comm = ["ideal"]
map = ["office"]
waf = [3.1, 6.0]           # a radio setting by name, or several in a table:
radio = [{comm = "wall"}, {comm = "disk", comm_range = 6.0}]
faults = [[], [{robot = 0, tick = 30, kind = "crash"}]]  # robot failures (docs/guides/faults.md)
[fleet]                    # any scenario field, fixed for every point (radio settings flat or in [fleet.radio])
max_ticks = 3000
```

A map is a built-in map's name, a registry map's name (``map = "hospital_section"``: fetched once with ``fleet
maps fetch hospital_section``), or a path: relative to the study file, to ``--maps DIR`` (or ``$FLEET_MAPS``),
or to the current directory. The ``[paper]`` table (``source``, ``rows``, ``claims``, ``beside``) is
what ``fleet sweep report`` prints beside the study's numbers, each claim judged (:mod:`fleet_emu.sweep.claims`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
import os
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.files import read_regular
from fleet_emu.core.limits import MAX_FILE_BYTES, check_text
from fleet_emu.core.radio import radio_settings
from fleet_emu.core.scenario import Scenario
from fleet_emu.core.setting_names import file_spelling, near
from fleet_emu.sweep import claims

STUDIES = Path(__file__).resolve().parent / "studies"
ENGINES = ("memory", "processes")
_STUDY_KEYS = {"name", "description", "engine", "seeds", "baseline", "maps", "record", "replicates", "more"}
#: ``[study] record``: which runs keep their folder (``run.mcap``, ``result.json``...) under ``DIR/runs/ID``.
RECORD = ("failed", "all", "none")
#: The most runs one study's grid may hold (grid values times seeds): a larger one is refused before it is
#: expanded, as expanding it alone would take minutes and memory (a day of the largest runs is a few thousand).
MAX_POINTS = 100_000


@dataclasses.dataclass(frozen=True)
class Point:
    """One run of a study: its parameters (as the grid names them, and the seed), its stable id, and its
    scenario as a dict (picklable, for a process pool or a Dask worker)."""

    id: str
    params: dict[str, Any]
    scenario: dict[str, Any]
    engine: str


@dataclasses.dataclass(frozen=True)
class Study:
    name: str
    grid: dict[str, list[Any]]
    seeds: list[int]
    fleet: dict[str, Any] = dataclasses.field(default_factory=dict)
    engine: str = "memory"
    record: str = "failed"
    baseline: str | None = None
    description: str = ""
    maps_hint: str = ""
    paper: dict[str, Any] = dataclasses.field(default_factory=dict)
    path: Path | None = None
    text: str = ""
    replicates: tuple[str, ...] = ()
    more: dict[str, list[Any]] = dataclasses.field(default_factory=dict)

    @classmethod
    def load(cls, name_or_path: str | Path) -> Study:
        """A study file, or the name of a shipped one (``fleet sweep --list``)."""
        p = Path(name_or_path)
        if not p.is_file() and (STUDIES / f"{name_or_path}.toml").exists():  # a folder named so: the shipped study
            p = STUDIES / f"{name_or_path}.toml"
        try:
            text = read_regular(p, MAX_FILE_BYTES).decode()  # a FIFO or a device refused at once, never waited on
        except FileNotFoundError:
            known = shipped()
            raise ConfigError(f"study {name_or_path} not found{near(str(name_or_path), known)} (a TOML file, or one "
                              f"of: {', '.join(known)})") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise ConfigError(f"cannot read study {p}: {getattr(exc, 'strerror', None) or exc}") from None
        check_text(text, f"study {p}")  # size and nesting before the parser recurses
        try:
            raw = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"study {p} is not valid TOML: {exc}") from None
        return cls.from_dict(raw, p, text)

    @classmethod
    def from_dict(cls, raw: dict[str, Any], path: Path | None = None, text: str = "") -> Study:
        where = f"study {path or ''}".strip()
        unknown = set(raw) - {"study", "grid", "fleet", "paper"}
        if unknown:
            raise ConfigError(f"{where}: unknown section(s) {', '.join(sorted(unknown))}")
        head, grid, fleet = raw.get("study", {}), raw.get("grid", {}), raw.get("fleet", {})
        if not all(isinstance(t, dict) for t in (head, grid, fleet)):
            raise ConfigError(f"{where}: [study], [grid] and [fleet] must be tables")
        if set(head) - _STUDY_KEYS:
            raise ConfigError(f"{where}: unknown key(s) in [study]: {', '.join(sorted(set(head) - _STUDY_KEYS))}")
        engine = head.get("engine", "memory")
        if engine not in ENGINES:
            raise ConfigError(f"{where}: engine must be one of {', '.join(ENGINES)} (got {engine!r})")
        record = head.get("record", "failed")
        if record not in RECORD:
            raise ConfigError(f"{where}: record must be one of {', '.join(RECORD)} (got {record!r})")
        seeds = head.get("seeds", 1)
        if isinstance(seeds, int) and not isinstance(seeds, bool) and seeds >= 1:
            check_grid_size({}, seeds, where)  # a count of seeds is a list of them: bounded before it is made
            seeds = list(range(seeds))
        if not (isinstance(seeds, list) and seeds and all(isinstance(s, int) and s >= 0 for s in seeds)):
            raise ConfigError(f"{where}: seeds must be a count N >= 1 (seeds 0..N-1) or a list of seeds")
        for k, v in grid.items():
            if not isinstance(v, list) or not v:
                raise ConfigError(f"{where}: [grid] {k} must be a non-empty list")
        check_grid_size(grid, len(seeds), where)
        replicates = head.get("replicates", [])
        if not (isinstance(replicates, list) and all(isinstance(k, str) and k in grid for k in replicates)):
            raise ConfigError(f"{where}: replicates must be a list of [grid] keys (got {replicates!r})")
        more = head.get("more", {})
        if not (isinstance(more, dict) and len(more) <= 1 and all(k in replicates and isinstance(v, list) and v
                                                                   for k, v in more.items())):
            raise ConfigError(f"{where}: more must be a table of one replicates key and the further values "
                              f"--until-decided may add (got {more!r})")
        name = head.get("name") or (path.stem if path else "study")
        study = cls(name=str(name), grid=dict(grid), seeds=list(seeds), fleet=dict(fleet), engine=engine,
                    record=record, baseline=head.get("baseline"), description=str(head.get("description", "")),
                    maps_hint=str(head.get("maps", "")), paper=dict(raw.get("paper", {})), path=path, text=text,
                    replicates=tuple(replicates), more=dict(more))
        paper = raw.get("paper", {})
        if not isinstance(paper, dict):
            raise ConfigError(f"{where}: [paper] must be a table")
        claims.parse(paper, where, grid)  # a bad claim fails now, not when the sweep is reported
        first = {k: v[0] for k, v in grid.items()}  # bad values fail now, each with the other keys' first
        extra = [first | {k: v} for k, values in more.items() for v in values]
        for params in [first, *(first | {k: v} for k, values in grid.items() for v in values[1:]), *extra]:
            study.scenario(params, seeds[0], resolve=False)
        return study

    def scenario(self, params: dict[str, Any], seed: int, maps_dir: Path | None = None,
                 resolve: bool = True, resolved: dict[str, str] | None = None) -> Scenario:
        """The scenario of one point: the defaults, ``[fleet]``, then the point's grid values (a radio setting
        flat, ``waf``, or in a ``radio`` table; the grid's win over ``[fleet]``'s, a flat name over its layer's
        table). ``resolved`` keeps the maps found so far (by name), so that a grid of many points looks each one
        up once; ``resolve=False`` leaves the map out (the study's checks before its maps are looked up)."""
        names = {s.name for s in radio_settings()}
        flat = {k: v for k, v in (self.fleet | params).items() if k not in names and k != "radio"}
        flat |= {"seed": seed, "radio": self._radio(params, names)}
        if "map" in flat and not resolve:
            del flat["map"]
        elif "map" in flat:
            memo = resolved if resolved is not None else {}
            name = str(flat["map"])
            if name not in memo:
                memo[name] = resolve_map(name, self, maps_dir)
            flat["map"] = memo[name]
        try:
            with file_spelling(self._keys(params, flat)):  # ``study s.toml: [grid] robots must be ...``
                s = Scenario().override(**flat)
        except ConfigError as exc:
            raise ConfigError(f"study {self.path or self.name}: {exc}") from None
        if resolve and not s.cell_size_given:
            from fleet_emu.world.maps import is_bare_bitmap, no_scale_error

            if is_bare_bitmap(s.map):
                raise ConfigError(f"study {self.name}: {no_scale_error(s.map)}")
        return s

    def _keys(self, params: dict[str, Any], flat: dict[str, Any]) -> dict[str, str]:
        """Where each value of a point came from, as the file writes it: ``[grid] robots``, ``[fleet] loss``,
        ``[grid] radio.waf`` (the grid's win over ``[fleet]``'s, a flat name over its layer's table)."""
        keys = {k: f"[{'grid' if k in params else 'fleet'}] {k}" for k in flat}
        for k in flat["radio"]:
            layer, table = next(((n, t) for n, t in (("grid", params), ("fleet", self.fleet))
                                 if k in t or k in (t.get("radio") or {})), ("fleet", self.fleet))
            keys[k] = f"[{layer}] {k}" if k in table else f"[{layer}] radio.{k}"
        return keys

    def _radio(self, params: dict[str, Any], names: set[str]) -> dict[str, Any]:
        """The radio settings of a point, layered: ``[fleet]``'s ``radio`` table, its flat names (``names``),
        then the grid's (each a table of radio settings, checked by :meth:`Scenario.override`)."""
        radio: dict[str, Any] = {}
        for layer, where in ((self.fleet, "[fleet]"), (params, "[grid]")):
            table = layer.get("radio", {})
            if not isinstance(table, dict):
                raise ConfigError(f"study {self.name}: {where} radio must be a table of radio settings "
                                  f"(got {table!r})")
            radio |= table
            radio |= {k: v for k, v in layer.items() if k in names}
        return radio

    def points(self, maps_dir: Path | None = None) -> list[Point]:
        """Every point of the grid, seeds innermost; a missing map is one ConfigError before any run."""
        keys = list(self.grid)
        out = []
        resolved: dict[str, str] = {}
        for values in itertools.product(*(self.grid[k] for k in keys)):
            params = dict(zip(keys, values, strict=True))
            for seed in self.seeds:
                s = self.scenario(params, seed, maps_dir, resolved=resolved)
                label = {k: param_label(v) for k, v in params.items()} | {"seed": seed}
                out.append(Point(point_id(params, seed), label, s.to_dict(), self.engine))
        return out


def check_grid_size(grid: dict[str, list[Any]], seeds: int, where: str) -> None:
    """A ConfigError, before any point is built, when the grid (every key's values times the seeds) holds more
    than :data:`MAX_POINTS` runs, saying how many: counted from the lists' lengths, never expanded."""
    runs = math.prod(len(v) for v in grid.values()) * seeds
    if runs > MAX_POINTS:
        sizes = " x ".join(f"{len(v)} {k}" for k, v in grid.items())
        raise ConfigError(f"{where}: its grid is {runs:,} runs ({sizes} x {seeds} seeds), more than the "
                          f"{MAX_POINTS:,} a sweep takes: split it into several studies")


def param_label(value: Any) -> Any:
    """A grid value as a column: an allocator table becomes ``minpos(wavefront=stop)``, a radio table
    ``comm=wall,waf=6.0``, a list of faults ``crash r0@30`` (``none`` when empty)."""
    if isinstance(value, list) and all(isinstance(f, dict) and "tick" in f for f in value):
        return " ".join(f"{f.get('kind', 'crash')} {_robot(f.get('robot'))}@{f['tick']}" for f in value) or "none"
    if isinstance(value, dict) and "type" in value:
        extra = ",".join(f"{k}={v}" for k, v in sorted(value.items()) if k != "type")
        return f"{value.get('type')}({extra})" if extra else str(value.get("type"))
    if isinstance(value, dict):  # a radio table: ``comm=wall,waf=6.0``
        return ",".join(f"{k}={v}" for k, v in sorted(value.items()))
    return value


def _robot(robot: Any) -> str:
    """A fault's robot as its id: ``r0`` for ``0``."""
    return f"r{robot}" if isinstance(robot, int) else str(robot)


def point_id(params: dict[str, Any], seed: int) -> str:
    """A stable id of a point (its grid values and seed), for resuming."""
    text = json.dumps({"params": params, "seed": seed}, sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def map_roots(study: Study, maps_dir: Path | None) -> Iterator[Path]:
    if study.path is not None:
        yield study.path.parent
    if maps_dir is not None:
        yield maps_dir
    if os.environ.get("FLEET_MAPS"):
        yield Path(os.environ["FLEET_MAPS"])
    yield Path.cwd()


def resolve_map(name: str, study: Study, maps_dir: Path | None) -> str:
    """A built-in map's name as is; a registry map's name as is once it is fetched; a path found under one of
    :func:`map_roots`, made absolute; else one line that says where to get it."""
    from fleet_emu.core.errors import MapError
    from fleet_emu.world.maps import BUILTIN_MAPS
    from fleet_emu.world.registry import local_map, registry

    if name in BUILTIN_MAPS:
        return name
    if name in registry():
        try:
            local_map(name)
        except MapError as exc:
            raise ConfigError(f"study {study.name}: {exc}") from None
        return name
    p = Path(name).expanduser()
    if p.is_absolute():
        if p.exists():
            return str(p)
    else:
        for root in map_roots(study, maps_dir):
            if (root / p).exists():
                return str((root / p).resolve())
    hint = f"; get it from {study.maps_hint}" if study.maps_hint else ""
    close = near(name, [*BUILTIN_MAPS, *registry()])  # a typo'd built-in or registry name
    raise ConfigError(f"study {study.name}: map {name} not found{close} (pass --maps DIR or set FLEET_MAPS to the "
                      f"folder that holds it){hint}")


def shipped() -> dict[str, str]:
    """The studies shipped in the package: name -> description."""
    out = {}
    for p in sorted(STUDIES.glob("*.toml"), key=lambda p: p.stem):
        head = tomllib.loads(p.read_text()).get("study", {})
        out[p.stem] = str(head.get("description", ""))
    return out
