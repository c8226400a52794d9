"""MinPos's parallel wavefronts (Bautin et al. 2012, section 4.3) as one compiled kernel: one BFS per frontier
cluster, all advanced a distance layer at a time, their queues in one pool of linked slots
(:func:`minpos_parallel`). The grid's other kernels are in :mod:`fleet_emu.core.kernels`."""

from __future__ import annotations

import numpy as np

from fleet_emu.core import kernels
from fleet_emu.core.jit import njit

_NO_KEY = np.int64(1) << np.int64(62)


@njit(cache=True)
def _grown(a: np.ndarray, cap: int) -> np.ndarray:
    out = np.empty(cap, dtype=a.dtype)
    for i in range(len(a)):  # not out[:len(a)] = a: its shape check compiles numba's string formatting (seconds)
        out[i] = a[i]
    return out


@njit(cache=True, inline="always")
def _push(cell: np.ndarray, link: np.ndarray, head: np.ndarray, tail: np.ndarray, j: int, slot: int,
          value: int) -> None:
    """Append ``value`` in pool slot ``slot`` to the tail of wavefront j's linked queue."""
    cell[slot] = value
    link[slot] = -1
    if head[j] < 0:
        head[j] = slot
    else:
        link[tail[j]] = slot
    tail[j] = slot


@njit(cache=True, inline="always")
def _first_visit(seen: np.ndarray, key: int) -> bool:
    """Mark bit ``key`` of the bitset ``seen`` (uint64 words); whether it was clear. One bit per (wavefront,
    cell): eight times less memory to clear and walk than a byte each (m wavefronts on a 512 x 512 map)."""
    word = key >> 6
    bit = np.uint64(1) << np.uint64(key & 63)
    if seen[word] & bit:
        return False
    seen[word] |= bit
    return True


@njit(cache=True)
def _expand_layer(flat_pass: np.ndarray, rows: int, cols: int, seen: np.ndarray, base: int, crowd: np.ndarray,
                  robots: np.ndarray, me: int, cell: np.ndarray, link: np.ndarray, spare: np.ndarray,
                  head: np.ndarray, tail: np.ndarray, span: np.ndarray, j: int, count: int, used: int, nspare: int
                  ) -> tuple[bool, int, int, int, int]:
    """Pop the ``count`` cells of wavefront j's current layer and queue their unseen passable neighbours
    (``span[j]``: the lowest and highest cell it marked). Returns (me found, robots met in the layer, cells
    queued, used, nspare)."""
    found = 0
    fresh = 0
    for _ in range(count):
        idx = head[j]
        cur = cell[idx]
        head[j] = link[idx]
        spare[nspare] = idx
        nspare += 1
        if cur == me:
            return True, found, fresh, used, nspare
        if crowd[cur >> 6] & (np.uint64(1) << np.uint64(cur & 63)):  # a teammate stands here: count them
            for r in robots:
                if r == cur:
                    found += 1
        for k in range(4):
            nxt = kernels._neighbour(cur, k, rows, cols)
            if nxt < 0:
                continue
            if flat_pass[nxt] and _first_visit(seen, base + nxt):
                span[j, 0] = min(span[j, 0], nxt)
                span[j, 1] = max(span[j, 1], nxt)
                if nspare > 0:
                    nspare -= 1
                    slot = spare[nspare]
                else:
                    slot = used
                    used += 1
                _push(cell, link, head, tail, j, slot, nxt)
                fresh += 1
    return False, found, fresh, used, nspare


@njit(cache=True)
def _seed_wavefronts(sources: np.ndarray, offsets: np.ndarray, n: int, seen: np.ndarray, cell: np.ndarray,
                     link: np.ndarray, head: np.ndarray, tail: np.ndarray, size: np.ndarray, key: np.ndarray,
                     span: np.ndarray) -> int:
    """Queue each wavefront's layer 0 (:func:`minpos_parallel`): cluster j's cells, each once and on the map,
    from pool slot 0 on; key 0 for every wavefront with a cell. Returns the pool slots used."""
    used = 0
    for j in range(len(offsets) - 1):
        base = j * n
        for t in range(offsets[j], offsets[j + 1]):
            s = sources[t]
            if 0 <= s < n and _first_visit(seen, base + s):
                span[j, 0] = min(span[j, 0], s)
                span[j, 1] = max(span[j, 1], s)
                _push(cell, link, head, tail, j, used, s)
                used += 1
                size[j] += 1
        if size[j] > 0:
            key[j] = 0
    return used


@njit(cache=True)
def minpos_parallel(passable: np.ndarray, sources: np.ndarray, offsets: np.ndarray, me: int,
                    robots: np.ndarray) -> tuple[int, int, int]:
    """MinPos with parallel wavefronts (Bautin et al. 2012, section 4.3, "Parallel computation of wavefronts").

    One BFS per frontier cluster ``j`` (its cells are ``sources[offsets[j]:offsets[j + 1]]``, seeded like
    :func:`wavefront`), all advanced one distance layer at a time. A wavefront's key is (robots it has met, next
    layer): a layer holding a teammate (``robots``, flat indices) raises the count, which pauses that wavefront
    behind every one that has met fewer robots; among equals the lowest layer goes first ("restarted
    sequentially from the lowest to the highest potential"), then the lowest cluster index. The first wavefront
    whose layer holds ``me`` is the answer: its key then is (P_ij, C_ij), so the result is Algorithm 3's
    argmin of position, then cost, then cluster index. Returns ``(j, P_ij, C_ij)``, or ``(-1, -1, -1)`` when
    no wavefront reaches ``me``. Queues share one pool of linked slots, recycled when popped.
    """
    n = passable.shape[0] * passable.shape[1]
    seen = np.zeros((max(len(offsets) - 1, 1) * n + 63) // 64, dtype=np.uint64)  # seen_words(n, m)
    return minpos_parallel_into(passable, sources, offsets, me, robots, seen)


def seen_words(n: int, m: int) -> int:
    """The uint64 words of :func:`minpos_parallel_into`'s ``seen`` for ``m`` wavefronts over ``n`` cells: a bit
    per (wavefront, cell)."""
    return (max(m, 1) * n + 63) // 64


@njit(cache=True)
def minpos_parallel_into(passable: np.ndarray, sources: np.ndarray, offsets: np.ndarray, me: int,
                         robots: np.ndarray, seen: np.ndarray) -> tuple[int, int, int]:
    """:func:`minpos_parallel` with its bitset of visited (wavefront, cell) pairs given: ``seen``, at least
    :func:`seen_words` uint64 words, all zero, and left all zero (only the words each wavefront's cells span are
    cleared). An allocator keeps one across calls: a fresh one per call was a memset of m x n bits (a megabyte
    for 32 clusters on a 512 x 512 map), most of it never read."""
    n = passable.shape[0] * passable.shape[1]
    span = np.empty((max(len(offsets) - 1, 1), 2), dtype=np.int64)
    span[:, 0] = n
    span[:, 1] = -1
    out = _minpos_search(passable, sources, offsets, me, robots, seen, span)
    for j in range(span.shape[0]):
        if span[j, 1] >= 0:
            seen[(j * n + span[j, 0]) >> 6:((j * n + span[j, 1]) >> 6) + 1] = 0
    return out


@njit(cache=True)
def _minpos_search(passable: np.ndarray, sources: np.ndarray, offsets: np.ndarray, me: int, robots: np.ndarray,
                   seen: np.ndarray, span: np.ndarray) -> tuple[int, int, int]:
    """:func:`minpos_parallel_into`'s search; ``span[j]``: the lowest and highest cell wavefront j marked."""
    rows, cols = passable.shape
    n = rows * cols
    m = len(offsets) - 1
    flat_pass = passable.ravel()
    crowd = np.zeros((n + 63) // 64, dtype=np.uint64)  # a bit per cell a teammate stands on (32 KB, not 2 MB
    for r in robots:  # of counts to clear on every call on a 512 x 512 map); they are counted when met
        if 0 <= r < n:
            crowd[r >> 6] |= np.uint64(1) << np.uint64(r & 63)
    width = max(m, 1)
    cap = 2 * len(sources) + 1024
    cell = np.empty(cap, dtype=np.int64)
    link = np.empty(cap, dtype=np.int64)
    spare = np.empty(cap, dtype=np.int64)
    nspare = 0
    head = np.full(width, -1, dtype=np.int64)
    tail = np.full(width, -1, dtype=np.int64)
    size = np.zeros(width, dtype=np.int64)
    met = np.zeros(width, dtype=np.int64)
    depth = np.zeros(width, dtype=np.int64)
    key = np.full(width, _NO_KEY, dtype=np.int64)
    stride = np.int64(n + 1)
    used = _seed_wavefronts(sources, offsets, n, seen, cell, link, head, tail, size, key, span)
    while m > 0:
        j = int(np.argmin(key))
        if key[j] >= _NO_KEY:
            break
        need = used + 4 * size[j]
        if need > cap:  # room for every cell this layer may queue, grown out of the hot loop
            cap = 2 * need
            cell = _grown(cell, cap)
            link = _grown(link, cap)
            spare = _grown(spare, cap)
        hit, found, fresh, used, nspare = _expand_layer(flat_pass, rows, cols, seen, j * n, crowd, robots, me, cell,
                                                        link, spare, head, tail, span, j, size[j], used, nspare)
        if hit:
            return j, met[j], depth[j]
        met[j] += found
        depth[j] += 1
        size[j] = fresh
        key[j] = met[j] * stride + depth[j] if fresh > 0 else _NO_KEY
    return -1, -1, -1
