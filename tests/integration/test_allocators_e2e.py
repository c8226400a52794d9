"""Every registered allocator drives a real fleet (real router, real sessions) to the target under loss."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleet_emu.agents.allocators import allocator_names
from fleet_emu.core.scenario import BASE_PLANNERS

from .conftest import fleet, result


@pytest.mark.parametrize("loss", [0.0, 0.3, 0.5])
@pytest.mark.parametrize("allocator", [a for a in allocator_names() if a not in BASE_PLANNERS])
# mhm needs a base station and stops where its robots cannot reach (step 18): tests/integration/test_mhm.py
def test_every_allocator_completes_under_loss(allocator: str, loss: float, small_map: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    # loss 0.5 runs one process per robot; the others run every node in one process (each its own session)
    layout = [] if loss == 0.5 else ["--in-process"]
    fleet("run", "--map", str(small_map), "--robots", "4", "--allocator", allocator, "--loss", str(loss),
          "--seed", "3", "--max-ticks", "400", "--no-record", "--quiet", "--out", str(out), *layout)
    res = result(out)
    assert res["allocator"] == allocator and res["failed"] == []
    assert res["completed"] is True and res["coverage"] >= 0.99, res["reason"]
    radio = res["radio"]
    if loss > 0:
        assert radio["dropped_loss"] > 0
        assert abs(radio["dropped_loss"] / (radio["delivered"] + radio["dropped_loss"]) - loss) < 0.15
    else:
        assert radio["dropped_loss"] == 0
