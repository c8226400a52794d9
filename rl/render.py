"""A picture of a fleet for ``render_mode="rgb_array"``: the true map, what the team has seen, the robots and
their radio links, one pixel per cell scaled up, numpy only."""

from __future__ import annotations

import numpy as np

from fleet_emu.core.grid import Cell

SCALE = 4
WALL, UNSEEN_FREE, SEEN_FREE = (40, 40, 40), (150, 150, 150), (245, 245, 245)
SEEN_WALL, ROBOT, LINK = (0, 0, 0), (220, 30, 30), (30, 90, 220)


def render_rgb(state: np.ndarray, cells: list[Cell], link: np.ndarray, scale: int = SCALE) -> np.ndarray:
    """``(rows * scale, cols * scale, 3)`` uint8: ``state`` as :meth:`FleetParallelEnv.state` gives it
    (truth, seen, poses), ``cells`` the radio endpoints' cells in ``link``'s order, a line for each link."""
    truth, seen = state[0], state[1]
    img = np.empty((*truth.shape, 3), dtype=np.uint8)
    img[:] = UNSEEN_FREE
    img[truth > 0] = WALL
    img[seen == 0] = SEEN_FREE
    img[seen > 0] = SEEN_WALL
    for i, a in enumerate(cells):
        for j in range(i + 1, len(cells)):
            if link[i, j]:
                _line(img, a, cells[j])
    for cell in cells:
        img[cell] = ROBOT
    return np.repeat(np.repeat(img, scale, axis=0), scale, axis=1)


def _line(img: np.ndarray, a: Cell, b: Cell) -> None:
    n = max(abs(b[0] - a[0]), abs(b[1] - a[1])) + 1
    rows = np.rint(np.linspace(a[0], b[0], n)).astype(int)
    cols = np.rint(np.linspace(a[1], b[1], n)).astype(int)
    img[rows, cols] = LINK
