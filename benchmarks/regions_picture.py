"""Pictures of Yan's regions (``agents/regions.py``) on a map: the whole map known, and a robot's belief during
a run; the segmentation's CPU per call printed.

    python -m benchmarks.regions_picture [--maps office autolab] [--tick 60] [--out docs/performance/img]

For each map, ``regions-MAP.png`` with two panels. Left: the map as if wholly known, segmented (each region a
colour, critical points as black crosses, their critical lines in black). Right: robot ``r0``'s belief at
``--tick`` of a 2-robot memory run with ``trade`` on regions (``full`` radio, no loss, seed 0): unknown cells
grey, region tasks coloured with their frontier cells dark and their entry points (the task's target) as white
stars, the other regions pale, the robots as red dots. The table gives the segmentation's CPU (ms, median
of 30 calls) on the whole map and on that belief.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._common import ROOT, fail, parser
from fleet_emu.agents.regions import Regions, region_tasks, segment
from fleet_emu.core.errors import ConfigError, MapError
from fleet_emu.core.grid import OCCUPIED, UNKNOWN
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from fleet_emu.world.maps import load_map


def cpu_ms(grid: np.ndarray, calls: int = 30) -> float:
    """The median thread CPU of ``segment`` on ``grid`` (ms)."""
    segment(grid)
    times = []
    for _ in range(calls):
        t0 = time.thread_time()
        segment(grid)
        times.append((time.thread_time() - t0) * 1000.0)
    return statistics.median(times)


def belief_at(map_name: str, tick: int) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Robot r0's belief at ``tick`` of a 2-robot run of trade on regions, and the robots' cells."""
    scenario = Scenario().override(map=map_name, robots=2, loss=0.0, comm="full", seed=0, max_ticks=tick + 1,
                                   allocator={"type": "trade", "tasks": "regions"})
    fleet = Fleet(scenario)
    obs, _ = fleet.reset()
    for _ in range(tick):
        obs, *_ = fleet.step()
        if fleet.done:
            break
    belief = fleet.brains["r0"].belief
    assert belief is not None
    grid = belief.grid.copy()
    return grid, [o.cell for o in obs.values()]


def colours(regions: Regions, seed: int = 3) -> np.ndarray:
    """An RGB colour per label (0 white)."""
    rng = np.random.default_rng(seed)
    table = 0.35 + 0.6 * rng.random((regions.count + 1, 3))
    table[0] = 1.0
    return table


def panel(ax: Any, grid: np.ndarray, title: str, robots: list[tuple[int, int]] | None = None) -> None:
    """One segmented grid drawn on ``ax``."""
    regions = segment(grid)
    table = colours(regions)
    rgb = table[regions.labels]
    tasks = region_tasks(grid, regions) if robots is not None else []
    if robots is not None:
        on = np.zeros(regions.count + 1, dtype=bool)
        rgb = 1.0 - 0.35 * (1.0 - rgb)  # regions that are no task: pale
        for t in tasks:
            k = regions.labels.ravel()[t.region[0]]
            on[k] = True
        rgb[on[regions.labels]] = table[regions.labels][on[regions.labels]]
        for t in tasks:
            rgb.reshape(-1, 3)[t.cells] = 0.55 * rgb.reshape(-1, 3)[t.cells]
    rgb[grid == UNKNOWN] = 0.75
    rgb[grid == OCCUPIED] = 0.1
    rgb[regions.cuts] = 0.0
    ax.imshow(rgb, interpolation="nearest")
    if len(regions.critical):
        ax.plot(regions.critical[:, 1], regions.critical[:, 0], "kx", ms=5, mew=1.5)
    for t in tasks:
        ax.plot(t.target[1], t.target[0], "w*", ms=11, mec="k")
    for r, c in robots or []:
        ax.plot(c, r, "o", color="red", ms=7, mec="k")
    ax.set_title(title, fontsize=9)
    ax.set_xticks([])
    ax.set_yticks([])


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.regions_picture", __doc__)
    p.add_argument("--maps", nargs="+", default=["office", "autolab"])
    p.add_argument("--tick", type=int, default=60)
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "performance" / "img")
    a = p.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    try:
        for name in a.maps:
            Scenario().override(map=name)
    except (ConfigError, MapError) as exc:
        fail("regions_picture", str(exc))
    a.out.mkdir(parents=True, exist_ok=True)
    print("| map | cells | regions (whole map) | critical points | ms/call, whole map | ms/call, belief at tick |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name in a.maps:
        truth = load_map(name, 0.5, 0).grid
        grid, robots = belief_at(name, a.tick)
        whole = segment(truth)
        print(f"| {Path(name).stem} | {truth.shape[0]} x {truth.shape[1]} | {whole.count} | {len(whole.critical)} "
              f"| {cpu_ms(truth):.2f} | {cpu_ms(grid):.2f} |")
        fig, axes = plt.subplots(1, 2, figsize=(11, 11 * truth.shape[0] / truth.shape[1] / 2 + 0.8))
        panel(axes[0], truth, f"{name}, whole map: {whole.count} regions")
        panel(axes[1], grid, f"r0's belief at tick {a.tick} (trade on regions, 2 robots): tasks and entry points",
              robots)
        fig.tight_layout()
        path = a.out / f"regions-{Path(name).stem}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
