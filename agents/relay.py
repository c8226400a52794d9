"""Multi-hop relaying of radio envelopes, as a pure decision per received envelope.

A robot that receives an :class:`~fleet_emu.core.messages.Envelope` decides two things: whether the message is
for it (``dst`` is its id or ``*``), and whether to send it on, once, with one hop less. The decision is a
function of the envelope's header only (payloads stay opaque, docs/reference/protocol.md), of the robot's id,
of a forwarding policy, and of a cache of the message ids already seen.

Rules (beyond "forward once, deduplicated by origin and id, while hops remain", the choices are ours):

- A message's id is ``(origin, seq)``; ``seq`` comes from the origin's one counter, so the pair is unique.
  The first copy heard is handled; every later copy (another relay's forward, an echo of our own) is a
  duplicate: neither delivered again nor forwarded again. A robot's own messages count as seen when it hears
  them back.
- ``ttl`` is the hops left *after* the one that brought the message: a message sealed with ``ttl = k`` crosses
  at most ``k + 1`` links, and a robot forwards only a copy received with ``ttl > 0``, re-sealed with
  ``src`` = itself and ``ttl - 1``. ``ttl = 0`` (the default of :class:`~fleet_emu.core.messages.RadioMsg`)
  is one hop, as before relaying existed. The hops a delivered copy took are ``ttl_sealed - ttl + 1``.
- The forwarded copy keeps ``origin``, ``seq``, ``dst``, ``payload`` and ``tick``: ``tick`` stays the tick
  the origin made the message, so a receiver reads the end-to-end latency as ``now - tick``.
- A message whose ``dst`` is this robot is delivered and not forwarded (it has arrived).
- ``flood``: every robot forwards what is not only for it. ``tree``: only a robot on the routes' tree path
  from the message's ``origin`` to its ``dst`` (strictly between them) forwards; for ``dst = "*"`` every robot
  with a child in the tree forwards. The routes are a parent map (robot -> parent, the root ``base`` has
  none), what a base-station allocator maintains; a robot or destination missing from it is not routed
  through, so under ``tree`` an unknown path is not forwarded (the base republishes routes as they change).

The cache is bounded (oldest ids forgotten first); the hop limit still bounds a copy that outlives its entry.
"""

from __future__ import annotations

import dataclasses
from collections import OrderedDict
from collections.abc import Mapping

import msgspec

from fleet_emu.core.messages import Envelope

POLICIES = ("flood", "tree")
BROADCAST = "*"


@dataclasses.dataclass(frozen=True)
class RelayDecision:
    """What to do with one received envelope: ``deliver`` it to this robot's protocols, and send ``forward``
    (a re-sealed copy) on the radio when it is not None. ``why`` names the rule that decided."""

    deliver: bool
    forward: Envelope | None
    why: str


class SeenCache:
    """The ids ``(origin, seq)`` already handled, the ``capacity`` most recent kept (FIFO eviction)."""

    def __init__(self, capacity: int = 4096) -> None:
        if capacity < 1:
            raise ValueError("capacity must be >= 1")
        self.capacity = capacity
        self._ids: OrderedDict[tuple[str, int], None] = OrderedDict()

    def __contains__(self, key: tuple[str, int]) -> bool:
        return key in self._ids

    def __len__(self) -> int:
        return len(self._ids)

    def add(self, key: tuple[str, int]) -> bool:
        """Record ``key``; False when it was already there."""
        if key in self._ids:
            return False
        self._ids[key] = None
        if len(self._ids) > self.capacity:
            self._ids.popitem(last=False)
        return True


def tree_path(parents: Mapping[str, str], a: str, b: str) -> list[str] | None:
    """The path from ``a`` to ``b`` in the tree given by ``parents`` (child -> parent), both ends included;
    None when either is not in the tree or they lie in different trees."""
    def up(x: str) -> list[str] | None:
        chain, seen = [x], {x}
        while chain[-1] in parents:
            nxt = parents[chain[-1]]
            if nxt in seen:  # a cycle: not a tree
                return None
            chain.append(nxt)
            seen.add(nxt)
        return chain

    known = set(parents) | set(parents.values())
    if a not in known or b not in known:
        return None
    ua, ub = up(a), up(b)
    if ua is None or ub is None or ua[-1] != ub[-1]:
        return None
    on_b = {x: k for k, x in enumerate(ub)}
    for k, x in enumerate(ua):
        if x in on_b:  # the lowest common ancestor
            return ua[:k + 1] + ub[:on_b[x]][::-1]
    return None  # unreachable: the roots agree


def forwards_on_tree(parents: Mapping[str, str], me: str, origin: str, dst: str) -> bool:
    """Whether ``me`` relays a message from ``origin`` to ``dst`` under the ``tree`` policy."""
    if dst == BROADCAST:
        return me in set(parents.values())
    path = tree_path(parents, origin, dst)
    return path is not None and me in path[1:-1]


class Relay:
    """One robot's relaying state: its id, the policy, the routes (``tree``) and the seen cache."""

    def __init__(self, me: str, policy: str = "flood", routes: Mapping[str, str] | None = None,
                 capacity: int = 4096) -> None:
        if policy not in POLICIES:
            raise ValueError(f"relay policy must be one of {', '.join(POLICIES)} (got {policy!r})")
        self.me = me
        self.policy = policy
        self.routes: dict[str, str] = dict(routes or {})
        self.seen = SeenCache(capacity)

    def set_routes(self, routes: Mapping[str, str]) -> None:
        """Replace the routes (a parent map) with the base's latest."""
        self.routes = dict(routes)

    def sent(self, env: Envelope) -> None:
        """Note a message this robot made, so that its echoes are dropped as duplicates."""
        self.seen.add((env.origin, env.seq))

    def handle(self, env: Envelope) -> RelayDecision:
        """Decide for one received envelope (see the module docstring for the rules)."""
        if env.origin == self.me or not self.seen.add((env.origin, env.seq)):
            return RelayDecision(False, None, "duplicate")
        if env.dst == self.me:
            return RelayDecision(True, None, "arrived")
        deliver = env.dst == BROADCAST
        if env.ttl <= 0:
            return RelayDecision(deliver, None, "hop limit")
        if self.policy == "tree" and not forwards_on_tree(self.routes, self.me, env.origin, env.dst):
            return RelayDecision(deliver, None, "not on the tree path")
        return RelayDecision(deliver, msgspec.structs.replace(env, src=self.me, ttl=env.ttl - 1), "forward")
