"""``agents/hearing.py`` decides nothing: it accepts a teammate's beacon or map delta only when the message decoders
accept it, with the same values, and otherwise gives the inbox back to the brain, which opens it message by
message and drops (and counts) what does not validate."""

from __future__ import annotations

import dataclasses
from typing import Any

import msgpack
import numpy as np
import pytest

from fleet_emu.agents.allocators.trade import TradeNumber
from fleet_emu.agents.brain import Brain, BrainConfig
from fleet_emu.agents.hearing import CACHE, Beacon, Delta, Fill, hear
from fleet_emu.agents.protocol import MapDelta, MapFill, PoseBeacon
from fleet_emu.core.codec import Context, DecodeError, decode_payload
from fleet_emu.core.envelope import Envelope, RadioMsg, RxBundle, WireEnvelope, read_rx, seal
from fleet_emu.core.messages import Observation
from tests.harness.spy import Spy
from tests.harness.wire import CTX, SAMPLES, equal, mutations

FIELDS = {"pose": ("cell", "next", "maps"), "map": ("cells", "values", "n", "covers")}


def _env(kind: str, payload: bytes, src: str = "r1", **head: Any) -> Envelope:
    fields = {"src": src, "tick": 3, "seq": 7, "origin": src, "dst": "*", "ttl": 0} | head
    return Envelope(payload_kind=kind, payload=payload, **fields)


@pytest.mark.parametrize("kind", ["pose", "map"])
def test_hear_accepts_only_what_the_payload_decoders_accept_with_their_values(kind: str) -> None:
    accepted = refused = 0
    for obj in (o for sample in SAMPLES[kind] for o in [sample, *mutations(sample)]):
        data = msgpack.packb(obj, use_bin_type=True)
        try:
            record: Any = decode_payload(kind, data, CTX)
        except DecodeError:
            record = None
        inbox = [_env("pose", PoseBeacon(cell=(0, 0)).encode()), _env(kind, data, src="r2")]
        got = hear(inbox, CTX, "r3")
        if record is None:
            assert got is None, obj  # the brain then opens it message by message, and drops it
            refused += 1
            continue
        if got is None:  # valid, in a form hear leaves to the message decoders (int64 cells, ...)
            continue
        origin, tick, body = got.messages[1]
        assert (origin, tick) == ("r2", 3) and isinstance(body, Beacon if kind == "pose" else Delta)
        assert all(equal(getattr(body, f), getattr(record, f)) for f in FIELDS[kind]), obj
        if kind == "pose":  # a beacon's requests, as each teammate reads those addressed to it
            for r in CTX.senders:
                heard = hear(inbox, CTX, r)
                assert heard is not None and heard.asks.get(1) == (record.want or {}).get(r), obj
        accepted += 1
    assert accepted > 10 and refused > 50


def test_a_header_that_does_not_validate_gives_the_inbox_back() -> None:
    payload = PoseBeacon(cell=(1, 2)).encode()
    assert hear([_env("pose", payload)], CTX, "r1") is not None
    for head in ({"ttl": 17}, {"tick": -1}, {"origin": "r9"}, {"src": "r9"}):
        assert hear([_env("pose", payload), _env("pose", payload, **head)], CTX, "r1") is None, head
    assert hear([_env("nonsense", payload)], CTX, "r1") is None  # an unknown kind: dropped message by message


def test_other_kinds_are_opened_as_messages_in_their_place() -> None:
    fill = MapFill(cells=np.array([3], np.int32), values=np.array([0], np.int8), seqs=(2,), upto=4)
    number = TradeNumber(number=5)
    inbox = [_env("pose", PoseBeacon(cell=(1, 2)).encode()), _env("mapfill", fill.encode(), src="r2"),
             _env("trade_num", number.encode()),
             _env("map", MapDelta(cells=np.array([4], np.int32), values=np.array([100], np.int8)).encode())]
    got = hear(inbox, CTX, "r0")
    assert got is not None
    (_, _, beacon), (_, _, filled), (_, _, other), (_, _, delta) = got.messages
    assert isinstance(beacon, Beacon) and isinstance(delta, Delta) and isinstance(filled, Fill)
    assert np.array_equal(filled.cells, fill.cells) and np.array_equal(filled.values, fill.values)
    assert (filled.seqs, filled.upto) == (fill.seqs, fill.upto)
    assert isinstance(other, RadioMsg) and other.body == number  # a kind not heard at once: opened as before
    assert not any(CACHE in env.__dict__ for env in inbox)  # kept only for receivers that share envelopes
    kept = hear(inbox, CTX, "r0", keep=True)
    assert kept is not None
    assert all(env.__dict__[CACHE][1] is item for env, item in zip(inbox, kept.messages, strict=True))
    again = hear(inbox, CTX, "r0", keep=True)  # the memory engine's receivers of one broadcast read it once
    assert again is not None and all(a is b for a, b in zip(again.messages, kept.messages, strict=True))


def test_a_shared_beacon_asks_each_receiver_for_its_own_deltas() -> None:
    beacon = PoseBeacon(cell=(1, 2), next=(1, 3), maps=4, want={"r0": (1, 2), "r2": (3,)})
    inbox = [_env("pose", beacon.encode())]
    first = hear(inbox, CTX, "r0", keep=True)
    assert first is not None and first.asks == {0: (1, 2)}
    for robot, asks in (("r2", {0: (3,)}), ("r1", {}), ("r0", {0: (1, 2)})):  # each reads the kept request map
        got = hear(inbox, CTX, robot, keep=True)
        assert got is not None and got.asks == asks and got.messages[0] is first.messages[0]


def test_the_brain_drops_and_counts_a_bad_message_and_hears_the_rest() -> None:
    drops: list[str] = []
    brain = Brain("r0", Spy(), np.random.default_rng(0), BrainConfig(), team=frozenset({"r0", "r1", "r2"}),
                  on_drop=lambda key, why: drops.append(key))
    obs = Observation(src="world", tick=4, seq=1, robot="r0", cell=(0, 0), shape=(4, 5), cell_size=0.5,
                      cells=np.array([0], np.int32), values=np.array([0], np.int8))
    brain._belief(obs)
    bad = msgpack.packb({"cell": [9, 9]}, use_bin_type=True)  # outside the 4 x 5 grid
    inbox = [seal(RadioMsg(PoseBeacon(cell=(1, 2))), "r1", 3, 1), _env("pose", bad, src="r2"),
             seal(RadioMsg(MapDelta(cells=np.array([7], np.int32), values=np.array([100], np.int8))), "r1", 3, 2)]
    opened = brain.open(inbox)
    assert drops == ["radio/pose"]
    assert [(o, type(b)) for o, _, b in opened.messages] == [("r1", RadioMsg), ("r1", RadioMsg)]


def test_a_brain_hearing_at_once_learns_what_it_learns_message_by_message(monkeypatch: pytest.MonkeyPatch) -> None:
    """Beacons and overlapping map deltas of three teammates (a cell changed by a later delta, unknown values):
    the belief, its news and count, and the teammates are those of the inbox opened message by message."""
    import fleet_emu.agents.brain as brain_module

    team = frozenset({"r0", "r1", "r2", "r3"})
    rng = np.random.default_rng(3)
    inbox = []
    for i, r in enumerate(["r1", "r2", "r3"]):
        inbox.append(seal(RadioMsg(PoseBeacon(cell=(i, 1), next=(i, 2))), r, 3, 1))
        cells = np.unique(rng.integers(0, 20, 8)).astype(np.int32)
        values = rng.choice(np.array([-1, 0, 100], np.int8), len(cells))
        inbox.append(seal(RadioMsg(MapDelta(cells=cells, values=values)), r, 3, 2))

    def run(at_once: bool) -> Brain:
        if not at_once:
            monkeypatch.setattr(brain_module, "hear", lambda *a: None)
        b = Brain("r0", Spy(), np.random.default_rng(0), BrainConfig(), team=team)
        b.step(Observation(src="world", tick=4, seq=1, robot="r0", cell=(3, 4), shape=(4, 5), cell_size=0.5,
                           cells=np.array([19], np.int32), values=np.array([0], np.int8)), inbox)
        monkeypatch.undo()
        return b

    assert hear(inbox, Context(senders=team, shape=(4, 5)), "r0") is not None  # heard at once, with no fallback
    fast, slow = run(True), run(False)
    assert fast.belief is not None and slow.belief is not None
    assert np.array_equal(fast.belief.grid, slow.belief.grid) and fast.belief.known_cells == slow.belief.known_cells
    assert fast.teammates == slow.teammates and list(fast.teammates) == ["r1", "r2", "r3"]
    assert fast.belief.known_cells > 5


@pytest.mark.parametrize("config", [BrainConfig(map_sync=True), BrainConfig(map_sync=True, relay="flood", relay_ttl=2)])
def test_a_robot_steps_alike_on_its_rx_bundle_s_envelopes_as_read_or_built(config: BrainConfig) -> None:
    """An agent hears its rx bundle's envelopes as read (``WireEnvelope``), building an ``Envelope`` only for
    one it opens message by message or relays: the command, the messages sent and the drops are those of
    built envelopes, at once and (a bad message in the inbox) message by message."""
    team = frozenset({"r0", "r1", "r2", "r3"})
    fill = MapFill(cells=np.array([3, 4], np.int32), values=np.array([0, 100], np.int8), seqs=(2,), upto=3)
    delta = MapDelta(cells=np.array([5, 6], np.int32), values=np.array([0, 0], np.int8), n=3)
    inbox = [seal(RadioMsg(PoseBeacon(cell=(0, 1), next=(0, 2), maps=3, want={"r0": (1, 2), "r3": (4,)})), "r1", 3, 1),
             seal(RadioMsg(delta), "r1", 3, 2), seal(RadioMsg(fill, dst="r0"), "r2", 3, 1),
             seal(RadioMsg(TradeNumber(number=2)), "r3", 3, 1),
             seal(RadioMsg(PoseBeacon(cell=(1, 1), want={"r1": (1,)})), "r2", 3, 2)]
    obs = Observation(src="world", tick=4, seq=1, robot="r0", cell=(3, 4), shape=(4, 5), cell_size=0.5,
                      cells=np.array([19], np.int32), values=np.array([0], np.int8))
    bad = _env("pose", msgpack.packb({"cell": [9, 9]}, use_bin_type=True), src="r2")
    for messages in (inbox, [*inbox, bad]):
        wires = read_rx(RxBundle(src="netem", tick=3, seq=1, dst="r0", msgs=tuple(messages)).encode())
        assert wires is not None and all(isinstance(w, WireEnvelope) for w in wires.msgs)
        outcomes = []
        for given in (messages, wires.msgs):
            drops: list[str] = []
            b = Brain("r0", Spy(), np.random.default_rng(0), config, team=team,
                      on_drop=lambda key, why, drops=drops: drops.append(key))
            cmd, out = b.step(obs, given)
            assert b.belief is not None
            outcomes.append((dataclasses.replace(cmd, decision_ms=0.0).encode(), [e.encode() for e in out],
                             list(drops), b.belief.grid.tobytes()))
        assert outcomes[0] == outcomes[1]
        assert len(outcomes[0][1]) > 2 and outcomes[0][2] == (["radio/pose"] if bad in messages else [])
