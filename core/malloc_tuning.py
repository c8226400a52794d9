"""Keep a node's freed heap memory for its next tick (glibc's ``mallopt``), and run Python's cycle collector
less often (:func:`collect_less`).

A robot allocates the same few arrays of the map's size every tick (the allocator's wavefront distances, a
frontier mask: 1 MB each on a 512 x 512 map) and frees them before the next. With glibc's defaults, a block
that large is served by ``mmap`` and handed back to the kernel when freed (or the heap top is trimmed), so the
next tick touches fresh pages again: a page fault and a zeroed page per 4 kB. Measured on the 2-core VM
(``benchmarks/scale.py --robots 16 --maps maze --ticks 100``, 2026-11-24): 255-1279 minor faults per robot-tick
in a robot process, none in the memory engine's long-lived heap, and the allocator's thread CPU 1.6 ms per
robot-tick in the robots against 0.2-0.45 ms with the heap kept. Raising the mmap and trim thresholds keeps
those blocks in the heap: the process keeps its peak heap (a few MB more PSS per robot) and stops faulting.

Only glibc has these knobs; elsewhere (musl, macOS) :func:`keep_heap` does nothing and says so.
"""

from __future__ import annotations

import contextlib
import ctypes
import gc
from collections.abc import Iterator

M_TRIM_THRESHOLD = -1  # glibc's malloc.h: free memory at the heap top above this is given back
M_MMAP_THRESHOLD = -3  # and a request at least this large gets its own mapping
MMAP_THRESHOLD = 32 * 2**20  # glibc's largest allowed value on 64-bit (DEFAULT_MMAP_THRESHOLD_MAX)
TRIM_THRESHOLD = 64 * 2**20


def keep_heap(mmap_threshold: int = MMAP_THRESHOLD, trim_threshold: int = TRIM_THRESHOLD) -> bool:
    """Set this process's malloc thresholds (module docstring); whether the C library took them."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(M_MMAP_THRESHOLD, mmap_threshold)) and bool(mallopt(M_TRIM_THRESHOLD, trim_threshold))


#: A node process's first-generation collector threshold: container allocations between two collections of
#: the youngest generation (CPython's default is 700).
GC_GEN0 = 20_000


def collect_less(gen0: int = GC_GEN0) -> tuple[int, int, int]:
    """Collect the youngest generation every ``gen0`` container allocations; the thresholds before. A robot of a
    hundred allocates tens of thousands of small containers a tick (its teammates' decoded beacons and map
    deltas, the tuples and dicts they hold), almost none of them in a cycle, and with the default threshold
    the collector scanned them several times a tick: measured with ``benchmarks/brain_step.py --robots 100``,
    a third of the radio decode's CPU and a fifth of the whole step's."""
    before = gc.get_threshold()
    gc.set_threshold(gen0, before[1], before[2])
    return before


@contextlib.contextmanager
def collecting_less(gen0: int = GC_GEN0) -> Iterator[None]:
    """:func:`collect_less` for the block, then the thresholds as they were (the memory engine runs inside the
    caller's process)."""
    before = collect_less(gen0)
    try:
        yield
    finally:
        gc.set_threshold(*before)
