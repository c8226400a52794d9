"""The brain's teammate positions: a pose beacon carries the cell after the sender's commanded move, and every
allocator and the navigation see the teammate there (MinPos section 4.3 compares costs at the moment
of the decision)."""

from __future__ import annotations

import msgpack
import numpy as np
import pytest

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.brain import Brain, BrainConfig
from fleet_emu.agents.protocol import PoseBeacon
from fleet_emu.core.codec import Context
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.grid import UNKNOWN, Cell, from_ascii
from fleet_emu.core.messages import Envelope, Observation, RadioMsg, open_envelope, seal
from fleet_emu.core.messages import decode_payload as decode_body
from tests.harness.spy import Spy


def _brain(me: str = "r0") -> tuple[Brain, Spy]:
    spy = Spy()
    return Brain(me, spy, np.random.default_rng(0), BrainConfig(), team=frozenset({"r0", "r1", "r2"})), spy


def _obs(art: str, robot: str, tick: int) -> Observation:
    """The robot's observation: every known cell of the drawing, and its own cell."""
    grid, robots = from_ascii(art)
    cells = np.flatnonzero(grid.ravel() != UNKNOWN).astype(np.int32)
    return Observation(src="world", tick=tick, seq=0, robot=robot, cell=robots[robot], shape=grid.shape,
                       cell_size=0.5, cells=cells, values=grid.ravel()[cells].copy())


def _beacon(src: str, tick: int, cell: Cell, nxt: Cell | None) -> Envelope:
    return seal(RadioMsg(PoseBeacon(cell=cell, next=nxt)), src, tick, 1)


def _sent_beacon(out: tuple[Envelope, ...]) -> PoseBeacon:
    (beacon,) = [open_envelope(e).body for e in out if e.payload_kind == PoseBeacon.KIND]
    return beacon  # type: ignore[return-value]


CORRIDOR = """
###########
?.0.....1.?
###########
"""


def test_the_beacon_carries_the_cell_after_the_commanded_move() -> None:
    brain, _ = _brain()
    cmd, out = brain.step(_obs(CORRIDOR, "r0", 0), ())
    assert cmd.move == (0, -1)  # toward the frontier on the left
    assert _sent_beacon(out) == PoseBeacon(cell=(1, 2), next=(1, 1))


def test_a_staying_robot_announces_its_own_cell() -> None:
    brain, _ = _brain()
    cmd, out = brain.step(_obs("#####\n#.0.#\n#####", "r0", 0), ())  # nothing to explore
    assert cmd.move == (0, 0)
    assert _sent_beacon(out) == PoseBeacon(cell=(1, 2), next=(1, 2))


def test_allocators_see_a_teammate_at_the_cell_it_announced() -> None:
    brain, spy = _brain()
    brain.step(_obs(CORRIDOR, "r0", 0), ())
    brain.step(_obs(CORRIDOR, "r0", 1), (_beacon("r1", 0, (1, 8), (1, 9)), _beacon("r2", 0, (1, 5), None)))
    # r1 moved on to its next cell; r2's beacon has no next cell (an older sender): where it was
    assert spy.seen[-1] == {"r0": (1, 2), "r1": (1, 9), "r2": (1, 5)}


def test_a_teammate_announced_onto_my_cell_is_still_where_it_was() -> None:
    brain, spy = _brain()
    brain.step(_obs(CORRIDOR, "r0", 0), ())
    brain.step(_obs(CORRIDOR, "r0", 1), (_beacon("r1", 0, (1, 3), (1, 2)),))  # its move into (1, 2) failed
    assert spy.seen[-1]["r1"] == (1, 3)


FOLLOW = """
#######
#?????#
#?.0.?#
#?.1.?#
#?...?#
#######
"""


@pytest.mark.parametrize(("nxt", "move"), [((1, 3), (-1, 0)), ((2, 3), (0, -1))])
def test_navigation_follows_a_moving_teammate_and_steps_around_a_standing_one(nxt: Cell, move: Cell) -> None:
    """r1 heads up toward the unknown above r0. r0 moving on up: r1 steps into the cell r0 leaves (the world
    lets a line advance in one tick). r0 standing: r1 takes the other way down the wavefront."""
    brain, _ = _brain("r1")
    brain.step(_obs(FOLLOW, "r1", 0), ())
    cmd, _ = brain.step(_obs(FOLLOW, "r1", 1), (_beacon("r0", 0, (2, 3), nxt),))
    assert cmd.move == move


def test_navigation_leaves_its_kept_wavefront_blank_and_the_plan_grows_the_whole_one() -> None:
    """Navigation's wavefront is grown in arrays kept per thread, stopped at the robot: after a step every
    distance is -1 again (the next robot or tick starts from a blank grid); the plan grows the cluster's whole
    wavefront when real time steps on it, and from the robot's cell it gives the move the step made."""
    from fleet_emu.agents.brain import _scratch

    brain = Brain("r1", make_allocator({"type": "minpos", "wavefront": "parallel"}), np.random.default_rng(0),
                  BrainConfig(), team=frozenset({"r0", "r1"}))  # an allocator that grows no whole wavefront
    cmd, _ = brain.step(_obs(FOLLOW, "r1", 0), ())
    grid, _ = from_ascii(FOLLOW)
    dist, _ = _scratch(grid.size)
    assert (dist == -1).all()
    assert brain.plan is not None and brain.plan.dist is None and brain.plan.sources is not None
    assert brain.plan.step(_obs(FOLLOW, "r1", 0).cell) == cmd.move != (0, 0)
    assert brain.plan.dist is not None and (brain.plan.dist >= 0).sum() > 3  # grown past the robot


def test_the_beacon_decodes_with_and_without_its_next_cell() -> None:
    ctx = Context(shape=(3, 11))
    with_next = PoseBeacon(cell=(1, 2), next=(1, 3))
    assert decode_body("pose", with_next.encode(), ctx) == with_next
    old = msgpack.packb({"cell": [1, 2]})  # a beacon from before the next cell: still read, expected in place
    assert decode_body("pose", old, ctx).expected == (1, 2)  # type: ignore[attr-defined]
    for bad in ((1, 4), (2, 3), (5, 3)):  # two steps away, diagonal, outside the grid
        with pytest.raises(DecodeError, match="pose"):
            decode_body("pose", PoseBeacon(cell=(1, 2), next=bad).encode(), ctx)


def test_the_allocator_gets_the_previous_decisions_target() -> None:
    """``Problem.previous_target`` (for ``replan="observed"``): the last command's target, None at the first
    decision and after one that found no frontier."""
    brain, spy = _brain()
    cmd0, _ = brain.step(_obs(CORRIDOR, "r0", 0), ())
    assert cmd0.target == (1, 1)
    brain.step(_obs(CORRIDOR, "r0", 1), ())
    closed = CORRIDOR.replace("?", "#")
    brain.step(_obs(closed, "r0", 2), ())
    brain.step(_obs(closed, "r0", 3), ())
    assert spy.previous == [None, (1, 1), (1, 1), None]
