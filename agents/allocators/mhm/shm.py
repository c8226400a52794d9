"""The Single Hinged Method (SHM), MHM's baseline, as Mukhija et al. describe it (``method = "shm"``).

SHM is the method of the paper's reference [1] (Mukhija, Sawhney & Krishna, "Multi Robotic Exploration with
Communication Requirement to a Fixed Base Station", AAMAS 2010). Its text is not available here; only its abstract
is (the IIIT Hyderabad robotics lab's publication page): "a tree traversal mechanism akin to a depth first
strategy, further embellished by an adaptive rule that decides the number of children based on the local obstacle
configuration at a node and avoidance of redundancy in traversal through a look-ahead method that decides the
utility of spreading the tree from the current robotic hop node". What is implemented is what the MHM paper says of
SHM, section by section:

- Section I: "only one hinge point (node) is allotted and expanded at a time for the tree growth in it": an
  expansion of a node C_i hinges one robot, explores the new cell, and the tree grows from that cell (depth
  first) before C_i hinges its next one (``MhmPlanner._expand_single``).
- Section I: "Instead of hinging along certain number of directions, MHM tries to cover the frontiers by fitting
  the boundary with overlapping cells": SHM hinges along directions from the node, here :data:`DIRECTIONS`
  compass bearings (the number is not given; 8, chosen once), one candidate point per direction on the
  node's cell boundary (:func:`direction_points`). A direction whose sector of the boundary is walled off gives
  none: the obstacles decide how many children a node can have (the abstract's adaptive rule).
- Section I: "simulated look-ahead", and the abstract's look-ahead "that decides the utility of spreading the
  tree": a direction is worth a hinge only when an exploration frontier lies within the sensor range R_s of its
  point (the paper's test for an Exploration Wavefront point, section III-A); each direction of a node is hinged
  once at most. The paper's look-ahead prunes "node layout configurations" at a computation cost "exponential
  ... with respect to the number of robots" (Table I); that search is not described, and this one is linear.
- Section I: "the time loss in rollback processes in the SHM": before a node hinges its next direction, the
  subtrees it grew are broken (section III-E.2) and their robots come back to its cell.
- Section III-E.1: "Wavefront Expansion or SHM lead to creation of new cells": SHM's cells join the tree by eq. 2
  and 3, as MHM's do; section III-D's phase 2 (the chains to the frontier nearest the base) is shared, so that
  both methods end where step 10 ends them (Table II: "both the methods having almost similar reach").

What this SHM is not: ``hinges = 1``, a cap of one position per MHM Wavefront Expansion iteration, still places
that position on the subtree's wavefront; SHM places it along a direction from the node being expanded.
"""

from __future__ import annotations

import math

import numpy as np

from fleet_emu.agents.allocators.mhm.wavefront import cell_boundary
from fleet_emu.core.grid import Cell

#: SHM's directions per node: the compass bearings, north first, clockwise (the paper does not give the number).
DIRECTIONS = 8


def _bearing(point: Cell, center: Cell) -> float:
    """Bearing of ``point`` from ``center``: clockwise from north (row decreasing), in ``[0, 2*pi)``."""
    b = math.atan2(point[1] - center[1], center[0] - point[0])
    return b + 2 * math.pi if b < 0 else b


def direction_points(grid: np.ndarray, center: Cell, r_comm: float, sensor_range: float, fdist: np.ndarray,
                     directions: int = DIRECTIONS) -> dict[int, Cell]:
    """Each useful direction of the node at ``center`` with its hinge point: for direction k (bearing
    ``k * 2 pi / directions``), the point of the node's cell boundary in that direction's sector (within half a
    step of its bearing) that has an exploration frontier within ``sensor_range`` (``fdist``:
    ``wavefront.frontier_distance``) and lies nearest the direction's bearing (then nearest the node's row and
    column order, for a total order). A direction with no such point is absent."""
    step = 2 * math.pi / directions
    best: dict[int, tuple[float, Cell]] = {}
    for r, c in cell_boundary(grid, center, r_comm):
        if fdist[r, c] > sensor_range:
            continue
        b = _bearing((int(r), int(c)), center)
        k = round(b / step) % directions
        off = abs((b - k * step + math.pi) % (2 * math.pi) - math.pi)
        key = (off, (int(r), int(c)))
        if k not in best or key < (best[k][0], best[k][1]):
            best[k] = key
    return {k: p for k, (_, p) in sorted(best.items())}
