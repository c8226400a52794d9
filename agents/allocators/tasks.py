"""What an allocator bids on (its ``tasks`` parameter): the frontier clusters the brain found, or Yan's regions.

``tasks = "frontiers"`` (the default) leaves :attr:`Problem.clusters` as the brain made it. ``tasks = "regions"``
puts the region tasks of the robot's belief in their place (:mod:`agents.regions`: a topological segmentation
of the known free space at critical points, Thrun 1998 / Wurm et al. 2008, as Yan et al. 2011 section 4.2 take
their tasks), before the allocator reads anything: every index the allocation gives, the cost matrix, and the
brain's navigation down the assigned task's wavefront then refer to the region tasks. A region task is a
:class:`~fleet_emu.agents.frontiers.Cluster` (its frontier cells, its entry point as ``target``), so an
allocator's cost machinery is unchanged.
"""

from __future__ import annotations

from fleet_emu.agents.allocators.interface import Problem
from fleet_emu.agents.allocators.params import Param
from fleet_emu.agents.regions import RegionTasks

#: The ``tasks`` parameter of the allocators that can bid on regions.
TASKS = Param("frontiers", choices=("frontiers", "regions"))


def use_tasks(problem: Problem, tasks: str, regions: RegionTasks) -> None:
    """With ``tasks == "regions"``, swap ``problem``'s clusters for the region tasks of its belief (segmented
    once per belief by ``regions``), in place, and drop any wavefront or cost already computed for the old
    ones."""
    if tasks != "regions":
        return
    problem.clusters = list(regions.of(problem.belief))
    problem.__dict__.pop("wavefronts", None)
    problem.__dict__.pop("costs", None)
