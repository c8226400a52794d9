"""The base station's core (agents/base.py): the team map from the map deltas and fills that reach it."""

from __future__ import annotations

import msgspec
import numpy as np

from fleet_emu.agents.base import BaseStation
from fleet_emu.agents.protocol import MapDelta, MapFill, PoseBeacon
from fleet_emu.core.grid import UNKNOWN, from_ascii
from fleet_emu.core.messages import RadioMsg, open_envelope, seal

TRUTH, _ = from_ascii("""
    #####
    #...#
    #.#.#
    #####
""")
TEAM = frozenset({"r0", "r1"})


def _cells(*rc: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    flat = np.array([r * TRUTH.shape[1] + c for r, c in rc], dtype=np.int32)
    return flat, TRUTH.reshape(-1)[flat].copy()


def _station(drops: list[str] | None = None) -> BaseStation:
    return BaseStation((1, 1), TRUTH.shape, TEAM, on_drop=None if drops is None else lambda k, w: drops.append(k))


def test_the_base_merges_every_delta_and_fill_that_reaches_it() -> None:
    st = _station()
    cells0, values0 = _cells((1, 1), (1, 2), (0, 0))
    cells1, values1 = _cells((2, 2), (2, 3))
    out = st.step(0, [seal(RadioMsg(MapDelta(cells=cells0, values=values0)), "r0", 0, 1)])
    assert out == ()  # no planner: the base sends nothing
    assert st.known_cells == 3 and st.merged == 1
    st.step(1, [seal(RadioMsg(MapFill(cells=cells1, values=values1), dst="base"), "r1", 1, 1)])
    grid = st.belief.grid
    assert st.known_cells == 5 and st.merged == 2 and st.ticks == 2
    assert grid[1, 1] == 0 and grid[0, 0] == 100 and grid[2, 2] == 100 and grid[2, 3] == 0
    assert grid[1, 3] == UNKNOWN  # nobody told the base
    assert st.known_fraction == 5 / TRUTH.size


def test_beacons_give_the_robots_last_cells_and_a_stranger_is_dropped_and_counted() -> None:
    drops: list[str] = []
    st = _station(drops)
    cells, values = _cells((1, 3))
    st.step(4, [seal(RadioMsg(PoseBeacon(cell=(1, 2), next=(1, 3))), "r0", 4, 1),
                seal(RadioMsg(MapDelta(cells=cells, values=values)), "r9", 4, 1)])  # not of the team
    assert st.heard["r0"].cell == (1, 2) and st.heard["r0"].tick == 4
    assert drops == ["radio/map"] and st.known_cells == 0


def test_a_planner_hook_gets_the_station_after_the_merge() -> None:
    seen: list[int] = []

    def planner(st: BaseStation) -> list[RadioMsg]:
        seen.append(st.known_cells)
        return [RadioMsg(PoseBeacon(cell=st.cell))]

    st = BaseStation((1, 1), TRUTH.shape, TEAM, planner=planner)
    cells, values = _cells((1, 1), (1, 2))
    out = st.step(0, [seal(RadioMsg(MapDelta(cells=cells, values=values)), "r0", 0, 1)])
    assert seen == [2] and len(out) == 1 and open_envelope(out[0]).body == PoseBeacon(cell=(1, 1))
    assert out[0].origin == out[0].src == "base" and out[0].tick == 0  # sealed as the base's


def test_relayed_copies_are_merged_once_under_their_origin_and_others_mail_is_ignored() -> None:
    st = _station()
    cells, values = _cells((1, 1), (1, 2))
    delta = seal(RadioMsg(MapDelta(cells=cells, values=values), ttl=2), "r0", 3, 7)
    beacon = seal(RadioMsg(PoseBeacon(cell=(1, 2)), ttl=2), "r0", 3, 8)
    via_r1 = [msgspec.structs.replace(e, src="r1", ttl=1) for e in (delta, beacon)]
    for_r1 = seal(RadioMsg(MapDelta(cells=cells, values=values), dst="r1", ttl=2), "r0", 3, 9)
    st.step(4, [*via_r1, delta, for_r1])  # the relay's copies first, then the direct ones (and r1's mail)
    assert st.merged == 1 and st.known_cells == 2
    assert set(st.heard) == {"r0"} and st.heard["r0"].cell == (1, 2)  # the relay's beacon is r0's
