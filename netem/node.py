"""The netem process shell: the radio between robots, in lockstep with the world.

Each tick t: on the world's state for t, compute the link graph from the true poses, publish it and every live
robot's rx bundle for t; then wait for every live robot's tx bundle for t and schedule its deliveries.

Real time (``realtime_hz``): netem follows the world's states as they come, on the wall clock, and waits for
no robot. What arrived from the robots between the states of t and t + 1 (whatever tick a bundle is stamped
with: a late decision's bundle too) is sent at t, over the links of t, so it is delivered at t + latency as in
lockstep; a robot that sent nothing in that time sent nothing at t.
The channel itself is :class:`netem.channel.Channel`; the signal model is :mod:`fleet_emu.core.radio`.

A base station that plans (``mhm``: ``Scenario.plans_at_base``) is a sender too: netem waits for its tx bundle
of t as for a live robot's (lockstep), and sends it from the base's cell, after the robots' bundles.
"""

from __future__ import annotations

import time

import msgspec
import numpy as np
import zenoh

from fleet_emu.core.bus import Inbox
from fleet_emu.core.codec import Context
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.grid import Cell, MapData
from fleet_emu.core.kernels import warm_up
from fleet_emu.core.keys import BASE, Keys, robot_ids
from fleet_emu.core.messages import Stop, TxBundle, WorldState
from fleet_emu.core.node import Declared, NodeShell, add_base_cell, node_main, undeclare
from fleet_emu.core.scenario import Scenario
from fleet_emu.netem.channel import make_channel, radio_tick

STATE_GRACE = 2.0  # seconds to wait, after a stop, for the states it announced


class NetemNode(NodeShell):
    role = "netem"

    def __init__(self, scenario: Scenario, run: str, map_data: MapData, base: Cell | None = None,
                 realtime_hz: float | None = None) -> None:
        """``base``: the base station's cell in a run with one, resolved by the launcher
        (``world.build.base_cell``)."""
        super().__init__(Keys(run), "netem")
        if scenario.has_base != (base is not None):
            raise ConfigError("netem takes the base station's cell (--base-cell) exactly when the scenario has a "
                              "base")
        warm_up()  # compile (or load) the kernels before the first tick, not inside it
        self.scenario = scenario
        self.robots = robot_ids(scenario.robots)
        self.occupied = map_data.grid > 0
        self.base = base  # a fixed radio endpoint, in a run with a base station
        self.channel = make_channel(scenario.seed, scenario.radio, scenario.tick_s, map_data.grid.shape,
                                    scenario.cell_size)
        self.base_sends = self.base is not None and scenario.plans_at_base  # the base's orders (mhm)
        senders = frozenset(self.robots) | ({BASE} if self.base_sends else set())
        self.ctx_tx = Context(senders=senders, shape=map_data.grid.shape)
        self.ctx_world = Context(senders=frozenset({"world"}))
        self.states: dict[int, WorldState] = {}  # states come in, by tick, from the next one awaited on
        self.next_state = 0  # the first tick whose state netem has not used yet
        self.tx: dict[int, dict[str, TxBundle]] = {}
        self.sent_tick = -1  # lockstep: the last tick whose bundles netem sent
        self.stopped = False
        self.stop_tick = -1
        self.abort = False
        self.realtime = bool(realtime_hz)

    async def run(self, session: zenoh.Session) -> None:
        keys = self.keys
        inbox = self.inbox()
        handles: list[Declared] = [
            inbox.subscribe(session, keys.state),
            inbox.subscribe(session, keys.wildcard("radio", "tx", "*")),
            inbox.subscribe(session, keys.stop),
        ]
        receivers = [*self.robots, *([BASE] if self.base is not None else [])]
        self.pub_rx = {r: self.publisher(session, keys.rx(r)) for r in receivers}
        self.pub_links = self.publisher(session, keys.links)
        handles += [*self.pub_rx.values(), self.pub_links, *self.declare_presence(session, inbox)]
        try:
            await (self._realtime(inbox) if self.realtime else self._lockstep(inbox))
        finally:
            undeclare(handles)

    async def _lockstep(self, inbox: Inbox) -> None:
        tick = 0
        while True:
            state = await self._await_state(inbox, tick)
            if state is None:
                break
            nodes, link = self._publish_tick(state)
            if state.done:
                break
            live = tuple(r for r in self.robots if r in state.live)
            bundles = await self._await_tx(inbox, tick, live)
            if bundles is None:
                break
            self.channel.transmit(tick, nodes, link, bundles)
            tick += 1
        await self._until_stop(inbox)

    async def _realtime(self, inbox: Inbox) -> None:
        tick = 0
        sent: tuple[int, tuple[str, ...], np.ndarray] | None = None  # the last tick: its live robots and links
        while True:
            state = await self._await_state(inbox, tick)
            if state is None:
                break
            if sent is not None:
                self._send_arrived(*sent)
            sent = (state.tick, *self._publish_tick(state))
            if state.done:
                break
            tick = state.tick + 1
        await self._until_stop(inbox)

    def _send_arrived(self, tick: int, live: tuple[str, ...], link: np.ndarray) -> None:
        """Every bundle that arrived since the state of ``tick``, sent at ``tick`` (oldest stamp first)."""
        bundles: dict[str, tuple] = {}
        for stamp in sorted(self.tx):
            for r, b in self.tx[stamp].items():
                bundles[r] = bundles.get(r, ()) + b.msgs
        self.tx.clear()
        self.channel.transmit(tick, live, link, bundles)

    async def _until_stop(self, inbox: Inbox) -> None:
        while not self.stopped:  # wait for the world's stop so the final links are recorded first
            if await self._next(inbox, timeout=5.0) is None:
                break

    async def _next(self, inbox: Inbox, timeout: float | None = None) -> bool | None:
        """Handle one incoming item; None on timeout."""
        item = await inbox.get(timeout)
        if item is None:
            return None
        key, data, _ = item
        channel = self.keys.channel(key)
        if channel == "hello":
            self.answer_hello(key, data)
        elif channel == "stop":
            stop = self.decode(key, data, Stop)
            if stop is not None:
                self.stopped = True
                self.stop_tick = stop.tick
                self.abort = stop.src != "world"  # the launcher's stop (Ctrl-C) ends at once
        elif channel == "state":
            st = self.decode(key, data, WorldState, self.ctx_world)
            if st is not None:
                self._keep_state(key, st)
        elif channel == "tx":
            b = self.decode(key, data, TxBundle, self.ctx_tx)  # envelopes only: payloads stay opaque
            if b is not None:  # decode checked that the key's robot sent it
                self._keep_tx(key, b)
        return True

    def _keep_tx(self, key: str, b: TxBundle) -> None:
        """Keep a sender's tx bundle for its tick; a second one of the same sender and tick, or one of a tick
        already sent (lockstep), is dropped and counted (first wins: a sender sends one bundle a tick, so a
        second is someone else's in its name)."""
        if not self.realtime and b.tick <= self.sent_tick:
            self.drop(key, f"a tx bundle of {b.src} for tick {b.tick}, already sent")
            return
        got = self.tx.setdefault(b.tick, {})
        if b.src in got:
            self.drop(key, f"a second tx bundle of {b.src} for tick {b.tick} (the first is kept)")
        else:
            got[b.src] = b

    def _keep_state(self, key: str, st: WorldState) -> None:
        """Keep a state for its tick; one of a tick already used, or a second one of a tick, is dropped and
        counted (the world publishes one state per tick, in order)."""
        if st.tick < self.next_state or st.tick in self.states:
            self.drop(key, f"a state of tick {st.tick} out of turn (netem awaits tick {self.next_state})")
        else:
            self.states[st.tick] = st

    async def _await_state(self, inbox: Inbox, tick: int) -> WorldState | None:
        """The world's state of exactly ``tick`` (the states of earlier ticks, never used, are let go); after a
        stop, only the states up to the stop's tick (which may arrive after the stop itself: they travel on
        another key)."""
        self.next_state = max(self.next_state, tick)
        for t in [t for t in self.states if t < tick]:
            del self.states[t]
        while tick not in self.states:
            if self.abort or (self.stopped and tick > self.stop_tick):
                return None
            if await self._next(inbox, timeout=STATE_GRACE if self.stopped else None) is None:
                return None
        self.next_state = tick + 1
        return self.states.pop(tick)

    async def _await_tx(self, inbox: Inbox, tick: int, live: tuple[str, ...]) -> dict | None:
        deadline = time.monotonic() + self.scenario.barrier_timeout
        base = {BASE} if self.base_sends else set()  # the world does not wait for the base: netem does
        needed = set(live) | base
        while not needed <= set(self.tx.get(tick, {})):
            if self.abort:
                return None
            heard = len(self.tx.get(tick, {}))
            if await self._next(inbox, timeout=max(0.0, deadline - time.monotonic())) is None:
                break  # silent robots send nothing this tick; the world fails them
            if len(self.tx.get(tick, {})) > heard:  # as the world's barrier: silent since the last bundle
                deadline = time.monotonic() + self.scenario.barrier_timeout
            if tick + 1 in self.states:  # the world moved on: only robots it failed may stay silent
                needed &= set(self.states[tick + 1].live) | base
        got = self.tx.pop(tick, {})
        self.sent_tick = tick
        return {r: got[r].msgs for r in (*live, *base) if r in got}

    def _publish_tick(self, state: WorldState) -> tuple[tuple[str, ...], np.ndarray]:
        """The links and rx bundles of the state's tick; the tick's radio endpoints and their link matrix."""
        s = self.scenario
        tick = radio_tick(self.channel, self.occupied, self.robots, self.base, s.cell_size, s.radio, state,
                          self.next_seq, self.dropped)
        links = msgspec.structs.replace(tick.links, foreign=self.foreign) if self.foreign else tick.links
        self.pub_links.put(links.encode())
        for bundle in tick.rx:
            self.pub_rx[bundle.dst].put(bundle.encode())
        return tick.nodes, tick.link


def main(argv: list[str] | None = None) -> None:
    """``python -m fleet_emu.netem --run RUN --connect ENDPOINT --scenario FILE.json --map-file MAP.npz``
    (and ``--base-cell ROW,COL`` in a run with a base station)."""
    node_main("netem", lambda a: NetemNode(a.scenario, a.run, a.map_file, a.base_cell, realtime_hz=a.realtime),
              argv, lambda p: add_base_cell(p, required=False), map_file=True)
