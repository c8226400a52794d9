"""Every message of the lockstep protocol, defined once (DESIGN.md "Messages"), and the radio envelope.

Barrier messages (world -> agents, netem -> agents, agents -> world/netem), control messages, and the
:class:`Envelope` that carries one radio message inside tx/rx bundles. Radio payloads are not defined here:
each protocol owns its own (``agents/protocol.py`` for poses and map deltas, each allocator's module for its
messages), and netem routes envelopes without decoding them. Encode with ``msg.encode()``; decode with
:func:`fleet_emu.core.codec.decode`.
"""

from __future__ import annotations

import dataclasses

import msgpack
import numpy as np

from fleet_emu.core.access import Credential
from fleet_emu.core.codec import (
    MAX_ARRAY_BYTES,
    Context,
    DecodeError,
    Message,
    Payload,
    decode,
    decode_payload,
    fast_decoder,
    peek_tick,
)
from fleet_emu.core.codec import _to_obj as to_obj
from fleet_emu.core.grid import MOVES, STAY, Cell
from fleet_emu.core.keys import HOST_ID, ROBOT_ID, RUN_ID
from fleet_emu.core.version import SCHEMA_VERSION

__all__ = [
    "Context", "DecodeError", "Message", "Payload", "decode", "decode_payload", "peek_tick",
    "Observation", "WorldState", "Command", "Envelope", "RadioMsg", "seal", "open_envelope",
    "check_cell", "check_cells", "check_robot_cells", "TxBundle", "RxBundle", "Links", "Hello", "Ready", "Failed",
    "Stop",
    "AgentReport", "BeliefSnapshot", "HostAssign", "HostStatus", "WorldClock", "AgentTiming", "STALE",
]

VALID_CELL_VALUES = np.array([-1, 0, 100], dtype=np.int8)
_VALID_BYTE = np.zeros(256, dtype=np.bool_)  # indexed by an int8 value's byte: True for -1, 0 and 100
_VALID_BYTE[VALID_CELL_VALUES.view(np.uint8)] = True
VALID_MOVES = frozenset(MOVES) | {STAY}


def check_cells(cells: np.ndarray, values: np.ndarray, shape: tuple[int, int] | None, what: str) -> None:
    """Flat cell indices inside a grid of ``shape`` and occupancy values (-1, 0, 100), of equal length."""
    if cells.ndim != 1 or values.ndim != 1 or len(cells) != len(values):
        raise DecodeError(f"{what}: cells and values differ in length")
    if cells.dtype.kind not in "iu" or values.dtype != np.int8:
        raise DecodeError(f"{what}: wrong dtypes")
    if len(cells) and _out_of_range(cells, shape):
        raise DecodeError(f"{what}: cell index out of range")
    if len(values) and not _VALID_BYTE[values.view(np.uint8)].all():
        raise DecodeError(f"{what}: cell value not in (-1, 0, 100)")


def _out_of_range(cells: np.ndarray, shape: tuple[int, int] | None) -> bool:
    """Whether a cell index of ``cells`` (not empty) is negative or (with a shape) past the grid's last cell.
    Signed indices are seen as unsigned of the same width, so that one maximum finds both: a negative one
    becomes larger than any grid."""
    if shape is not None and cells.dtype.kind == "i" and cells.dtype.itemsize >= 4:
        size = shape[0] * shape[1]
        return size <= 0 or int(cells.view(f"u{cells.dtype.itemsize}").max()) >= size
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
        check_cell(self.cell, self.shape, "obs")
        check_cells(self.cells, self.values, self.shape, "obs")


@dataclasses.dataclass(frozen=True)
class WorldState(Message):
    """All true poses, coverage and the run's status at ``tick`` (world/state); ``dropped`` counts the
    messages the world has dropped so far (malformed, or from a sender that may not write on their key)."""

    KIND = "state"
    poses: dict[str, Cell]
    live: tuple[str, ...]
    coverage: float
    path_length: dict[str, int]
    done: bool = False
    reason: str | None = None
    dropped: int = 0


# --- agent -> world -----------------------------------------------------------------------------------

#: The status of a command a robot sends in real-time mode without a decision: a step along its last plan, or a
#: stay while it has none (``agents/realtime.py``); never sent in lockstep.
STALE = "STALE"


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
            check_cell(self.target, ctx.shape if ctx else None, "cmd")


# --- radio (inside bundles) --------------------------------------------------------------------------

MAX_TTL = 16
MAX_PAYLOAD_BYTES = 16 * 1024 * 1024


@dataclasses.dataclass(frozen=True)
class Envelope(Message):
    """One radio message as netem and relays see it: who sent this hop (``src``), who made it (``origin``),
    for whom (``dst``: a robot id, ``base`` or ``*`` for everyone), hops left (``ttl``), and an opaque
    ``payload`` of ``payload_kind`` that only the protocol owning that kind decodes. ``(origin, seq)`` is the
    message's id; ``seq`` comes from the origin's one counter."""

    KIND = "radio"
    origin: str
    dst: str
    ttl: int
    payload_kind: str
    payload: bytes

    def encode(self) -> bytes:
        """The envelope's bytes, packed once and kept (an envelope is immutable): netem puts each broadcast
        envelope in every receiver's rx bundle, and counts its size (issue 11, part 4)."""
        packed = self.__dict__.get("_packed")
        if packed is None:
            packed = super().encode()
            object.__setattr__(self, "_packed", packed)
        return packed

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if not 0 <= self.ttl <= MAX_TTL:
            raise DecodeError("radio: ttl out of range")
        if len(self.payload) > MAX_PAYLOAD_BYTES:
            raise DecodeError("radio: payload too large")
        if ctx is not None and ctx.senders is not None and self.origin not in ctx.senders:
            raise DecodeError(f"radio: unknown origin {self.origin!r}")


_ENVELOPE_KEYS = frozenset({"kind", "v", "src", "tick", "seq", "origin", "dst", "ttl", "payload_kind", "payload"})


@fast_decoder(Envelope)
def _fast_envelope(obj: dict, ctx: Context | None) -> Envelope | None:
    """An envelope straight from its map when every field has exactly its type and it validates
    (:meth:`Envelope.validate`'s checks, inlined); None for anything else, which the generic decode then
    checks (an rx bundle holds every teammate's envelopes: issue 11, part 4)."""
    if obj.keys() != _ENVELOPE_KEYS:
        return None
    src, tick, seq, origin, dst = obj["src"], obj["tick"], obj["seq"], obj["origin"], obj["dst"]
    v, ttl, kind, payload = obj["v"], obj["ttl"], obj["payload_kind"], obj["payload"]
    if not (type(v) is int and v <= SCHEMA_VERSION and type(src) is str and type(tick) is int and tick >= 0
            and type(seq) is int and seq >= 0 and type(origin) is str and type(dst) is str and type(ttl) is int
            and 0 <= ttl <= MAX_TTL and type(kind) is str and type(payload) is bytes
            and len(payload) <= min(MAX_PAYLOAD_BYTES, MAX_ARRAY_BYTES)):
        return None
    senders = ctx.senders if ctx is not None else None
    if senders is not None and (src not in senders or origin not in senders):
        return None
    env = object.__new__(Envelope)
    env.__dict__.update(src=src, tick=tick, seq=seq, origin=origin, dst=dst, ttl=ttl, payload_kind=kind,
                        payload=payload)
    return env


@dataclasses.dataclass(frozen=True)
class RadioMsg:
    """A radio message as a robot's protocols see it: a decoded :class:`~fleet_emu.core.codec.Payload` and its
    envelope's header. A protocol that sends gives ``body`` and ``dst`` (and ``ttl``); the sender's brain
    fills in the rest when it seals the envelope."""

    body: Payload
    dst: str = "*"
    ttl: int = 0
    src: str = ""
    origin: str = ""
    tick: int = 0
    seq: int = 0

    @property
    def kind(self) -> str:
        return self.body.KIND


def seal(msg: RadioMsg, src: str, tick: int, seq: int) -> Envelope:
    """The envelope of a message ``src`` makes at ``tick``."""
    return Envelope(src=src, tick=tick, seq=seq, origin=src, dst=msg.dst, ttl=msg.ttl, payload_kind=msg.kind,
                    payload=msg.body.encode())


def open_envelope(env: Envelope, ctx: Context | None = None) -> RadioMsg:
    """Decode an envelope's payload; raises DecodeError (an unknown kind included).

    The decoded payload is kept on the envelope with the context it was checked against, and given again to
    the next receiver with an equal context: in the memory engine one broadcast envelope object reaches every
    teammate, and decoding it once is enough (a payload is immutable: frozen, its arrays read-only views of
    the message bytes). Over Zenoh every receiver decodes its own copy, so nothing changes there."""
    cached = env.__dict__.get("_opened")
    if cached is not None and cached[0] == ctx:
        body = cached[1]
    else:
        body = decode_payload(env.payload_kind, env.payload, ctx)
        object.__setattr__(env, "_opened", (ctx, body))
    msg = object.__new__(RadioMsg)  # RadioMsg(...) without the frozen dataclass's setattr per field
    msg.__dict__.update(body=body, dst=env.dst, ttl=env.ttl, src=env.src, origin=env.origin, tick=env.tick,
                        seq=env.seq)
    return msg


def _pack_bundle(bundle: TxBundle | RxBundle) -> bytes:
    """A bundle's bytes as ``msgpack.packb(bundle.to_obj())`` gives them, with each envelope's kept bytes
    (:meth:`Envelope.encode`) put in as they are rather than packed again."""
    obj = {"kind": bundle.KIND, "v": SCHEMA_VERSION,
           **{name: to_obj(getattr(bundle, name)) for name in _BUNDLE_HEAD[type(bundle)]}}
    head = msgpack.packb(obj, use_bin_type=True)
    n = len(obj) + 1  # a map header of 0x80 + n (n < 16 here), then the fields; msgs is the last field
    assert head[0] == 0x80 + n - 1 and n < 16
    body = msgpack.packb("msgs") + _array_header(len(bundle.msgs)) + b"".join(e.encode() for e in bundle.msgs)
    return bytes([0x80 + n]) + head[1:] + body


def _bundle_head(cls: type) -> tuple[str, ...]:
    """A bundle class's fields before ``msgs``, its last."""
    names = tuple(f.name for f in dataclasses.fields(cls))
    assert names[-1] == "msgs"
    return names[:-1]


def _array_header(n: int) -> bytes:
    """msgpack's header of an array of ``n`` items."""
    if n < 16:
        return bytes([0x90 + n])
    if n < 1 << 16:
        return b"\xdc" + n.to_bytes(2, "big")
    return b"\xdd" + n.to_bytes(4, "big")


@dataclasses.dataclass(frozen=True)
class TxBundle(Message):
    """Everything one robot sends at ``tick`` (radio/tx/<robot>); sent even when empty."""

    KIND = "tx"
    msgs: tuple[Envelope, ...]

    def encode(self) -> bytes:
        return _pack_bundle(self)

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if any(m.src != self.src for m in self.msgs):
            raise DecodeError("tx: a message's src differs from the bundle's")


@dataclasses.dataclass(frozen=True)
class RxBundle(Message):
    """What netem delivers to robot ``dst`` at ``tick`` (radio/rx/<robot>); sent even when empty."""

    KIND = "rx"
    dst: str
    msgs: tuple[Envelope, ...]

    def encode(self) -> bytes:
        return _pack_bundle(self)


_BUNDLE_HEAD = {cls: _bundle_head(cls) for cls in (TxBundle, RxBundle)}


# --- netem -> everyone ---------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Links(Message):
    """The link graph at ``tick`` (netem/links): signal P_ij in dB, links, and cumulative radio counters
    (``dropped``: the messages netem itself dropped as malformed or spoofed, not radio losses)."""

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
    # runs with a base station: per robot of ``robots``, its signal to the base (dB) and whether they are linked
    base_strength: np.ndarray | None = None
    base_link: np.ndarray | None = None

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        n = len(self.robots)
        if self.link.shape != (n, n) or self.strength.shape != (n, n):
            raise DecodeError(f"links: matrices of shape {self.link.shape} for {n} robots")
        for name, arr in (("base_strength", self.base_strength), ("base_link", self.base_link)):
            if arr is not None and arr.shape != (n,):
                raise DecodeError(f"links: {name} of shape {arr.shape} for {n} robots")


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
    decision_cpu_ms: float = 0.0  # thread CPU in the allocator, summed over the decisions (issue 11)
    step_cpu_ms: float = 0.0  # thread CPU in the brain's whole step, summed (decision included)
    # the agent process's CPU (every thread) from the start of its first step to this report: minus step_cpu_ms,
    # its bus work over the same ticks (benchmarks/scale.py's a.bus); 0 where not measured (the memory engine)
    process_cpu_ms: float = 0.0


@dataclasses.dataclass(frozen=True)
class BaseReport(Message):
    """The base station's summary when it stops (ctl/report/base): what its team map holds
    (``agents/base.py``): known cells of ``cells``, the map deltas and fills merged, the ticks heard."""

    KIND = "base_report"
    cell: Cell
    known_cells: int
    cells: int
    merged: int
    ticks: int
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


# --- the hosts' lobby (fleet-host/<host>/..., launch/hosts.py) --------------------------------------------

MAX_REALTIME_HZ = 1000.0  # the fastest real-time rate a run accepts (``fleet run --realtime``)
HOST_EVENTS = frozenset({"accepted", "busy", "spawned", "exited", "ended"})


@dataclasses.dataclass(frozen=True)
class HostAssign(Message):
    """The launcher's request to host ``host`` (fleet-host/<host>/spawn): start ``robots`` of run ``run``, whose
    scenario (as ``scenario.json``) is ``scenario``; ``secrets`` maps each robot to its bus credential (JSON,
    user and password: the host adds its own TLS CA), empty on an unauthenticated bus; ``realtime_hz`` the
    run's real-time rate (``fleet run --realtime HZ``; 0: lockstep), which the robots are started with. ``end``
    set: tear the run's robots down instead."""

    KIND = "host_assign"
    host: str
    run: str
    robots: tuple[str, ...] = ()
    scenario: str = ""
    secrets: dict[str, str] = dataclasses.field(default_factory=dict)
    fork_server: bool = True
    end: bool = False
    realtime_hz: float = 0.0

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if not HOST_ID.fullmatch(self.host) or not RUN_ID.fullmatch(self.run):
            raise DecodeError("host_assign: bad host or run id")
        if not 0.0 <= self.realtime_hz <= MAX_REALTIME_HZ:  # NaN fails too
            raise DecodeError(f"host_assign: realtime_hz {self.realtime_hz!r} not in [0, {MAX_REALTIME_HZ:g}]")
        if not all(ROBOT_ID.fullmatch(r) for r in self.robots) or len(set(self.robots)) != len(self.robots):
            raise DecodeError("host_assign: bad robot ids")
        if not set(self.secrets) <= set(self.robots):
            raise DecodeError("host_assign: a secret for a robot not assigned")
        for robot, secret in self.secrets.items():
            try:
                cred = Credential.from_json(secret)
            except ValueError:
                raise DecodeError(f"host_assign: {robot}'s credential is not a user and password") from None
            if cred.user != robot:
                raise DecodeError(f"host_assign: {robot}'s credential is {cred.user!r}'s")


@dataclasses.dataclass(frozen=True)
class HostStatus(Message):
    """A host's report (fleet-host/<host>/status) about run ``run``: ``accepted`` (or ``busy`` with another run),
    ``spawned`` (``robot`` with its ``pid``), ``exited`` (``robot`` with its exit ``code``), ``ended`` (every
    robot of the run is gone)."""

    KIND = "host_status"
    run: str
    event: str
    robot: str = ""
    pid: int = 0
    code: int = 0
    error: str = ""

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if self.event not in HOST_EVENTS:
            raise DecodeError(f"host_status: unknown event {self.event!r}")


# --- real-time mode only (``fleet run --realtime HZ``) ---------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class WorldClock(Message):
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


@dataclasses.dataclass(frozen=True)
class AgentTiming(Message):
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
