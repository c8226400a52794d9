"""The occupancy-grid convention and ASCII-art grids for tests.

Grids are ``int8`` arrays indexed ``[row, col]`` with row 0 at the top: ``-1`` unknown, ``0`` free,
``100`` occupied (the ROS OccupancyGrid convention). A cell is a ``(row, col)`` tuple of ints.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

UNKNOWN: int = -1
FREE: int = 0
OCCUPIED: int = 100

Cell = tuple[int, int]

#: 4-connected moves in a fixed order (up, down, left, right); every tie-break that walks
#: neighbours uses this order, so that runs are deterministic.
MOVES: tuple[Cell, ...] = ((-1, 0), (1, 0), (0, -1), (0, 1))
#: The command that stays in place.
STAY: Cell = (0, 0)

_ASCII = {"#": OCCUPIED, ".": FREE, "?": UNKNOWN}


@dataclasses.dataclass(frozen=True)
class MapData:
    """A ground-truth map: ``grid`` is int8 ``[row, col]`` (row 0 at the top), 0 free, 100 occupied.

    Built once per run by the launcher (``fleet_emu.world.maps.load_map``) and handed to the world and netem
    processes as a file (:meth:`save`, :meth:`load`), so that every process holds the same truth."""

    name: str
    grid: np.ndarray
    cell_size: float
    start: Cell

    def save(self, path: str | Path) -> None:
        """Write the map to ``path`` (numpy ``.npz``, no pickles)."""
        with open(path, "wb") as f:
            np.savez(f, grid=self.grid, start=np.array(self.start, dtype=np.int64),
                     cell_size=np.array(self.cell_size), name=np.array(self.name))

    @classmethod
    def load(cls, path: str | Path) -> MapData:
        """Read a map written by :meth:`save`."""
        with np.load(path, allow_pickle=False) as z:
            start = z["start"]
            return cls(name=str(z["name"]), grid=z["grid"].astype(np.int8), cell_size=float(z["cell_size"]),
                       start=(int(start[0]), int(start[1])))


def from_ascii(art: str) -> tuple[np.ndarray, dict[str, Cell]]:
    """Parse ASCII art into a grid and robot cells.

    ``#`` wall, ``.`` free, ``?`` unknown, ``0``-``9`` a robot (``r0``..``r9``) standing on a free cell.
    Leading/trailing blank lines and common indentation are ignored; rows must have equal length.
    """
    lines = [ln.strip() for ln in art.strip("\n").splitlines() if ln.strip()]
    if not lines:
        raise ValueError("empty grid art")
    width = len(lines[0])
    if any(len(ln) != width for ln in lines):
        raise ValueError("grid art rows differ in length")
    grid = np.empty((len(lines), width), dtype=np.int8)
    robots: dict[str, Cell] = {}
    for r, line in enumerate(lines):
        for c, ch in enumerate(line):
            if ch.isdigit():
                robots[f"r{ch}"] = (r, c)
                grid[r, c] = FREE
            elif ch in _ASCII:
                grid[r, c] = _ASCII[ch]
            else:
                raise ValueError(f"unknown grid art character {ch!r} at row {r}, col {c}")
    return grid, dict(sorted(robots.items()))


def to_ascii(grid: np.ndarray, robots: dict[str, Cell] | None = None) -> str:
    """Draw a grid back as ASCII art (the inverse of :func:`from_ascii`)."""
    inv = {OCCUPIED: "#", FREE: ".", UNKNOWN: "?"}
    rows = [[inv.get(int(v), "#" if v > 0 else "?") for v in row] for row in grid]
    for name, (r, c) in (robots or {}).items():
        rows[r][c] = name[1:] if name[1:].isdigit() and len(name) == 2 else "R"
    return "\n".join("".join(row) for row in rows)


def flat(shape: tuple[int, int], cell: Cell) -> int:
    """Row-major flat index of ``cell``."""
    return cell[0] * shape[1] + cell[1]


def unflat(shape: tuple[int, int], index: int) -> Cell:
    """The cell of a row-major flat index."""
    return (int(index) // shape[1], int(index) % shape[1])


def nearest_cells(passable: np.ndarray, free: np.ndarray, source: int, n: int | None = None,
                  radius: int | None = None) -> np.ndarray:
    """Flat indices of the ``free`` cells reachable from ``source`` through ``passable`` cells (4-connected), by
    BFS distance then row-major: the first ``n`` of them, within ``radius`` steps. A breadth-first search ring by
    ring in numpy, which stops as soon as it has ``n`` (the kernels' wavefront gives the same distances, but
    would load numba in a process that only checks a scenario)."""
    rows, cols = passable.shape
    can, good = passable.ravel(), free.ravel()
    seen = np.zeros(can.size, dtype=bool)
    seen[source] = True
    ring, found, count, steps = np.array([source], dtype=np.int64), [], 0, 0
    while ring.size:
        found.append(ring[good[ring]])
        count += found[-1].size
        if (n is not None and count >= n) or (radius is not None and steps >= radius):
            break
        r, c = ring // cols, ring % cols
        nxt = distinct(np.concatenate((ring[r > 0] - cols, ring[r < rows - 1] + cols, ring[c > 0] - 1,
                                       ring[c < cols - 1] + 1)))  # sorted: each ring is row-major
        ring = nxt[can[nxt] & ~seen[nxt]]
        seen[ring] = True
        steps += 1
    return np.concatenate(found)[:n]


def distinct(a: np.ndarray) -> np.ndarray:
    """The distinct values of the 1-D array ``a``, ascending: ``np.unique(a)``, by a sort. numpy 2's
    ``unique`` hashes first and costs ten to twenty times a sort on the fleet's cell indices (0.9 ms against
    0.07 ms for 11,000 of them), and a robot takes the union of its tick's news every tick."""
    s = np.sort(a)
    if s.size < 2:
        return s
    keep = np.empty(s.size, dtype=bool)
    keep[0] = True
    np.not_equal(s[1:], s[:-1], out=keep[1:])
    return s[keep]
