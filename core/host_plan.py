"""A scenario's ``[hosts]``: how its robots are spread over other machines (``fleet host``), with the fleet's and
the hosts' size limits it is checked against."""

from __future__ import annotations

import dataclasses
from typing import Any

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.keys import HOST_ID

#: The largest fleet, and the most hosts a run may spread it over.
MAX_ROBOTS = 256
MAX_HOSTS = 64


@dataclasses.dataclass(frozen=True)
class HostPlan:
    """The scenario's ``[hosts]``: robots on ``count`` other machines (``fleet host``), as ``fleet run --hosts
    count`` does. ``names``: which hosts (``hostK`` logins; default the first ``count`` that come, by number);
    ``robots``: how many robots each of them runs, in that order, the rest running here (default: robots dealt
    round-robin over this machine and the hosts). Placement is dealt one robot at a time round the machines that
    still have room (``launch.host_client.placement``)."""

    count: int
    names: tuple[str, ...] = ()
    robots: tuple[int, ...] = ()

    @classmethod
    def from_dict(cls, d: dict[str, Any], where: str) -> HostPlan | None:
        """``[hosts]``: ``count``, ``names``, ``robots`` (None for ``count = 0`` alone: no hosts)."""
        bad = set(d) - {"count", "names", "robots"}
        if bad:
            raise ConfigError(f"{where}: unknown key(s) in [hosts]: {', '.join(sorted(bad))} (count, names, robots)")
        lists = {}
        for key in ("names", "robots"):
            value = d.get(key, [])
            if not isinstance(value, list | tuple):
                raise ConfigError(f"{where}: [hosts] {key} must be a list (got {value!r})")
            lists[key] = tuple(value)
        if "count" not in d and not lists["names"]:
            raise ConfigError(f"{where}: [hosts] needs count = N or names = [\"host0\", ...]")
        count = d.get("count", len(lists["names"]))
        if count == 0 and not isinstance(count, bool) and not lists["names"] and not lists["robots"]:
            return None
        return cls(count, lists["names"], lists["robots"])

    def to_dict(self) -> dict[str, Any]:
        """The ``[hosts]`` table, with only the keys given."""
        return {"count": self.count, **({"names": list(self.names)} if self.names else {}),
                **({"robots": list(self.robots)} if self.robots else {})}

    def validate(self, fleet: int) -> None:
        """A ConfigError on the first bad value; ``fleet`` is the scenario's number of robots."""
        whole_number("[hosts] count", self.count, 1, MAX_HOSTS)
        if self.names:
            if len(self.names) != self.count:
                raise ConfigError(f"[hosts] names lists {len(self.names)} host(s) but count is {self.count}")
            bad = [n for n in self.names if not isinstance(n, str) or not HOST_ID.fullmatch(n)]
            if bad:
                raise ConfigError(f"[hosts] names must be host0, host1, ... (the hosts' logins; got {bad[0]!r})")
            if len(set(self.names)) != len(self.names):
                raise ConfigError(f"[hosts] names lists a host twice ({', '.join(self.names)})")
        if self.robots:
            if len(self.robots) != self.count:
                raise ConfigError(f"[hosts] robots gives {len(self.robots)} number(s) for {self.count} host(s)")
            for n in self.robots:
                whole_number("[hosts] robots (each host's)", n, 0, MAX_ROBOTS)
            if sum(self.robots) > fleet:
                raise ConfigError(f"[hosts] robots puts {sum(self.robots)} robots on hosts, more than the fleet's "
                                  f"{fleet} (--robots)")


def whole_number(field: str, value: Any, low: int, high: int) -> None:
    """A ConfigError unless ``value`` is a whole number (not a bool) from ``low`` to ``high``."""
    if not isinstance(value, int) or isinstance(value, bool):
        raise ConfigError(f"{field} must be a whole number from {low} to {high} (got {value!r})")
    if not low <= value <= high:
        raise ConfigError(f"{field} must be from {low} to {high} (got {value})")
