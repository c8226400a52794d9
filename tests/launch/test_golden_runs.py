"""Fixed memory-engine runs give the result recorded on main before the incremental frontier clustering
(recorded on main at be5c9a7, and again at fab62f8, whose map sync changed lossy runs; ``allocator_params``
later became every effective parameter, the only key that changed):
``result.json``'s deterministic keys, and a digest of every command and every radio payload of the run, are
identical. Regenerate (only for a deliberate behaviour change) with
``python -m tests.launch.test_golden_runs``."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path
from typing import Any

import pytest

from fleet_emu.core.messages import Command, Message, TxBundle
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic

DATA = Path(__file__).parent / "data" / "golden_runs.json"
MAZE_CS = 30.0 / 512  # the 30 m maze at 512 x 512 cells


def scenarios() -> dict[str, Scenario]:
    office = Scenario().override(map="office", robots=4, allocator="minpos", seed=3, loss=0.1)
    utility = Scenario().override(map="office", robots=3, allocator="utility", seed=8, loss=0.3, max_ticks=200)
    maze = Scenario().override(map="maze", cell_size=MAZE_CS, robots=8, seed=0, max_ticks=50, target_coverage=1.0,
                               sensor_range=8 * MAZE_CS, comm_range=20 * MAZE_CS)
    maze = dataclasses.replace(maze, allocator={"type": "minpos", "wavefront": "parallel"}).validate()
    return {"office_minpos": office, "office_utility": utility, "maze512_minpos_parallel": maze}


def run(scenario: Scenario) -> dict[str, Any]:
    """The run's deterministic keys, and sha256 digests of its commands (move, target, status, tick, robot)
    and of every radio payload the robots sent, in order."""
    cmds, radio = hashlib.sha256(), hashlib.sha256()

    def tap(_key: str, msg: Message, _ns: int) -> None:
        if isinstance(msg, Command):
            cmds.update(repr((msg.src, msg.tick, msg.move, msg.target, msg.status)).encode())
        elif isinstance(msg, TxBundle):
            for env in msg.msgs:
                radio.update(repr((env.src, env.tick, env.dst, env.payload_kind)).encode() + env.payload)

    result = Fleet(scenario, tap=tap).run()
    return {"result": json.loads(json.dumps(deterministic(result.data))), "commands": cmds.hexdigest(),
            "radio": radio.hexdigest()}


@pytest.mark.parametrize("name", sorted(scenarios()))
def test_run_is_the_recorded_one(name: str) -> None:
    recorded = json.loads(DATA.read_text())[name]
    got = run(scenarios()[name])
    assert got["result"]["ticks"] > 0 and got["result"]["radio"]["sent"] > 0
    assert got == recorded


if __name__ == "__main__":
    DATA.write_text(json.dumps({n: run(s) for n, s in scenarios().items()}, indent=1, sort_keys=True) + "\n")
    print(f"wrote {DATA}")
