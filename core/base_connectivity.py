"""Base connectivity: which robots have a path to the base station in the link graph.

A pure function of the link matrix that :func:`fleet_emu.core.radio.link_matrix` gives (rows and columns in
the order of ``names``, the base station one of them), and a fold over ticks for ``result.json``'s
``base_connected_fraction``. A robot is connected to the base when some chain of links, of any length, joins
them: relays may be robots of any role. Definitions (ours):

- per tick, the *fraction* is the share of live robots (the base excluded) with a path to the base;
- ``overall`` is the mean of that fraction over the ticks folded; ``per_robot`` the share of the ticks
  folded in which that robot was connected (counted over the ticks it was live); ``all_ticks`` the share of
  ticks in which every live robot was connected (the MHM constraint: 1.0 means it never broke).
"""

from __future__ import annotations

import dataclasses
from collections import deque
from collections.abc import Sequence
from typing import TypedDict

import numpy as np

from fleet_emu.core.keys import BASE


def reachable(link: np.ndarray, source: int) -> np.ndarray:
    """Bool per node: a path of links joins it to ``source`` (breadth-first; ``source`` itself True)."""
    n = len(link)
    seen = np.zeros(n, dtype=bool)
    seen[source] = True
    queue = deque([source])
    while queue:
        i = queue.popleft()
        for j in np.flatnonzero(link[i] & ~seen):
            seen[j] = True
            queue.append(int(j))
    return seen


def base_connected(names: Sequence[str], link: np.ndarray, base: str = BASE) -> dict[str, bool]:
    """For every robot in ``names`` but the base, whether it has a path to the base. ValueError when the
    base is not among ``names`` or the matrix does not match them."""
    if link.shape != (len(names), len(names)):
        raise ValueError(f"link matrix {link.shape} does not match {len(names)} names")
    if base not in names:
        raise ValueError(f"no {base!r} among the link graph's nodes")
    seen = reachable(np.asarray(link, dtype=bool), list(names).index(base))
    return {name: bool(seen[k]) for k, name in enumerate(names) if name != base}


class ReachSummary(TypedDict):
    """:meth:`BaseConnectivity.summary`: result.json's ``base_connected_fraction`` before rounding."""

    overall: float | None
    all_ticks: float | None
    per_robot: dict[str, float]


@dataclasses.dataclass
class BaseConnectivity:
    """A fold of :func:`base_connected` over ticks (see the module docstring for the fractions)."""

    ticks: int = 0
    fraction_sum: float = 0.0
    all_connected: int = 0
    connected: dict[str, int] = dataclasses.field(default_factory=dict)
    live: dict[str, int] = dataclasses.field(default_factory=dict)
    series: list[float] = dataclasses.field(default_factory=list)

    def add(self, names: Sequence[str], link: np.ndarray, base: str = BASE) -> float:
        """Fold one tick's link graph (``names``: the base and the live robots); its fraction."""
        flags = base_connected(names, link, base)
        fraction = sum(flags.values()) / len(flags) if flags else 1.0
        self.ticks += 1
        self.fraction_sum += fraction
        self.all_connected += all(flags.values())
        for robot, ok in flags.items():
            self.live[robot] = self.live.get(robot, 0) + 1
            self.connected[robot] = self.connected.get(robot, 0) + ok
        self.series.append(fraction)
        return fraction

    def summary(self) -> ReachSummary:
        """``{"overall", "all_ticks", "per_robot"}``; None fractions before any tick."""
        per_robot = {r: self.connected[r] / self.live[r] for r in sorted(self.live, key=_robot_key)}
        if not self.ticks:
            return {"overall": None, "all_ticks": None, "per_robot": per_robot}
        return {"overall": self.fraction_sum / self.ticks, "all_ticks": self.all_connected / self.ticks,
                "per_robot": per_robot}


def _robot_key(robot: str) -> tuple[int, str]:
    return (int(robot[1:]), "") if robot[:1] == "r" and robot[1:].isdigit() else (1 << 30, robot)
