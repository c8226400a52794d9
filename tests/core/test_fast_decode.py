"""The fast decoders (``core.codec.fast_decoder``: envelopes, pose beacons, map deltas) accept exactly what the
generic decode accepts, and give the same records: checked on well-formed messages and on many mutations of
them (a field removed, added, of another type, out of range)."""

from __future__ import annotations

import copy
from collections.abc import Iterable
from typing import Any

import msgpack
import numpy as np
import pytest

from fleet_emu.agents.protocol import MapDelta, MapFill, PoseBeacon
from fleet_emu.core.codec import Context, DecodeError, decode, decode_payload, generic_decode
from fleet_emu.core.messages import Envelope, Observation, RxBundle, TxBundle

CTX = Context(senders=frozenset({"r0", "r1", "r2"}), shape=(4, 5))
ODD = [None, True, False, -1, 0, 1, 3, 19, 20, 2**40, 1.5, "r1", "r9", "", b"x", [], [1], [1, 2], [2, 1], [0, 1],
       [3, 3], [True, 1], {}, {"r1": [1]}, {"r9": [1]}, {"r1": [2, 1]}, {"r1": "1"}, {1: [1]}, list(range(1, 70)),
       {b"r1": [1]}, {"r1": [0]}, {"r1": [True]}, {"r1": [1.0]}, {"r1": [1], "r2": [7]}, {"r1": [1], "r2": []},
       {"r1": [1], "r2": [0]}, {"r1": [2], "r2": [1, 2]}, {"r1": list(range(1, 66))}, {"r1": list(range(1, 65))},
       {"dtype": "int32", "shape": [1], "data": b"\0\0\0\0"}, {"dtype": "int8", "shape": [1], "data": b"\x64"},
       {"dtype": "int32", "shape": [1], "data": b"\xff\xff\xff\xff"}, {"dtype": "int8", "shape": [1], "data": b"\7"},
       {"dtype": "int32", "shape": [2], "data": b"\0\0\0\0"}]


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, type) or isinstance(b, type):  # DecodeError: both rejected
        return a is b
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return isinstance(a, np.ndarray) and isinstance(b, np.ndarray) and a.dtype == b.dtype \
            and np.array_equal(a, b)
    if type(a) is not type(b):
        return False
    if hasattr(a, "__dataclass_fields__"):
        return all(_equal(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    return a == b


def _outcome(decoder: Any, *args: Any, **kwargs: Any) -> Any:
    try:
        return decoder(*args, **kwargs)
    except DecodeError:
        return DecodeError


def _mutations(obj: dict) -> list[dict]:
    out = []
    for key in [*obj, "extra"]:
        if key in obj:
            drop = dict(obj)
            del drop[key]
            out.append(drop)
        for value in ODD:
            m = copy.deepcopy(obj)
            m[key] = value
            out.append(m)
    return out


SAMPLES = {
    "pose": [{"cell": [1, 2]}, {"cell": [1, 2], "next": [1, 3]}, {"cell": [0, 0], "next": [0, 0], "maps": 4},
             {"cell": [3, 4], "next": [2, 4], "maps": 0, "want": {"r1": [1, 2, 9], "r2": []}}],
    "map": [MapDelta(cells=np.array([0, 19], np.int32), values=np.array([0, 100], np.int8)).fields_obj(),
            MapDelta(cells=np.array([3], np.int32), values=np.array([-1], np.int8), n=5, covers=(1, 4)).fields_obj(),
            MapDelta(cells=np.zeros(0, np.int32), values=np.zeros(0, np.int8), n=1).fields_obj()],
    "mapfill": [MapFill(cells=np.array([0, 19], np.int32), values=np.array([0, 100], np.int8)).fields_obj(),
                MapFill(cells=np.array([3], np.int32), values=np.array([0], np.int8), seqs=(2, 5), upto=9).fields_obj(),
                {"cells": {"dtype": "int32", "shape": [1], "data": b"\1\0\0\0"},
                 "values": {"dtype": "int8", "shape": [1], "data": b"\0"}}],
}


def _tally(objs: Iterable[dict], expected: type | None = None, kind: str | None = None) -> tuple[int, int]:
    """Each map packed and decoded the fast way and the generic way (a message of class ``expected``, or a
    payload of ``kind``), with the team's context and without: the two agree on every one (equal records, or
    both a DecodeError). Returns how many were accepted and how many rejected."""
    accepted = rejected = 0
    for obj in objs:
        data = msgpack.packb(obj, use_bin_type=True)
        for ctx in (CTX, None):
            if kind is not None:
                fast, slow = _outcome(decode_payload, kind, data, ctx), _outcome(generic_decode, data, ctx, kind=kind)
            else:
                fast, slow = _outcome(decode, data, ctx, expected), _outcome(generic_decode, data, ctx, expected)
            assert _equal(fast, slow), (obj, ctx)
            accepted += fast is not DecodeError
            rejected += fast is DecodeError
    return accepted, rejected


@pytest.mark.parametrize("kind", sorted(SAMPLES))
def test_payload_fast_decoders_agree_with_the_generic_decode(kind: str) -> None:
    accepted, rejected = _tally((obj for sample in SAMPLES[kind] for obj in [sample, *_mutations(sample)]),
                                kind=kind)
    assert accepted > 20 and rejected > 100  # both ways were exercised


def test_envelope_fast_decoder_agrees_with_the_generic_decode() -> None:
    env = Envelope(src="r1", tick=3, seq=7, origin="r2", dst="*", ttl=1, payload_kind="pose",
                   payload=PoseBeacon(cell=(1, 2)).encode())
    bundles = ({"kind": "rx", "v": 2, "src": "netem", "tick": 3, "seq": 1, "dst": "r0", "msgs": [obj]}
               for obj in [env.to_obj(), *_mutations(env.to_obj())])
    accepted, rejected = _tally(bundles, RxBundle)
    assert accepted > 5 and rejected > 50


@pytest.mark.parametrize("n", [0, 1, 15, 16, 70_000])
def test_bundles_encode_as_msgpack_packs_them(n: int) -> None:
    """Bundles put their envelopes' kept bytes in as they are: the bytes are msgpack's own, at every array
    header size."""
    env = Envelope(src="r0", tick=0, seq=1, origin="r0", dst="*", ttl=0, payload_kind="pose",
                   payload=PoseBeacon(cell=(1, 2)).encode())
    for bundle in (TxBundle(src="r0", tick=2, seq=3, msgs=(env,) * n),
                   RxBundle(src="netem", tick=2, seq=3, dst="r1", msgs=(env,) * n)):
        data = bundle.encode()
        assert data == msgpack.packb(bundle.to_obj(), use_bin_type=True)
        assert decode(data, None, type(bundle)) == bundle


def test_a_beacons_requests_are_checked_at_once_as_list_by_list() -> None:
    """The fast pose decoder checks every request list at once (``_wants_of``): the same verdict as checking
    each list (``check_seqs``) on random lists, ascending or not, with zeros, negatives and large numbers, and
    on requests of one number per teammate (where it checks no list's order)."""
    from fleet_emu.agents.protocol import _wants_of, check_seqs

    rng = np.random.default_rng(11)
    verdicts = set()
    for _ in range(3000):
        want = {}
        ones = rng.random() < 0.3
        for r in range(int(rng.integers(0, 4))):
            n = 1 if ones else int(rng.integers(0, 5))
            pool = [0, -3, 1, 2, 3, 5, 8, 2**40] if rng.random() < 0.5 else list(range(1, 9))
            seqs = sorted(rng.choice(pool, n).tolist()) if rng.random() < 0.7 else rng.choice(pool, n).tolist()
            want[f"r{r}"] = [int(x) for x in seqs]
        try:
            for seqs in want.values():
                check_seqs(tuple(seqs), "pose")
            expected = {r: tuple(v) for r, v in want.items()}
        except DecodeError:
            expected = None
        assert _wants_of(want) == expected, want
        verdicts.add(expected is None)
    assert verdicts == {True, False}


@pytest.mark.parametrize("cls", [TxBundle, RxBundle])
def test_bundle_fast_decoders_agree_with_the_generic_decode(cls: type) -> None:
    """Mutations of a bundle's header, of its list of envelopes (an envelope of another sender in a tx bundle,
    an item that is no envelope) and of one of its envelopes: the fast decode and the generic one agree."""
    def env(src: str, seq: int) -> Envelope:
        return Envelope(src=src, tick=3, seq=seq, origin=src, dst="*", ttl=0, payload_kind="pose",
                        payload=PoseBeacon(cell=(1, 2)).encode())

    head = {"src": "r1", "tick": 3, "seq": 9} | ({"dst": "r0"} if cls is RxBundle else {})
    good = cls(**head, msgs=(env("r1", 1), env("r1", 2))).to_obj()
    samples = [good, cls(**head, msgs=()).to_obj()]
    odd_lists = [[env("r1", 1).to_obj(), env("r2", 2).to_obj()], [env("r1", 1).to_obj(), 5], [{"kind": "pose"}],
                 [env("r1", 1).to_obj() | {"kind": "tx"}], (env("r1", 1).to_obj(),)]
    objs = [*samples, *_mutations(good), *({**good, "msgs": m} for m in odd_lists),
            *({**good, "msgs": [good["msgs"][0], m]} for m in _mutations(good["msgs"][1]))]
    accepted, rejected = _tally(objs, cls)
    assert accepted > 10 and rejected > 100


def test_observation_typed_decoder_agrees_with_the_generic_decode() -> None:
    """Mutations of an observation (a field removed, added, of another type; a cell or an index outside its own
    grid, an odd cell value, an int cell size): the typed decode and the generic one agree, and the typed one
    is the one that accepts a well-formed observation."""
    from fleet_emu.core import codec

    def obs(**kw: Any) -> dict:
        fields = dict(src="r1", tick=3, seq=9, robot="r0", cell=(1, 2), shape=(4, 5), cell_size=0.5,
                      cells=np.array([0, 19], np.int32), values=np.array([0, 100], np.int8)) | kw
        return Observation(**fields).to_obj()

    good = obs()
    samples = [good, obs(cells=np.zeros(0, np.int32), values=np.zeros(0, np.int8)), obs(cell=(3, 4)),
               obs(cells=np.array([20], np.int32), values=np.array([0], np.int8)), obs(cell=(4, 0)),
               obs(values=np.array([0, 7], np.int8)), obs(cells=np.array([1, 2], np.int64)), obs(cell_size=1),
               obs(shape=(0, 5)), obs(cell_size=-0.5), obs(cells=np.array([1], np.int32))]
    accepted, rejected = _tally([*samples, *_mutations(good)], Observation)
    assert accepted > 5 and rejected > 50
    assert codec._typed(Observation, msgpack.packb(good, use_bin_type=True), CTX) is not None
