"""The idle robot-ticks of result.json: counted by the monitor from the world's states and the robots' commands."""

from __future__ import annotations

from fleet_emu.core.messages import Command, WorldState
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.result import fold_keys

ROBOTS = ("r0", "r1", "r2")


def _state(tick: int, poses: dict[str, tuple[int, int]], live: tuple[str, ...] = ROBOTS) -> WorldState:
    return WorldState(src="world", tick=tick, seq=tick, poses=poses, live=live, coverage=0.1,
                      path_length={r: 0 for r in poses})


def _cmd(robot: str, tick: int, status: str, move: tuple[int, int] = (0, 0)) -> Command:
    return Command(src=robot, tick=tick, seq=tick, move=move, status=status)


def test_a_robot_with_something_to_do_that_stays_is_idle() -> None:
    m = Monitor(ROBOTS)
    m.fold(_state(0, {"r0": (1, 1), "r1": (1, 2), "r2": (1, 3)}))
    m.fold(_cmd("r0", 0, "WAITING"))  # stays: idle (waiting)
    m.fold(_cmd("r1", 0, "ASSIGNED", (1, 0)))  # moves: not idle
    m.fold(_cmd("r2", 0, "ASSIGNED", (0, -1)))  # blocked by r1's cell: idle (assigned)
    m.fold(_state(1, {"r0": (1, 1), "r1": (2, 2), "r2": (1, 3)}))
    m.fold(_cmd("r0", 1, "NO_FRONTIER"))  # nothing to do: not idle
    m.fold(_cmd("r1", 1, "WAITING"))
    m.fold(_cmd("r2", 1, "WAITING"))
    m.fold(_state(2, {"r0": (1, 1), "r1": (2, 2), "r2": (1, 3)}, live=("r0", "r1")))  # r2 failed
    res = fold_keys(m, {"seed": 0, "map": "m", "allocator": {"type": "trade"}, "robots": 3,
                        "radio": {"loss": 0.0, "comm": "full"}}, "run", 0.99)
    assert res["idle_by_status"] == {"ASSIGNED": 1, "WAITING": 2}
    assert res["idle_robot_ticks"] == 3


def test_the_count_does_not_depend_on_the_order_messages_arrive_in() -> None:
    msgs = [_state(0, {"r0": (0, 0)}, ("r0",)), _cmd("r0", 0, "WAITING"), _state(1, {"r0": (0, 0)}, ("r0",)),
            _cmd("r0", 1, "ASSIGNED", (0, 1)), _state(2, {"r0": (0, 1)}, ("r0",)), _cmd("r0", 2, "ASSIGNED")]
    counts = []
    for order in (msgs, msgs[::-1]):
        m = Monitor(("r0",))
        for msg in order:
            m.fold(msg)
        counts.append(m.idle())
    assert counts == [{"WAITING": 1}, {"WAITING": 1}]  # the last command has no next state: not counted
