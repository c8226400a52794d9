"""A PettingZoo ``ParallelEnv`` over the memory engine: a policy chooses each robot's frontier target.

Each tick every live robot perceives (:meth:`Fleet.perceive`: its belief, the teammates it heard, its frontier
clusters), the policy chooses for each one of its K nearest frontier targets or none (``Discrete(K + 1)``, the
last action "none": the robot holds), and the robot then acts exactly as it does after an allocator's decision:
it walks down the wavefront to that target, announces the move it takes in its beacon, and sends its map news
(:meth:`Brain.act`). With ``moves=True`` the action is a raw move instead (``Discrete(5)``: stay, up, down,
left, right), driven as a goal on the neighbouring cell. The radio, its losses and the map exchange are the
scenario's, as in every engine.

Observations hold only what the robot knows (:func:`observe`): ``map`` a crop of its belief around its cell
(unknown outside the map), ``targets`` its candidates' features (``fleet_emu.agents.allocators.policy``), the
``action_mask``, ``teammates`` (for every other robot in id order: heard or not, its last known cell relative
to the robot's, the age of that belief in ticks) and ``radio`` (teammates linked now, teammates heard this
tick, bytes queued at its radio). :meth:`FleetParallelEnv.state` gives the truth for centralised training.

Rewards: every robot gets the team's coverage gain of the tick (the fraction of free cells newly sensed), less
``time_cost`` per tick and ``overlap_cost`` for each teammate that chose the same target. The run terminates
at the scenario's target coverage and is truncated at ``max_cycles`` ticks (or when the scenario's stall
rules end it). The observation returned with the last step repeats the robot's last decision's. The run's
``result.json`` (``env.fleet.result()``) is a run's in every key but the allocator's name, which stays the
scenario's: the policy took its seat.

Every constructor argument is declared once (:class:`EnvOptions`, with :func:`~fleet_emu.core.fields.setting`,
as a scenario's settings are) and checked the same way, and so is every action: a bad one is a
:class:`~fleet_emu.core.errors.ConfigError` of one line, as is :meth:`FleetParallelEnv.step` before
:meth:`~FleetParallelEnv.reset`.
"""

from __future__ import annotations

import dataclasses
import numbers
from collections.abc import Mapping
from typing import Any

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv

from fleet_emu.agents.allocators import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.policy import DEFAULT_K, FEATURES, MAX_K, candidates, target_features
from fleet_emu.agents.brain import Brain, Percept
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.fields import check_all, setting
from fleet_emu.core.grid import FREE, MOVES, STAY, UNKNOWN, Cell
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from fleet_emu.rl.render import render_rgb

RENDER_MODES = ("rgb_array",)
#: Raw moves (``moves=True``): action i moves by ``ACTION_MOVES[i]``.
ACTION_MOVES: tuple[Cell, ...] = (STAY, *MOVES)


@dataclasses.dataclass(frozen=True)
class EnvOptions:
    """The environment's own settings (its other keywords are scenario overrides), each declared once."""

    k: int = setting(DEFAULT_K, low=1, high=MAX_K, help="candidate frontier targets per robot (K + 1 actions)")
    crop: int = setting(8, unit="cells", low=0, high=256, help="the map observation's half side")
    time_cost: float = setting(0.0, low=0.0, high=1e6, help="reward taken off every robot each tick")
    overlap_cost: float = setting(0.0, low=0.0, high=1e6, help="reward taken off for each teammate on the same target")


def check_options(k: Any, crop: Any, time_cost: Any, overlap_cost: Any, moves: Any, render_mode: Any) -> None:
    """A ConfigError of one line on the first argument of :class:`FleetParallelEnv` that is not accepted."""
    check_all(EnvOptions(k, crop, time_cost, overlap_cost))
    if not isinstance(moves, bool):
        raise ConfigError(f"moves must be True or False (got {moves!r})")
    if render_mode is not None and not isinstance(render_mode, str):  # a mode it does not draw renders None
        raise ConfigError(f"render_mode must be None or a name such as {', '.join(RENDER_MODES)} "
                          f"(got {render_mode!r})")


def check_action(robot: str, action: Any, n_actions: int) -> int | None:
    """``action`` as the index it names (None for none): a whole number in ``[0, n_actions)`` (numpy's too, or
    an array of one), else a ConfigError of one line naming the robot."""
    if action is None:
        return None
    value = action.item() if isinstance(action, np.ndarray) and action.size == 1 else action
    if not isinstance(value, numbers.Integral) or isinstance(value, bool | np.bool_) or not 0 <= int(value) < n_actions:
        raise ConfigError(f"the action of {robot} must be a whole number from 0 to {n_actions - 1} or None "
                          f"(got {action!r})")
    return int(value)


class Chosen(Allocator):
    """The allocator seat a policy fills: it returns the allocation the environment set for this tick."""

    def __init__(self) -> None:
        super().__init__()
        self.allocation = Allocation.none()

    def allocate(self, problem: Problem, inbox: Any = ()) -> Allocation:
        return self.allocation


class FleetParallelEnv(ParallelEnv):
    """The fleet of ``scenario`` as a PettingZoo parallel environment (module docstring)."""

    metadata = {"name": "fleet_emu_v0", "render_modes": list(RENDER_MODES), "is_parallelizable": True, "render_fps": 10}

    def __init__(self, scenario: Scenario | str = "default", *, k: int = DEFAULT_K, crop: int = 8,
                 max_cycles: int | None = None, moves: bool = False, time_cost: float = 0.0,
                 overlap_cost: float = 0.0, render_mode: str | None = None, **overrides: Any) -> None:
        check_options(k, crop, time_cost, overlap_cost, moves, render_mode)
        s = Scenario.load(scenario) if isinstance(scenario, str) else scenario
        if not isinstance(s, Scenario):
            raise ConfigError(f"scenario must be a Scenario or a scenario's name or file (got {scenario!r})")
        if max_cycles is not None:
            overrides["max_ticks"] = max_cycles
        self.scenario = s.override(**overrides) if overrides else s
        self.k, self.crop, self.moves = k, crop, moves
        self.time_cost, self.overlap_cost = time_cost, overlap_cost
        self.render_mode = render_mode
        self.fleet = Fleet(self.scenario)
        self.possible_agents = list(self.fleet.possible_agents)
        self.agents: list[str] = []
        self._obs: dict[str, dict[str, np.ndarray]] = {}
        self._percepts: dict[str, Percept] = {}
        self._spaces()

    def _spaces(self) -> None:
        n, side = len(self.possible_agents), 2 * self.crop + 1
        n_actions = len(ACTION_MOVES) if self.moves else self.k + 1
        obs = gymnasium.spaces.Dict({
            "map": gymnasium.spaces.Box(UNKNOWN, 100, (side, side), np.int8),
            "targets": gymnasium.spaces.Box(0.0, np.inf, (self.k, len(FEATURES)), np.float32),
            "action_mask": gymnasium.spaces.Box(0, 1, (n_actions,), np.int8),
            "teammates": gymnasium.spaces.Box(-np.inf, np.inf, (n - 1, 4), np.float32),
            "radio": gymnasium.spaces.Box(0.0, np.inf, (3,), np.float32),
        })
        self.observation_spaces = {r: obs for r in self.possible_agents}
        self.action_spaces = {r: gymnasium.spaces.Discrete(n_actions) for r in self.possible_agents}
        shape = self.fleet_shape()
        self.state_space = gymnasium.spaces.Box(-1, 100, (3, *shape), np.int8)

    def fleet_shape(self) -> tuple[int, int]:
        """The grid's shape (the map is loaded to know it)."""
        from fleet_emu.launch.memory import fleet_map

        rows, cols = fleet_map(self.scenario).grid.shape
        return int(rows), int(cols)

    def observation_space(self, agent: str) -> gymnasium.spaces.Space:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> gymnasium.spaces.Space:
        return self.action_spaces[agent]

    def reset(self, seed: int | None = None, options: Mapping[str, Any] | None = None
              ) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, dict[str, Any]]]:
        """A new run (the scenario's seed, or ``seed``); every robot's observation of tick 0."""
        self.fleet.reset(seed)
        for brain in self.fleet.brains.values():
            brain.allocator = Chosen()
            brain.allocator.reset(brain.rng)
        self.agents = list(self.fleet.agents)
        self._perceive()
        return dict(self._obs), {r: {} for r in self.agents}

    def _perceive(self) -> None:
        self._percepts = self.fleet.perceive()
        f = self.fleet
        self._obs = {r: observe(f.brains[r], self._percepts[r], self.k, self.crop, self.possible_agents,
                                self._radio(r), self.moves) for r in self.agents}

    def _radio(self, r: str) -> np.ndarray:
        """Teammates linked now, teammates heard this tick, bytes queued at the robot's radio."""
        f = self.fleet
        i = f.nodes.index(r)
        linked = sum(1 for j, n in enumerate(f.nodes) if j != i and n != "base" and f.link[i, j])
        t = f.world.tick
        heard = sum(1 for tm in f.brains[r].teammates.values() if tm.heard >= t)
        medium = f.channel.medium
        queued = medium.queues[r].nbytes if medium is not None and r in medium.queues else 0
        return np.array([linked, heard, queued], dtype=np.float32)

    def step(self, actions: Mapping[str, Any]) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, float],
                                                        dict[str, bool], dict[str, bool], dict[str, Any]]:
        """Every live robot acts on its action (none for a missing one), netem sends, the world moves."""
        if not self.agents:
            raise ConfigError("step() before reset(), or after the run ended: call reset() first")
        if not isinstance(actions, Mapping):
            raise ConfigError(f"actions must be a mapping of robot to action (got {type(actions).__name__})")
        unknown = sorted(map(str, set(actions) - set(self.possible_agents)))
        if unknown:
            raise ConfigError(f"actions for unknown robot(s) {', '.join(unknown)} (robots: "
                              f"{', '.join(self.possible_agents)})")
        n_actions = len(ACTION_MOVES) if self.moves else self.k + 1
        chosen = {r: check_action(r, actions.get(r), n_actions) for r in self.agents}
        targets: dict[str, Cell | None] = {}
        for r in self.agents:
            alloc = self._allocation(self._percepts[r], chosen[r])
            chooser = self.fleet.brains[r].allocator
            assert isinstance(chooser, Chosen)
            chooser.allocation = alloc
            targets[r] = alloc.target
        _, rewards, terms, truncs, infos = self.fleet.step()
        for r in rewards:
            same = sum(1 for q, t in targets.items() if q != r and t is not None and t == targets[r])
            rewards[r] = float(rewards[r]) - self.time_cost - self.overlap_cost * same
        live = list(self.agents)
        if self.fleet.done:
            self.agents = []
            obs = {r: self._obs[r] for r in live}
        else:
            self.agents = list(self.fleet.agents)
            self._perceive()
            obs = dict(self._obs)
        return obs, rewards, terms, truncs, infos

    def _allocation(self, p: Percept, a: int | None) -> Allocation:
        """The allocation action ``a`` stands for (none for a masked one)."""
        problem = p.problem
        if self.moves:
            m = ACTION_MOVES[a] if a is not None and 0 <= a < len(ACTION_MOVES) else STAY
            cell = (p.obs.cell[0] + m[0], p.obs.cell[1] + m[1])
            if m == STAY or not _inside(problem.belief, cell) or problem.belief[cell] != FREE:
                return Allocation.hold()
            return Allocation.goal(cell)
        cands = candidates(problem, self.k)
        if a is None or not 0 <= a < len(cands):
            return Allocation.none()
        return Allocation.assigned(problem, cands[a])

    def state(self) -> np.ndarray:
        """The truth: the true map, the union of what the robots have seen (true values, unknown elsewhere),
        and every robot's cell (1, else 0), stacked ``(3, rows, cols)``."""
        w = self.fleet.world
        truth = np.where(self.fleet.map.grid > 0, 100, 0).astype(np.int8)
        seen = np.where(w._sensed, truth, UNKNOWN).astype(np.int8)
        poses = np.zeros_like(truth)
        for cell in w.poses.values():
            poses[cell] = 1
        return np.stack([truth, seen, poses])

    def render(self) -> np.ndarray | None:
        """With ``render_mode="rgb_array"`` (the one mode, :attr:`metadata`): the truth, what was seen, each robot
        and its radio links (:func:`render_rgb`); None in any other mode."""
        if self.render_mode != "rgb_array":
            return None
        f = self.fleet
        return render_rgb(self.state(), [f.world.poses[n] for n in f.nodes if n in f.world.poses], f.link)

    def close(self) -> None:
        """Nothing to release."""


def observe(brain: Brain, p: Percept, k: int, crop: int, robots: list[str], radio: np.ndarray,
            moves: bool = False) -> dict[str, np.ndarray]:
    """One robot's observation, from its brain alone (module docstring)."""
    problem, cell, t = p.problem, p.obs.cell, p.obs.tick
    cands = candidates(problem, k)
    targets = np.zeros((k, len(FEATURES)), dtype=np.float32)
    targets[:len(cands)] = target_features(problem, cands)
    if moves:
        mask = np.array([1] + [int(_inside(problem.belief, (cell[0] + m[0], cell[1] + m[1]))
                                   and problem.belief[cell[0] + m[0], cell[1] + m[1]] == FREE) for m in MOVES],
                        dtype=np.int8)
    else:
        mask = np.zeros(k + 1, dtype=np.int8)
        mask[:len(cands)] = 1
        mask[k] = 1
    mates = np.zeros((len(robots) - 1, 4), dtype=np.float32)
    for i, r in enumerate(q for q in robots if q != brain.me):
        tm = brain.teammates.get(r)
        if tm is not None:
            at = p.expected[r]
            mates[i] = (1.0, at[0] - cell[0], at[1] - cell[1], t - tm.heard)
    return {"map": belief_crop(problem.belief, cell, crop), "targets": targets, "action_mask": mask,
            "teammates": mates, "radio": radio}


def belief_crop(belief: np.ndarray, cell: Cell, crop: int) -> np.ndarray:
    """The ``(2 crop + 1)²`` window of ``belief`` centred on ``cell``, unknown outside the grid."""
    padded = np.pad(belief, crop, constant_values=UNKNOWN)
    r, c = cell
    return padded[r:r + 2 * crop + 1, c:c + 2 * crop + 1].astype(np.int8, copy=True)


def _inside(grid: np.ndarray, cell: Cell) -> bool:
    return 0 <= cell[0] < grid.shape[0] and 0 <= cell[1] < grid.shape[1]
