"""Helpers for the end-to-end tests: they start real routers and real processes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from benchmarks.faults import RunSpec

ROOT = Path(__file__).resolve().parents[2]

#: A lockstep run that cannot end by itself while a test signals or kills it (``ENDLESS.args(robots=N)``: its
#: ``fleet run`` flags): a 1 m sensor on the maze at 10 cm cells. Three robots see a third of it in 2,000 ticks
#: (17 s on this machine), and only the whole of it or 100,000 ticks end the run. The office ends in 5 s with 2
#: or 3 robots, start-up included, so a signal a few seconds in can come after the run's own end.
ENDLESS = RunSpec("maze", max_ticks=100000, target_coverage=1.0, extra=("--cell-size", "0.1", "--sensor-range", "1"))

# A small two-room map (white free, black walls), drawn like the tests' ASCII grids.
SMALL = """
########################
#..........#...........#
#..........#...........#
#......................#
#..........#...........#
#..........#...........#
####.#######.......#####
#..........#...........#
#..........#...........#
#......................#
#..........#...........#
########################
"""


@pytest.fixture(scope="session")
def small_bitmap(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``two_rooms.png`` alone: a bare bitmap, read one pixel per cell at the cell size a run gives (the
    benchmarks that fit a map to a number of cells give theirs)."""
    rows = [ln.strip() for ln in SMALL.strip().splitlines()]
    img = np.array([[0 if ch == "#" else 255 for ch in row] for row in rows], dtype=np.uint8)
    path = tmp_path_factory.mktemp("maps") / "two_rooms.png"
    Image.fromarray(img, mode="L").save(path)
    return path


@pytest.fixture(scope="session")
def small_map(small_bitmap: Path) -> Path:
    """``two_rooms.yaml``: the bitmap with its scale, 0.5 m per pixel (one pixel per cell at the default cell
    size), so that a run needs no --cell-size."""
    path = small_bitmap.with_suffix(".yaml")
    path.write_text(f"image: {small_bitmap.name}\nresolution: 0.5\norigin: [0.0, 0.0, 0.0]\n")
    return path


def fleet(*args: str, timeout: float = 240, check: bool = True,
          env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """Run the ``fleet`` CLI as a user would (``python -m fleet_emu`` is the console script's module);
    ``env``: variables set on top of this process's environment."""
    proc = subprocess.run([sys.executable, "-m", "fleet_emu", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=ROOT, env={**os.environ, **env} if env else None)
    if check and proc.returncode not in (0, 3):
        raise AssertionError(f"fleet {' '.join(args)} exited {proc.returncode}:\n{proc.stderr[-3000:]}")
    return proc


def result(out: Path) -> dict:
    return json.loads((out / "result.json").read_text())


def wait_for(predicate, timeout: float) -> None:  # type: ignore[no-untyped-def]
    """Poll ``predicate`` every 0.1 s; AssertionError after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError("timed out waiting")
        time.sleep(0.1)


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie is not alive
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"


def all_pids(res: dict) -> list[int]:
    """Every process of the run: world, netem, the agents, and the fork server, the router and the base (when
    there were)."""
    more = [res["pids"][k] for k in ("fork_server", "router", "base") if k in res["pids"]]
    return sorted({res["pids"]["world"], res["pids"]["netem"], *res["pids"]["agents"], *more})


def children_of(pid: int) -> list[int]:
    """The direct children of ``pid``."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if int((d / "stat").read_text().split(")")[-1].split()[1]) == pid:
                    found.append(int(d.name))
            except (OSError, ValueError, IndexError):
                pass
    return found


def _runs(pid: int, module: bytes) -> bool:
    try:
        return module in Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False


def is_fork_server(pid: int) -> bool:
    """Whether a launcher's child is the robots' fork server (the robots it forks share its command line)."""
    return _runs(pid, b"fleet_emu.agents.forkserver")


def is_router(pid: int) -> bool:
    """Whether a launcher's child is the run's router process."""
    return _runs(pid, b"fleet_emu.launch.router_process")


def fleet_processes(launcher: int) -> list[int]:
    """The fleet's node processes under a launcher: its children but the fork server and the router, and the
    robots the fork server forked."""
    found = []
    for pid in children_of(launcher):
        if not is_router(pid):
            found += children_of(pid) if is_fork_server(pid) else [pid]
    return found
