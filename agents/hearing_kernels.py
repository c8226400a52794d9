"""Teammates' pose beacons, map deltas and fills read straight from their bytes, all of an inbox's in one compiled
pass.

A robot of a hundred hears about sixty map deltas and sixty beacons a tick, most beacons asking teammates for
lost deltas (map sync), and in its first ticks a whole map from most teammates. Decoding all of it into structs
and dicts and checking it in Python cost more than the merge it feeds. Here :func:`read` walks every map
delta's and fill's MessagePack bytes (``docs/reference/protocol.md``: a map of ``cells``, ``values``, then a
delta's ``n`` and ``covers`` when map sync numbers it, a fill's ``seqs`` and ``upto``), checks what
:meth:`~fleet_emu.agents.protocol.MapDelta.validate` and :meth:`~fleet_emu.agents.protocol.MapFill.validate`
check and copies the cells and values into two arrays; it reads every beacon (``cell``, ``next``, ``maps``,
``want``) and checks it as :meth:`~fleet_emu.agents.protocol.PoseBeacon.validate` does, reading of its requests
only those addressed to the robot. One call for the inbox: each call of a compiled function costs a few
microseconds before it does anything.

It reads only the encoding the robots' own encoder writes (keys in that order, ``bin`` for the arrays, unsigned
integers, short strings): anything else, valid or not, gets None, and the caller opens the inbox the general
way, message by message, which accepts or refuses each as the message decoders do. The kernel accepts a
subset of what those accept, with the same values (``tests/agents/test_hearing_kernels.py`` compares them on
damaged bytes of the robots' own messages, ``tests/agents/test_hearing.py`` on mutated maps).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import NamedTuple

import numpy as np

from fleet_emu.core import kernels
from fleet_emu.core.jit import njit

# the keys and array headers as the encoder writes them (fixstr: 0xa0 + length, then the bytes)
_CELLS = np.frombuffer(b"\xa5cells\x83\xa5dtype\xa5int32\xa5shape\x91", np.uint8)
_VALUES = np.frombuffer(b"\xa6values\x83\xa5dtype\xa4int8\xa5shape\x91", np.uint8)
_DATA = np.frombuffer(b"\xa4data", np.uint8)
_N = np.frombuffer(b"\xa1n", np.uint8)
_COVERS = np.frombuffer(b"\xa6covers", np.uint8)
_SEQS = np.frombuffer(b"\xa4seqs", np.uint8)
_UPTO = np.frombuffer(b"\xa4upto", np.uint8)
_CELL = np.frombuffer(b"\xa4cell\x92", np.uint8)
_NEXT = np.frombuffer(b"\xa4next", np.uint8)
_MAPS = np.frombuffer(b"\xa4maps", np.uint8)
_WANT = np.frombuffer(b"\xa4want", np.uint8)
_MAX_INT = (1 << 63) - 1
_HASH = -7046029254386353131  # 0x9E3779B97F4A7C15 (Fibonacci hashing) as a signed 64-bit number
_NO_KEYS = np.zeros(0, np.int64)  # a team whose names are not packed: its requests go the general way


@njit(cache=True, inline="always")
def _same(buf: np.ndarray, p: int, end: int, lit: np.ndarray) -> bool:
    """Whether ``buf[p:]`` starts with ``lit`` before ``end``."""
    if p + lit.shape[0] > end:
        return False
    for i in range(lit.shape[0]):  # noqa: SIM110 (a generator in all() does not compile in numba)
        if buf[p + i] != lit[i]:
            return False
    return True


@njit(cache=True)
def _uint(buf: np.ndarray, p: int, end: int) -> tuple[int, int]:
    """A non-negative integer (positive fixint or uint 8 to 64) at ``p``: (value, next position), or (-1, p)."""
    if p >= end:
        return -1, p
    b = int(buf[p])
    if b < 0x80:
        return b, p + 1
    width = 1 if b == 0xCC else 2 if b == 0xCD else 4 if b == 0xCE else 8 if b == 0xCF else 0
    if width == 0 or p + 1 + width > end or (width == 8 and buf[p + 1] >= 0x80):
        return -1, p  # not such an integer, or above int64's range: the general way
    v = 0
    for i in range(width):
        v = (v << 8) | int(buf[p + 1 + i])
    return v, p + 1 + width


@njit(cache=True)
def _bin(buf: np.ndarray, p: int, end: int, size: int) -> int:
    """The position of the bytes of a ``bin`` of ``size`` bytes whose header is at ``p``, or -1."""
    b = int(buf[p]) if p < end else 0
    width = 1 if b == 0xC4 else 2 if b == 0xC5 else 4 if b == 0xC6 else 0
    if width == 0 or p + 1 + width > end:
        return -1
    n = 0
    for i in range(width):
        n = (n << 8) | int(buf[p + 1 + i])
    q = p + 1 + width
    return q if n == size and q + size <= end else -1


@njit(cache=True)
def _array(buf: np.ndarray, p: int, end: int, head: np.ndarray, width: int, max_bytes: int) -> tuple[int, int]:
    """An array field (``head``, its shape's one number, ``data``) of ``width``-byte items at ``p``: (count,
    position of its data) or (-1, p)."""
    if not _same(buf, p, end, head):
        return -1, p
    k, p = _uint(buf, p + head.shape[0], end)
    if k < 0 or k > max_bytes // width or not _same(buf, p, end, _DATA):
        return -1, p
    q = _bin(buf, p + _DATA.shape[0], end, k * width)
    return (k, q) if q >= 0 else (-1, p)


@njit(cache=True)
def _covers(buf: np.ndarray, p: int, end: int, n: int, max_seqs: int, out: np.ndarray, o: int) -> tuple[int, int]:
    """A list of delta numbers at ``p`` (``covers``, ``seqs``, a request): strictly ascending from 1, at most
    ``max_seqs``, the last below ``n``, written at ``out[o:]``. (How many, the position after them), or (-1, p)."""
    if p >= end:
        return -1, p
    b = int(buf[p])
    if 0x90 <= b <= 0x9F:
        count, p = b - 0x90, p + 1
    elif b == 0xDC and p + 3 <= end:
        count, p = int(buf[p + 1]) << 8 | int(buf[p + 2]), p + 3
    else:
        return -1, p
    if count > max_seqs or o + count > out.shape[0]:
        return -1, p
    last = 0
    for i in range(count):
        s, p = _uint(buf, p, end)
        if s <= last:  # also s < 0: not an unsigned integer
            return -1, p
        out[o + i] = s
        last = s
    return (count, p) if last < n else (-1, p)


@njit(cache=True)
def _read(buf: np.ndarray, lengths: np.ndarray, fills: np.ndarray, beacons: int, rows: int, cols: int,
          keys: np.ndarray, ids: np.ndarray, me: int, max_bytes: int, max_seqs: int
          ) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every payload (``lengths`` bytes each, one after another in ``buf``) read: first map deltas and fills
    (``fills[i]``), then ``beacons`` pose beacons, then beacons' request maps alone. (Whether all are in the
    encoder's form and valid; the deltas' and fills' cells and values one after another; per delta or fill the
    end of its cells and three numbers; per beacon its cell, next cell (-1, -1: none), ``maps`` (-1: none) and
    the offset of its request map in its bytes (-1: none); per request map (in a beacon or alone) that asks
    teammate ``me`` for deltas, its index among the beacons and request maps and the span of the numbers; the
    delta numbers.) A delta's three: ``n`` or 0 and the span of ``covers`` in the last array (-1, -1 without);
    a fill's: ``upto`` and the span of ``seqs``. The grid has ``rows`` x ``cols`` cells."""
    room = buf.shape[0] // 5  # a cell takes at least 5 bytes of its message: 4 for its index, 1 for its value
    cells, values = np.empty(room, np.int32), np.empty(room, np.int8)
    maps, size = fills.shape[0], rows * cols
    meta = np.empty((maps, 4), np.int64)
    poses = np.empty((beacons, 6), np.int64)
    asked = np.empty((lengths.shape[0] - maps, 3), np.int64)
    seqs = np.empty(min(buf.shape[0], lengths.shape[0] * max_seqs), np.int64)
    c, o, a, end = 0, 0, 0, 0
    for i in range(lengths.shape[0]):
        p, end = end, end + lengths[i]
        if i >= maps:
            count = -1
            if i < maps + beacons:
                start = p
                p = _pose(buf, p, end, rows, cols, poses[i - maps])
                if p >= 0 and p < end:  # its request map, the last field
                    poses[i - maps, 5] = p - start
                    count, p = _want(buf, p, end, keys, ids, me, max_seqs, seqs, int(o))
            else:
                count, p = _want(buf, p, end, keys, ids, me, max_seqs, seqs, int(o))
            if p != end:
                return False, cells[:c], values[:c], meta, poses, asked[:a], seqs[:o]
            if count >= 0:
                asked[a, 0], asked[a, 1], asked[a, 2] = i - maps, o, o + count
                a, o = a + 1, o + count
            continue
        if p >= end or not 0x82 <= buf[p] <= 0x84:
            return False, cells[:c], values[:c], meta, poses, asked[:a], seqs[:o]
        fields = int(buf[p]) - 0x80
        k, q = _array(buf, p + 1, end, _CELLS, 4, max_bytes)
        k2, r = _array(buf, q + 4 * k, end, _VALUES, 1, max_bytes) if k >= 0 else (-1, p)
        if k2 != k or k < 0 or not _cells(buf, q, r, k, size, cells[c:c + k], values[c:c + k]):
            return False, cells[:c], values[:c], meta, poses, asked[:a], seqs[:o]
        c += k
        if fills[i]:
            n, count, p = _fill_tail(buf, r + k, end, fields, max_seqs, seqs, int(o))
        else:
            n, count, p = _delta_tail(buf, r + k, end, fields, max_seqs, seqs, int(o))
        if p != end or n < 0:
            return False, cells[:c], values[:c], meta, poses, asked[:a], seqs[:o]
        meta[i, 0], meta[i, 1] = c, n
        meta[i, 2], meta[i, 3] = (o, o + count) if count >= 0 else (-1, -1)
        o += max(count, 0)
    return True, cells[:c], values[:c], meta, poses, asked[:a], seqs[:o]


@njit(cache=True)
def _pose(buf: np.ndarray, p: int, end: int, rows: int, cols: int, out: np.ndarray) -> int:
    """A pose beacon's fields at ``p`` before its request map, as its encoder writes them (``cell``, ``next``,
    then ``maps`` and ``want`` when present) and checked as
    :meth:`~fleet_emu.agents.protocol.PoseBeacon.validate` checks them: ``out`` its cell, next cell (-1, -1:
    none), ``maps`` (-1: none), -1 (no request map). The position of its request map's bytes, ``end`` without
    one, or -1 when they are not in that form or not valid."""
    fields = int(buf[p]) - 0x80 if p < end else -1
    if not 2 <= fields <= 4 or not _same(buf, p + 1, end, _CELL):
        return -1
    r, p = _uint(buf, p + 1 + _CELL.shape[0], end)
    col, p = _uint(buf, p, end) if r >= 0 else (-1, p)
    if not (0 <= r < rows and 0 <= col < cols) or not _same(buf, p, end, _NEXT):
        return -1
    p += _NEXT.shape[0]
    nr = nc = -1
    if p < end and buf[p] == 0xC0:
        p += 1
    elif p < end and buf[p] == 0x92:
        nr, p = _uint(buf, p + 1, end)
        nc, p = _uint(buf, p, end) if nr >= 0 else (-1, p)
        if not (0 <= nr < rows and 0 <= nc < cols) or abs(nr - r) + abs(nc - col) > 1:
            return -1
    else:
        return -1
    maps = -1
    if fields > 2 and _same(buf, p, end, _MAPS):
        maps, p = _uint(buf, p + _MAPS.shape[0], end)
        if maps < 0:
            return -1
        fields -= 1
    out[0], out[1], out[2], out[3], out[4], out[5] = r, col, nr, nc, maps, -1
    if fields == 2:
        return p
    if fields == 3 and _same(buf, p, end, _WANT) and p + _WANT.shape[0] < end:
        return p + _WANT.shape[0]
    return -1


@njit(cache=True)
def _delta_tail(buf: np.ndarray, p: int, end: int, fields: int, max_seqs: int, out: np.ndarray, o: int
                ) -> tuple[int, int, int]:
    """A delta's fields after its arrays: (``n`` or 0, how many ``covers`` written at ``out[o:]`` or -1
    without, the position after them); ``n`` -1 when they are not valid."""
    if fields == 2:
        return 0, -1, p
    n, p = _uint(buf, p + _N.shape[0], end) if _same(buf, p, end, _N) else (-1, p)
    if fields == 3 or n < 1:
        return (n if n >= 1 else -1), -1, p
    count, p = _covers(buf, p + _COVERS.shape[0], end, n, max_seqs, out, o) if _same(buf, p, end, _COVERS) \
        else (-1, p)
    return (n if count >= 0 else -1), count, p


@njit(cache=True)
def _fill_tail(buf: np.ndarray, p: int, end: int, fields: int, max_seqs: int, out: np.ndarray, o: int
               ) -> tuple[int, int, int]:
    """A fill's fields after its arrays, both as its encoder writes them: (``upto``, how many ``seqs`` written
    at ``out[o:]``, the position after them); ``upto`` -1 when they are not valid."""
    if fields != 4 or not _same(buf, p, end, _SEQS):
        return -1, -1, p
    count, p = _covers(buf, p + _SEQS.shape[0], end, _MAX_INT, max_seqs, out, o)
    if count < 0 or not _same(buf, p, end, _UPTO):
        return -1, -1, p
    upto, p = _uint(buf, p + _UPTO.shape[0], end)
    return upto, count, p


@njit(cache=True)
def _cells(buf: np.ndarray, q: int, r: int, k: int, size: int, cells: np.ndarray, values: np.ndarray) -> bool:
    """``k`` cells (int32 from ``q``, in the machine's byte order as ``np.frombuffer`` reads them) and values
    (int8 from ``r``) copied out; False when a cell is outside a grid of ``size`` cells or a value not -1, 0
    or 100 (``kernels.cells_valid``'s checks)."""
    src, vals = buf[q:q + 4 * k].view(np.int32), buf[r:r + k].view(np.int8)
    # written without a branch, so that the compiler vectorizes both loops: ten times as fast on a whole map
    # as stopping at the first bad cell (the check fails the whole read then anyway)
    bad, limit = np.uint32(0), np.uint32(size)
    for j in range(k):
        c = src[j]
        cells[j] = c
        bad |= np.uint32(np.uint32(c) >= limit)  # a negative cell is above the limit as an unsigned number
    bad_value = np.int8(0)
    for j in range(k):
        v = vals[j]
        values[j] = v
        bad_value |= np.int8((v != 0) & (v != 100) & (v != -1))
    return bad == 0 and bad_value == 0


@njit(cache=True, inline="always")
def _want(buf: np.ndarray, p: int, end: int, keys: np.ndarray, ids: np.ndarray, me: int, max_seqs: int,
          seqs: np.ndarray, base: int) -> tuple[int, int]:
    """A beacon's request map at ``p`` checked and read: (how many numbers it asks teammate ``me`` for, written
    at ``seqs[base:]``, or -1 when none; the position after it, -1 when it is not valid or not in the
    encoder's form). Valid: keys teammates' names (``keys``/``ids``: :class:`Team`'s table, empty when the
    team's names are not packed), values strictly ascending delta numbers from 1, at most ``max_seqs``; a key
    twice, the last holds (as in a dict). Its steps written out: helpers called per request cost several times
    the work."""
    b = int(buf[p]) if p < end else 0
    if 0x80 <= b <= 0x8F:
        count, p = b - 0x80, p + 1
    elif b == 0xDE and p + 3 <= end:
        count, p = int(buf[p + 1]) << 8 | int(buf[p + 2]), p + 3
    else:
        return -1, -1
    mask, asked = keys.shape[0] - 1, -1
    if mask < 0:
        return -1, -1
    for _ in range(count):
        k = int(buf[p]) - 0xA0 if p < end else -1  # a name of up to 7 bytes, packed with its length
        if not 0 <= k <= 7 or p + 2 + k > end:
            return -1, -1
        x = k << 56
        for q in range(k):
            x |= int(buf[p + 1 + q]) << (8 * q)
        s, j = ((x * _HASH) >> 40) & mask, -1
        while ids[s] >= 0 and j < 0:
            j = ids[s] if keys[s] == x else -1
            s = (s + 1) & mask
        p += 1 + k
        # :func:`_covers`, written out: called here it makes the read of requests four times as slow (23
        # against 5.7 us a robot-tick at 100 robots)
        a = int(buf[p])
        if 0x90 <= a <= 0x9F:
            n, p = a - 0x90, p + 1
        elif a == 0xDC and p + 3 <= end:
            n, p = int(buf[p + 1]) << 8 | int(buf[p + 2]), p + 3
        else:
            return -1, -1
        if j < 0 or n > max_seqs:
            return -1, -1
        last = 0
        for m in range(n):
            v, p = _uint(buf, p, end)
            if v <= last:  # also v < 0: not an unsigned integer
                return -1, -1
            last = v
            if j == me:
                seqs[base + m] = v
        if j == me:
            asked = n
    return asked, p


@dataclasses.dataclass(frozen=True)
class Team:
    """A team's names as :func:`read` looks them up: an open-addressing hash table of the names packed in
    a number each (their UTF-8 bytes and length: ``keys``, their index in ``ids``, -1 where empty), and each
    name's index; ``keys`` is None when a name is longer than 7 bytes (a robot's id is ``r0`` to ``r255``, the
    base station's ``base``), and such a team's requests go the general way."""

    keys: np.ndarray | None
    ids: np.ndarray
    index: dict[str, int]


@functools.lru_cache(maxsize=16)
def team(members: frozenset[str]) -> Team:
    """The :class:`Team` of ``members`` (built once per team)."""
    order = sorted(members)
    index = {name: j for j, name in enumerate(order)}
    encoded = [name.encode() for name in order]
    size = 1 << (2 * len(encoded)).bit_length()  # at most half full
    keys, ids = np.zeros(size, np.int64), np.full(size, -1, np.int64)
    if any(len(e) > 7 for e in encoded):
        return Team(None, ids, index)
    for j, e in enumerate(encoded):
        x = int.from_bytes(e, "little") | len(e) << 56
        s = ((x * _HASH) % (1 << 64) >> 40) & (size - 1)  # the kernel's wrapping product, shifted
        while ids[s] >= 0:
            s = (s + 1) & (size - 1)
        keys[s], ids[s] = x, j
    return Team(keys, ids, index)


class Read(NamedTuple):
    """What :func:`read` read: the deltas' and fills' cells (int32) and values (int8) one message after another,
    read only; per delta or fill the end of its cells and three numbers (``n`` or 0 and the span of
    ``covers`` in ``seqs``, -1, -1 without, for a delta; ``upto`` and the span of ``seqs`` for a fill); per
    beacon its cell's row and column, its next cell's (-1, -1: none), ``maps`` (-1: none) and the offset of its
    request map in its bytes (-1: none); per request map that asks the robot for deltas, its index among the
    beacons and lone request maps and the span of the numbers asked; the delta numbers those spans index."""

    cells: np.ndarray
    values: np.ndarray
    maps: list[list[int]]
    poses: list[list[int]]
    asked: list[list[int]]
    seqs: list[int]


def read(maps: list[bytes], fills: list[bool], beacons: list[bytes], wants: list[bytes], shape: tuple[int, int],
         members: Team, robot: str, max_bytes: int, max_seqs: int) -> Read | None:
    """The map deltas and fills ``maps`` (``fills``), pose beacons ``beacons`` and lone request maps ``wants``
    (their MessagePack bytes) of a grid of ``shape`` and a team ``members``, read at once (:class:`Read`), each
    checked as its ``validate`` checks it. A request map's keys are teammates, its delta numbers strictly
    ascending from 1, at most ``max_seqs``, and only what it asks ``robot`` for is read. None when one is not
    in the encoder's form or not valid, for the caller to decode them the general way."""
    payloads = maps + beacons + wants
    buf = np.frombuffer(b"".join(payloads), np.uint8)
    keys = members.keys if members.keys is not None else _NO_KEYS
    ok, cells, values, meta, poses, asked, seqs = _read(
        buf, np.fromiter(map(len, payloads), np.int64, len(payloads)), np.array(fills, np.bool_), len(beacons),
        shape[0], shape[1], keys, members.ids, members.index.get(robot, -1), max_bytes, max_seqs)
    if not ok:
        return None
    cells.flags.writeable = values.flags.writeable = False  # as arrays read from a message's bytes are
    return Read(cells, values, meta.tolist(), poses.tolist(), asked.tolist(), seqs.tolist())


def warm_up() -> None:
    """Compile (or load from cache) every kernel a robot runs, the grid's (``core.kernels.warm_up``) and
    these, so the first tick does not pay for them."""
    from fleet_emu.agents.protocol import MapDelta, MapFill, PoseBeacon

    kernels.warm_up()

    delta = MapDelta(cells=np.array([0], np.int32), values=np.array([0], np.int8), n=2, covers=(1,)).encode()
    fill = MapFill(cells=np.array([0], np.int32), values=np.array([0], np.int8), seqs=(1,), upto=1).encode()
    beacon = PoseBeacon(cell=(0, 0), next=(0, 0), maps=2, want={"r1": (1,)}).encode()
    read([delta, fill], [False, True], [beacon], [b"\x81\xa2r1\x91\x01"], (1, 1), team(frozenset({"r1"})), "r1",
         1 << 20, 64)
