"""Key expressions, built by one function (docs/reference/protocol.md)."""

from __future__ import annotations

import dataclasses
import re

ROOT = "fleet"
BASE = "base"  # the base station's node id (robots are r0 .. r<N-1>, a base station is ``base``)
HOST_ROOT = "fleet-host"  # the hosts' lobby: outside ``fleet/<run>/**``, so never recorded nor readable by a run


@dataclasses.dataclass(frozen=True)
class ParsedKey:
    """What a key of a run names: its ``channel`` (``obs``, ``state``, ``cmd``, ``belief``, ``tx``, ``rx``,
    ``links``, ``hello``, ``ready``, ``stop``, ``failed``, ``report``, ``alive``, and in real-time runs
    ``clock`` and ``timing``), the robot or node id in it,
    and for liveliness tokens the role."""

    channel: str
    node: str | None = None
    role: str | None = None


#: A run id: one key-expression chunk that is also a directory name.
RUN_ID = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]{0,99}")


def key(run: str, *parts: str) -> str:
    """``fleet/<run>/<parts...>``; every key on the bus is built here."""
    if not RUN_ID.fullmatch(run):
        raise ValueError(f"bad run id {run!r}")
    return "/".join((ROOT, run, *parts))


class Keys:
    """The key expressions of one run."""

    def __init__(self, run: str) -> None:
        self.run = run
        self.all = key(run, "**")
        self.state = key(run, "world", "state")
        self.clock = key(run, "world", "clock")
        self.links = key(run, "netem", "links")
        self.hello = key(run, "ctl", "hello")
        self.ready_all = key(run, "ctl", "ready", "*")
        self.stop = key(run, "ctl", "stop")

    def obs(self, robot: str) -> str:
        return key(self.run, "world", "obs", robot)

    def cmd(self, robot: str) -> str:
        return key(self.run, "robot", robot, "cmd")

    def belief(self, robot: str) -> str:
        return key(self.run, "robot", robot, "belief")

    def timing(self, robot: str) -> str:
        return key(self.run, "robot", robot, "timing")

    def tx(self, robot: str) -> str:
        return key(self.run, "radio", "tx", robot)

    def rx(self, robot: str) -> str:
        return key(self.run, "radio", "rx", robot)

    def ready(self, node: str) -> str:
        return key(self.run, "ctl", "ready", node)

    def failed(self, robot: str) -> str:
        return key(self.run, "ctl", "failed", robot)

    def report(self, robot: str) -> str:
        return key(self.run, "ctl", "report", robot)

    def alive(self, role: str, node: str) -> str:
        return key(self.run, "alive", role, node)

    def folded(self, radio: bool = False) -> tuple[str, ...]:
        """The keys the launcher's fold reads (``recording/monitor.py``), and the world's hello it answers:
        what it subscribes to when it does not record (at 256 robots the observations, the
        rx and tx bundles and the belief snapshots are most of the bus); with ``radio`` (a relaying run, whose
        bundles' headers it folds) the radio bundles too."""
        return (self.state, self.clock, self.links, self.hello, self.stop, self.report("*"),
                self.wildcard("robot", "*", "cmd"), self.wildcard("robot", "*", "timing"),
                *((self.tx("*"), self.rx("*")) if radio else ()))

    def wildcard(self, *parts: str) -> str:
        return key(self.run, *parts)

    def parse(self, key_expr: object) -> ParsedKey | None:
        """The channel and id a key of this run names; None for another run's key or one this run never uses
        (the inverse of the builders above)."""
        got = parse_key(key_expr)
        return got[1] if got is not None and got[0] == self.run else None

    def channel(self, key_expr: object) -> str | None:
        """The channel a key of this run names (``parse(key).channel``); None where :meth:`parse` gives None."""
        parsed = self.parse(key_expr)
        return parsed.channel if parsed is not None else None


def parse_key(key_expr: object) -> tuple[str, ParsedKey] | None:
    """The run and the channel a key names, whatever the run (for a recording read back); None for a key the
    fleet never uses."""
    parts = str(key_expr).split("/")
    if len(parts) < 3 or parts[0] != ROOT:
        return None
    match parts[2:]:
        case ["world", "obs", robot]:
            parsed = ParsedKey("obs", robot)
        case ["world", ("state" | "clock")] | ["netem", "links"] | ["ctl", "hello"] | ["ctl", "stop"]:
            parsed = ParsedKey(parts[-1])
        case ["robot", robot, ("cmd" | "belief" | "timing") as channel]:
            parsed = ParsedKey(channel, robot)
        case ["radio", ("tx" | "rx") as channel, robot]:
            parsed = ParsedKey(channel, robot)
        case ["ctl", ("ready" | "failed" | "report") as channel, node]:
            parsed = ParsedKey(channel, node)
        case ["alive", role, node]:
            parsed = ParsedKey("alive", node, role)
        case _:
            return None
    return parts[1], parsed


#: A host's id (and its bus user): ``host0``, ``host1``, ...
HOST_ID = re.compile(r"host[0-9]{1,3}")
ROBOT_ID = re.compile(r"r[0-9]{1,3}")


class HostKeys:
    """The lobby keys of one host (``fleet-host/<host>/...``, the same for every run): its liveliness token
    ``alive``, the launcher's requests ``spawn`` (the robots' credentials: only this host may receive them) and
    the host's reports ``status``. The launcher watches every host's token through :data:`ALL_ALIVE`."""

    ALL_ALIVE = f"{HOST_ROOT}/*/alive"

    def __init__(self, host: str) -> None:
        if not HOST_ID.fullmatch(host):
            raise ValueError(f"bad host id {host!r}")
        self.host = host
        self.alive = f"{HOST_ROOT}/{host}/alive"
        self.spawn = f"{HOST_ROOT}/{host}/spawn"
        self.status = f"{HOST_ROOT}/{host}/status"

    @staticmethod
    def host_of(key_expr: object) -> str | None:
        """The host a lobby key names, or None."""
        parts = str(key_expr).split("/")
        ok = len(parts) == 3 and parts[0] == HOST_ROOT and HOST_ID.fullmatch(parts[1])
        return parts[1] if ok else None


def host_ids(n: int) -> list[str]:
    """``host0 .. host<n-1>``."""
    return [f"host{i}" for i in range(n)]


def robot_ids(n: int) -> list[str]:
    """``r0 .. r<n-1>``."""
    return [f"r{i}" for i in range(n)]
