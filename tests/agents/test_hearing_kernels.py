"""The hearing kernels read map deltas, fills and beacons' requests straight from their bytes: on the robots' own
encodings and on damaged copies of them (a byte changed, cut, added or removed), what :func:`hear` accepts the
message decoders accept too, with the same values; what they refuse, it refuses (the brain then opens the inbox
message by message, as it does for a valid message in another encoding)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from fleet_emu.agents.hearing import Beacon, Delta, Fill, hear
from fleet_emu.agents.hearing_kernels import read, team
from fleet_emu.agents.protocol import MAX_SEQS, MapDelta, MapFill, PoseBeacon
from fleet_emu.core.codec import Context, DecodeError, decode_payload
from fleet_emu.core.envelope import Envelope

TEAM = frozenset({"r0", "r1", "r2", "r10", "ü", "base"})
CTX = Context(senders=TEAM, shape=(40, 50))


def _deltas(rng: np.random.Generator, count: int) -> list[MapDelta]:
    """Deltas of 0 to 400 cells (a bin of each header size), with and without map sync's numbers."""
    out = []
    for i in range(count):
        k = int(rng.choice([0, 1, 3, 70, 400]))
        cells = rng.integers(0, 2000, k).astype(np.int32)
        values = rng.choice(np.array([-1, 0, 100], np.int8), k)
        n = int(rng.integers(1, 300)) if i % 3 else None
        covers = tuple(sorted(set(rng.integers(1, n, 4).tolist()))) if n and n > 1 and i % 2 else None
        out.append(MapDelta(cells=cells, values=values, n=n, covers=covers))
    return out


def _fills(rng: np.random.Generator, count: int) -> list[MapFill]:
    return [MapFill(cells=d.cells, values=d.values, seqs=d.covers or (), upto=int(rng.integers(0, 300)))
            for d in _deltas(rng, count)]


def _beacons(rng: np.random.Generator, count: int) -> list[PoseBeacon]:
    out = []
    for _ in range(count):
        asked = rng.choice(sorted(TEAM), int(rng.integers(0, 4)), replace=False).tolist()
        want = {r: tuple(sorted(set(rng.integers(1, 400, int(rng.integers(0, 5))).tolist()))) for r in asked}
        out.append(PoseBeacon(cell=(3, 4), next=(3, 5), maps=int(rng.integers(0, 1000)), want=want or None))
    return out


def _damaged(data: bytes, rng: np.random.Generator) -> bytes:
    i = int(rng.integers(0, len(data)))
    how = int(rng.integers(0, 4))
    if how == 0:
        return data[:i] + bytes([int(rng.integers(0, 256))]) + data[i + 1:]
    if how == 1:
        return data[:i]
    if how == 2:
        return data[:i] + bytes([int(rng.integers(0, 256))]) + data[i:]
    return data[:i] + data[i + 1:]


def _decoded(kind: str, data: bytes) -> Any:
    try:
        return decode_payload(kind, data, CTX)
    except DecodeError:
        return None


def _env(kind: str, payload: bytes) -> Envelope:
    return Envelope(src="r1", tick=3, seq=7, origin="r1", dst="*", ttl=0, payload_kind=kind, payload=payload)


def test_the_robots_own_deltas_and_fills_are_read_from_their_bytes_as_decoded() -> None:
    rng = np.random.default_rng(0)
    messages: list[MapDelta | MapFill] = [m for pair in zip(_deltas(rng, 40), _fills(rng, 40), strict=True)
                                          for m in pair]
    got = read([m.encode() for m in messages], [isinstance(m, MapFill) for m in messages], [], [], (40, 50),
               team(TEAM), "r1", 1 << 26, MAX_SEQS)
    assert got is not None and not got.asked  # every one the fast way
    cells, values, rows, seqs = got.cells, got.values, got.maps, got.seqs
    assert not cells.flags.writeable and cells.dtype == np.int32 and values.dtype == np.int8
    a = 0
    for m, (end, n, s0, s1) in zip(messages, rows, strict=True):
        assert np.array_equal(cells[a:end], m.cells) and np.array_equal(values[a:end], m.values)
        if isinstance(m, MapFill):
            assert (n, tuple(seqs[s0:s1])) == (m.upto, m.seqs)
        else:
            assert (n or None, tuple(seqs[s0:s1]) if s0 >= 0 else None) == (m.n, m.covers)
        a = end
    assert read([messages[0].encode()], [True], [], [], (40, 50), team(TEAM), "r1", 1 << 26, MAX_SEQS) is None


def test_the_robots_own_beacons_and_requests_are_checked_and_read_for_the_robot_asked() -> None:
    beacons = _beacons(np.random.default_rng(1), 80)
    wants = [PoseBeacon(cell=(0, 0), want=b.want).encode()[len(PoseBeacon(cell=(0, 0)).encode()) + 5:]
             for b in beacons if b.want]  # a request map's own bytes: after the cell and the key "want"
    delta = MapDelta(cells=np.array([5], np.int32), values=np.array([100], np.int8), n=3, covers=(1, 2)).encode()
    for robot in [*TEAM, "r9"]:
        got = read([delta, delta], [False, False], [b.encode() for b in beacons], wants, (40, 50), team(TEAM), robot,
                   1 << 26, MAX_SEQS)  # all kinds together
        assert got is not None
        assert [(r, c, nr, nc, maps) for r, c, nr, nc, maps, _ in got.poses] == [(3, 4, 3, 5, b.maps) for b in beacons]
        asked = {j: tuple(got.seqs[s0:s1]) for j, s0, s1 in got.asked}
        expected = [b.want.get(robot) if b.want else None for b in beacons]
        expected += [b.want.get(robot) for b in beacons if b.want]  # the lone request maps, after the beacons
        assert asked == {j: seqs for j, seqs in enumerate(expected) if seqs is not None}
        assert got.cells.tolist() == [5, 5] and [tuple(got.seqs[r[2]:r[3]]) for r in got.maps] == [(1, 2)] * 2
    assert read([], [], [], wants, (1, 1), team(TEAM - {"r2"}), "r1", 1, MAX_SEQS) is None  # a request to a stranger
    assert read([], [], [], wants, (1, 1), team(TEAM | {"robot-10"}), "r1", 1, MAX_SEQS) is None  # a long name


@pytest.mark.parametrize("kind", ["map", "mapfill", "pose"])
def test_damaged_bytes_are_refused_or_read_as_the_decoders_read_them(kind: str) -> None:
    rng = np.random.default_rng(2)
    make = {"map": _deltas, "mapfill": _fills, "pose": _beacons}[kind]
    messages: list[Any] = make(rng, 40)
    fast = refused = 0
    for msg in messages:
        for _ in range(60):
            data = _damaged(msg.encode(), rng)
            record = _decoded(kind, data)
            for robot in sorted(TEAM):
                got = hear([_env(kind, data)], CTX, robot)
                if got is None:
                    refused += record is None
                    continue
                assert record is not None, (data, robot)  # hear never accepts what the decoders refuse
                body = got.messages[0][2]
                if kind == "map":
                    assert isinstance(body, Delta) and np.array_equal(body.cells, record.cells)
                    assert np.array_equal(body.values, record.values)
                    assert (body.n, body.covers) == (record.n, record.covers)
                elif kind == "mapfill":
                    assert isinstance(body, Fill) and np.array_equal(body.cells, record.cells)
                    assert np.array_equal(body.values, record.values)
                    assert (body.seqs, body.upto) == (record.seqs, record.upto)
                else:
                    assert isinstance(body, Beacon) and (body.cell, body.next, body.maps) == \
                        (record.cell, record.next, record.maps)
                    assert got.asks.get(0) == (record.want or {}).get(robot), (data, robot)
                fast += 1
    assert fast > 200 and refused > 2000  # both outcomes were tried, many times
