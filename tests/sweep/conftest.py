"""A small map and study files for the sweep tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.harness.files import ROOMS, draw_map


@pytest.fixture
def study_dir(tmp_path: Path) -> Path:
    """A folder with ``rooms.png`` and ``tiny.toml`` (2 allocators x 2 robot counts x 2 seeds)."""
    draw_map(ROOMS, tmp_path / "rooms.png")
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
