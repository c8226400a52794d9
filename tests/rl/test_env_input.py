"""The environment's arguments and actions are checked as a scenario's settings are (``core/fields.setting``):
each bad one is a :class:`ConfigError` of one line before anything is allocated (a ``crop`` of a million once
asked numpy for terabytes), never a raw error; and ``step()`` before ``reset()`` says so."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

import fleet_emu as fe
from fleet_emu import rl
from fleet_emu.core.errors import ConfigError


@pytest.fixture
def scenario(small_map: Path) -> fe.Scenario:
    return fe.Scenario().override(map=str(small_map), robots=2, seed=1, max_ticks=20)


@pytest.mark.parametrize(("options", "says"), [
    ({"k": -1}, "k must be from 1 to 256 (got -1)"),
    ({"k": 0}, "k must be from 1 to 256"),
    ({"k": 10**12}, "k must be from 1 to 256"),
    ({"k": 2.5}, "k must be a whole number"),
    ({"k": True}, "k must be a whole number"),
    ({"crop": -3}, "crop must be from 0 to 256 cells"),
    ({"crop": 1_000_000}, "crop must be from 0 to 256 cells"),
    ({"crop": "8"}, "crop must be a whole number"),
    ({"time_cost": math.nan}, "time_cost must be a finite number"),
    ({"time_cost": math.inf}, "time_cost must be a finite number"),
    ({"overlap_cost": -1.0}, "overlap_cost must be within [0, 1000000]"),
    ({"moves": "yes"}, "moves must be True or False"),
    ({"render_mode": 3}, "render_mode must be None or a name"),
    ({"robots": 0}, "robots"),
])
def test_a_bad_argument_is_one_config_error(scenario: fe.Scenario, options: dict[str, object], says: str) -> None:
    with pytest.raises(ConfigError) as err:
        rl.parallel_env(scenario, **options)
    assert says in str(err.value) and "\n" not in str(err.value)


def test_a_bad_action_or_a_step_before_reset_is_one_config_error(scenario: fe.Scenario) -> None:
    env = rl.parallel_env(scenario, k=4)
    with pytest.raises(ConfigError, match=r"step\(\) before reset\(\)"):
        env.step({})
    env.reset(seed=1)
    for bad in ("abc", math.nan, [1], 2.5, True, -1, 5, np.float64(1.0), np.array([1, 2])):
        with pytest.raises(ConfigError, match="the action of r0 must be a whole number from 0 to 4 or None"):
            env.step({"r0": bad, "r1": 0})
    with pytest.raises(ConfigError, match="unknown robot"):
        env.step({"r9": 0})
    with pytest.raises(ConfigError, match="actions must be a mapping"):
        env.step([0, 0])  # type: ignore[arg-type]
    obs, rewards, *_ = env.step({"r0": np.int64(4), "r1": np.array(0)})  # numpy's whole numbers are actions
    assert set(obs) == {"r0", "r1"} and all(math.isfinite(r) for r in rewards.values())
    moves = rl.parallel_env(scenario, moves=True)
    moves.reset(seed=1)
    with pytest.raises(ConfigError, match="from 0 to 4 or None"):
        moves.step({"r0": 5})
