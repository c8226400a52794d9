"""A small map and study files for the sweep tests."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

ROOT = Path(__file__).resolve().parents[2]

ROOMS = """
##############
#.....#......#
#............#
#.....#......#
###.#####.####
#............#
#.....#......#
##############
"""


def draw(ascii_map: str, path: Path) -> Path:
    rows = [ln.strip() for ln in ascii_map.strip().splitlines()]
    Image.fromarray(np.array([[0 if ch == "#" else 255 for ch in r] for r in rows], np.uint8), "L").save(path)
    return path


@pytest.fixture
def study_dir(tmp_path: Path) -> Path:
    """A folder with ``rooms.png`` and ``tiny.toml`` (2 allocators x 2 robot counts x 2 seeds)."""
    draw(ROOMS, tmp_path / "rooms.png")
    (tmp_path / "tiny.toml").write_text("""
[study]
name = "tiny"
engine = "memory"
seeds = 2
baseline = "nearest"
[grid]
allocator = ["nearest", "minpos"]
robots = [2, 3]
loss = [0.0]
comm = ["ideal"]
map = ["rooms.png"]
[fleet]
cell_size = 0.5
sensor_range = 1.5
start = [1, 1]
max_ticks = 300
""")
    return tmp_path


def fleet(*args: str, cwd: Path = ROOT, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "fleet_emu", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=cwd)
