"""The codec: every message round-trips, and anything malformed is rejected with DecodeError only."""

from __future__ import annotations

import contextlib
import zlib

import msgpack
import numpy as np
import pytest

from fleet_emu.agents.protocol import MapDelta, PoseBeacon
from fleet_emu.core.messages import (
    MAX_PAYLOAD_BYTES,
    Command,
    Context,
    DecodeError,
    Envelope,
    Hello,
    Links,
    Observation,
    RadioMsg,
    Ready,
    RobotReport,
    RxBundle,
    Stop,
    TxBundle,
    WorldState,
    compact,
    decode,
    expand,
    open_envelope,
    peek_tick,
    seal,
)
from fleet_emu.core.version import SCHEMA_VERSION

CTX = Context(senders=frozenset({"r0", "r1"}), shape=(4, 5))


def _samples() -> list:
    cells = np.array([0, 7, 19], dtype=np.int32)
    values = np.array([0, 100, -1], dtype=np.int8)
    beacon = seal(RadioMsg(PoseBeacon(cell=(1, 2))), "r0", 2, 1)
    delta = seal(RadioMsg(MapDelta(cells=cells, values=values), dst="r1", ttl=1), "r0", 2, 2)
    return [
        Observation(src="r0", tick=1, seq=3, robot="r0", cell=(0, 0), shape=(4, 5), cell_size=0.5,
                    cells=cells, values=values),
        WorldState(src="r0", tick=1, seq=4, poses={"r0": (0, 1)}, live=("r0",), coverage=0.5,
                   path_length={"r0": 3}, done=True, reason="coverage"),
        Command(src="r1", tick=1, seq=5, move=(0, -1), target=(3, 4), status="ASSIGNED", decision_ms=1.5,
                known=12),
        beacon, delta,
        TxBundle(src="r0", tick=2, seq=6, msgs=(beacon, delta)),
        RxBundle(src="r1", tick=3, seq=7, dst="r1", msgs=(beacon,)),
        Links(src="r0", tick=3, seq=8, robots=("r0", "r1"), strength=np.zeros((2, 2), np.float32),
              link=np.eye(2, dtype=bool), connected=False, sent=4, delivered=2, dropped_loss=1,
              dropped_signal=1, bytes_sent=99),
        Hello(src="r0", tick=0, seq=9), Ready(src="r1", tick=0, seq=1, role="agent", pid=42),
        Stop(src="r0", tick=9, seq=2, reason="coverage"),
        RobotReport(src="r1", tick=9, seq=3, decisions=9, decision_ms_mean=1.0, decision_ms_p95=2.0,
                    dropped=0, peak_rss_kb=1000),
    ]


@pytest.mark.parametrize("msg", _samples(), ids=lambda m: f"{m.KIND}-{m.seq}")
def test_round_trip(msg) -> None:
    back = decode(msg.encode(), CTX)
    assert type(back) is type(msg)
    assert repr(back.to_obj()) == repr(msg.to_obj())
    assert peek_tick(msg.encode()) == msg.tick


def _obj(msg) -> dict:
    return msgpack.unpackb(msg.encode())


@pytest.mark.parametrize("data", [
    b"", b"\xc1", b"random bytes \x00\xff", msgpack.packb([1, 2, 3]), msgpack.packb({"kind": "nope"}),
    msgpack.packb({"kind": "cmd", "src": "r0", "tick": 1, "seq": 1}),  # missing move
    msgpack.packb({"kind": "cmd", "src": "r0", "tick": "1", "seq": 1, "move": [0, 1]}),  # tick of wrong type
    msgpack.packb({"kind": "cmd", "src": "r0", "tick": 1, "seq": 1, "move": [0, 1], "extra": 1}),
    msgpack.packb({"kind": "cmd", "src": "r0", "tick": True, "seq": 1, "move": [0, 1]}),  # bool is not an int
    msgpack.packb({"kind": "cmd", "src": "r7", "tick": 1, "seq": 1, "move": [0, 1]}),  # unknown robot
    msgpack.packb({"kind": "cmd", "src": "r0", "tick": 1, "seq": 1, "move": [2, 0]}),  # not a 4-step
    msgpack.packb({"kind": "cmd", "src": "r0", "tick": -1, "seq": 1, "move": [0, 1]}),
    msgpack.packb({"kind": "cmd", "src": "r0", "tick": 1, "seq": 1, "move": [0, 1], "target": [9, 9]}),
])
def test_rejects_malformed(data: bytes) -> None:
    with pytest.raises(DecodeError):
        decode(data, CTX)


def test_rejects_bad_arrays_and_cells() -> None:
    obs = _obj(_samples()[0])
    bad_shape = dict(obs, cells={"dtype": "int32", "shape": [5], "data": b"\x00" * 12})
    bad_dtype = dict(obs, cells={"dtype": "object", "shape": [3], "data": b"\x00" * 24})
    out_of_range = dict(obs, cells={"dtype": "int32", "shape": [3],
                                    "data": np.array([0, 1, 20], np.int32).tobytes()})
    bad_value = dict(obs, values={"dtype": "int8", "shape": [3], "data": np.array([0, 5, 0], np.int8).tobytes()})
    negative = dict(obs, values={"dtype": "int8", "shape": [3], "data": np.array([0, -100, 0], np.int8).tobytes()})
    wrapping = dict(obs, cells={"dtype": "int32", "shape": [2**32, 2**32], "data": b""})  # 2**64 cells, 0 in int64
    for obj in (bad_shape, bad_dtype, out_of_range, bad_value, negative, wrapping):
        with pytest.raises(DecodeError):
            decode(msgpack.packb(obj), CTX)


def test_a_command_s_known_cells_fit_the_grid() -> None:
    """A command's ``known`` (the stall rule's signal) is a count of the grid's cells: 0 to its size."""
    for known in (-1, 21):  # CTX's grid is 4 x 5
        cmd = Command(src="r1", tick=1, seq=5, move=(0, 1), known=known)
        with pytest.raises(DecodeError, match="known cells"):
            decode(cmd.encode(), CTX)
    assert decode(Command(src="r1", tick=1, seq=5, move=(0, 1), known=20).encode(), CTX).known == 20


def test_bundle_rejects_foreign_message_and_wrong_expected_kind() -> None:
    beacon = seal(RadioMsg(PoseBeacon(cell=(1, 2))), "r1", 2, 1)
    with pytest.raises(DecodeError, match="src"):
        decode(TxBundle(src="r0", tick=2, seq=1, msgs=(beacon,)).encode(), CTX)
    with pytest.raises(DecodeError, match="expected"):
        decode(beacon.encode(), CTX, expected=Command)
    outside = decode(seal(RadioMsg(PoseBeacon(cell=(4, 0))), "r1", 2, 1).encode(), CTX)  # the envelope is fine
    with pytest.raises(DecodeError, match="outside"):
        open_envelope(outside, CTX)  # the payload is checked by the protocol that opens it


def test_envelope_payload_is_opaque_until_opened() -> None:
    cells = np.array([0, 7], dtype=np.int32)
    env = seal(RadioMsg(MapDelta(cells=cells, values=np.array([0, 100], np.int8)), dst="r1", ttl=2), "r0", 5, 9)
    assert isinstance(env.payload, bytes) and env.payload_kind == "map"
    assert (env.src, env.origin, env.dst, env.ttl, env.tick, env.seq) == ("r0", "r0", "r1", 2, 5, 9)
    back = open_envelope(decode(env.encode(), CTX, Envelope), CTX)
    assert back.src == "r0" and back.body.cells.tolist() == [0, 7] and back.body.values.tolist() == [0, 100]
    for kind, payload in (("telepathy", env.payload), ("map", b"\xc1"), ("pose", msgpack.packb({"cell": [1]})),
                          ("pose", msgpack.packb({"cell": [1, 2], "extra": 1}))):
        with pytest.raises(DecodeError):
            open_envelope(Envelope(src="r0", tick=5, seq=9, origin="r0", dst="*", ttl=0, payload_kind=kind,
                                   payload=payload), CTX)
    with pytest.raises(DecodeError, match="origin"):
        decode(Envelope(src="r0", tick=1, seq=1, origin="r7", dst="*", ttl=0, payload_kind="pose",
                        payload=b"").encode(), CTX)


@pytest.mark.parametrize("cells", [np.arange(0, 20, dtype=np.int32), np.array([19, 0, 7, 3, 2**31 - 1], np.int64),
                                   np.array([2**31 - 1, -2**31, 5], np.int32)])  # unsorted; differences that wrap
def test_a_limited_radio_sends_map_data_compact_and_only_when_smaller(cells: np.ndarray) -> None:
    big = MapDelta(cells=cells, values=np.zeros(len(cells), np.int8), n=3, covers=(1,))
    plain = seal(RadioMsg(big), "r0", 5, 9)
    packed = seal(RadioMsg(big), "r0", 5, 9, deflate=True)
    assert expand(plain.payload) == plain.payload  # a plain payload is its own msgpack
    assert len(packed.payload) < len(plain.payload) and expand(packed.payload) == plain.payload
    assert packed.payload[0] == zlib.compress(b"")[0] and plain.payload[0] in (0x80 + 4, 0xDE)
    if cells.min() >= 0:  # negative cells (differences that wrap) round-trip, and are then refused as cells
        back = open_envelope(decode(packed.encode(), Context(), Envelope)).body
        assert back.cells.tolist() == cells.tolist() and back.cells.dtype == cells.dtype and back.n == 3
    beacon = RadioMsg(PoseBeacon(cell=(1, 2)))  # not map data: never deflated
    assert seal(beacon, "r0", 5, 9, deflate=True).payload == seal(beacon, "r0", 5, 9).payload
    noise = np.random.default_rng(0).integers(0, 2**62, 400)  # nothing to deflate: sent as it is
    dense = RadioMsg(MapDelta(cells=noise, values=noise.astype(np.int8)))
    assert seal(dense, "r0", 5, 9, deflate=True).payload == seal(dense, "r0", 5, 9).payload


@pytest.mark.parametrize("payload, why", [
    (zlib.compress(b"\x00" * (MAX_PAYLOAD_BYTES + 1), 9), "beyond the payload limit"),  # a 16 KiB bomb
    (zlib.compress(msgpack.packb({"cells": 1}))[:-6], "cut short"),
    (b"\x78\x9c" + b"\xff" * 20, "corrupt"),
    (zlib.compress(b"\xc1"), "not msgpack"),
    (compact(seal(RadioMsg(MapDelta(cells=np.array([3, 30, 1], np.int32), values=np.zeros(3, np.int8))),
                  "r0", 5, 9).payload), "out of range"),  # cells restored and checked against the 4 x 5 grid
])
def test_a_bad_deflated_payload_is_a_decode_error(payload: bytes, why: str) -> None:
    env = Envelope(src="r0", tick=5, seq=9, origin="r0", dst="*", ttl=0, payload_kind="map", payload=payload)
    assert len(payload) < 20_000
    with pytest.raises(DecodeError, match=why):
        open_envelope(env, CTX)


def test_schema_version_is_stamped_and_a_newer_one_refused() -> None:
    obj = _obj(Stop(src="r0", tick=9, seq=2, reason="coverage"))
    assert obj["v"] == SCHEMA_VERSION
    decode(msgpack.packb({k: v for k, v in obj.items() if k != "v"}), CTX)  # the first round's: no version
    with pytest.raises(DecodeError, match="newer"):
        decode(msgpack.packb(dict(obj, v=SCHEMA_VERSION + 1)), CTX)


def test_random_garbage_never_raises_anything_else() -> None:
    rng = np.random.default_rng(0)
    valid = [m.encode() for m in _samples()]
    for i in range(2000):
        data = bytearray(valid[i % len(valid)])
        for _ in range(int(rng.integers(1, 4))):
            data[int(rng.integers(len(data)))] = int(rng.integers(256))
        with contextlib.suppress(DecodeError):  # anything else propagates and fails the test
            decode(bytes(data), CTX)
