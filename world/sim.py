"""Ground truth: the map, true poses, the 360-degree range sensor, motion, coverage and the end of the run.

A plain simulation with no I/O; :mod:`world.node` drives it over Zenoh. Tick ``t``: :meth:`World.reset`
gives the readings of tick 0, and each :meth:`World.step` applies the robots' moves and gives the next
tick's readings.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.grid import FREE, MOVES, OCCUPIED, STAY, Cell, MapData, flat, nearest_cells
from fleet_emu.core.kernels import visible_cells, wavefront


class StartAreaError(ConfigError):
    """More robots than the free area reachable from the start holds, or bad explicit start cells (one line
    for the user)."""


#: The belief stall window in diameters of the map: a robot may cross the known map twice to reach a frontier
#: without learning anything on its way.
STALL_DIAMETERS = 2


def diamond_cells(radius: int) -> int:
    """Cells within ``radius`` 4-connected steps of a cell on an open grid: 2r(r + 1) + 1."""
    return 2 * radius * (radius + 1) + 1


@dataclasses.dataclass(frozen=True)
class WorldConfig:
    """``sensor_range`` in cells; the fleet is placed on the free cells nearest the start cell (BFS distance,
    then row-major), as many as it has robots: a fleet of any size that the start's free component holds;
    ``start_radius``: the BFS distance a ``"random"`` start must hold the fleet within (grown, for fleets larger
    than its open diamond of :func:`diamond_cells` cells, to the least radius whose diamond holds them), so that
    the fleet starts packed; ``placement``: explicit start cells instead, one per robot in robot order (the
    start cell is then the first, unless ``start`` is a cell); ``stall_ticks``: ticks without any move or new
    sensed cell that end the run;
    ``coverage_stall_ticks``: the least stall window of the belief rule: ticks in which no robot's own belief
    gained a known cell end the run, whatever the robots do (robots that keep moving back and forth stall too),
    once there are :attr:`World.stall_window` of them in a row: this or :data:`STALL_DIAMETERS` times the map's
    diameter in cells, whichever is larger;
    ``start``: a cell, ``"random"`` (a cell drawn from the world's generator where the robots fit, in the map's
    main free component), or None for the map's own start;
    ``crashes``: (robot, tick) of the scenario's crash faults (``core/faults.py``): the robot leaves the run at
    that tick, before its readings, as a robot whose process died does; its body stays where it stood."""

    sensor_range: float = 8.0
    target_coverage: float = 0.99
    max_ticks: int = 2000
    stall_ticks: int = 30
    coverage_stall_ticks: int = 500
    start: Cell | str | None = None
    start_radius: int = 4
    placement: tuple[Cell, ...] | None = None
    crashes: tuple[tuple[str, int], ...] = ()


@dataclasses.dataclass(frozen=True)
class Reading:
    """What one robot's sensor returned: its true cell, the flat indices and true map values it saw, and the
    cells among them that hold another robot's body (a teammate's or a failed robot's): a body is reported to
    the sensor, never written into the map, so that one that moves on frees its cell."""

    cell: Cell
    cells: np.ndarray
    values: np.ndarray
    bodies: np.ndarray


class World:
    """The simulation of one run."""

    def __init__(self, map_data: MapData, robots: list[str], config: WorldConfig,
                 rng: np.random.Generator | None = None) -> None:
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.map = map_data
        self.grid = map_data.grid
        self.occupied = self.grid == OCCUPIED
        self.robots = list(robots)
        self.config = config
        self.start: Cell = map_data.start if not isinstance(config.start, tuple) else config.start
        self.tick = 0
        self.poses: dict[str, Cell] = {}
        self.live: list[str] = []
        self.path_length: dict[str, int] = {}
        self.done = False
        self.reason: str | None = None
        self.coverage = 0.0
        self.blocked: dict[str, int] = {}

    @property
    def shape(self) -> tuple[int, int]:
        return self.grid.shape

    @property
    def sensed_cells(self) -> int:
        """Cells of the map, free or occupied, that some robot's sensor has returned so far (the team's
        "total visibility" of Mukhija et al. Fig. 7); 0 before :meth:`reset`."""
        sensed = getattr(self, "_sensed", None)
        return int(sensed.sum()) if sensed is not None else 0

    def start_cells(self, n: int | None = None, radius: int | None = None) -> list[Cell]:
        """The ``n`` free cells nearest the start (all of them without ``n``; only those within ``radius`` BFS
        steps with it), nearest first: BFS distance, then row-major, so deterministic. The first ``n`` of
        this order do not depend on ``n``: a fleet that fits a smaller area is placed the same way."""
        s = self.start
        if not (0 <= s[0] < self.shape[0] and 0 <= s[1] < self.shape[1]) or self.grid[s] != FREE:
            raise StartAreaError(f"start cell {tuple(s)} is not a free cell of the map")
        area = nearest_cells(~self.occupied, self.grid == FREE, flat(self.shape, s), n, radius)
        return [(int(i) // self.shape[1], int(i) % self.shape[1]) for i in area]

    def place(self) -> list[Cell]:
        """The robots' start cells (the explicit ones checked, or the free cells nearest the start, drawn first
        for a ``random`` start): what :meth:`reset` does first, without sensing, so that a launcher checks a
        scenario without running a compiled kernel. A :class:`StartAreaError` when the fleet does not fit."""
        if self.config.placement is not None:
            return self._placement()
        if self.config.start == "random":
            self.start = self._random_start()
        cells = self.start_cells(len(self.robots))
        if len(self.robots) > len(cells):
            raise StartAreaError(
                f"{len(self.robots)} robots do not fit the free area reachable from the start cell "
                f"{tuple(self.start)} of map {self.map.name!r}: it has {len(cells)} free cells")
        return cells

    def reset(self, failed: frozenset[str] | set[str] = frozenset()) -> dict[str, Reading]:
        """Place the robots around the start (or on ``placement``) and sense; the readings of tick 0. Robots in
        ``failed`` (their process died before the first tick) are placed but neither sense nor act."""
        cells = self.place()
        self.tick = 0
        self.poses = dict(zip(self.robots, cells, strict=True))
        crashed = {r for r, t in self.config.crashes if t <= 0}
        self.live = [r for r in self.robots if r not in failed and r not in crashed]
        self.path_length = {r: 0 for r in self.robots}
        self.done, self.reason = False, None
        self.blocked = {}
        dist = wavefront(~self.occupied, np.array([flat(self.shape, self.start)], np.int64), -1)
        self._reachable = (dist >= 0) & (self.grid == FREE)
        self._total = int(self._reachable.sum())
        self.diameter = self._diameter(dist)
        self.stall_window = max(self.config.coverage_stall_ticks, STALL_DIAMETERS * self.diameter)
        self._sensed = np.zeros(self.shape, dtype=bool)
        self._body = np.zeros(self.grid.size, dtype=bool)
        self._idle = 0
        self._known: dict[str, int] = {}  # each robot's most known cells so far (its commands' ``known``)
        self._quiet = 0  # ticks since some robot's belief last gained a cell
        readings = self._sense()
        self._check_end(progress=True)
        return readings

    def _diameter(self, dist: np.ndarray) -> int:
        """The map's diameter in cells: the longest shortest path (4-connected steps) between two free cells
        reachable from the start, from ``dist`` (the start's distances) by a second sweep from the farthest
        cell (exact where the free space is a tree, as a perfect maze's is; at least half of it always)."""
        if not self._total:
            return 0
        far = int(np.argmax(np.where(self._reachable, dist, -1)))
        return int(wavefront(~self.occupied, np.array([far], np.int64), -1)[self._reachable].max())

    def _placement(self) -> list[Cell]:
        """The explicit start cells, checked: one per robot, distinct, each a free cell of the map."""
        cells = [(int(c[0]), int(c[1])) for c in self.config.placement or ()]
        if len(cells) != len(self.robots):
            raise StartAreaError(f"{len(cells)} start cells given for {len(self.robots)} robots")
        if len(set(cells)) != len(cells):
            raise StartAreaError("two robots are given the same start cell")
        for c in cells:
            if not (0 <= c[0] < self.shape[0] and 0 <= c[1] < self.shape[1]) or self.grid[c] != FREE:
                raise StartAreaError(f"start cell {c} is not a free cell of the map")
        if self.config.start == "random":
            raise StartAreaError("explicit start cells and a random start exclude each other")
        if not isinstance(self.config.start, tuple):
            self.start = cells[0]
        return cells

    def _random_start(self) -> Cell:
        """A start cell drawn from the world's generator: a free cell of the map's main component (the one
        holding its own start) with every robot's cell within the start radius (grown for fleets larger than
        its diamond); the map's start if no draw fits."""
        n = len(self.robots)
        radius = self.config.start_radius
        while diamond_cells(radius) < n:
            radius += 1
        candidates = np.sort(nearest_cells(~self.occupied, self.grid == FREE, flat(self.shape, self.map.start)))
        for k in self.rng.permutation(len(candidates))[:200]:
            cell = (int(candidates[k]) // self.shape[1], int(candidates[k]) % self.shape[1])
            self.start = cell
            if len(self.start_cells(n, radius)) >= n:
                return cell
        return self.map.start

    def fail(self, robot: str) -> None:
        """A robot that stopped answering leaves the run (its body stays where it stopped)."""
        if robot in self.live:
            self.live.remove(robot)
            if not self.live and not self.done:
                self.done, self.reason = True, "no_robots"

    def step(self, moves: dict[str, Cell], known: dict[str, int] | None = None) -> dict[str, Reading]:
        """Apply the moves of the live robots, advance to the next tick, sense; the readings of that tick.
        ``known``: the cells each robot's belief held after its decision (its command's ``known``), for the
        stall rule; without it (a World stepped alone), the cells the fleet sensed stand for them.

        A robot cannot enter a wall, leave the grid, or enter a cell another robot holds. Conflicts are
        resolved in passes in robot order: a move goes through when its target is free of every robot's
        current cell; passes repeat until nothing changes, so a line of robots can advance together, and
        two robots never swap or meet.
        """
        pending = {r: moves[r] for r in self.live if moves.get(r, STAY) != STAY and moves[r] in MOVES}
        held = set(self.poses.values())
        moved = False
        changed = True
        while changed and pending:
            changed = False
            for r in list(pending):
                dr, dc = pending[r]
                cur = self.poses[r]
                nxt = (cur[0] + dr, cur[1] + dc)
                if not (0 <= nxt[0] < self.shape[0] and 0 <= nxt[1] < self.shape[1]) or self.occupied[nxt]:
                    del pending[r]
                    continue
                if nxt in held:
                    continue
                held.discard(cur)
                held.add(nxt)
                self.poses[r] = nxt
                self.path_length[r] += 1
                del pending[r]
                changed = moved = True
        self.tick += 1
        for r, t in self.config.crashes:  # a crash: the robot misses this tick and every one after
            if t == self.tick:
                self.fail(r)
        before = int(self._sensed.sum())
        readings = self._sense()
        sensed = int(self._sensed.sum()) > before
        self._quiet = 0 if (self._learned(known) if known is not None else sensed) else self._quiet + 1
        self._check_end(progress=moved or sensed)
        return readings

    def _learned(self, known: dict[str, int]) -> bool:
        """Whether some robot's belief holds more cells than it ever did (``known``: their counts now)."""
        grew = False
        for r, k in known.items():
            if k > self._known.get(r, 0):
                self._known[r] = k
                grew = True
        return grew

    def _sense(self) -> dict[str, Reading]:
        out: dict[str, Reading] = {}
        flat_grid = self.grid.ravel()
        sensed = self._sensed.ravel()
        body = self._body  # every robot's cell, live or failed, for this call (kept all False between calls)
        held = [c[0] * self.shape[1] + c[1] for c in self.poses.values()]
        body[held] = True
        for r in self.live:
            cell = self.poses[r]
            cells = visible_cells(self.occupied, cell[0], cell[1], self.config.sensor_range)
            sensed[cells] = True
            near = cells[body[cells]]
            bodies = near[near != cell[0] * self.shape[1] + cell[1]].astype(np.int32)
            out[r] = Reading(cell=cell, cells=cells.astype(np.int32), values=flat_grid[cells].copy(), bodies=bodies)
        body[held] = False
        self.coverage = float((self._sensed & self._reachable).sum() / self._total) if self._total else 1.0
        return out

    def _check_end(self, progress: bool) -> None:
        self._idle = 0 if progress else self._idle + 1
        if self.done:
            return
        if self.coverage >= self.config.target_coverage:
            self.done, self.reason = True, "coverage"
        elif not self.live:
            self.done, self.reason = True, "no_robots"
        elif self.tick >= self.config.max_ticks:
            self.done, self.reason = True, "max_ticks"
        elif self._idle >= self.config.stall_ticks or self._quiet >= self.stall_window:
            self.done, self.reason = True, "stall"
        if self.done and self.reason in ("max_ticks", "stall"):
            self.blocked = self.blocking()

    def blocking(self) -> dict[str, int]:
        """The failed robots whose bodies cut the live robots off from cells still to sense (free cells
        reachable from the start that no sensor returned yet), each with how many cells it alone holds off: with
        the failed bodies as walls, the cells the live robots reach when that body is gone. When no single body
        frees a cell but all of them together do (two in one corridor), each body the live robots then reach is
        named with the cells they free together. Empty when nothing is cut off."""
        failed = [r for r in self.robots if r not in self.live]
        missing = self._reachable & ~self._sensed
        if not failed or not self.live or not missing.any():
            return {}
        walls = self.occupied.copy()
        for r in failed:
            walls[self.poses[r]] = True
        sources = np.array([flat(self.shape, self.poses[r]) for r in self.live], np.int64)
        reached = wavefront(~walls, sources, -1) >= 0
        out: dict[str, int] = {}
        for r in failed:
            walls[self.poses[r]] = self.occupied[self.poses[r]]
            freed = int(((wavefront(~walls, sources, -1) >= 0) & missing & ~reached).sum())
            walls[self.poses[r]] = True
            if freed:
                out[r] = freed
        if not out:
            every = wavefront(~self.occupied, sources, -1) >= 0
            freed = int((every & missing & ~reached).sum())
            out = {r: freed for r in failed if freed and every[self.poses[r]]}
        return out
