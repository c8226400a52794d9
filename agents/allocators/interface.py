"""The allocator interface: a :class:`Problem` in, a typed :class:`Allocation` out, a registry by name.

An allocator is a pure function of (belief grid, frontier clusters, wavefront distances, known teammate poses,
its own protocol state). It never touches Zenoh, clocks or files; radio messages it wants to send go out in
``Allocation.outbox`` and the ones addressed to it come back through ``inbox``. Building one by name, with
installed plugins, is :mod:`.registry`'s.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import operator
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from fleet_emu.agents.allocators.params import Param, check_params
from fleet_emu.agents.frontiers import Cluster
from fleet_emu.core.grid import FREE, Cell
from fleet_emu.core.kernels import wavefront
from fleet_emu.core.messages import RadioMsg
from fleet_emu.core.scenario import Scenario

INF = np.inf


class AllocStatus(enum.Enum):
    """What an allocation says: a cluster was assigned, there is no reachable frontier, or the robot waits
    (a protocol round is under way); a planner's orders (``mhm``) add ``GOAL``, drive to a given cell (not a
    frontier cluster's) over ``Allocation.passable``, and ``HOLD``, stay (a relay node, or a robot without a
    usable order)."""

    ASSIGNED = "assigned"
    NO_FRONTIER = "no_frontier"
    WAITING = "waiting"
    GOAL = "goal"
    HOLD = "hold"


@dataclasses.dataclass(frozen=True)
class Allocation:
    """The result of one call: ``cluster`` indexes ``Problem.clusters``; ``target`` is that cluster's target
    (with ``GOAL``, the goal cell itself). ``passable`` (``GOAL`` only) restricts the cells navigation and
    unsticking may use (None: every known-free cell); ``routes`` (not None) are new relay routes for the
    robot's ``tree`` relaying (``agents/relay.py``), a parent map."""

    status: AllocStatus
    cluster: int | None = None
    target: Cell | None = None
    outbox: tuple[RadioMsg, ...] = ()
    passable: np.ndarray | None = dataclasses.field(default=None, compare=False, repr=False)
    routes: Mapping[str, str] | None = None

    @staticmethod
    def assigned(problem: Problem, j: int, outbox: tuple[RadioMsg, ...] = ()) -> Allocation:
        return Allocation(AllocStatus.ASSIGNED, j, problem.clusters[j].target, outbox)

    @staticmethod
    def none(outbox: tuple[RadioMsg, ...] = ()) -> Allocation:
        return Allocation(AllocStatus.NO_FRONTIER, None, None, outbox)

    @staticmethod
    def goal(cell: Cell, passable: np.ndarray | None = None, routes: Mapping[str, str] | None = None) -> Allocation:
        """Drive to ``cell`` over ``passable`` cells."""
        return Allocation(AllocStatus.GOAL, None, cell, passable=passable, routes=routes)

    @staticmethod
    def hold(routes: Mapping[str, str] | None = None) -> Allocation:
        """Stay where it stands."""
        return Allocation(AllocStatus.HOLD, routes=routes)


@dataclasses.dataclass
class Problem:
    """One robot's view at one tick. ``poses`` holds the robot's own cell and its teammates' last known
    cells (sorted by robot id). ``previous_target`` is the target of the robot's previous decision (its last
    command's), None at the first or after one that assigned nothing: the Brain passes it, so that an allocator
    that keeps its target (``replan="observed"``) stays a pure function of the problem. ``obstacles``: flat
    indices of cells that are free in the belief but hold a robot's body the robot takes for a wreck
    (``agents/bodies.py``): no wavefront crosses them. Wavefronts and the cost matrix are computed lazily, so
    that an allocator that needs less (MinPos with stopping) pays less, and the decision time measures what it
    used."""

    me: str
    poses: dict[str, Cell]
    belief: np.ndarray
    clusters: list[Cluster]
    tick: int = 0
    heard: dict[str, int] = dataclasses.field(default_factory=dict)
    previous_target: Cell | None = None
    obstacles: frozenset[int] = frozenset()

    def __post_init__(self) -> None:
        self.poses = dict(sorted(self.poses.items(), key=lambda kv: robot_order(kv[0])))

    @property
    def robots(self) -> list[str]:
        """Every robot with a known pose, the deciding one included, in id order."""
        return list(self.poses)

    @property
    def index(self) -> int:
        """Row of the deciding robot in :attr:`costs`."""
        return self.robots.index(self.me)

    @functools.cached_property
    def passable(self) -> np.ndarray:
        """Known-free cells, less the :attr:`obstacles`: the only ones a wavefront crosses."""
        passable = self.belief == FREE
        if self.obstacles:
            passable.reshape(-1)[np.fromiter(self.obstacles, dtype=np.int64, count=len(self.obstacles))] = False
        return passable

    @functools.cached_property
    def wavefronts(self) -> list[np.ndarray]:
        """BFS distance from each cluster's cells over known-free cells (MinPos section 4.2); -1 unreached."""
        return [wavefront(self.passable, c.cells.astype(np.int64), -1) for c in self.clusters]

    def wavefront_to(self, j: int, stop: Cell | None = None) -> np.ndarray:
        """Cluster ``j``'s wavefront: :attr:`wavefronts`'s when they were computed, else this one alone, ended
        once ``stop`` has its distance (section 4.3's stopping). Then every cell nearer the cluster than
        ``stop`` has its distance too, which is all that descending the gradient from ``stop`` reads."""
        if "wavefronts" in self.__dict__:
            return self.wavefronts[j]
        at = -1 if stop is None else stop[0] * self.belief.shape[1] + stop[1]
        return wavefront(self.passable, self.clusters[j].cells.astype(np.int64), at)

    @functools.cached_property
    def costs(self) -> np.ndarray:
        """The cost matrix C (robots x clusters): wavefront distance, ``inf`` where unreachable."""
        c = np.full((len(self.poses), len(self.clusters)), INF)
        for j, wf in enumerate(self.wavefronts):
            for i, cell in enumerate(self.poses.values()):
                d = wf[cell]
                if d >= 0:
                    c[i, j] = d
        return c


@functools.lru_cache(maxsize=4096)
def robot_order(robot: str) -> tuple[int, str]:
    """Sort key of robot ids: ``r2`` before ``r10``; anything else (``base``) after, by name. Kept per id:
    every decision sorts every teammate's pose by it."""
    return (int(robot[1:]), "") if robot[:1] == "r" and robot[1:].isdigit() else (1 << 30, robot)


class Allocator:
    """Base class: subclasses register with ``class X(Allocator, plugin_name="x")`` and implement
    :meth:`allocate`.

    ``parameters`` declares each keyword parameter (:class:`Param`: default, type, range); the base
    ``__init__`` checks the given values against it (ConfigError otherwise) and sets them as attributes, and
    :meth:`to_dict` gives them back in the scenario's shape ``{"type": name, **params}``. ``scenario_fields``
    maps a parameter to the :class:`~core.scenario.Scenario` attribute it defaults to in a run (a dotted
    path: ``"radio.comm_range"``, ``"cell_size"``, ``"sensor_cells"``); a value the scenario's
    ``[allocator]`` sets wins. ``DESCRIPTION`` is the one line ``fleet allocators`` prints (else the first line
    of the class docstring)."""

    DESCRIPTION: ClassVar[str] = ""
    plugin_name: ClassVar[str] = ""
    registry: ClassVar[dict[str, type[Allocator]]] = {}
    parameters: ClassVar[dict[str, Param]] = {}
    scenario_fields: ClassVar[dict[str, str]] = {}

    def __init_subclass__(cls, plugin_name: str = "", **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if plugin_name:
            cls.register(plugin_name)

    @classmethod
    def register(cls, name: str) -> None:
        """Enter the class in the registry under ``name``; TypeError when the name is taken or the
        declarations are inconsistent (a default out of its own range, a scenario field that is not a
        parameter or not an attribute of a Scenario)."""
        if name in Allocator.registry:
            raise TypeError(f"allocator {name!r} registered twice")
        for param, spec in cls.parameters.items():
            refused = spec.refusal(spec.default)
            if refused is not None:
                raise TypeError(f"allocator {name!r}: default of {param} {refused}")
        for param, field in cls.scenario_fields.items():
            if param not in cls.parameters:
                raise TypeError(f"allocator {name!r}: scenario field for {param!r}, which is not a parameter")
            try:
                operator.attrgetter(field)(Scenario())
            except AttributeError:
                raise TypeError(f"allocator {name!r}: {field!r} is not a scenario field") from None
        cls.plugin_name = name
        Allocator.registry[name] = cls

    @classmethod
    def summary(cls) -> str:
        """What the allocator does, in one line: ``DESCRIPTION``, or the first line of the class's own docstring."""
        doc = (cls.__dict__.get("__doc__") or "").strip()
        return cls.DESCRIPTION or (doc.splitlines()[0] if doc else "")

    def __init__(self, **params: Any) -> None:
        for name, value in check_params(self.plugin_name, self.parameters, params).items():
            setattr(self, name, value)
        self.rng = np.random.default_rng(0)

    def params(self) -> dict[str, Any]:
        """The allocator's parameters, as checked."""
        return {name: getattr(self, name) for name in self.parameters}

    def to_dict(self) -> dict[str, Any]:
        return {"type": self.plugin_name, **self.params()}

    def reset(self, rng: np.random.Generator) -> None:
        """Start afresh; every random draw comes from ``rng``."""
        self.rng = rng

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        raise NotImplementedError
