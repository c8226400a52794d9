"""Reinforcement learning on the fleet (the ``rl`` extra: pettingzoo, gymnasium): :func:`parallel_env`, a
PettingZoo ``ParallelEnv`` over the memory engine where a policy chooses each robot's frontier target, and
:func:`env`, its AEC form. A linear policy saved with
:func:`~fleet_emu.agents.allocators.policy.save_policy` runs in every engine as the ``policy`` allocator
(docs/guides/learning.md)."""

from __future__ import annotations

from typing import Any

from fleet_emu.rl.env import FleetParallelEnv


def parallel_env(scenario: Any = "default", **options: Any) -> FleetParallelEnv:
    """The fleet of ``scenario`` (a Scenario or a shipped scenario's name) as a parallel environment; options:
    ``k``, ``crop``, ``max_cycles``, ``moves``, ``time_cost``, ``overlap_cost``, ``render_mode``, and any
    scenario override (``robots=3``, ``map="maze"``, ``loss=0.3``)."""
    return FleetParallelEnv(scenario, **options)


def env(scenario: Any = "default", **options: Any) -> Any:
    """The AEC form of :func:`parallel_env` (PettingZoo's own conversion)."""
    from pettingzoo.utils.conversions import parallel_to_aec

    return parallel_to_aec(parallel_env(scenario, **options))


__all__ = ["FleetParallelEnv", "env", "parallel_env"]
