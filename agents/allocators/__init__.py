"""Frontier allocators, one per module, registered by name (``make_allocator({"type": "minpos"})``)."""

from fleet_emu.agents.allocators import (  # noqa: F401  (registration)
    connectivity,
    greedy,
    hungarian,
    minpos,
    nearest,
    trade,
    utility,
)
from fleet_emu.agents.allocators.base import (
    Allocation,
    Allocator,
    AllocStatus,
    Problem,
    make_allocator,
    robot_order,
)

__all__ = ["AllocStatus", "Allocation", "Allocator", "Problem", "make_allocator", "robot_order"]
