"""Rows of a study's results, made by hand for the sweep's report, table and plot tests."""

from __future__ import annotations

import json


def row(alloc: str, robots: int, ticks: int, loss: float = 0.0, completed: bool = True) -> dict:
    """One run's row of a study's ``runs.csv`` as the report reads it (the other columns fixed)."""
    return {"param.allocator": alloc, "robots": robots, "map": "office", "comm": "full", "loss_applied": loss,
            "ticks": ticks, "completed": completed, "coverage": 0.99, "connected_fraction": 0.5,
            "path_length": json.dumps([ticks, ticks]), "status": "ok"}
