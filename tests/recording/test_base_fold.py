"""The launcher's fold of base connectivity (recording/monitor.py) from netem's links messages: the same in
every engine, and recomputed from a recording by ``fleet report``."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest

from fleet_emu.core.codec import DecodeError, decode
from fleet_emu.core.keys import Keys
from fleet_emu.core.messages import BaseReport, Links
from fleet_emu.netem.channel import Counters, links_message
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.result import fold_keys

K = Keys("run1")
ROBOTS = ("r0", "r1", "r2")


def _links(tick: int, robots: tuple[str, ...], pairs: list[tuple[str, str]]) -> Links:
    """netem's links of a tick whose nodes are ``robots`` and the base, linked by ``pairs``."""
    nodes = (*robots, "base")
    link = np.zeros((len(nodes), len(nodes)), dtype=bool)
    for a, b in pairs:
        i, j = nodes.index(a), nodes.index(b)
        link[i, j] = link[j, i] = True
    return links_message(tick, tick + 1, nodes, np.where(link, 3.0, -5.0), link, Counters())


def test_the_fold_over_given_link_graphs() -> None:
    m = Monitor(ROBOTS, base=True)
    ticks = [
        # r0 - base directly, r1 through r0 (a relay), r2 alone: 2/3
        _links(0, ROBOTS, [("r0", "base"), ("r1", "r0")]),
        # everyone through r2: 3/3
        _links(1, ROBOTS, [("r2", "base"), ("r0", "r2"), ("r1", "r0")]),
        # r2 failed; r0 and r1 linked to each other only: 0/2
        _links(2, ("r0", "r1"), [("r0", "r1")]),
    ]
    for lk in ticks:
        m.feed(K.links, lk.encode())
    m.feed(K.report("base"), BaseReport(src="base", tick=3, seq=1, cell=(2, 3), known_cells=50, cells=200,
                                        merged=7, ticks=3, dropped=1, peak_rss_kb=1).encode())
    res = fold_keys(m, {"seed": 0, "map": "m", "allocator": {"type": "nearest"}, "robots": 3,
                        "radio": {"loss": 0.0, "comm": "disk"}}, "run1", 0.99)
    frac = res["base_connected_fraction"]
    assert frac["overall"] == pytest.approx(round((2 / 3 + 1 + 0) / 3, 6))
    assert frac["all_ticks"] == pytest.approx(round(1 / 3, 6))
    assert frac["per_robot"] == {"r0": pytest.approx(round(2 / 3, 6)), "r1": pytest.approx(round(2 / 3, 6)),
                                 "r2": 0.5}  # r2 counted over the 2 ticks it was live
    assert [t for t, _ in m.base_curve] == [0, 1, 2]
    assert res["base"] == {"cell": [2, 3], "known_cells": 50, "known_fraction": 0.25, "merged": 7, "ticks": 3}
    assert res["malformed_dropped_by"]["base"] == 1
    assert res["connected_fraction"] == pytest.approx(2 / 3)  # the robots' own graph, the base left out


def test_a_run_without_a_base_has_no_base_keys_and_links_without_base_fields() -> None:
    m = Monitor(ROBOTS)
    nodes = ROBOTS
    lk = links_message(0, 1, nodes, np.zeros((3, 3)), ~np.eye(3, dtype=bool), Counters())
    assert lk.base_link is None and lk.base_strength is None
    m.feed(K.links, lk.encode())
    res = fold_keys(m, {"seed": 0, "map": "m", "allocator": {"type": "nearest"}, "robots": 3,
                        "radio": {"loss": 0.0, "comm": "disk"}}, "run1", 0.99)
    assert "base_connected_fraction" not in res and "base" not in res


def test_links_whose_base_fields_do_not_match_the_robots_do_not_decode() -> None:
    lk = _links(0, ROBOTS, [("r0", "base")])
    assert decode(lk.encode(), expected=Links).base_link.tolist() == [True, False, False]  # type: ignore[union-attr]
    bad = msgspec.structs.replace(lk, **{"base_link": np.zeros(2, dtype=bool)})
    with pytest.raises(DecodeError, match="base_link"):
        decode(bad.encode())
    m = Monitor(ROBOTS, base=True)
    m.feed(K.links, bad.encode())
    assert m.malformed == 1 and m.base_reach.ticks == 0
