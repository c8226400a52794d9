"""The fleet's bus messages as ROS 2 messages: a pure fold (no I/O, no clock of its own) that the live bridge
(:mod:`.bridge`) and the rosbag2 export (:mod:`.export`) share, so both carry the same topics:

==================  ===============================  ===========================================================
topic               type                             when
==================  ===============================  ===========================================================
``/clock``          ``rosgraph_msgs/Clock``          every world state (the run's clock: ``use_sim_time``)
``/tf``             ``tf2_msgs/TFMessage``           every world state: ``map`` -> ``<robot>/base_link``
``/<robot>/pose``   ``geometry_msgs/PoseStamped``    every world state (its true cell's centre)
``/<robot>/goal``   ``geometry_msgs/PoseStamped``    when its command's target changes
``/<robot>/path``   ``nav_msgs/Path``                every ``grid_every`` ticks: the cells it walked
``/<robot>/map``    ``nav_msgs/OccupancyGrid``       each belief snapshot (every ``belief_every`` ticks)
``/map``            ``nav_msgs/OccupancyGrid``       once (the true map)
``/coverage``       ``nav_msgs/OccupancyGrid``       every ``grid_every`` ticks: what the team has sensed
``/links``          ``visualization_msgs/MarkerArray``  every tick's links: one ``LINE_LIST`` of the radio links
==================  ===============================  ===========================================================

Frames: everything in ``map``, x to the right (columns) and y up, as the Foxglove channels
(:mod:`fleet_emu.recording.foxglove`): cell ``(row, col)`` has its centre at ``((col + .5) * cell_size,
(rows - row - .5) * cell_size)``, so a grid's data is the map's rows bottom-up, origin ``(0, 0)``. Occupancy is the
fleet's own coding, which is ROS's: -1 unknown, 0 free, 100 occupied. The grids are latched (``latched``: transient
local on the bus, so a late rviz2 gets the last one).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from fleet_emu.core.keys import robot_ids
from fleet_emu.core.messages import BeliefSnapshot, Command, Links, Message, Observation, WorldState
from fleet_emu.recording.clock import EPOCH, RunClock
from fleet_emu.recording.first_seen import FirstSeen, fold_team
from fleet_emu.ros2.types import CLOCK, GRID, MARKERS, PATH, POSE, TF, make

FRAME = "map"
LINE_LIST, ADD = 5, 0  # visualization_msgs/Marker's type and action


@dataclasses.dataclass(frozen=True)
class Out:
    """One ROS 2 message of the fold: its topic, type, the message (a rosbags object) and tick; ``latched``:
    published transient local."""

    topic: str
    typename: str
    msg: Any
    tick: int
    latched: bool = False


def topics(robots: int) -> dict[str, tuple[str, bool]]:
    """Every topic of a run of ``robots`` robots: its type and whether it is latched (transient local)."""
    out = {"/clock": (CLOCK, False), "/tf": (TF, False), "/map": (GRID, True), "/coverage": (GRID, True),
           "/links": (MARKERS, False)}
    for r in robot_ids(robots):
        out |= {f"/{r}/pose": (POSE, False), f"/{r}/goal": (POSE, False), f"/{r}/path": (PATH, False),
                f"/{r}/map": (GRID, True)}
    return out


class Ros2Fold:
    """Bus messages in, :class:`Out` messages out (see the module doc): a fold fed messages (:meth:`fold`;
    ``core/fold.py``)."""

    def __init__(self, scenario: dict[str, Any], truth: np.ndarray | None = None, grid_every: int | None = None,
                 clock: RunClock = EPOCH) -> None:
        self.robots = tuple(robot_ids(scenario["robots"]))
        self.cell_size = float(scenario["cell_size"])
        self.grid_every = max(1, int(grid_every or scenario.get("belief_every") or 10))
        self.clock = clock
        self.truth = None if truth is None else np.asarray(truth, dtype=np.int8)
        self.shape: tuple[int, int] | None = None if self.truth is None else \
            (int(self.truth.shape[0]), int(self.truth.shape[1]))
        self.coverage: FirstSeen | None = None
        self.poses: dict[str, tuple[int, int]] = {}
        self.paths: dict[str, list[Any]] = {r: [] for r in self.robots}
        self.targets: dict[str, tuple[int, int] | None] = {}
        self.truth_sent = False
        self.last_tick = -1
        self.threshold = float(scenario.get("radio", {}).get("threshold", 0.0))

    def fold(self, msg: Message) -> list[Out]:
        """One decoded, checked message in; the ROS 2 messages it gives (a ``MessageFold``, ``core/fold.py``)."""
        if isinstance(msg, WorldState) and msg.src == "world":
            return self._state(msg)
        if isinstance(msg, Observation):
            self._observe(msg)
        elif isinstance(msg, Command):
            return self._goal(msg)
        elif isinstance(msg, BeliefSnapshot) and msg.src in self.robots:
            return [Out(f"/{msg.src}/map", GRID, self.grid(msg.grid, msg.tick), msg.tick, True)]
        elif isinstance(msg, Links) and msg.src == "netem":
            return [Out("/links", MARKERS, self._links(msg), msg.tick)]
        return []

    def finish(self) -> list[Out]:
        """The last paths and coverage (a run rarely ends on a multiple of ``grid_every``)."""
        return self._every(self.last_tick) if self.last_tick >= 0 else []

    # --- message builders ---------------------------------------------------------------------------------

    def header(self, tick: int, frame: str = FRAME) -> Any:
        ns = self.clock.ns(tick)
        return make("std_msgs/msg/Header", stamp=self.time(ns), frame_id=frame)

    @staticmethod
    def time(ns: int) -> Any:
        return make("builtin_interfaces/msg/Time", sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def xy(self, cell: tuple[int, int]) -> tuple[float, float]:
        rows = self.shape[0] if self.shape else 0
        return (cell[1] + 0.5) * self.cell_size, (rows - cell[0] - 0.5) * self.cell_size

    def pose(self, cell: tuple[int, int], tick: int) -> Any:
        x, y = self.xy(cell)
        return make(POSE, header=self.header(tick), pose=make(
            "geometry_msgs/msg/Pose", position=make("geometry_msgs/msg/Point", x=x, y=y, z=0.0),
            orientation=make("geometry_msgs/msg/Quaternion", w=1.0)))

    def grid(self, values: np.ndarray, tick: int) -> Any:
        """An OccupancyGrid of a map-shaped grid (rows top-down) in frame ``map``: rows bottom-up, origin 0."""
        rows, cols = values.shape
        info = make("nav_msgs/msg/MapMetaData", map_load_time=self.time(self.clock.ns(tick)),
                    resolution=self.cell_size, width=cols, height=rows,
                    origin=make("geometry_msgs/msg/Pose", orientation=make("geometry_msgs/msg/Quaternion", w=1.0)))
        data = np.ascontiguousarray(np.flipud(np.asarray(values, dtype=np.int8))).reshape(-1)
        return make(GRID, header=self.header(tick), info=info, data=data)

    # --- folds ----------------------------------------------------------------------------------------------

    def _observe(self, o: Observation) -> None:
        self.coverage = fold_team(self.coverage, self.shape, o)
        self.shape = self.coverage.shape

    def _state(self, st: WorldState) -> list[Out]:
        t = st.tick
        self.last_tick = max(self.last_tick, t)
        out = [Out("/clock", CLOCK, make(CLOCK, clock=self.time(self.clock.ns(t))), t)]
        if self.truth is not None and not self.truth_sent:
            self.truth_sent = True
            out.append(Out("/map", GRID, self.grid(self.truth, t), t, True))
        transforms = []
        for r in self.robots:
            cell = st.poses.get(r)
            if cell is None:
                continue
            self.poses[r] = (int(cell[0]), int(cell[1]))
            pose = self.pose(cell, t)
            self.paths[r].append(pose)
            out.append(Out(f"/{r}/pose", POSE, pose, t))
            x, y = self.xy(cell)
            transforms.append(make(
                "geometry_msgs/msg/TransformStamped", header=self.header(t), child_frame_id=f"{r}/base_link",
                transform=make("geometry_msgs/msg/Transform",
                               translation=make("geometry_msgs/msg/Vector3", x=x, y=y, z=0.0),
                               rotation=make("geometry_msgs/msg/Quaternion", w=1.0))))
        out.append(Out("/tf", TF, make(TF, transforms=transforms), t))
        if t % self.grid_every == 0:
            out += self._every(t)
        return out

    def _every(self, t: int) -> list[Out]:
        """The paths walked so far and the team's coverage, at tick ``t``."""
        out = [Out(f"/{r}/path", PATH, make(PATH, header=self.header(t), poses=list(self.paths[r])), t)
               for r in self.robots if self.paths[r]]
        if self.coverage is not None:
            out.append(Out("/coverage", GRID, self.grid(self.coverage.grid(t), t), t, True))
        return out

    def _goal(self, c: Command) -> list[Out]:
        if c.src not in self.robots or c.target is None or self.targets.get(c.src) == c.target:
            return []
        self.targets[c.src] = c.target
        return [Out(f"/{c.src}/goal", POSE, self.pose(c.target, c.tick), c.tick)]

    def _links(self, lk: Links) -> Any:
        """One LINE_LIST marker of the tick's radio links (either way) between robots with a known pose,
        coloured as the Foxglove scene's: red at the radio's threshold to green 20 dB above it."""
        link = np.asarray(lk.link, dtype=bool)
        strength = np.asarray(lk.strength, dtype=float)
        points, colors = [], []
        for i, a in enumerate(lk.robots):
            for j in range(i + 1, len(lk.robots)):
                b = lk.robots[j]
                if not (link[i, j] or link[j, i]) or a not in self.poses or b not in self.poses:
                    continue
                p = max(strength[i, j], strength[j, i])
                s = float(np.clip(((p if np.isfinite(p) else self.threshold) - self.threshold) / 20.0, 0.0, 1.0))
                for r in (a, b):
                    x, y = self.xy(self.poses[r])
                    points.append(make("geometry_msgs/msg/Point", x=x, y=y, z=0.5 * self.cell_size))
                    colors.append(make("std_msgs/msg/ColorRGBA", r=1.0 - s, g=s, b=0.2, a=0.9))
        marker = make("visualization_msgs/msg/Marker", header=self.header(lk.tick), ns="links", id=0,
                      type=LINE_LIST, action=ADD, pose=make("geometry_msgs/msg/Pose",
                                                            orientation=make("geometry_msgs/msg/Quaternion", w=1.0)),
                      scale=make("geometry_msgs/msg/Vector3", x=0.1 * self.cell_size),
                      color=make("std_msgs/msg/ColorRGBA", r=0.2, g=0.9, b=0.2, a=0.9),
                      points=points, colors=colors)
        return make(MARKERS, markers=[marker])
