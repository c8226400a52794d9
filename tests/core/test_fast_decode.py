"""The fast decoders (``core.codec.fast_decoder``: envelopes, pose beacons, map deltas) accept exactly what the
generic decode accepts, and give the same records: checked on well-formed messages and on many mutations of
them (a field removed, added, of another type, out of range)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import msgpack
import numpy as np
import pytest

from fleet_emu.agents.protocol import PoseBeacon
from fleet_emu.core.codec import DecodeError, decode, decode_payload, generic_decode
from fleet_emu.core.messages import Envelope, Observation, RxBundle, TxBundle
from tests.harness.wire import CTX, SAMPLES, equal, mutations


def _outcome(decoder: Any, *args: Any, **kwargs: Any) -> Any:
    try:
        return decoder(*args, **kwargs)
    except DecodeError:
        return DecodeError


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
            assert equal(fast, slow), (obj, ctx)
            accepted += fast is not DecodeError
            rejected += fast is DecodeError
    return accepted, rejected


@pytest.mark.parametrize("kind", sorted(SAMPLES))
def test_payload_fast_decoders_agree_with_the_generic_decode(kind: str) -> None:
    accepted, rejected = _tally((obj for sample in SAMPLES[kind] for obj in [sample, *mutations(sample)]),
                                kind=kind)
    assert accepted > 20 and rejected > 100  # both ways were exercised


def test_envelope_fast_decoder_agrees_with_the_generic_decode() -> None:
    env = Envelope(src="r1", tick=3, seq=7, origin="r2", dst="*", ttl=1, payload_kind="pose",
                   payload=PoseBeacon(cell=(1, 2)).encode())
    bundles = ({"kind": "rx", "v": 2, "src": "netem", "tick": 3, "seq": 1, "dst": "r0", "msgs": [obj]}
               for obj in [env.to_obj(), *mutations(env.to_obj())])
    accepted, rejected = _tally(bundles, RxBundle)
    assert accepted > 5 and rejected > 50


@pytest.mark.parametrize("n", [0, 1, 15, 16, pytest.param(70_000, marks=pytest.mark.slow)])  # 70,000: 2 CPU s
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
    objs = [*samples, *mutations(good), *({**good, "msgs": m} for m in odd_lists),
            *({**good, "msgs": [good["msgs"][0], m]} for m in mutations(good["msgs"][1]))]
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
    accepted, rejected = _tally([*samples, *mutations(good)], Observation)
    assert accepted > 5 and rejected > 50
    assert codec._typed(Observation, msgpack.packb(good, use_bin_type=True), CTX) is not None
