"""The trade-based allocator (Yan et al. 2011) driven as a fleet: each allocator's outbox goes, through the
codec, to the others' inboxes one tick later (netem's latency), with a seeded function that drops some."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from fleet_emu.agents.allocators import AllocStatus, Problem, make_allocator
from fleet_emu.agents.allocators.conformance import api_test, seed_test
from fleet_emu.agents.allocators.trade import Phase, TradeAllocation, TradeNumber, TradePurchase, greedy_table
from fleet_emu.agents.frontiers import find_clusters
from fleet_emu.agents.navigation import next_move
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.grid import FREE, OCCUPIED, UNKNOWN, Cell, from_ascii
from fleet_emu.core.kernels import visible_cells, wavefront
from fleet_emu.core.messages import Context, Envelope, RadioMsg, decode, open_envelope, seal

Drop = Callable[[RadioMsg, str, int], bool]  # (message, receiver, tick it was sent) -> lost?

# Four one-cell frontiers at the corners; each robot has its own nearest one.
CORNERS = """
?.............?
#.0...........#
#...........2.#
#.1...........#
?.............?
"""

# Same frontiers, but r0 and r1 both nearest the top-left one.
CONTENDED = """
?.............?
#.0...........#
#.1.........2.#
#.............#
?.............?
"""

T, A, R = 2, 5, 1  # the defaults: time_max, award_timeout, retries
BOUND = (R + 1) * (T + A) + T  # the documented worst case, in ticks after a robot becomes free


def never(msg: RadioMsg, dst: str, tick: int) -> bool:
    return False


class Fleet:
    """Allocators of several robots on one shared belief, messages delivered the next tick."""

    def __init__(self, robots: list[str], **params: int | bool) -> None:
        self.allocs = {r: make_allocator({"type": "trade", **params}) for r in robots}
        for k, a in enumerate(self.allocs.values()):
            a.reset(np.random.default_rng(k))
        self.pending: list[RadioMsg] = []
        self.sent: list[RadioMsg] = []
        self.statuses: dict[str, list[AllocStatus]] = {r: [] for r in robots}
        self.in_task: dict[str, list[bool]] = {r: [] for r in robots}  # allocated a task (not in a round)
        self.targets: dict[str, Cell | None] = dict.fromkeys(robots)

    def tick(self, t: int, belief: np.ndarray, poses: dict[str, Cell], drop: Drop = never,
             silent: frozenset[str] = frozenset()) -> dict[str, int | None]:
        ctx = Context(senders=frozenset(self.allocs), shape=belief.shape)
        clusters = find_clusters(belief, 4)
        out: list[RadioMsg] = []
        chosen: dict[str, int | None] = {}
        for r, alloc in self.allocs.items():
            inbox = [m for m in self.pending if m.src != r and m.dst in ("*", r) and not drop(m, r, t - 1)]
            p = Problem(me=r, poses=poses, belief=belief, clusters=clusters, tick=t)
            a = alloc.allocate(p, inbox)
            self.statuses[r].append(a.status)
            self.in_task[r].append(alloc.s.phase is Phase.TASK)
            self.targets[r] = a.target
            chosen[r] = a.cluster if a.status is AllocStatus.ASSIGNED else None
            for m in a.outbox:
                assert m.ttl == 0 and m.dst in ({"*"} | set(self.allocs))
            if r not in silent:  # sealed as the brain does, and through the codec as the radio carries it
                envelopes = [seal(m, r, t, k) for k, m in enumerate(a.outbox)]
                out.extend(open_envelope(decode(e.encode(), ctx, Envelope), ctx) for e in envelopes)
        self.sent.extend(out)
        self.pending = out
        return chosen

    def run_static(self, art: str, ticks: int, drop: Drop = never, silent_from: dict[str, int] | None = None) -> None:
        grid, poses = from_ascii(art)
        for t in range(ticks):
            silent = frozenset(r for r, t0 in (silent_from or {}).items() if t >= t0)
            self.tick(t, grid, poses, drop, silent)

    def first_assigned(self, robot: str, after: int = 0) -> int | None:
        """The first tick the robot was in an allocated task (a round ended for it)."""
        for t, in_task in enumerate(self.in_task[robot]):
            if t >= after and in_task:
                return t
        return None


def drop_first(kind: type, src: str | None = None, dst: str | None = None) -> Drop:
    """Loses the first message of ``kind`` (from ``src``, to receiver ``dst``), once."""
    state = {"done": False}

    def drop(msg: RadioMsg, receiver: str, tick: int) -> bool:
        if state["done"] or not isinstance(msg.body, kind):
            return False
        if (src is None or msg.src == src) and (dst is None or receiver == dst):
            state["done"] = True
            return True
        return False

    return drop


def test_conformance() -> None:
    api_test({"type": "trade"})
    seed_test({"type": "trade"})
    api_test({"type": "trade", "time_max": 0, "bid_period": 0, "award_timeout": 1, "retries": 0})
    assert make_allocator({"type": "trade"}).to_dict() == {
        "type": "trade", "time_max": 2, "bid_period": 2, "award_timeout": 5, "retries": 1, "task_radius": 3,
        "claim_ttl": 100, "task_timeout": 300, "explore_in_round": True, "blocked_after": 4,
        "tasks": "frontiers"}
    with pytest.raises(ConfigError, match=r"time_max must be >= 0 \(got -1\)"):
        make_allocator({"type": "trade", "time_max": -1})


def test_greedy_table_is_algorithm_2() -> None:
    requests = {"r2": ((0, 0), 3.0), "r1": ((0, 1), 5.0), "r3": ((9, 9), 1.0), "r0": ((0, 0), 5.0)}
    # r0, r1 and r2 ask for the same task (within 3 cells): the lowest cost, r2, keeps it; r3 alone.
    assert greedy_table(requests, 3) == {"r2": (0, 0), "r3": (9, 9)}
    assert greedy_table({"r1": ((0, 0), 2.0), "r0": ((0, 0), 2.0)}, 0) == {"r0": (0, 0)}  # tie: lower number


@pytest.mark.parametrize("explore_in_round", [True, False])
def test_normal_round_allocates_distinct_tasks(explore_in_round: bool) -> None:
    fleet = Fleet(["r0", "r1", "r2"], explore_in_round=explore_in_round)
    fleet.run_static(CORNERS, 12)
    # tick 0-1: numbers; tick 2: r0 seller, r1 and r2 buy; tick 4: r0 allocates; tick 5: buyers have it.
    assert fleet.first_assigned("r0") == 2 + 2
    assert fleet.first_assigned("r1") == fleet.first_assigned("r2") == 2 + 2 + 1
    assert all(s is AllocStatus.ASSIGNED for st in fleet.statuses.values() for s in st[5:])
    assert fleet.targets == {"r0": (0, 1), "r1": (4, 1), "r2": (0, 13)}
    buys = [m for m in fleet.sent if isinstance(m.body, TradePurchase)]
    assert sorted((m.src, m.dst, m.body.task, m.body.cost) for m in buys) == [("r1", "r0", (4, 1), 2.0),
                                                                    ("r2", "r0", (0, 13), 3.0)]
    allocs = [m for m in fleet.sent if isinstance(m.body, TradeAllocation)]
    assert len(allocs) == 1 and allocs[0].src == "r0"
    assert allocs[0].body.awards == {"r0": (0, 1), "r1": (4, 1), "r2": (0, 13)}
    numbers = [m for m in fleet.sent if isinstance(m.body, TradeNumber)]
    assert all(m.tick <= 4 for m in numbers)  # robots in a task stop broadcasting their numbers
    in_round = {r: fleet.statuses[r][:fleet.first_assigned(r)] for r in fleet.allocs}
    if explore_in_round:  # on toward the task each trades for, never standing still
        assert all(st == [AllocStatus.ASSIGNED] * len(st) for st in in_round.values())
    else:  # the first version: WAITING, the brain stays
        assert all(st == [AllocStatus.WAITING] * len(st) for st in in_round.values())


@pytest.mark.parametrize("art", [CORNERS, CONTENDED])
def test_exploring_in_a_round_leaves_the_protocol_as_it_was(art: str) -> None:
    """Same messages, same ticks in a task and same final tasks whether robots move during rounds or not (the
    static map: only the robots' motion differs); during the round each heads for its pick, then its bid."""
    runs = []
    for explore in (True, False):
        fleet = Fleet(["r0", "r1", "r2"], explore_in_round=explore)
        fleet.run_static(art, 30)
        runs.append(fleet)
    moving, standing = runs
    assert [(m.src, m.dst, m.body) for m in moving.sent] == [(m.src, m.dst, m.body) for m in standing.sent]
    assert moving.in_task == standing.in_task and moving.targets == standing.targets
    assert AllocStatus.WAITING not in {s for st in moving.statuses.values() for s in st}
    assert AllocStatus.WAITING in {s for st in standing.statuses.values() for s in st}


def test_a_buyer_heads_for_the_task_it_bid_for() -> None:
    # r1 is as near r0's corner as r0: while electing it heads there (its pick) and keeps heading there while
    # its purchase is out (ticks 2-4); outbid at tick 5, it heads for the corner left over while it elects and
    # sells to itself, and is in that task from tick 9.
    fleet = Fleet(["r0", "r1", "r2"])
    grid, poses = from_ascii(CONTENDED)
    targets = []
    for t in range(10):
        fleet.tick(t, grid, poses)
        targets.append(fleet.targets["r1"])
    assert targets == [(0, 1)] * 5 + [(4, 1)] * 5
    assert fleet.first_assigned("r1") == 9
    assert fleet.statuses["r1"] == [AllocStatus.ASSIGNED] * 10


def test_outbid_buyer_gets_another_task() -> None:
    fleet = Fleet(["r0", "r1", "r2"])
    fleet.run_static(CONTENDED, 30)
    # r1 asks for r0's task and loses (Algorithm 2); it learns r0's and r2's tasks and buys another.
    t1 = fleet.first_assigned("r1")
    assert t1 is not None and t1 <= BOUND
    assert len(set(fleet.targets.values())) == 3 and None not in fleet.targets.values()


@pytest.mark.parametrize("drop", [
    drop_first(TradePurchase, src="r1"),
    drop_first(TradeAllocation, src="r0", dst="r1"),
    drop_first(TradeAllocation, src="r0"),  # lost to every buyer
], ids=["lost-purchase", "lost-allocation", "lost-allocation-all"])
def test_lost_message_does_not_deadlock(drop: Drop) -> None:
    fleet = Fleet(["r0", "r1", "r2"])
    fleet.run_static(CORNERS, 40, drop=drop)
    for r in fleet.allocs:
        t = fleet.first_assigned(r)
        assert t is not None and t <= BOUND, (r, t)
        assert all(fleet.in_task[r][t:]), r
    assert len(set(fleet.targets.values())) == 3


def test_silent_seller_leads_to_re_election() -> None:
    fleet = Fleet(["r0", "r1", "r2"])
    fleet.run_static(CORNERS, 40, silent_from={"r0": 1})  # r0 is heard at tick 0, elected, never heard again
    for r in ("r1", "r2"):
        t = fleet.first_assigned(r)
        assert t is not None and t <= BOUND, (r, t)
    allocs = [m for m in fleet.sent if isinstance(m.body, TradeAllocation)]
    assert [m.src for m in allocs] == ["r1"]  # the next lowest number sold
    assert fleet.targets["r1"] != fleet.targets["r2"]


def test_silent_teammate_from_the_start() -> None:
    fleet = Fleet(["r0", "r1", "r2"])
    fleet.run_static(CORNERS, 20, silent_from={"r1": 0})
    # r1 hears the others, so it buys from r0; its purchase never arrives and r0's allocation lacks it: it
    # elects again (alone, the others in their tasks), sells to itself and takes the task left over.
    assert {r: fleet.first_assigned(r) for r in fleet.allocs} == {"r0": 4, "r1": 5 + T + 2, "r2": 5}
    assert len(set(fleet.targets.values())) == 3


# --- a small explored world: moving robots, sensing, tasks completing, half the messages lost -------------

TRUTH = """
######################
#0.1.....#...........#
#2.3.....#...........#
#........#...........#
#####.####...........#
#....................#
#........######.######
#........#...........#
#........#...........#
######################
"""


def explore(ticks: int, loss: float, seed: int) -> tuple[Fleet, float]:
    truth, poses = from_ascii(TRUTH)
    occupied = truth == OCCUPIED
    belief = np.full(truth.shape, UNKNOWN, dtype=np.int8)
    fleet = Fleet(sorted(poses))
    rng = np.random.default_rng(seed)

    def lossy(msg: RadioMsg, dst: str, tick: int) -> bool:
        return bool(rng.random() < loss)

    for t in range(ticks):
        for cell in poses.values():  # every robot's scan, shared (map sharing is the brain's business)
            seen = visible_cells(occupied, cell[0], cell[1], 3.0)
            belief.flat[seen] = truth.flat[seen]
        chosen = fleet.tick(t, belief.copy(), poses, lossy)
        clusters = find_clusters(belief, 4)
        passable = belief == FREE
        for r, j in chosen.items():
            if j is None:
                continue
            wf = wavefront(passable, clusters[j].cells.astype(np.int64), -1)
            dr, dc = next_move(wf, poses[r])  # robots pass each other here: no traffic jams in this test
            poses[r] = (poses[r][0] + dr, poses[r][1] + dc)
    known = (belief != UNKNOWN) & (truth == FREE)
    return fleet, known.sum() / (truth == FREE).sum()


def longest_round(fleet: Fleet, robot: str) -> int:
    """The longest run of ticks out of a task with a frontier to explore (in a protocol round)."""
    run = best = 0
    for busy, status in zip(fleet.in_task[robot], fleet.statuses[robot], strict=True):
        run = 0 if busy or status is AllocStatus.NO_FRONTIER else run + 1
        best = max(best, run)
    return best


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_half_the_messages_lost_still_assigns(seed: int) -> None:
    fleet, coverage = explore(200, 0.5, seed)
    for r, busy in fleet.in_task.items():
        assert longest_round(fleet, r) <= BOUND, (r, longest_round(fleet, r))
        assert any(busy)
        assert AllocStatus.WAITING not in fleet.statuses[r]  # rounds or not, the robot explores
    rounds = [m for m in fleet.sent if isinstance(m.body, TradeAllocation)]
    assert len(rounds) > len(fleet.allocs)  # tasks were completed and traded again
    assert coverage == 1.0


def test_lossless_exploration_completes() -> None:
    fleet, coverage = explore(200, 0.0, 0)
    assert coverage == 1.0
    for r in fleet.allocs:
        assert longest_round(fleet, r) <= BOUND
