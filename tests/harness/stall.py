"""A fleet that never finishes and never learns: the stall rule's case, run by the memory engine's tests and by
every engine's."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from fleet_emu.core.scenario import Scenario


def oscillating(small_map: Path, seed: int = 0) -> Scenario:
    """Three robots whose allocator yields the target each nears (connectivity, ``position = "literal"``, a heavy
    beta, replanning every tick): they swap targets back and forth and never finish the two rooms. The move
    rule is off (``stall_ticks``), the window at twice the map's diameter."""
    s = Scenario().override(map=str(small_map), robots=3, target_coverage=1.0, coverage_stall_ticks=1,
                            stall_ticks=10**6, seed=seed, max_ticks=400)
    return dataclasses.replace(s, allocator={"type": "connectivity", "alpha": 0.1, "beta": 0.9,
                                             "position": "literal", "replan": "tick"}).validate()
