"""Every message on the bus, defined once (DESIGN.md "Messages").

Barrier messages (world -> agents, netem -> agents, agents -> world/netem) and radio messages carried inside
tx/rx bundles. Encode with ``msg.encode()``; decode with :func:`core.codec.decode`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from fleet_emu.core.codec import Context, DecodeError, Message, decode, peek_tick
from fleet_emu.core.grid import MOVES, Cell

__all__ = [
    "Context", "DecodeError", "Message", "decode", "peek_tick",
    "Observation", "WorldState", "Command", "RadioMsg", "PoseBeacon", "MapDelta",
    "TxBundle", "RxBundle", "Links", "Hello", "Ready", "Failed", "Stop", "AgentReport", "BeliefSnapshot",
    "Assignment", "TradeNumber", "TradePurchase", "TradeAllocation", "TradeDone",
]

VALID_CELL_VALUES = np.array([-1, 0, 100], dtype=np.int8)
VALID_MOVES = frozenset(MOVES) | {(0, 0)}


def _check_cells(cells: np.ndarray, values: np.ndarray, shape: tuple[int, int] | None, what: str) -> None:
    if cells.ndim != 1 or values.ndim != 1 or len(cells) != len(values):
        raise DecodeError(f"{what}: cells and values differ in length")
    if cells.dtype.kind not in "iu" or values.dtype != np.int8:
        raise DecodeError(f"{what}: wrong dtypes")
    if len(cells) and (cells.min() < 0 or (shape is not None and cells.max() >= shape[0] * shape[1])):
        raise DecodeError(f"{what}: cell index out of range")
    if len(values) and not np.isin(values, VALID_CELL_VALUES).all():
        raise DecodeError(f"{what}: cell value not in (-1, 0, 100)")


def _check_cell(cell: Cell, shape: tuple[int, int] | None, what: str) -> None:
    if shape is not None and not (0 <= cell[0] < shape[0] and 0 <= cell[1] < shape[1]):
        raise DecodeError(f"{what}: cell {cell} outside the grid")


# --- world -> agent ---------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Observation(Message):
    """What one robot's sensor saw at ``tick``, and its true pose (world/obs/<robot>)."""

    KIND = "obs"
    robot: str
    cell: Cell
    shape: Cell
    cell_size: float
    cells: np.ndarray
    values: np.ndarray

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if self.shape[0] <= 0 or self.shape[1] <= 0 or self.cell_size <= 0:
            raise DecodeError("obs: bad grid shape or cell size")
        _check_cell(self.cell, self.shape, "obs")
        _check_cells(self.cells, self.values, self.shape, "obs")


@dataclasses.dataclass(frozen=True)
class WorldState(Message):
    """All true poses, coverage and the run's status at ``tick`` (world/state)."""

    KIND = "state"
    poses: dict[str, Cell]
    live: tuple[str, ...]
    coverage: float
    path_length: dict[str, int]
    done: bool = False
    reason: str | None = None


# --- agent -> world -----------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Command(Message):
    """A robot's move for ``tick`` (robot/<robot>/cmd), with what it decided, for the record."""

    KIND = "cmd"
    move: Cell
    target: Cell | None = None
    status: str = ""
    decision_ms: float = 0.0

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if self.move not in VALID_MOVES:
            raise DecodeError(f"cmd: move {self.move} is not a 4-connected step")
        if self.target is not None:
            _check_cell(self.target, ctx.shape if ctx else None, "cmd")


# --- radio (inside bundles) --------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class RadioMsg(Message):
    """Base of everything a robot sends over the radio: ``dst`` is a robot id or ``*``; ``ttl`` hops left."""

    dst: str
    ttl: int

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if self.ttl < 0 or self.ttl > 16:
            raise DecodeError("radio: ttl out of range")


@dataclasses.dataclass(frozen=True)
class PoseBeacon(RadioMsg):
    """A robot's own pose, broadcast every tick."""

    KIND = "pose"
    cell: Cell

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        _check_cell(self.cell, ctx.shape if ctx else None, "pose")


@dataclasses.dataclass(frozen=True)
class MapDelta(RadioMsg):
    """The cells a robot newly learned this tick (flat indices and their values)."""

    KIND = "map"
    cells: np.ndarray
    values: np.ndarray

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        _check_cells(self.cells, self.values, ctx.shape if ctx else None, "map")


# --- allocator protocols (inside bundles) ------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Assignment(RadioMsg):
    """A coordinator's assignment (``hungarian``): each robot's target cell, for round ``round``."""

    KIND = "assign"
    round: int
    targets: dict[str, Cell]

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        for cell in self.targets.values():
            _check_cell(cell, ctx.shape if ctx else None, "assign")


# --- trade-based allocation (Yan et al. 2011, section 4) ------------------------------------------------

@dataclasses.dataclass(frozen=True)
class TradeNumber(RadioMsg):
    """Role allocation (Algorithm 1): a robot not in a task broadcasts its number every tick."""

    KIND = "trade_num"
    number: int

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if self.number < 0:
            raise DecodeError("trade_num: negative robot number")


@dataclasses.dataclass(frozen=True)
class TradePurchase(RadioMsg):
    """A buyer's purchase message ``pums_r = {r, m, c}`` (eq. 3) to the seller: ``r`` is ``src``, ``m`` the
    task (a frontier cluster's target cell), ``c`` its wavefront cost (eq. 2)."""

    KIND = "trade_buy"
    task: Cell
    cost: float

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        _check_cell(self.task, ctx.shape if ctx else None, "trade_buy")
        if not (0.0 <= self.cost < 1e9):
            raise DecodeError("trade_buy: cost out of range")


@dataclasses.dataclass(frozen=True)
class TradeAllocation(RadioMsg):
    """A seller's task-allocation messages ``tams = {r, m}`` (eq. 4) of one round, as one broadcast:
    ``src`` is the seller, ``awards`` maps each robot allocated a task to that task's cell."""

    KIND = "trade_alloc"
    awards: dict[str, Cell]

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        for robot, cell in self.awards.items():
            if ctx is not None and ctx.senders is not None and robot not in ctx.senders:
                raise DecodeError(f"trade_alloc: unknown robot {robot!r}")
            _check_cell(cell, ctx.shape if ctx else None, "trade_alloc")


@dataclasses.dataclass(frozen=True)
class TradeDone(RadioMsg):
    """A completed (or abandoned) task, broadcast so that teammates update their task lists (section 4.2)."""

    KIND = "trade_done"
    task: Cell

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        _check_cell(self.task, ctx.shape if ctx else None, "trade_done")


@dataclasses.dataclass(frozen=True)
class TxBundle(Message):
    """Everything one robot sends at ``tick`` (radio/tx/<robot>); sent even when empty."""

    KIND = "tx"
    msgs: tuple[RadioMsg, ...]

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if any(m.src != self.src for m in self.msgs):
            raise DecodeError("tx: a message's src differs from the bundle's")


@dataclasses.dataclass(frozen=True)
class RxBundle(Message):
    """What netem delivers to robot ``dst`` at ``tick`` (radio/rx/<robot>); sent even when empty."""

    KIND = "rx"
    dst: str
    msgs: tuple[RadioMsg, ...]


# --- netem -> everyone ---------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Links(Message):
    """The link graph at ``tick`` (netem/links): signal P_ij in dB, links, and cumulative radio counters."""

    KIND = "links"
    robots: tuple[str, ...]
    strength: np.ndarray
    link: np.ndarray
    connected: bool
    sent: int
    delivered: int
    dropped_loss: int
    dropped_signal: int
    bytes_sent: int


# --- control ---------------------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Hello(Message):
    """The world's start handshake (ctl/hello): every node answers with :class:`Ready`."""

    KIND = "hello"


@dataclasses.dataclass(frozen=True)
class Ready(Message):
    """A node's answer to :class:`Hello` (ctl/ready/<id>): its subscriptions are in place."""

    KIND = "ready"
    role: str
    pid: int


@dataclasses.dataclass(frozen=True)
class Failed(Message):
    """The launcher saw a robot's process exit (ctl/failed/<robot>): the world fails it at once, even
    before its liveliness token existed."""

    KIND = "failed"
    robot: str
    reason: str


@dataclasses.dataclass(frozen=True)
class Stop(Message):
    """The run is over (ctl/stop): nodes report and exit."""

    KIND = "stop"
    reason: str


@dataclasses.dataclass(frozen=True)
class AgentReport(Message):
    """An agent's summary when it stops (ctl/report/<robot>): counters the launcher puts in result.json."""

    KIND = "report"
    decisions: int
    decision_ms_mean: float
    decision_ms_p95: float
    dropped: int
    peak_rss_kb: int


@dataclasses.dataclass(frozen=True)
class BeliefSnapshot(Message):
    """A robot's whole belief grid (robot/<robot>/belief), every few ticks, for the recording only."""

    KIND = "belief"
    grid: np.ndarray

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if self.grid.ndim != 2 or self.grid.dtype != np.int8:
            raise DecodeError("belief: expected a 2-D int8 grid")
        if ctx is not None and ctx.shape is not None and self.grid.shape != ctx.shape:
            raise DecodeError("belief: grid shape differs from the map's")
