"""Every message of the lockstep protocol (docs/reference/protocol.md), the one module to import them from:
the barrier messages, netem's links, the belief snapshots and the real-time messages defined here, the radio
envelope (``core/envelope.py``) and the control messages (``core/control_messages.py``) re-exported. Radio
payloads are each protocol's own (``agents/protocol.py``, each allocator's module). Encode with
``msg.encode()``; decode with :func:`fleet_emu.core.codec.decode`."""

from __future__ import annotations

import msgspec
import numpy as np

from fleet_emu.core import jit, kernels
from fleet_emu.core.codec import Context, DecodeError, Message, Payload, decode, decode_payload, peek_tick
from fleet_emu.core.control_messages import (
    HOST_EVENTS,
    MAX_REALTIME_HZ,
    BaseReport,
    Failed,
    Hello,
    HostAssign,
    HostStatus,
    Ready,
    RobotReport,
    Stop,
    ready,
)
from fleet_emu.core.envelope import (
    BULK_KINDS,
    MAX_PAYLOAD_BYTES,
    MAX_TTL,
    Envelope,
    RadioMsg,
    RxBundle,
    TxBundle,
    compact,
    expand,
    open_envelope,
    seal,
)
from fleet_emu.core.grid import MOVES, STAY, Cell

__all__ = [
    "Context", "DecodeError", "Message", "Payload", "decode", "decode_payload", "peek_tick", "Observation",
    "WorldState", "Command", "Envelope", "RadioMsg", "seal", "open_envelope", "compact", "expand", "BULK_KINDS",
    "MAX_TTL", "MAX_PAYLOAD_BYTES", "check_cell", "check_cells", "check_robot_cells", "TxBundle", "RxBundle", "Links",
    "Hello", "Ready", "ready", "Failed", "Stop", "RobotReport", "BaseReport", "BeliefSnapshot", "HostAssign",
    "HostStatus", "HOST_EVENTS", "MAX_REALTIME_HZ", "WorldClock", "RobotTiming", "STALE",
]

VALID_CELL_VALUES = np.array([-1, 0, 100], dtype=np.int8)
VALID_MOVES = frozenset(MOVES) | {STAY}
_KERNEL_CELLS = (np.dtype(np.int32), np.dtype(np.int64))  # the cell index types cells_valid is warmed up for


def check_cells(cells: np.ndarray, values: np.ndarray, shape: tuple[int, int] | None, what: str) -> None:
    """Flat cell indices inside a grid of ``shape`` and occupancy values (-1, 0, 100), of equal length (a
    robot checks every teammate's map delta every tick: in one compiled pass once its kernels are loaded)."""
    if (shape is not None and jit.loaded() and cells.dtype in _KERNEL_CELLS and values.dtype == np.int8
            and cells.ndim == 1 and values.ndim == 1 and len(cells) == len(values)
            and kernels.cells_valid(cells, values, shape[0] * shape[1])):
        return
    if cells.ndim != 1 or values.ndim != 1 or len(cells) != len(values):
        raise DecodeError(f"{what}: cells and values differ in length")
    if cells.dtype.kind not in "iu" or values.dtype != np.int8:
        raise DecodeError(f"{what}: wrong dtypes")
    if len(cells) and _out_of_range(cells, shape):
        raise DecodeError(f"{what}: cell index out of range")
    if not np.isin(values, VALID_CELL_VALUES).all():
        raise DecodeError(f"{what}: cell value not in (-1, 0, 100)")


def _out_of_range(cells: np.ndarray, shape: tuple[int, int] | None) -> bool:
    """Whether a cell index of ``cells`` (not empty) is negative or (with a shape) past the grid's last cell."""
    return bool(cells.min() < 0 or (shape is not None and cells.max() >= shape[0] * shape[1]))


def check_cell(cell: Cell, shape: tuple[int, int] | None, what: str) -> None:
    """A cell inside a grid of ``shape`` (unchecked when the shape is not known)."""
    if shape is not None and not (0 <= cell[0] < shape[0] and 0 <= cell[1] < shape[1]):
        raise DecodeError(f"{what}: cell {cell} outside the grid")


def check_robot_cells(cells: dict[str, Cell], ctx: Context | None, what: str) -> None:
    """A map of robot ids to cells: every id one of the team's, every cell inside the grid."""
    for robot, cell in cells.items():
        if ctx is not None and ctx.senders is not None and robot not in ctx.senders:
            raise DecodeError(f"{what}: unknown robot {robot!r}")
        check_cell(cell, ctx.shape if ctx else None, what)


# --- world -> agent ---------------------------------------------------------------------------------

#: An observation's ``bodies`` when the sensor found none (read-only, shared).
NO_BODIES: np.ndarray = np.zeros(0, dtype=np.int32)
NO_BODIES.flags.writeable = False


class Observation(Message, kw_only=True, frozen=True):
    """What one robot's sensor saw at ``tick``, and its true pose (world/obs/<robot>). ``values`` are the map's
    (a robot's body is not written into them: it moves on); ``bodies`` are the cells among ``cells`` where the
    sensor found another robot's body this tick, a teammate's or a failed robot's (flat indices)."""

    KIND = "obs"
    robot: str
    cell: Cell
    shape: Cell
    cell_size: float
    cells: np.ndarray
    values: np.ndarray
    bodies: np.ndarray = msgspec.field(default_factory=lambda: NO_BODIES)

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if self.shape[0] <= 0 or self.shape[1] <= 0 or self.cell_size <= 0:
            raise DecodeError("obs: bad grid shape or cell size")
        check_cell(self.cell, self.shape, "obs")
        check_cells(self.cells, self.values, self.shape, "obs")
        b = self.bodies
        if b.ndim != 1 or b.dtype.kind not in "iu" or (len(b) and _out_of_range(b, self.shape)):
            raise DecodeError("obs: a body's cell outside the grid")


class WorldState(Message, kw_only=True, frozen=True):
    """All true poses, coverage and the run's status at ``tick`` (world/state); ``dropped`` counts the
    messages the world has dropped so far (malformed, or from a sender that may not write on their key),
    ``foreign`` those it dropped for not carrying the run's nonce (another run's, a replayed recording's);
    ``blocked``, in the last state of a run that missed its target: each failed robot whose body cuts the live
    robots off from cells still to sense, and how many (``world.sim.World.blocking``)."""

    KIND = "state"
    poses: dict[str, Cell]
    live: tuple[str, ...]
    coverage: float
    path_length: dict[str, int]
    done: bool = False
    reason: str | None = None
    dropped: int = 0
    foreign: int = 0
    blocked: dict[str, int] = msgspec.field(default_factory=dict)


# --- agent -> world -----------------------------------------------------------------------------------

#: The status of a command a robot sends in real-time mode without a decision: a step along its last plan, or a
#: stay while it has none (``agents/realtime.py``); never sent in lockstep.
STALE = "STALE"


class Command(Message, kw_only=True, frozen=True):
    """A robot's move for ``tick`` (robot/<robot>/cmd), with what it decided, for the record, and ``known``: the
    cells its belief holds after the tick (0 in a real-time step without a decision), which the world's stall
    rule reads (``world/sim.py``)."""

    KIND = "cmd"
    move: Cell
    target: Cell | None = None
    status: str = ""
    decision_ms: float = 0.0
    known: int = 0

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if self.move not in VALID_MOVES:
            raise DecodeError(f"cmd: move {self.move} is not a 4-connected step")
        if self.known < 0 or (ctx is not None and ctx.shape is not None and self.known > ctx.shape[0] * ctx.shape[1]):
            raise DecodeError(f"cmd: {self.known} known cells for the map's grid")
        if self.target is not None:
            check_cell(self.target, ctx.shape if ctx else None, "cmd")


# --- netem -> everyone ---------------------------------------------------------------------------------

class Links(Message, kw_only=True, frozen=True):
    """The link graph at ``tick`` (netem/links): signal P_ij in dB, links, and cumulative radio counters
    (``dropped``: the messages netem itself dropped as malformed or spoofed, not radio losses; ``foreign``: those
    it dropped for not carrying the run's nonce)."""

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
    dropped: int = 0
    foreign: int = 0
    # runs with a base station: per robot of ``robots``, its signal to the base (dB) and whether they are linked
    base_strength: np.ndarray | None = None
    base_link: np.ndarray | None = None
    # airtime (netem/medium.py): cumulative bytes on the air, queue drops, the largest queue, emissions by delay
    # (ticks from hand-off to delivery); with a bandwidth, each medium's bytes at the last tick served, each
    # endpoint's medium then, and a medium's capacity a tick
    airtime_bytes: int = 0
    dropped_queue: int = 0
    queued_max_bytes: int = 0
    delays: tuple[int, ...] = ()
    medium_load: tuple[int, ...] = ()
    medium_of: dict[str, int] = msgspec.field(default_factory=dict)
    medium_capacity: int = 0
    # each sender's part of ``bytes_sent`` (cumulative; the base station's too)
    bytes_by: dict[str, int] = msgspec.field(default_factory=dict)
    # with shadowing (``[radio] shadowing_db``), cumulative over the robots' pairs and ticks: the pairs, those
    # eq. 4 without the field (the connectivity allocator's model) called linked that were not, and the reverse
    pair_ticks: int = 0
    false_links: int = 0
    missed_links: int = 0

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        n = len(self.robots)
        if self.link.shape != (n, n) or self.strength.shape != (n, n):
            raise DecodeError(f"links: matrices of shape {self.link.shape} for {n} robots")
        for name, arr in (("base_strength", self.base_strength), ("base_link", self.base_link)):
            if arr is not None and arr.shape != (n,):
                raise DecodeError(f"links: {name} of shape {arr.shape} for {n} robots")


class BeliefSnapshot(Message, kw_only=True, frozen=True):
    """A robot's whole belief grid (robot/<robot>/belief), every few ticks, for the recording only."""

    KIND = "belief"
    grid: np.ndarray

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if self.grid.ndim != 2 or self.grid.dtype != np.int8:
            raise DecodeError("belief: expected a 2-D int8 grid")
        if ctx is not None and ctx.shape is not None and self.grid.shape != ctx.shape:
            raise DecodeError("belief: grid shape differs from the map's")


# --- real-time mode only (``fleet run --realtime HZ``) ---------------------------------------------------------

class WorldClock(Message, kw_only=True, frozen=True):
    """The world's wall clock at ``tick`` (world/clock), published with every state of a real-time run and never
    in lockstep. Counters are cumulative: ``late`` per robot the decisions whose command arrived after the tick
    it was stamped for had ended (each applied at the next tick), ``late_steps`` the same for the steps along
    the last plan (status ``STALE``), ``missed`` per robot the ticks in which no command at
    all came from it (it stood still), ``overruns`` the ticks the world itself started after their scheduled
    time, ``elapsed`` the seconds since tick 0 was scheduled."""

    KIND = "clock"
    hz: float
    elapsed: float
    overruns: int
    late: dict[str, int]
    late_steps: dict[str, int]
    missed: dict[str, int]


class RobotTiming(Message, kw_only=True, frozen=True):
    """A robot's real-time summary when it stops (robot/<robot>/timing), sent just before its report and never
    in lockstep: ``decisions`` made, ``plan_steps`` (ticks it stepped along its last plan while a decision
    ran), ``waits`` (ticks a decision ran and it had no plan yet: it stood still), and percentiles of the wall
    time of a whole decision (``decision_ms``: the brain's step in its worker thread) and of the allocator
    alone (``allocator_ms``), each with keys p50, p90, p99, max and mean."""

    KIND = "timing"
    decisions: int
    plan_steps: int
    waits: int
    decision_ms: dict[str, float]
    allocator_ms: dict[str, float]
