"""Multi-hop relaying: a chain of relays, duplicates, the hop limit, a lost hop, the tree policy.

Hops are simulated by a small loop that plays netem's part: each round, every envelope sent reaches the
sender's linked neighbours (a broadcast medium), unless that directed link is in ``lost``.
"""

from __future__ import annotations

from collections import Counter
from itertools import pairwise

import pytest

from fleet_emu.agents.relay import Relay, SeenCache, forwards_on_tree, tree_path
from fleet_emu.core.messages import Envelope

CHAIN = ["a", "r1", "r2", "r3", "d"]  # a - r1 - r2 - r3 - d: only neighbours hear each other


def chain_links(names: list[str]) -> set[frozenset[str]]:
    return {frozenset(p) for p in pairwise(names)}


def make(origin: str, dst: str, ttl: int, seq: int = 1) -> Envelope:
    return Envelope(src=origin, tick=5, seq=seq, origin=origin, dst=dst, ttl=ttl, payload_kind="x", payload=b"p")


def simulate(relays: dict[str, Relay], links: set[frozenset[str]], first: Envelope,
             lost: frozenset[tuple[str, str]] = frozenset(), rounds: int = 20
             ) -> tuple[Counter[str], list[tuple[str, Envelope]], int]:
    """Deliveries per robot, (receiver, envelope) of each delivery, and the transmissions made."""
    relays[first.origin].sent(first)
    pending = [first]
    delivered: Counter[str] = Counter()
    log: list[tuple[str, Envelope]] = []
    transmissions = 0
    for _ in range(rounds):
        nxt = []
        for env in pending:
            transmissions += 1
            for name, relay in relays.items():
                if name == env.src or frozenset((env.src, name)) not in links or (env.src, name) in lost:
                    continue
                decision = relay.handle(env)
                if decision.deliver:
                    delivered[name] += 1
                    log.append((name, env))
                if decision.forward is not None:
                    nxt.append(decision.forward)
        pending = nxt
    return delivered, log, transmissions


def team(names: list[str], policy: str = "flood", routes: dict[str, str] | None = None) -> dict[str, Relay]:
    return {n: Relay(n, policy, routes) for n in names}


def test_a_message_crosses_a_chain_of_three_relays() -> None:
    delivered, log, transmissions = simulate(team(CHAIN), chain_links(CHAIN), make("a", "d", ttl=3))
    assert delivered == Counter({"d": 1})  # the relays forward but do not deliver what is for d
    (_, env), = log
    assert env.src == "r3" and env.origin == "a" and env.seq == 1 and env.ttl == 0
    assert env.tick == 5  # the origin's tick: end-to-end latency is now - tick
    assert 3 - env.ttl + 1 == 4  # hops taken
    assert transmissions == 4  # a, r1, r2, r3; d does not forward what has arrived


def test_the_hop_limit_holds() -> None:
    delivered, _, transmissions = simulate(team(CHAIN), chain_links(CHAIN), make("a", "d", ttl=2))
    assert delivered["d"] == 0
    assert transmissions == 3  # r3 got it with ttl 0 and stopped
    delivered, _, _ = simulate(team(CHAIN), chain_links(CHAIN), make("a", "d", ttl=0))
    assert delivered["d"] == 0  # ttl 0 is one hop: only r1 hears it, and does not forward it


def test_a_lost_hop_loses_the_message() -> None:
    delivered, _, transmissions = simulate(team(CHAIN), chain_links(CHAIN), make("a", "d", ttl=8),
                                           lost=frozenset({("r2", "r3")}))
    assert delivered["d"] == 0
    assert transmissions == 3


def test_duplicates_are_dropped_in_a_mesh() -> None:
    names = ["a", "b", "c", "d"]
    mesh = {frozenset((x, y)) for x in names for y in names if x < y}
    delivered, _, transmissions = simulate(team(names), mesh, make("a", "*", ttl=5))
    assert delivered == Counter({"b": 1, "c": 1, "d": 1})  # a broadcast: once each, never to its origin
    assert transmissions == 4  # each robot sends it once, however many copies it hears


def test_the_same_id_is_a_duplicate_even_with_another_header() -> None:
    relay = Relay("r1")
    assert relay.handle(make("a", "*", ttl=2)).forward is not None
    again = relay.handle(make("a", "*", ttl=4))  # the same (origin, seq) from another path
    assert not again.deliver and again.forward is None and again.why == "duplicate"
    assert relay.handle(make("a", "*", ttl=2, seq=2)).deliver  # another id is new
    mine = Relay("a")
    assert mine.handle(make("a", "*", ttl=2)).why == "duplicate"  # an echo of one's own


def test_the_cache_forgets_the_oldest_first() -> None:
    cache = SeenCache(capacity=2)
    assert cache.add(("a", 1)) and cache.add(("a", 2)) and not cache.add(("a", 1))
    assert cache.add(("a", 3))
    assert ("a", 1) not in cache and ("a", 2) in cache and len(cache) == 2


#       base
#      /    \
#     r1     r4
#     |       \
#     r2       r5
#     |
#     r3
ROUTES = {"r1": "base", "r2": "r1", "r3": "r2", "r4": "base", "r5": "r4"}


def test_tree_paths_and_who_forwards() -> None:
    assert tree_path(ROUTES, "r3", "base") == ["r3", "r2", "r1", "base"]
    assert tree_path(ROUTES, "r3", "r5") == ["r3", "r2", "r1", "base", "r4", "r5"]
    assert tree_path(ROUTES, "r2", "r2") == ["r2"]
    assert tree_path(ROUTES, "r9", "base") is None
    assert forwards_on_tree(ROUTES, "r1", "base", "r3")
    assert not forwards_on_tree(ROUTES, "r4", "base", "r3")
    assert not forwards_on_tree(ROUTES, "r3", "base", "r3")  # the destination does not forward
    assert forwards_on_tree(ROUTES, "base", "r3", "r5")
    assert forwards_on_tree(ROUTES, "r4", "r1", "*") and not forwards_on_tree(ROUTES, "r3", "r1", "*")


def test_tree_policy_forwards_only_on_the_path() -> None:
    names = ["base", "r1", "r2", "r3", "r4", "r5"]
    everyone = {frozenset((x, y)) for x in names for y in names if x < y}  # all hear all: only policy limits
    tree = team(names, "tree", ROUTES)
    delivered, _, transmissions = simulate(tree, everyone, make("base", "r3", ttl=5))
    assert delivered == Counter({"r3": 1})
    assert transmissions == 3  # base, r1, r2: r4 and r5 hear it but are off the path
    flood = team(names, "flood")
    _, _, flooded = simulate(flood, everyone, make("base", "r3", ttl=5))
    assert flooded == 5  # everyone but r3 sends it once


def test_tree_policy_without_a_route_does_not_forward() -> None:
    relay = Relay("r1", "tree", ROUTES)
    assert relay.handle(make("r9", "base", ttl=3)).forward is None
    relay.set_routes({"r9": "r1", "r1": "base"})
    assert relay.handle(make("r9", "base", ttl=3, seq=2)).forward is not None


def test_a_bad_policy_is_refused() -> None:
    with pytest.raises(ValueError, match="flood, tree"):
        Relay("r1", "gossip")
