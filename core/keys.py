"""Key expressions, built by one function (DESIGN.md "Key expressions")."""

from __future__ import annotations

ROOT = "fleet"


def key(run: str, *parts: str) -> str:
    """``fleet/<run>/<parts...>``; every key on the bus is built here."""
    if not run or any(ch in run for ch in "/*$?#"):
        raise ValueError(f"bad run id {run!r}")
    return "/".join((ROOT, run, *parts))


class Keys:
    """The key expressions of one run."""

    def __init__(self, run: str) -> None:
        self.run = run
        self.all = key(run, "**")
        self.state = key(run, "world", "state")
        self.links = key(run, "netem", "links")
        self.hello = key(run, "ctl", "hello")
        self.ready_all = key(run, "ctl", "ready", "*")
        self.stop = key(run, "ctl", "stop")
        self.report_all = key(run, "ctl", "report", "*")
        self.alive_all = key(run, "alive", "**")

    def obs(self, robot: str) -> str:
        return key(self.run, "world", "obs", robot)

    def cmd(self, robot: str) -> str:
        return key(self.run, "robot", robot, "cmd")

    def belief(self, robot: str) -> str:
        return key(self.run, "robot", robot, "belief")

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

    def wildcard(self, *parts: str) -> str:
        return key(self.run, *parts)

    @staticmethod
    def last(key_expr: str) -> str:
        """The final chunk of a key (a robot id in obs/cmd/tx/rx keys)."""
        return str(key_expr).rsplit("/", 1)[-1]


def robot_ids(n: int) -> list[str]:
    """``r0 .. r<n-1>``."""
    return [f"r{i}" for i in range(n)]
