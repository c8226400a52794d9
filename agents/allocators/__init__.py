"""Frontier allocators, one per module, registered by name (``make_allocator({"type": "minpos"})``); installed
packages add theirs through the ``fleet_emu.allocators`` entry-point group (:mod:`.registry`)."""

from fleet_emu.agents.allocators import (  # noqa: F401  (registration)
    connectivity,
    greedy,
    hungarian,
    minpos,
    nearest,
    policy,
    random_frontier,
    trade,
    utility,
)
from fleet_emu.agents.allocators.interface import (
    Allocation,
    Allocator,
    AllocStatus,
    Problem,
    robot_order,
)
from fleet_emu.agents.allocators.mhm import robot as _mhm_robot  # noqa: F401  (registers ``mhm``)
from fleet_emu.agents.allocators.params import Param
from fleet_emu.agents.allocators.registry import allocator_class, allocator_names, make_allocator

__all__ = ["AllocStatus", "Allocation", "Allocator", "Param", "Problem", "allocator_class", "allocator_names",
           "make_allocator", "robot_order"]
