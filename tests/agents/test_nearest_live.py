"""Nearest frontier run live (:mod:`tests.harness.lockstep`): a robot behind a teammate on the way to the same
frontier follows it, with no wait for the cell the teammate has just left.

Before the beacons carried the next cell, a robot saw its teammate on the cell the teammate
had left one tick earlier, waited for it, and after two such waits took a random step. These false waits and
random steps spread out two nearest-frontier robots that started together; with the teammate seen where it is,
they follow each other as the MinPos paper says nearest frontier robots do (Bautin et al. 2012, Fig. 6(a):
"both robots would have continued exploring the area behind F1"), and a pair on hospital_section is slower
than it was."""

from __future__ import annotations

from tests.harness.lockstep import run_fleet

# r1 starts two cells behind r0; the only frontier is ahead of both.
CORRIDOR = """
##################################
#1.0.............................#
##################################
"""


def test_a_follower_does_not_wait_for_the_cell_its_leader_has_left() -> None:
    trace = run_fleet(CORRIDOR, {"type": "nearest"}, sensor_range=3.0)
    assert trace.reason == "coverage"
    lead = [c for _, c in trace.visited("r0")]
    follow = [c for _, c in trace.visited("r1")]
    moving = [t for t in range(len(lead) - 1) if lead[t + 1] > lead[t]]
    assert len(moving) > 20
    # the follower steps every tick its leader steps and stays two cells behind it (with the old view it saw
    # r0 on the cell r0 had left at tick 0 and waited a tick)
    assert all(follow[t + 1] == follow[t] + 1 for t in moving), follow
    assert all(lead[t] - follow[t] == 2 for t in range(len(lead))), (lead, follow)
