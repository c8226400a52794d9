"""Fuzzed bus traffic for the fault trials: random bytes, wrong shapes, oversized payloads,
unknown ids and spoofed ids, on every key of a run. A plain generator of ``(key, bytes)`` from a seeded
``numpy`` generator; sending it is :mod:`faults`' job.

Two flavours:

- ``open`` (an outsider on an unauthenticated router): nothing it sends may be accepted by a node, so the run's
  seeded result must not change. Every message either does not decode, or carries a ``src`` that may not
  write on its key (docs/design/security.md, "A second line"), or names a robot that is not in the fleet on
  that robot's own key.
- ``robot`` (a compromised robot with its own credentials, ``user``): the same garbage on every key (the
  router drops what is not its own), plus tx bundles from itself whose envelopes carry garbage payloads, so
  that the other robots' payload decoders see them through netem.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import msgpack
import numpy as np

from fleet_emu.agents.protocol import MapDelta, PoseBeacon
from fleet_emu.core.codec import Record
from fleet_emu.core.keys import Keys
from fleet_emu.core.messages import (
    BeliefSnapshot,
    Command,
    Envelope,
    Failed,
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
    seal,
)

UNKNOWN = ("r99", "r-1", "x" * 40)  # robot ids no fleet has
SPOOFS = ("outsider", "r98", "launcher ", "World", "netem2", "*")  # never an allowed sender of any key
OVERSIZED = (64 * 1024, 512 * 1024)  # bytes of an oversized payload
#: mutation -> weight; "unknown" is a well-formed message from an unknown robot on that robot's own key.
MUTATIONS = {"bytes": 20, "shape": 20, "field": 25, "kind": 10, "version": 5, "spoof": 15, "unknown": 4,
             "oversized": 0.1, "envelope": 0, "own": 0}
TICKS = (0, 1, 7, 10**6, 2**40, 2**62, 2**64 - 1)  # the ticks of a compromised robot's own messages


def run_keys(run: str, robots: list[str]) -> list[str]:
    """Every key a run's nodes put on or listen to (the robots' and a few unknown robots')."""
    k = Keys(run)
    ids = [*robots, *(u for u in UNKNOWN if u)]
    per_robot = [f(r) for r in ids for f in (k.obs, k.cmd, k.belief, k.tx, k.rx, k.failed, k.report, k.ready)]
    nodes = [k.ready(n) for n in ("world", "netem", "launcher", "recorder")]
    return [k.state, k.links, k.hello, k.stop, *nodes, *per_robot]


def _template(channel: str, node: str, src: str, rng: np.random.Generator) -> Record:
    """A well-formed message of ``channel`` (``node``: the robot in its key), from ``src``."""
    t, s = int(rng.integers(0, 500)), int(rng.integers(0, 10_000))
    cells = rng.integers(0, 400, size=8).astype(np.int64)
    values = rng.choice(np.array([0, 100], dtype=np.int8), size=8)
    env = seal(RadioMsg(PoseBeacon(cell=(1, 1))), src, t, s)
    match channel:
        case "obs":
            return Observation(src=src, tick=t, seq=s, robot=node, cell=(1, 1), shape=(20, 20), cell_size=0.5,
                               cells=cells, values=values)
        case "state":
            return WorldState(src=src, tick=t + 5000, seq=s, poses={"r0": (1, 1)}, live=("r0",), coverage=1.0,
                              path_length={"r0": 3}, done=True, reason="coverage")
        case "cmd":
            return Command(src=src, tick=t, seq=s, move=(0, 0), target=(2, 2))
        case "belief":
            return BeliefSnapshot(src=src, tick=t, seq=s, grid=np.full((4, 4), 100, np.int8))
        case "tx":
            return TxBundle(src=src, tick=t, seq=s, msgs=(env,))
        case "rx":
            return RxBundle(src=src, tick=t, seq=s, dst=node, msgs=(env,))
        case "links":
            return Links(src=src, tick=t, seq=s, robots=("r0",), strength=np.zeros((1, 1), np.float32),
                         link=np.ones((1, 1), bool), connected=True, sent=1, delivered=1, dropped_loss=0,
                         dropped_signal=0, bytes_sent=9)
        case "failed":
            return Failed(src=src, tick=t, seq=s, robot=node or "r0", reason="fuzz")
        case "report":
            return RobotReport(src=src, tick=t, seq=s, decisions=1, decision_ms_mean=1.0, decision_ms_p95=1.0,
                               dropped=0, peak_rss_kb=1)
        case "ready":
            return Ready(src=src, tick=0, seq=0, role="agent", pid=1)
        case "hello":
            return Hello(src=src, tick=0, seq=0)
        case _:
            return Stop(src=src, tick=t, seq=s, reason="fuzz")


def _random_value(rng: np.random.Generator, depth: int = 0) -> Any:
    """Any msgpack value: the wrong shape for whatever field it lands in."""
    choice = int(rng.integers(0, 9 if depth < 3 else 6))
    match choice:
        case 0:
            return int(rng.integers(-(2**63), 2**63 - 1))
        case 1:
            return float(rng.choice([np.nan, np.inf, -np.inf, -1.0, 1e308, 0.5]))
        case 2:
            return "".join(chr(int(c)) for c in rng.integers(32, 0x2FF, size=int(rng.integers(0, 12))))
        case 3:
            return rng.bytes(int(rng.integers(0, 40)))
        case 4:
            return None
        case 5:
            return bool(rng.integers(0, 2))
        case 6:
            return [_random_value(rng, depth + 1) for _ in range(int(rng.integers(0, 5)))]
        case 7:
            return {str(_random_value(rng, 3)): _random_value(rng, depth + 1) for _ in range(int(rng.integers(0, 4)))}
        case _:
            return {"kind": str(rng.choice(["cmd", "state", "tx", "rx", "obs", "stop", "failed"])),
                    "src": _random_value(rng, 3), "tick": _random_value(rng, 3), "v": 2}


def _pack(obj: Any) -> bytes:
    return msgpack.packb(obj, use_bin_type=True)


def _spoof_for(channel: str, node: str, rng: np.random.Generator) -> str:
    """A sender that may not write on the key (a robot other than the key's, or an outsider)."""
    others = [r for r in ("r0", "r1", "r2", "world", "netem", "launcher") if r != node]
    if channel in ("obs", "state", "hello", "stop"):
        others = [r for r in others if r not in ("world", "launcher")]
    elif channel in ("rx", "links"):
        others = [r for r in others if r != "netem"]
    elif channel == "failed":
        others = [r for r in others if r != "launcher"]
    return str(rng.choice([*others, *SPOOFS]))


def _garbage_envelope(src: str, rng: np.random.Generator) -> dict[str, Any]:
    """An envelope whose header is well-formed (netem routes it) and whose payload is garbage of a real kind."""
    kinds = ["pose", "map", "assign", "trade_num", "trade_buy", "trade_alloc", "trade_done", "nope"]
    payload = _pack(_random_value(rng)) if rng.random() < 0.6 else rng.bytes(int(rng.integers(0, 64)))
    if rng.random() < 0.2:  # a well-formed map delta with cells far outside any map
        delta = MapDelta(cells=rng.integers(10**9, 10**12, size=4).astype(np.int64),
                         values=np.full(4, 100, np.int8))
        payload, kind = _pack(delta.fields_obj()), "map"
    else:
        kind = str(rng.choice(kinds))
    env = Envelope(src=src, tick=0, seq=int(rng.integers(0, 10**6)), origin=src,
                   dst=str(rng.choice(["*", "r0", "r2", "r99"])), ttl=int(rng.integers(0, 3)), payload_kind=kind,
                   payload=payload)
    return env.fields_obj()


def _message(key: str, mutation: str, robots: list[str], rng: np.random.Generator, user: str | None) -> bytes:
    parsed = Keys(key.split("/")[1]).parse(key)
    channel = parsed.channel if parsed else "stop"
    node = parsed.node or "" if parsed else ""
    if mutation == "bytes":
        return rng.bytes(int(rng.integers(0, 256)))
    if mutation == "shape":
        return _pack(_random_value(rng))
    if mutation == "oversized":
        return rng.bytes(int(rng.integers(*OVERSIZED)))
    if mutation == "unknown":  # a well-formed message from a robot the fleet does not have, on its own key
        return _template(channel, node, node, rng).encode()
    if mutation == "own":  # the compromised robot's own well-formed messages on its own keys, at any tick
        obj = _template(channel, node, node, rng).to_obj()
        obj["tick"] = TICKS[int(rng.integers(0, len(TICKS)))]
        return _pack(obj)
    if mutation == "envelope":  # the compromised robot's own tx bundle: garbage inside well-formed envelopes
        obj = _template("tx", user or "r1", user or "r1", rng).to_obj()
        obj["msgs"] = [_garbage_envelope(user or "r1", rng) for _ in range(int(rng.integers(1, 6)))]
        return _pack(obj)
    src = _spoof_for(channel, node, rng)
    if mutation == "kind":
        other = str(rng.choice(["obs", "state", "cmd", "belief", "tx", "rx", "links", "failed", "report", "stop"]))
        return _template(other, node, src, rng).encode()
    obj = _template(channel, node, src, rng).to_obj()
    if mutation == "version":
        obj["v"] = _random_value(rng) if rng.random() < 0.5 else 999
    elif mutation == "field":
        name = str(rng.choice([k for k in obj if k != "kind"]))
        if rng.random() < 0.2:
            del obj[name]
        else:
            obj[name] = _random_value(rng)
        if rng.random() < 0.2:
            obj[str(_random_value(rng, 3))] = _random_value(rng)
    return _pack(obj)


def fuzz_messages(rng: np.random.Generator, run: str, robots: list[str], n: int,
                  user: str | None = None) -> Iterator[tuple[str, bytes, str]]:
    """``n`` fuzzed messages ``(key, data, mutation)`` on every key of ``run``. ``user`` None is the ``open``
    flavour (nothing may be accepted); a robot id is the ``robot`` flavour (adds its own garbage bundles)."""
    keys = run_keys(run, robots)
    weights = dict(MUTATIONS)
    if user is not None:
        weights["envelope"], weights["own"] = 15, 10
    own = [k for k in keys if k.split("/")[-2:] in ([user, "cmd"], [user, "belief"], ["report", user], ["ready", user])]
    names = list(weights)
    p = np.array([weights[m] for m in names], dtype=float)
    p /= p.sum()
    unknown_keys = [k for k in keys if any(f"/{u}" in k for u in UNKNOWN if u)]
    for _ in range(n):
        mutation = str(rng.choice(names, p=p))
        pool = unknown_keys if mutation == "unknown" else own if mutation == "own" else keys
        key = Keys(run).tx(user) if mutation == "envelope" and user else str(rng.choice(pool))
        yield key, _message(key, mutation, robots, rng, user), mutation
