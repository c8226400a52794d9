"""The hearing kernels read map deltas and beacons' requests straight from their bytes: on the robots' own
encodings and on damaged copies of them (a byte changed, cut, added or removed), what :func:`hear` accepts the
message decoders accept too, with the same values; what they refuse, it refuses (the brain then opens the inbox
message by message, as it does for a valid message in another encoding)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from fleet_emu.agents.hearing import Beacon, Delta, hear
from fleet_emu.agents.hearing_kernels import read_deltas, read_wants, team
from fleet_emu.agents.protocol import MAX_SEQS, MapDelta, PoseBeacon
from fleet_emu.core.codec import Context, DecodeError, decode_payload
from fleet_emu.core.envelope import Envelope

TEAM = frozenset({"r0", "r1", "r2", "robot-10", "ü"})
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


def test_the_robots_own_deltas_are_read_from_their_bytes_as_decoded() -> None:
    deltas = _deltas(np.random.default_rng(0), 60)
    got = read_deltas([d.encode() for d in deltas], 40 * 50, 1 << 26, MAX_SEQS)
    assert got is not None  # every one the fast way
    cells, values, rows, covers = got
    assert not cells.flags.writeable and cells.dtype == np.int32 and values.dtype == np.int8
    a = 0
    for d, (end, n, c0, c1) in zip(deltas, rows, strict=True):
        assert np.array_equal(cells[a:end], d.cells) and np.array_equal(values[a:end], d.values)
        assert (n or None, tuple(covers[c0:c1]) if c0 >= 0 else None) == (d.n, d.covers)
        a = end


def test_the_robots_own_requests_are_checked_and_read_for_the_robot_asked() -> None:
    beacons = [b for b in _beacons(np.random.default_rng(1), 80) if b.want]
    wants = [PoseBeacon(cell=(0, 0), want=b.want).encode()[len(PoseBeacon(cell=(0, 0)).encode()) + 5:]
             for b in beacons]  # the want map's own bytes: after the cell and the key "want"
    for robot in [*TEAM, "r9"]:
        got = read_wants(wants, team(TEAM), robot, MAX_SEQS)
        assert got == {i: b.want[robot] for i, b in enumerate(beacons) if b.want and robot in b.want}
    assert read_wants(wants, team(TEAM - {"r2"}), "r1", MAX_SEQS) is None  # a request to a stranger


@pytest.mark.parametrize("kind", ["map", "pose"])
def test_damaged_bytes_are_refused_or_read_as_the_decoders_read_them(kind: str) -> None:
    rng = np.random.default_rng(2)
    messages = _deltas(rng, 40) if kind == "map" else _beacons(rng, 40)
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
                else:
                    assert isinstance(body, Beacon) and (body.cell, body.next, body.maps) == \
                        (record.cell, record.next, record.maps)
                    assert got.asks.get(0) == record.asks(robot), (data, robot)
                fast += 1
    assert fast > 200 and refused > 2000  # both outcomes were tried, many times
