"""Each message is one declaration (``core/codec.py``): a real run's bundles and payloads decode and encode back
to the very bytes they came from, a batch of payloads decodes as each does alone (``decode_many`` decides
nothing), and what the declarations refuse is refused."""

from __future__ import annotations

import dataclasses
from collections import Counter

import msgpack
import numpy as np
import pytest

from fleet_emu.agents.protocol import MapDelta, MapFill, PoseBeacon
from fleet_emu.core.codec import Context, DecodeError, Payload, decode, decode_many, decode_payload, decoder
from fleet_emu.core.envelope import Envelope, RadioMsg, RxBundle, TxBundle, open_envelope, seal
from fleet_emu.core.messages import Message
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from tests.harness.wire import CTX, SAMPLES, equal, mutations

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


def test_a_runs_bundles_and_payloads_decode_and_encode_back_to_their_bytes(traffic: tuple) -> None:
    tx, rx, team, shape = traffic
    assert len(tx) > 50 and len(rx) > 50
    for cls, blobs, ctx in ((TxBundle, tx, Context(senders=team)), (RxBundle, rx, None)):
        for data in blobs:
            assert decode(data, ctx, cls).encode() == data
    ctx = Context(senders=team, shape=shape)
    kinds: Counter[str] = Counter()
    for data in rx:
        by_kind: dict[str, list[bytes]] = {}
        for env in decode(data, None, RxBundle).msgs:
            body = decode_payload(env.payload_kind, env.payload, ctx)
            assert body.encode() == env.payload
            by_kind.setdefault(env.payload_kind, []).append(env.payload)
            kinds[env.payload_kind] += 1
            kinds["want"] += isinstance(body, PoseBeacon) and bool(body.want)
            kinds["covers"] += isinstance(body, MapDelta) and bool(body.covers)
        for kind, payloads in by_kind.items():  # a batch gives what each gives alone
            batch = decode_many(kind, payloads, ctx)
            assert batch is not None and equal(batch, [decode_payload(kind, p, ctx) for p in payloads])
    assert kinds["pose"] > 100 and kinds["map"] > 50 and kinds["want"] > 0 and kinds["covers"] > 0


@pytest.mark.parametrize("kind", sorted(SAMPLES))
def test_a_batch_decodes_a_payload_as_it_decodes_alone(kind: str) -> None:
    """Each mutation of a well-formed payload, in a batch with a well-formed one: the batch never accepts one
    that does not decode alone (None: each is then decoded alone, to drop and count it), and gives what it gives
    alone when it accepts (it may leave an unusual one, cells of another dtype than the batch's, to the one by
    one decode)."""
    good = msgpack.packb(SAMPLES[kind][0], use_bin_type=True)
    accepted = refused = 0
    for obj in [m for sample in SAMPLES[kind] for m in mutations(sample)]:
        data = msgpack.packb(obj, use_bin_type=True)
        try:
            alone = decode_payload(kind, data, CTX)
        except DecodeError:
            assert decode_many(kind, [good, data], CTX) is None, obj
            refused += 1
            continue
        batch = decode_many(kind, [good, data], CTX)
        assert batch is None or equal(batch[1], alone), obj
        accepted += batch is not None
    assert accepted > 5 and refused > 20


def test_a_payload_cut_short_or_run_on_does_not_borrow_its_neighbours_bytes() -> None:
    """A batch is read from the payloads put end to end: one that ends early (or carries bytes after its map)
    must not be read with part of the next, though the whole would parse."""
    a = PoseBeacon(cell=(1, 2)).encode()
    header = b"\x82" + a[1:]  # a map of two keys, its second key and value taken from the next payload
    for batch in ([header, msgpack.packb("next") + msgpack.packb([1, 3]), a], [a + b"\xc0", a]):
        assert decode_many("pose", batch, CTX) is None


def test_what_the_declarations_refuse_is_refused() -> None:
    """Wrong-typed or out-of-range fields, a missing ``kind``, an unknown field and a cell outside the grid."""
    ctx = Context(senders=frozenset({"r0", "r1"}), shape=(4, 5))
    env = Envelope(src="r1", tick=3, seq=7, origin="r1", dst="*", ttl=1, payload_kind="pose",
                   payload=PoseBeacon(cell=(1, 2)).encode()).to_obj()
    for m in [{**env, "ttl": 17}, {**env, "tick": -1}, {k: v for k, v in env.items() if k != "kind"},
              {**env, "extra": 1}, {**env, "origin": "r9"}, {**env, "payload": "text"}, {**env, "v": 99}]:
        data = msgpack.packb({"kind": "tx", "v": 2, "src": "r1", "tick": 3, "seq": 1, "msgs": [m]}, use_bin_type=True)
        with pytest.raises(DecodeError):
            decode(data, ctx, TxBundle)
    with pytest.raises(DecodeError, match="missing required field `kind`"):
        decode(msgpack.packb({k: v for k, v in env.items() if k != "kind"}), ctx, Envelope)
    cells = {"dtype": "int32", "shape": [1], "data": np.array([20], np.int32).tobytes()}
    values = {"dtype": "int8", "shape": [1], "data": b"\0"}
    for cls, obj in [(PoseBeacon, {"cell": [4, 0]}), (PoseBeacon, {"cell": [1, 1], "next": [2, 2]}),
                     (PoseBeacon, {"cell": [1, 1], "want": {"r1": [2, 1]}}), (PoseBeacon, {"cell": [True, 1]}),
                     (MapDelta, {"cells": cells, "values": values}),
                     (MapDelta, {"cells": values, "values": {**values, "data": b"\7"}}),
                     (MapFill, {"cells": cells, "values": values, "seqs": [3, 3]})]:
        with pytest.raises(DecodeError):
            decode_payload(cls.KIND, msgpack.packb(obj, use_bin_type=True), ctx)


def test_optional_fields_left_out_keep_the_bytes_of_a_message_without_them() -> None:
    """A fleet without map sync sends beacons and deltas without ``maps``, ``want``, ``n`` and ``covers``: not
    even as nil, the bytes written before those fields existed."""
    cells, values = np.array([3, 7], np.int32), np.array([0, 100], np.int8)
    assert PoseBeacon(cell=(1, 2), next=(1, 3)).encode() == msgpack.packb({"cell": [1, 2], "next": [1, 3]})
    assert MapDelta(cells=cells, values=values).encode() == msgpack.packb(
        {"cells": {"dtype": "int32", "shape": [2], "data": cells.tobytes()},
         "values": {"dtype": "int8", "shape": [2], "data": values.tobytes()}}, use_bin_type=True)


def test_a_record_declared_without_kw_only_is_refused() -> None:
    """Its fields would be written before its base's (``kind``, ``v``, ``src``...): the codec refuses it."""
    class Stray(Message):  # no kw_only=True
        KIND = "stray-test"
        x: int

    try:
        with pytest.raises(TypeError, match="kw_only"):
            decoder(Stray)
    finally:
        del Message.REGISTRY["stray-test"]


def test_a_payload_declared_as_a_dataclass_says_how_it_is_declared() -> None:
    """A script written for an older fleet_emu meets one line that names the declaration, not msgspec's
    'readonly attribute'."""
    with pytest.raises(TypeError, match=r"Bid is declared `class Bid\(Payload, kw_only=True, frozen=True\)`"):
        @dataclasses.dataclass(frozen=True)
        class Bid(Payload):
            KIND = "bid-dataclass-test"
            cost: int = 0
    Payload.REGISTRY.pop("bid-dataclass-test", None)


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


def test_every_payload_kind_is_a_registered_declaration() -> None:
    assert {"pose", "map", "mapfill"} <= Payload.REGISTRY.keys()
    for cls in [*Payload.REGISTRY.values(), *Message.REGISTRY.values()]:
        decoder(cls)  # each laid out after its base
