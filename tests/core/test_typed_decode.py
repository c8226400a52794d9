"""The typed decoders (``core.codec.typed_decoder``: rx and tx bundles, pose beacons, map deltas and fills, decoded
by msgspec straight from their bytes) accept the messages of a real run themselves, and what they decode encodes
back to the very bytes it came from. ``tests/core/test_fast_decode.py`` checks that they accept nothing the
generic decode refuses (its ``decode`` tries them first)."""

from __future__ import annotations

import dataclasses
from collections import Counter

import msgpack
import numpy as np
import pytest

from fleet_emu.agents.protocol import MapDelta, MapFill, PoseBeacon
from fleet_emu.core.codec import _TYPED, Context, DecodeError, Payload, _typed, decode, decode_payload, generic_decode
from fleet_emu.core.envelope import Envelope, RadioMsg, RxBundle, TxBundle, open_envelope, seal
from fleet_emu.core.messages import Message
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet

MAZE_CS = 30.0 / 512


def _traffic() -> tuple[list[bytes], list[bytes], frozenset[str], tuple[int, int]]:
    """A lossy 8-robot maze run's bundles, encoded as a node publishes them (tx and rx): map sync is on, so
    beacons carry requests and deltas their numbers and covers."""
    s = Scenario().override(map="maze", cell_size=MAZE_CS, robots=8, seed=0, max_ticks=14, target_coverage=1.0,
                            sensor_range=8 * MAZE_CS, comm_range=20 * MAZE_CS, loss=0.2)
    s = dataclasses.replace(s, allocator={"type": "minpos", "wavefront": "parallel"}).validate()
    tx: list[bytes] = []
    rx: list[bytes] = []

    def tap(_key: str, msg: Message, _ns: int) -> None:
        if isinstance(msg, TxBundle):
            tx.append(msg.encode())
        elif isinstance(msg, RxBundle):
            rx.append(msg.encode())

    fleet = Fleet(s, tap=tap)
    fleet.run()
    return tx, rx, frozenset(fleet.possible_agents), fleet.map.grid.shape


@pytest.fixture(scope="module")
def traffic() -> tuple[list[bytes], list[bytes], frozenset[str], tuple[int, int]]:
    return _traffic()


def test_a_runs_bundles_decode_typed_and_encode_back_to_their_bytes(traffic: tuple) -> None:
    tx, rx, team, _ = traffic
    assert len(tx) > 50 and len(rx) > 50
    for cls, blobs, ctx in ((TxBundle, tx, Context(senders=team)), (RxBundle, rx, None)):
        for data in blobs:
            typed = _TYPED[cls](data, ctx)
            assert typed is not None  # the typed decoder took it, not the fallback
            assert typed.encode() == data
            assert typed == generic_decode(data, ctx, cls)


def test_a_runs_payloads_decode_typed_and_encode_back_to_their_bytes(traffic: tuple) -> None:
    _, rx, team, shape = traffic
    ctx = Context(senders=team, shape=shape)
    kinds: Counter[str] = Counter()
    for data in rx:
        for env in decode(data, None, RxBundle).msgs:
            cls = Payload.REGISTRY[env.payload_kind]
            typed = _TYPED[cls](env.payload, ctx)
            assert typed is not None, env.payload_kind
            assert typed.encode() == env.payload
            slow = generic_decode(env.payload, ctx, kind=env.payload_kind)
            assert typed.fields_obj().keys() == slow.fields_obj().keys()
            assert msgpack.packb(typed.fields_obj(), use_bin_type=True) == slow.encode()
            kinds[env.payload_kind] += 1
            if isinstance(typed, PoseBeacon) and typed.want:
                kinds["want"] += 1
            if isinstance(typed, MapDelta) and typed.covers:
                kinds["covers"] += 1
    assert kinds["pose"] > 100 and kinds["map"] > 50 and kinds["want"] > 0  # the run exercised them


def test_typed_decoders_refuse_what_they_cannot_vouch_for() -> None:
    """Wrong-typed or out-of-range fields, a missing ``kind``, an unknown field and a cell outside the grid
    are not the typed decoders' to accept: they give None, and the checking decode raises."""
    ctx = Context(senders=frozenset({"r0", "r1"}), shape=(4, 5))
    env = Envelope(src="r1", tick=3, seq=7, origin="r1", dst="*", ttl=1, payload_kind="pose",
                   payload=PoseBeacon(cell=(1, 2)).encode()).to_obj()
    bad_bundles = [{**env, "ttl": 17}, {**env, "tick": -1}, {k: v for k, v in env.items() if k != "kind"},
                   {**env, "extra": 1}, {**env, "origin": "r9"}, {**env, "payload": "text"}]
    for m in bad_bundles:
        data = msgpack.packb({"kind": "tx", "v": 2, "src": "r1", "tick": 3, "seq": 1, "msgs": [m]},
                             use_bin_type=True)
        assert _typed(TxBundle, data, ctx) is None
        with pytest.raises(DecodeError):
            decode(data, ctx, TxBundle)
    cells = {"dtype": "int32", "shape": [1], "data": np.array([20], np.int32).tobytes()}
    values = {"dtype": "int8", "shape": [1], "data": b"\0"}
    bad_payloads = [(PoseBeacon, {"cell": [4, 0]}), (PoseBeacon, {"cell": [1, 1], "next": [2, 2]}),
                    (PoseBeacon, {"cell": [1, 1], "want": {"r1": [2, 1]}}), (PoseBeacon, {"cell": [True, 1]}),
                    (MapDelta, {"cells": cells, "values": values}),
                    (MapDelta, {"cells": values, "values": {**values, "data": b"\7"}}),
                    (MapFill, {"cells": cells, "values": values, "seqs": [3, 3]})]
    for cls, obj in bad_payloads:
        data = msgpack.packb(obj, use_bin_type=True)
        assert _typed(cls, data, ctx) is None
        with pytest.raises(DecodeError):
            decode_payload(cls.KIND, data, ctx)


def test_an_envelope_encodes_as_its_map_packs() -> None:
    """:meth:`Envelope.encode` writes its map out rather than converting each field: the bytes msgpack packs
    from ``to_obj`` (numpy integers included, which take the generic conversion)."""
    payload = PoseBeacon(cell=(1, 2)).encode()
    for tick, ttl in ((3, 0), (2**40, 16), (np.int64(7), np.int8(2))):
        env = Envelope(src="r1", tick=tick, seq=9, origin="r0", dst="*", ttl=ttl, payload_kind="pose",  # type: ignore[arg-type]
                       payload=payload)
        assert env.encode() == msgpack.packb(env.to_obj(), use_bin_type=True)


def test_a_broadcast_is_opened_once_for_receivers_of_one_team() -> None:
    """The memory engine hands one envelope object to every receiver: the message opened for one is given as it
    is to the next whose context has the same team set (or an equal one), and decoded afresh for a receiver
    whose context differs (another grid: the payload is checked again)."""
    team = frozenset({"r0", "r1"})
    env = seal(RadioMsg(PoseBeacon(cell=(3, 4))), "r0", 5, 9)
    first = open_envelope(env, Context(senders=team, shape=(4, 5)))
    assert open_envelope(env, Context(senders=team, shape=(4, 5))) is first
    assert open_envelope(env, Context(senders=frozenset({"r0", "r1"}), shape=(4, 5))) is first
    with pytest.raises(DecodeError, match="outside"):
        open_envelope(env, Context(senders=team, shape=(3, 3)))  # (3, 4) is outside a 3 x 3 grid
    other = open_envelope(env, Context(senders=team, shape=(9, 9)))
    assert other is not first and other == first
