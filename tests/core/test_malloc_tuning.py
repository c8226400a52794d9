"""core/malloc_tuning.py: a node that allocates and frees the same map-sized arrays every tick stops faulting pages in
once its heap is kept (the pattern that cost a robot's allocator 1.6 ms per tick on a 512 x 512 map)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from fleet_emu.core.malloc_tuning import keep_heap

# Three 1 MB arrays (a 512 x 512 int32 grid each) made and dropped per "tick"; minor page faults counted over
# ten ticks after five of warm-up.
SCRIPT = """
import resource, sys
import numpy as np
from fleet_emu.core.malloc_tuning import keep_heap
if sys.argv[1] == "keep" and not keep_heap():
    raise SystemExit("mallopt refused")
def tick():
    arrays = [np.ones(262144, dtype=np.int32) for _ in range(3)]
    del arrays
for _ in range(5):
    tick()
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(10):
    tick()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


def faults(mode: str) -> int:
    out = subprocess.run([sys.executable, "-c", SCRIPT, mode], capture_output=True, text=True, check=True)
    return int(out.stdout.strip())


def test_a_kept_heap_stops_the_page_faults_of_each_tick() -> None:
    if not keep_heap():
        pytest.skip("not glibc: mallopt is not there to keep the heap")
    default, kept = faults("default"), faults("keep")
    assert default > 10 * 256  # the default gives the 3 MB back and faults it in again every tick
    assert kept < 50

