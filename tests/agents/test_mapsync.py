"""Map sync (agents/mapsync.py): a map delta lost on one link is recovered while the two robots stay in contact,
a lost request is retried, and a fleet on a radio that loses nothing sends what it sent before map sync."""

from __future__ import annotations

from collections.abc import Callable

import msgpack
import numpy as np
import pytest

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.belief import Belief
from fleet_emu.agents.brain import Brain, BrainConfig, brain_config
from fleet_emu.agents.mapsync import MapSync, Peer, SyncConfig
from fleet_emu.agents.protocol import MAX_SEQS, MapDelta, MapFill, PoseBeacon
from fleet_emu.core.grid import UNKNOWN, MapData, from_ascii
from fleet_emu.core.messages import Envelope, Observation, RadioMsg, RxBundle, decode, open_envelope, seal
from fleet_emu.core.messages import decode_payload as decode_body
from fleet_emu.core.rng import generator
from fleet_emu.core.scenario import Scenario
from fleet_emu.netem.channel import Channel
from fleet_emu.world.sim import WorldConfig
from tests.agents.lockstep import DrawnWorld

# Two robots at the ends of a long corridor, every pair linked: each learns cells the other cannot sense for
# many ticks, and they are always in contact.
CORRIDOR = """
##########################################
#0......................................1#
##########################################
"""

#: Decides whether netem loses one envelope: (tick, sender, envelope) -> lost.
Drop = Callable[[int, str, Envelope], bool]


class Run:
    """Two brains, the real world and channel (ideal, no loss), stepped in lockstep as the nodes are;
    ``drop`` loses chosen envelopes on the way (the only losses), ``dropped`` keeps them."""

    def __init__(self, drop: Drop, map_sync: bool = True) -> None:
        grid, marks = from_ascii(CORRIDOR)
        self.world = DrawnWorld(MapData("drawn", grid, 0.5, marks["r0"]), marks,
                                WorldConfig(sensor_range=3.0, target_coverage=1.0, max_ticks=200),
                                generator(0, "world"))
        self.channel = Channel(0.0, generator(0, "netem"))
        team = frozenset(marks)
        self.brains = {r: Brain(r, make_allocator({"type": "nearest"}), generator(0, r),
                                BrainConfig(cluster_max=6, map_sync=map_sync), team=team) for r in marks}
        self.drop = drop
        self.dropped: list[tuple[int, str, Envelope]] = []
        self.readings = self.world.reset()

    def step(self) -> None:
        w, t = self.world, self.world.tick
        arriving = self.channel.deliver(t)
        moves, bundles = {}, {}
        for r, brain in self.brains.items():
            rd = self.readings[r]
            obs = Observation(src="world", tick=t, seq=0, robot=r, cell=rd.cell, shape=w.shape, cell_size=0.5,
                              cells=rd.cells, values=rd.values)
            rx = decode(RxBundle(src="netem", tick=t, seq=0, dst=r, msgs=tuple(arriving.get(r, ()))).encode())
            cmd, out = brain.step(obs, rx.msgs)
            moves[r] = cmd.move
            kept = []
            for env in out:
                if self.drop(t, r, env):
                    self.dropped.append((t, r, env))
                else:
                    kept.append(env)
            bundles[r] = tuple(kept)
        self.channel.transmit(t, tuple(self.brains), np.ones((2, 2), dtype=bool) & ~np.eye(2, dtype=bool), bundles)
        self.readings = w.step(moves)

    def knows(self, robot: str, cells: np.ndarray) -> bool:
        return bool((self.brains[robot].belief.grid.reshape(-1)[cells] != UNKNOWN).all())  # type: ignore[union-attr]


def _delta_of(tick: int, src: str) -> Drop:
    return lambda t, r, env: t == tick and r == src and env.payload_kind == MapDelta.KIND


def _lost_cells(run: Run) -> np.ndarray:
    (_, _, env), = [d for d in run.dropped if d[2].payload_kind == MapDelta.KIND]
    return open_envelope(env).body.cells  # type: ignore[attr-defined]


def test_a_lost_delta_is_recovered_within_three_ticks() -> None:
    run = Run(_delta_of(3, "r0"))
    for _ in range(4):  # ticks 0-3: r0's delta of tick 3 is lost on its way to r1
        run.step()
    lost = _lost_cells(run)
    assert len(lost) and not run.knows("r1", lost)
    run.step()  # tick 4: r0's beacon says 4 deltas were sent, r1 has 3: r1's beacon asks r0 for delta 4
    assert _wants(run.brains["r1"].sync, 4)  # type: ignore[arg-type]
    run.step()  # tick 5: r0's delta carries the cells of delta 4 again
    assert not run.knows("r1", lost)
    run.step()  # tick 6: r1 merges them
    assert run.knows("r1", lost)
    assert run.brains["r1"].sync.peer("r0").missing == {}  # type: ignore[union-attr]
    r0, r1 = run.brains["r0"].sync, run.brains["r1"].sync
    # one request, one delta sent again; one whole map: r0's to r1 when it first heard it (tick 1)
    assert (r1.asked, r0.resent, r0.wholes) == (1, 1, 1)  # type: ignore[union-attr]


def test_without_map_sync_the_lost_delta_stays_lost() -> None:
    run = Run(_delta_of(3, "r0"), map_sync=False)
    for _ in range(10):
        run.step()
    assert not run.knows("r1", _lost_cells(run))  # the bug map sync fixes: nothing is ever sent again


def _asks(env: Envelope) -> bool:
    return env.payload_kind == PoseBeacon.KIND and open_envelope(env).body.want is not None  # type: ignore[attr-defined]


def _wants(sync: MapSync, n: int) -> bool:
    return sync.peer("r0").missing.get(n) is not None  # asked, not yet filled


def test_a_lost_request_is_retried() -> None:
    def drop(t: int, r: str, env: Envelope) -> bool:
        first_request = r == "r1" and _asks(env) and not any(_asks(d[2]) for d in run.dropped)
        return _delta_of(3, "r0")(t, r, env) or first_request

    run = Run(drop)
    for _ in range(9):  # ticks 0-8: the request of tick 4 is lost, asked again at 4 + 3 = 7, answered at 8
        run.step()
    assert [(t, r) for t, r, env in run.dropped if _asks(env)] == [(4, "r1")]
    assert not run.knows("r1", _lost_cells(run))
    run.step()  # tick 9: merged
    assert run.knows("r1", _lost_cells(run))
    assert run.brains["r1"].sync.asked == 2  # type: ignore[union-attr]


def test_a_lost_resent_delta_is_asked_again() -> None:
    run = Run(lambda t, r, env: _delta_of(3, "r0")(t, r, env) or _delta_of(5, "r0")(t, r, env))
    for _ in range(8):  # ticks 0-7: delta 4 lost, asked at 4; delta 6 (carrying 4 again) lost at 5
        run.step()
    lost = open_envelope(run.dropped[0][2]).body.cells  # type: ignore[attr-defined]
    assert not run.knows("r1", lost)
    for _ in range(2):  # 6 asked at 6, sent again at 7 (its news only), merged at 8; 4 asked again at 7,
        run.step()      # sent again at 8, merged at 9
    assert run.knows("r1", lost)
    assert run.brains["r1"].sync.peer("r0").missing == {}  # type: ignore[union-attr]
    assert run.brains["r0"].sync.resent == 3  # type: ignore[union-attr]


# --- the pure state ----------------------------------------------------------------------------------------


def test_a_gap_seen_from_a_delta_or_a_beacon_is_asked_for_and_retried() -> None:
    p = Peer()
    p.received(1)
    p.received(4)  # 2 and 3 lost
    assert p.request(10, 3) == (2, 3)
    p.exists(5)  # a beacon: delta 5 was sent, not received
    assert p.request(11, 3) == (5,)  # only what was never asked
    assert p.request(12, 3) is None
    p.filled((2, 3), 0)
    assert p.request(13, 3) is None
    assert p.request(14, 3) == (5,)  # asked at 11, no fill: asked again
    p.filled((), 5)  # a whole map up to 5
    assert p.missing == {} and p.request(20, 3) is None


def test_many_missing_are_asked_oldest_first_in_chunks() -> None:
    p = Peer()
    p.received(1)
    p.exists(40)  # 2 .. 40 lost
    p.exists(80)  # 41 .. 80 too
    assert p.request(0, 3) == tuple(range(2, MAX_SEQS + 2))
    assert p.request(1, 3) == tuple(range(MAX_SEQS + 2, 81))
    assert p.request(2, 3) is None


def test_a_long_gap_asks_for_the_whole_map_then_the_numbers_after_it() -> None:
    p = Peer()
    p.received(1)
    p.received(MAX_SEQS + 10)  # back in range: more than MAX_SEQS missing at once, not listed
    assert p.missing == {} and p.request(0, 3) == ()
    p.exists(MAX_SEQS + 12)  # 11 lost after it
    assert p.request(1, 3) is None and p.request(3, 3) == ()  # the whole map first, asked again after 3 ticks
    p.filled((), MAX_SEQS + 10)  # a whole map up to where the gap was seen
    assert p.request(4, 3) == (MAX_SEQS + 11, MAX_SEQS + 12)
    p.received(10**12)  # a corrupt number: no list of a trillion entries
    assert p.missing == {} and p.request(5, 3) == ()


def test_the_sender_resends_the_asked_cells_in_its_next_delta_or_its_whole_map() -> None:
    belief = Belief((3, 4))
    belief.merge(np.arange(12, dtype=np.int32), np.zeros(12, dtype=np.int8))
    sync = MapSync(SyncConfig(history=2))
    for cells in ([0, 1], [2], [5, 6]):
        sync.number(np.array(cells, dtype=np.int32))
    assert sync.answer((2, 3), belief) is None  # queued for the next delta
    cells, covers = sync.news(np.array([9], dtype=np.int32))
    assert cells.tolist() == [2, 5, 6, 9] and covers == (2, 3)
    assert sync.news(np.array([10], dtype=np.int32))[1] is None  # sent once
    whole = sync.answer((1,), belief)  # delta 1 is no longer kept
    assert whole is not None and whole.seqs == () and whole.upto == 3 and len(whole.cells) == 12


def test_requests_go_only_to_teammates_in_contact() -> None:
    sync = MapSync(SyncConfig(retry_after=3))
    sync.peer("r1").received(2)
    sync.peer("r2").received(2)
    assert sync.requests(10, {"r1": 9, "r2": 6}) == {"r1": (1,)}
    assert sync.requests(11, {"r1": 9, "r2": 6}) is None  # asked at 10


# --- messages ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("kind", "body"), [
    ("pose", {"cell": [1, 1], "next": None, "want": {"r1": [3, 2]}}),
    ("pose", {"cell": [1, 1], "next": None, "want": {"r1": [0]}}),
    ("pose", {"cell": [1, 1], "next": None, "want": {"r1": list(range(1, MAX_SEQS + 2))}}),
    ("pose", {"cell": [1, 1], "next": None, "want": {"r1": "1"}}),
    ("pose", {"cell": [1, 1], "next": None, "want": {"r9": [1]}}),
    ("mapfill", {"cells": {"dtype": "int32", "shape": [0], "data": b""},
                 "values": {"dtype": "int8", "shape": [0], "data": b""}, "seqs": [2, 2]}),
    ("map", {"cells": {"dtype": "int32", "shape": [0], "data": b""},
             "values": {"dtype": "int8", "shape": [0], "data": b""}, "n": 3, "covers": [3]}),
    ("map", {"cells": {"dtype": "int32", "shape": [0], "data": b""},
             "values": {"dtype": "int8", "shape": [0], "data": b""}, "covers": [1]}),
    ("mapfill", {"cells": None, "values": None}),
    ("map", {"cells": {"dtype": "int32", "shape": [0], "data": b""},
             "values": {"dtype": "int8", "shape": [0], "data": b""}, "n": 0}),
    ("pose", {"cell": [1, 1], "next": None, "maps": -1}),
])
def test_a_malformed_sync_message_is_counted_and_dropped(kind: str, body: dict) -> None:
    drops: list[str] = []
    brain = Brain("r0", make_allocator({"type": "nearest"}), np.random.default_rng(0), BrainConfig(map_sync=True),
                  team=frozenset({"r0", "r1"}), on_drop=lambda key, why: drops.append(key))
    env = Envelope(src="r1", tick=0, seq=1, origin="r1", dst="r0", ttl=0, payload_kind=kind,
                   payload=msgpack.packb(body, use_bin_type=True))
    grid, marks = from_ascii("####\n#0.#\n####")
    cells = np.flatnonzero(grid.ravel() != UNKNOWN).astype(np.int32)
    obs = Observation(src="world", tick=1, seq=0, robot="r0", cell=marks["r0"], shape=grid.shape, cell_size=0.5,
                      cells=cells, values=grid.ravel()[cells].copy())
    brain.step(obs, (env,))
    assert drops == [f"radio/{kind}"]


def test_without_map_sync_beacons_and_deltas_encode_as_before() -> None:
    beacon = PoseBeacon(cell=(1, 2), next=(1, 3))
    delta = MapDelta(cells=np.array([4], dtype=np.int32), values=np.array([0], dtype=np.int8))
    assert set(msgpack.unpackb(delta.encode())) == {"cells", "values"}
    assert set(msgpack.unpackb(beacon.encode())) == {"cell", "next"}
    numbered = decode_body("map", MapDelta(cells=delta.cells, values=delta.values, n=7).encode())
    assert numbered.n == 7  # type: ignore[attr-defined]


@pytest.mark.parametrize(("comm", "loss", "on"), [
    ("ideal", 0.3, False), ("full", 0.0, False), ("full", 0.1, True), ("wall", 0.0, True), ("disk", 0.0, True),
])
def test_map_sync_is_on_where_the_radio_can_lose_a_message(comm: str, loss: float, on: bool) -> None:
    assert brain_config(Scenario().override(comm=comm, loss=loss)).map_sync is on


def test_a_brain_without_sync_ignores_requests_and_merges_fills() -> None:
    brain = Brain("r0", make_allocator({"type": "nearest"}), np.random.default_rng(0), BrainConfig(),
                  team=frozenset({"r0", "r1"}))
    grid, marks = from_ascii("####\n#0.#\n####")
    cells = np.flatnonzero(grid.ravel() != UNKNOWN).astype(np.int32)
    obs = Observation(src="world", tick=1, seq=0, robot="r0", cell=marks["r0"], shape=grid.shape, cell_size=0.5,
                      cells=cells, values=grid.ravel()[cells].copy())
    req = seal(RadioMsg(PoseBeacon(cell=(1, 2), want={"r0": (1,)})), "r1", 0, 1)
    fill = seal(RadioMsg(MapFill(cells=np.array([0], dtype=np.int32), values=np.array([100], dtype=np.int8),
                                 seqs=(1,)), dst="r0"), "r1", 0, 2)
    _, out = brain.step(obs, (req, fill))
    # its news, and its whole map for r1 heard for the first time (the rule without map sync); no fill
    assert [(e.payload_kind, e.dst) for e in out] == [("pose", "*"), ("map", "*"), ("map", "r1")]
    assert brain.belief.grid[0, 0] == 100  # type: ignore[union-attr]

