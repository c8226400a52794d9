"""Hand-made messages for the Foxglove fold's tests: a small drawn map, a scenario, and a world's observation and
state, a netem's links and a robot's command at a tick."""

from __future__ import annotations

import numpy as np

from fleet_emu.core.messages import Command, Links, Observation, WorldState

ART = """
#######
#.....#
#.#...#
#.....#
#######
"""


def scenario() -> dict:
    return {"robots": 2, "cell_size": 0.5, "map": "art", "belief_every": 2, "target_coverage": 0.99,
            "allocator": {"type": "minpos"}, "radio": {"threshold": 0.0}}


def obs(robot: str, tick: int, cell: tuple[int, int], cells: list[int], truth: np.ndarray) -> Observation:
    c = np.array(cells, np.int32)
    return Observation(src="world", tick=tick, seq=0, robot=robot, cell=cell, shape=truth.shape, cell_size=0.5,
                       cells=c, values=truth.ravel()[c].astype(np.int8))


def state(tick: int, poses: dict, live: tuple[str, ...], coverage: float) -> WorldState:
    return WorldState(src="world", tick=tick, seq=0, poses=poses, live=live, coverage=coverage,
                      path_length={r: tick for r in poses})


def links(tick: int, robots: tuple[str, ...], linked: bool) -> Links:
    n = len(robots)
    link = np.full((n, n), linked) & ~np.eye(n, dtype=bool)
    strength = np.full((n, n), 12.0 if linked else -5.0, np.float32)
    return Links(src="netem", tick=tick, seq=0, robots=robots, strength=strength, link=link, connected=linked,
                 sent=0, delivered=0, dropped_loss=0, dropped_signal=0, bytes_sent=0)


def cmd(robot: str, tick: int, target: tuple[int, int] | None) -> Command:
    return Command(src=robot, tick=tick, seq=0, move=(0, 0), target=target, status="ASSIGNED", decision_ms=0.5)
