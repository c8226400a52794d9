"""The control messages (the start handshake, stop, failures, the nodes' reports) and the hosts' lobby
(``fleet-host/<host>/...``, ``launch/host_client.py``); split out of ``core/messages.py``, which re-exports every
name here.
"""

from __future__ import annotations

import re

import msgspec

from fleet_emu.core.access import Credential
from fleet_emu.core.codec import Context, DecodeError, Message
from fleet_emu.core.grid import Cell
from fleet_emu.core.keys import HOST_ID, ROBOT_ID, RUN_ID

# --- control ---------------------------------------------------------------------------------------------

class Hello(Message, kw_only=True, frozen=True):
    """The world's start handshake (ctl/hello): every node answers with :class:`Ready`."""

    KIND = "hello"


class Ready(Message, kw_only=True, frozen=True):
    """A node's answer to :class:`Hello` (ctl/ready/<id>): its subscriptions are in place."""

    KIND = "ready"
    role: str
    pid: int


def ready(node_id: str, role: str, pid: int) -> Ready:
    """Node ``node_id``'s answer to the hello, as every engine builds it: tick 0 and seq 0 like the hello (the
    handshake repeats as timing goes, so it draws from no sequence counter)."""
    return Ready(src=node_id, tick=0, seq=0, role=role, pid=pid)


class Failed(Message, kw_only=True, frozen=True):
    """The launcher saw a robot's process exit (ctl/failed/<robot>): the world fails it at once, even
    before its liveliness token existed."""

    KIND = "failed"
    robot: str
    reason: str


class Stop(Message, kw_only=True, frozen=True):
    """The run is over (ctl/stop): nodes report and exit."""

    KIND = "stop"
    reason: str


class RobotReport(Message, kw_only=True, frozen=True):
    """A robot's summary when it stops (ctl/report/<robot>): counters the launcher puts in result.json."""

    KIND = "report"
    decisions: int
    decision_ms_mean: float
    decision_ms_p95: float
    dropped: int
    peak_rss_kb: int
    decision_cpu_ms: float = 0.0  # thread CPU in the allocator, summed over the decisions
    step_cpu_ms: float = 0.0  # thread CPU in the brain's whole step, summed (decision included)
    # the agent process's CPU (every thread) from the start of its first step to this report: minus step_cpu_ms,
    # its bus work over the same ticks (benchmarks/scale.py's a.bus); 0 where not measured (the memory engine)
    process_cpu_ms: float = 0.0
    # the event loop's thread CPU over the same span (lockstep: its steps included): process_cpu_ms minus this is
    # Zenoh's own threads, this minus step_cpu_ms the Python shell's (decode, encode, asyncio) (scale.py)
    loop_cpu_ms: float = 0.0
    stage_cpu_ms: dict[str, float] = msgspec.field(default_factory=dict)  # step_cpu_ms by stage (Brain.cpu_ms)
    # the first step's share of the sums above (``process``, ``loop``, ``step``, ``decision`` and each stage): tick
    # 0 merges every teammate's first map and clusters the whole belief, a start-up cost scale.py reports apart
    first_cpu_ms: dict[str, float] = msgspec.field(default_factory=dict)
    foreign: int = 0  # messages dropped for not carrying the run's nonce (another run's, a replayed recording's)


class BaseReport(Message, kw_only=True, frozen=True):
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
    foreign: int = 0  # messages dropped for not carrying the run's nonce


# --- the hosts' lobby (fleet-host/<host>/..., launch/host_client.py) --------------------------------------------

MAX_REALTIME_HZ = 1000.0  # the fastest real-time rate a run accepts (``fleet run --realtime``)
NONCE_HEX = re.compile(r"(?:[0-9a-f]{2}){0,32}")  # a run nonce in hex (empty: none)
HOST_EVENTS = frozenset({"accepted", "busy", "spawned", "exited", "ended"})


class HostAssign(Message, kw_only=True, frozen=True):
    """The launcher's request to host ``host`` (fleet-host/<host>/spawn): start ``robots`` of run ``run``, whose
    scenario (as ``scenario.json``) is ``scenario``; ``secrets`` maps each robot to its bus credential (JSON,
    user and password: the host adds its own TLS CA), empty on an unauthenticated bus; ``realtime_hz`` the
    run's real-time rate (``fleet run --realtime HZ``; 0: lockstep), which the robots are started with;
    ``nonce`` the run's nonce in hex, which they put on every message. ``end`` set: tear the run's robots down
    instead."""

    KIND = "host_assign"
    host: str
    run: str
    robots: tuple[str, ...] = ()
    scenario: str = ""
    secrets: dict[str, str] = msgspec.field(default_factory=dict)
    fork_server: bool = True
    end: bool = False
    realtime_hz: float = 0.0
    nonce: str = ""

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if not HOST_ID.fullmatch(self.host) or not RUN_ID.fullmatch(self.run):
            raise DecodeError("host_assign: bad host or run id")
        if not 0.0 <= self.realtime_hz <= MAX_REALTIME_HZ:  # NaN fails too
            raise DecodeError(f"host_assign: realtime_hz {self.realtime_hz!r} not in [0, {MAX_REALTIME_HZ:g}]")
        if not NONCE_HEX.fullmatch(self.nonce):
            raise DecodeError("host_assign: bad nonce")
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


class HostStatus(Message, kw_only=True, frozen=True):
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
