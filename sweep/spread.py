"""The order in which a study's runs are taken when only some are run (``fleet sweep --limit N``, ``--quick``):
spread over the grid, so that the first runs already compare every allocator at settings far apart, and the
report's tables and paper claims have numbers after a few runs.

Every grid point's first seed comes before any point's second seed. Within a seed, the settings other than the
allocator (robot counts, radios, maps...) come in a farthest-first order: the first setting, then the one farthest
from it (each axis's index scaled to [0, 1]), then the one farthest from both, and so on (ties to the earlier in
grid order); and for each setting every allocator in a row, so that every allocator is compared with the baseline
at the same setting. The order depends on the grid alone: a later call with a larger limit continues it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol, TypeVar

#: The grid axis whose values are compared with one another (kept together at each setting).
COMPARED = "allocator"


class _Point(Protocol):
    @property
    def params(self) -> dict[str, Any]: ...


P = TypeVar("P", bound=_Point)


def farthest_first(cells: Sequence[tuple[float, ...]]) -> list[int]:
    """The indices of ``cells`` (points of the unit cube) in farthest-first order, from the first."""
    if not cells:
        return []
    order = [0]
    nearest = [_dist(c, cells[0]) for c in cells]
    while len(order) < len(cells):
        best = max((i for i in range(len(cells)) if i not in order), key=lambda i: (nearest[i], -i))
        order.append(best)
        nearest = [min(d, _dist(c, cells[best])) for d, c in zip(nearest, cells, strict=True)]
    return order


def _dist(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    return sum((x - y) ** 2 for x, y in zip(a, b, strict=True))


def spread(points: Sequence[P], labels: dict[str, list[Any]], seeds: Sequence[int]) -> list[P]:
    """``points`` (each with its grid labels and ``seed`` in ``params``) in the spread order; ``labels``: each
    grid axis's values as the points label them, in the grid's order; ``seeds``: the study's seeds in order."""
    others = [k for k in labels if k != COMPARED]

    def setting(p: P) -> tuple[int, ...]:
        """The point's place on each other axis: indices, as a value may be a list (a start cell) or a table."""
        return tuple(labels[k].index(p.params[k]) for k in others)

    settings = sorted({setting(p) for p in points})
    scale = {k: max(len(labels[k]) - 1, 1) for k in others}
    cells = [tuple(i / scale[k] for k, i in zip(others, s, strict=True)) for s in settings]
    rank = {settings[i]: n for n, i in enumerate(farthest_first(cells))}
    compared = labels.get(COMPARED, [])

    def key(p: P) -> tuple[int, int, int]:
        c = compared.index(p.params[COMPARED]) if COMPARED in labels else 0
        return seeds.index(p.params["seed"]), rank[setting(p)], c

    return sorted(points, key=key)
