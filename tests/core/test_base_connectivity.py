"""Base connectivity: paths to the base in link graphs from the radio model, and the fold."""

from __future__ import annotations

import numpy as np
import pytest

from fleet_emu.core.base_connectivity import BaseConnectivity, base_connected, reachable
from fleet_emu.core.grid import OCCUPIED, from_ascii
from fleet_emu.core.radio import RadioConfig, link_matrix

DISK = RadioConfig(comm="disk", comm_range=2.0)  # 4 cells of 0.5 m

# The base stands where r0 is drawn; r1 is 4 cells from it, r2 4 cells from r1 (8 from the base), r3 beyond
# reach of everyone, r4 4 cells below r0.
ROW = """
0...1...2.........3
...................
...................
...................
4..................
"""


def links(art: str, p: RadioConfig = DISK) -> tuple[list[str], np.ndarray]:
    grid, robots = from_ascii(art)
    names = ["base" if r == "r0" else r for r in robots]
    _, link = link_matrix(grid == OCCUPIED, list(robots.values()), 0.5, p)
    return names, link


def test_paths_of_several_hops_reach_the_base() -> None:
    names, link = links(ROW)
    assert base_connected(names, link) == {"r1": True, "r2": True, "r3": False, "r4": True}
    assert reachable(link, names.index("r3")).tolist() == [False, False, False, True, False]


def test_a_wall_cuts_the_only_path() -> None:
    art = """
    0...1#..2
    .....#...
    """
    wall = RadioConfig(comm="wall", comm_range=2.0, waf=10.0)
    names, link = links(art, wall)
    assert base_connected(names, link) == {"r1": True, "r2": False}


def test_bad_input_is_refused() -> None:
    with pytest.raises(ValueError, match="no 'base'"):
        base_connected(["r1", "r2"], np.zeros((2, 2), dtype=bool))
    with pytest.raises(ValueError, match="does not match"):
        base_connected(["base", "r1"], np.zeros((3, 3), dtype=bool))


def test_the_fold_over_ticks() -> None:
    fold = BaseConnectivity()
    names, link = links(ROW)
    assert fold.add(names, link) == pytest.approx(3 / 4)
    everyone = np.ones((5, 5), dtype=bool) & ~np.eye(5, dtype=bool)
    assert fold.add(names, everyone) == 1.0
    s = fold.summary()
    assert s["overall"] == pytest.approx((0.75 + 1.0) / 2)
    assert s["all_ticks"] == pytest.approx(0.5)
    assert s["per_robot"] == {"r1": 1.0, "r2": 1.0, "r3": 0.5, "r4": 1.0}
    assert BaseConnectivity().summary()["overall"] is None
