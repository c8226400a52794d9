"""A site's files read and checked (world/sites.py), and the site drawn as a map (world/site_grid.py): the walls
between two positions are the emulator's own count, a thick wall is one wall, heights count in the distance."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.kernels import count_walls
from fleet_emu.world.site_grid import cells_of, draw, geometry, inside
from fleet_emu.world.sites import load_site, lookup_site
from tests.radio.synthetic import LAYOUT, write_site


def test_the_site_is_drawn_as_a_map_and_walls_are_counted_by_the_emulators_counter() -> None:
    layout = np.array(LAYOUT)
    grid = draw(layout, 0.05)
    left, right, door = np.array([[1.0, 3.0]]), np.array([[5.0, 3.0]]), np.array([[3.05, 0.5]])
    assert inside(layout, np.vstack([left, right, door])).all()
    assert not inside(layout, np.array([[3.05, 2.0], [7.0, 1.0]])).any()  # in the partition; outside the room
    (lr, lc), (rr, rc) = cells_of(grid, left)[0][0], cells_of(grid, right)[0][0]
    assert grid.occupied[cells_of(grid, np.array([[3.05, 2.0]]))[0][0][0], :].sum() > 0
    assert count_walls(grid.occupied, int(lr), int(lc), int(rr), int(rc)) == 1  # a 10 cm wall: one run, one wall
    geo = geometry(grid, np.array([[1.0, 3.0, 2.0], [5.0, 3.0, 0.0]]), np.vstack([left, right]), np.zeros(2))
    assert geo.walls.tolist() == [[0, 1], [1, 0]]
    assert geo.distance[0, 0] == pytest.approx(2.0) and geo.distance[1, 0] == pytest.approx(np.hypot(4.0, 2.0))


def test_a_position_on_a_wall_is_counted_from_the_nearest_free_cell() -> None:
    grid = draw(np.array(LAYOUT), 0.05)
    cells, moved = cells_of(grid, np.array([[0.01, 2.0], [1.0, 1.0]]))
    assert moved == 1 and not grid.occupied[cells[:, 0], cells[:, 1]].any()


def test_a_folder_site_is_read_and_bad_files_are_one_line(tmp_path: Path) -> None:
    site = load_site(str(write_site(tmp_path / "ok", points=50)))
    assert site.anchor_ids == (1, 2, 3) and site.rss.shape == (len(site.xy), 3) and site.readings == site.rss.size
    bad = {
        "no column rssi_3": "x,y,rssi_1,rssi_2\n1,1,-50,-60\n",
        "y must be a finite number": "x,y,rssi_1,rssi_2,rssi_3\n1,nan,-50,-60,-70\n",
        "x must be a finite number": "x,y,rssi_1,rssi_2,rssi_3\n,1,-50,-60,-70\n",
    }
    for i, (message, text) in enumerate(bad.items()):
        folder = write_site(tmp_path / f"bad{i}", readings_text=text)
        with pytest.raises(ConfigError, match=message) as exc:
            load_site(str(folder))
        assert "\n" not in str(exc.value)
    folder = write_site(tmp_path / "far", points=10)
    (folder / "anchors.csv").write_text("id,x,y,z\n1,1,3,2\n2,5,3,2.5\n3,9,0.5,1.5\n")
    with pytest.raises(ConfigError, match=r"anchor 3 at \(9, 0\.5\) is outside the walls' box"):
        load_site(str(folder))
    empty = write_site(tmp_path / "empty", readings_text="x,y,rssi_1,rssi_2,rssi_3\n1,1,,,\n")
    assert load_site(str(empty)).readings == 0  # nothing heard is a reading missing, not an error


def test_an_unknown_or_unfetched_site_name_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    with pytest.raises(ConfigError, match="unknown radio site 'nope'"):
        lookup_site("nope")
    with pytest.raises(ConfigError, match="is not fetched: run `fleet radio fetch kolakowski-ble-2021`"):
        load_site("kolakowski-ble-2021")
    with pytest.raises(ConfigError, match="--resolution must be within"):
        draw(np.array(LAYOUT), 0.0)
