"""``fleet_emu.rl``: PettingZoo's own tests on the environment (a small map, three robots, few cycles), what an
observation may hold, and that a policy's choices in the environment are the ``policy`` allocator's run."""

from __future__ import annotations

import functools
import types
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pettingzoo")

from pettingzoo.test import (
    api_test,
    max_cycles_test,
    parallel_api_test,
    parallel_seed_test,
    render_test,
    seed_test,
    state_test,
)

import fleet_emu as fe
from fleet_emu import rl
from fleet_emu.agents.allocators.policy import candidates, save_policy
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic


def _scenario(small_map: Path, **kw: object) -> fe.Scenario:
    return fe.Scenario().override(**{"map": str(small_map), "robots": 3, "seed": 3, "max_ticks": 40, **kw})


@pytest.fixture
def mod(small_map: Path) -> types.SimpleNamespace:
    """A module as PettingZoo's tests take one: ``parallel_env`` and ``env`` over the small map."""
    s = _scenario(small_map, loss=0.3)
    return types.SimpleNamespace(parallel_env=functools.partial(rl.parallel_env, s),
                                 env=functools.partial(rl.env, s))


def test_pettingzoo_parallel_api_and_aec_api(mod: types.SimpleNamespace) -> None:
    parallel_api_test(mod.parallel_env(), num_cycles=30)
    api_test(mod.env(), num_cycles=30)


def test_pettingzoo_seed_test(mod: types.SimpleNamespace) -> None:
    parallel_seed_test(functools.partial(mod.parallel_env, max_cycles=30), num_cycles=30)
    seed_test(functools.partial(mod.env, max_cycles=30), num_cycles=30)


def test_pettingzoo_max_cycles_render_and_state(mod: types.SimpleNamespace) -> None:
    max_cycles_test(mod)
    render_test(functools.partial(mod.env, max_cycles=10))
    state_test(mod.env(max_cycles=10), mod.parallel_env(max_cycles=10), num_cycles=10)
    img = mod.parallel_env(render_mode="rgb_array")
    img.reset(seed=1)
    frame = img.render()
    assert frame is not None and frame.dtype == np.uint8 and frame.shape[2] == 3


def test_an_observation_holds_only_what_the_robot_knows(small_map: Path) -> None:
    """With every message lost a robot hears no teammate: none is in its observation, and its map crop is its
    own belief; with the radio on, teammates appear."""
    for loss, heard in ((1.0, False), (0.0, True)):
        env = rl.parallel_env(_scenario(small_map, loss=loss), crop=5)
        obs, _ = env.reset()
        for _ in range(4):
            obs, *_ = env.step({r: 0 for r in env.agents})
        for r in env.agents:
            brain = env.fleet.brains[r]
            assert bool(obs[r]["teammates"].any()) is heard and bool(brain.teammates) is heard
            grid, (row, col) = brain.belief.grid, env.fleet.world.poses[r]
            padded = np.pad(grid, 5, constant_values=-1)
            assert np.array_equal(obs[r]["map"], padded[row:row + 11, col:col + 11])
            assert obs[r]["action_mask"][-1] == 1 and env.observation_space(r).contains(obs[r])


def _linear(weights: np.ndarray, obs: dict[str, np.ndarray]) -> int:
    """The ``policy`` allocator's choice, from the observation alone."""
    n = int(obs["action_mask"][:-1].sum())
    return int(np.argmax(obs["targets"][:n] @ weights)) if n else len(obs["action_mask"]) - 1


def test_a_policy_in_the_environment_is_the_policy_allocator(small_map: Path, tmp_path: Path) -> None:
    """Acting on the observations with a linear policy makes the run the ``policy`` allocator makes with the
    same weights, at loss: the choice enters the brain where the allocator's does."""
    weights = np.array([-1.0, 0.3, -0.5, 0.1, 0.4])
    save_policy(tmp_path / "p.npz", weights)
    s = _scenario(small_map, loss=0.3, max_ticks=300)
    env = rl.parallel_env(s)
    obs, _ = env.reset()
    while env.agents:
        obs, *_ = env.step({r: _linear(weights, o) for r, o in obs.items()})
    fleet = Fleet(s.override(allocator={"type": "policy", "path": str(tmp_path / "p.npz")}))
    learned, allocated = env.fleet.result(), fleet.run()
    named = {"allocator", "allocator_params", "scenario"}  # the environment's scenario names its own allocator
    assert {k: v for k, v in deterministic(learned.data).items() if k not in named} == \
        {k: v for k, v in deterministic(allocated.data).items() if k not in named}
    assert learned.curve == allocated.curve and learned["ticks"] > 10 and learned["radio"]["dropped_loss"] > 0


def test_raw_moves_and_the_reward_terms(small_map: Path) -> None:
    """``moves=True``: Discrete(5) raw moves pass PettingZoo's API test, and a robot told to stay stays; the time
    and overlap costs come off the team's gain."""
    s = _scenario(small_map, loss=0.3)
    parallel_api_test(rl.parallel_env(s, moves=True), num_cycles=20)
    env = rl.parallel_env(s, moves=True)
    env.reset()
    before = dict(env.fleet.world.poses)
    env.step(dict.fromkeys(env.agents, 0))
    assert env.fleet.world.poses == before
    plain, costly = rl.parallel_env(s), rl.parallel_env(s, time_cost=0.01, overlap_cost=0.1)
    plain.reset()
    costly.reset()
    shared = 0
    for _ in range(15):
        targets = {}
        for r, p in costly._percepts.items():  # action 0: each robot's nearest candidate
            cands = candidates(p.problem, costly.k)
            targets[r] = p.problem.clusters[cands[0]].target if cands else None
        _, gain, *_ = plain.step(dict.fromkeys(plain.agents, 0))
        _, paid, *_ = costly.step(dict.fromkeys(costly.agents, 0))
        for r in gain:
            same = sum(1 for q, t in targets.items() if q != r and t is not None and t == targets[r])
            shared += same
            assert paid[r] == pytest.approx(gain[r] - 0.01 - 0.1 * same)
    assert shared > 0  # robots near one another head for the same nearest frontier at times


@pytest.mark.slow  # a benchmark script's smoke run
def test_env_speed_smoke(capsys: pytest.CaptureFixture[str]) -> None:
    from tests.harness.bench import bench, markdown

    code, out, _ = bench("env_speed", "--robots", "2", "--ticks", "3", "--big-ticks", "2", "--repeat", "1",
                         capsys=capsys)
    rows = markdown(out)
    assert code == 0 and len(rows) == 2 and all(float(r["environment steps/s"]) > 0 for r in rows)
