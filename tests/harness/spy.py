"""An allocator that remembers what it was given, for the brain's tests and the hearing's."""

from __future__ import annotations

from collections.abc import Sequence

from fleet_emu.agents.allocators import Allocation, Allocator, Problem, make_allocator
from fleet_emu.core.grid import Cell
from fleet_emu.core.messages import RadioMsg


class Spy(Allocator):
    """Nearest frontier, remembering the poses it was given (not registered: no plugin name)."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: list[dict[str, Cell]] = []
        self.previous: list[Cell | None] = []
        self.nearest = make_allocator({"type": "nearest"})

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        self.seen.append(dict(problem.poses))
        self.previous.append(problem.previous_target)
        return self.nearest.allocate(problem, inbox)
