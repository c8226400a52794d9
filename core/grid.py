"""The occupancy-grid convention and ASCII-art grids for tests.

Grids are ``int8`` arrays indexed ``[row, col]`` with row 0 at the top: ``-1`` unknown, ``0`` free,
``100`` occupied (the ROS OccupancyGrid convention). A cell is a ``(row, col)`` tuple of ints.
"""

from __future__ import annotations

import numpy as np

UNKNOWN: int = -1
FREE: int = 0
OCCUPIED: int = 100

Cell = tuple[int, int]

#: 4-connected moves in a fixed order (up, down, left, right); every tie-break that walks
#: neighbours uses this order, so that runs are deterministic.
MOVES: tuple[Cell, ...] = ((-1, 0), (1, 0), (0, -1), (0, 1))

_ASCII = {"#": OCCUPIED, ".": FREE, "?": UNKNOWN}


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


def in_bounds(shape: tuple[int, int], cell: Cell) -> bool:
    """Whether ``cell`` lies inside a grid of ``shape``."""
    return 0 <= cell[0] < shape[0] and 0 <= cell[1] < shape[1]


def flat(shape: tuple[int, int], cell: Cell) -> int:
    """Row-major flat index of ``cell``."""
    return cell[0] * shape[1] + cell[1]


def unflat(shape: tuple[int, int], index: int) -> Cell:
    """The cell of a row-major flat index."""
    return (int(index) // shape[1], int(index) % shape[1])
