"""The agent process shell: one robot. Waits for its observation and rx bundle of each tick, runs the brain,
publishes its tx bundle and command. Only this module touches Zenoh and the clock."""

from __future__ import annotations

import asyncio
import resource

import numpy as np
import zenoh

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.brain import Brain, allocator_config, brain_config
from fleet_emu.core.bus import Inbox, publisher
from fleet_emu.core.codec import Context
from fleet_emu.core.kernels import warm_up
from fleet_emu.core.keys import Keys, robot_ids
from fleet_emu.core.messages import AgentReport, BeliefSnapshot, Observation, RxBundle, Stop, TxBundle
from fleet_emu.core.node import NodeBase, node_main
from fleet_emu.core.rng import generator
from fleet_emu.core.scenario import Scenario


class AgentNode(NodeBase):
    role = "agent"

    def __init__(self, scenario: Scenario, run: str, robot: str) -> None:
        super().__init__(Keys(run), robot)
        warm_up()  # compile (or load) the kernels before the first tick, not inside it
        self.scenario = scenario
        self.robot = robot
        allocator = make_allocator(allocator_config(scenario))
        self.brain = Brain(robot, allocator, generator(scenario.seed, robot), brain_config(scenario))
        self.ctx_world = Context(senders=frozenset({"world"}))
        self.ctx_rx: Context | None = None
        self.team = frozenset(robot_ids(scenario.robots))

    async def run(self, session: zenoh.Session) -> None:
        keys = self.keys
        inbox = Inbox()
        handles = [
            inbox.subscribe(session, keys.obs(self.robot)),
            inbox.subscribe(session, keys.rx(self.robot)),
            inbox.subscribe(session, keys.stop),
        ]
        pub_cmd = publisher(session, keys.cmd(self.robot))
        pub_tx = publisher(session, keys.tx(self.robot))
        pub_report = publisher(session, keys.report(self.robot))
        pub_belief = publisher(session, keys.belief(self.robot)) if self.scenario.belief_every else None
        handles += self.declare_presence(session, inbox)
        obs: dict[int, Observation] = {}
        rx: dict[int, RxBundle] = {}
        tick = 0
        stopped = False
        while not stopped:
            item = await inbox.get()
            assert item is not None
            key, data, _ = item
            if key == keys.stop:
                stopped = self.decode(key, data, Stop) is not None
            elif key.endswith("/ctl/hello"):
                self.answer_hello(key, data)
            elif "/world/obs/" in key:
                o = self.decode(key, data, Observation, self.ctx_world)
                if o is not None and o.robot == self.robot and o.tick >= tick:
                    obs[o.tick] = o
                    if self.ctx_rx is None:
                        self.ctx_rx = Context(senders=self.team, shape=o.shape)
                elif o is not None:
                    self.drop(key, "observation for another robot or a past tick")
            elif "/radio/rx/" in key:
                b = self.decode(key, data, RxBundle)  # the radio messages inside are checked one by one
                if b is not None and b.src != "netem":
                    self.drop(key, f"rx bundle from {b.src!r}, not netem")
                elif b is not None and b.dst == self.robot and b.tick >= tick:
                    rx[b.tick] = b
            while tick in obs and tick in rx:
                bundle = rx.pop(tick)
                msgs = tuple(m for m in bundle.msgs if self._valid(m))
                cmd, out = self.brain.step(obs.pop(tick), msgs)
                pub_tx.put(TxBundle(src=self.robot, tick=tick, seq=self.brain._seq(), msgs=out).encode())
                pub_cmd.put(cmd.encode())
                if pub_belief is not None and tick % self.scenario.belief_every == 0 \
                        and self.brain.belief is not None:
                    pub_belief.put(BeliefSnapshot(src=self.robot, tick=tick, seq=self.next_seq(),
                                                  grid=self.brain.belief.grid).encode())
                tick += 1
        ms = np.array(self.brain.decision_ms or [0.0])
        pub_report.put(AgentReport(
            src=self.robot, tick=tick, seq=self.next_seq(), decisions=len(self.brain.decision_ms),
            decision_ms_mean=float(ms.mean()), decision_ms_p95=float(np.percentile(ms, 95)),
            dropped=self.dropped, peak_rss_kb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss).encode())
        await asyncio.sleep(0.05)
        del handles

    def _valid(self, msg: object) -> bool:
        """Radio messages are checked against the grid and the team (the rx bundle was checked loosely)."""
        try:
            msg.validate(self.ctx_rx)  # type: ignore[attr-defined]
        except ValueError as exc:
            self.drop("rx", str(exc))
            return False
        return True


def main(argv: list[str] | None = None) -> None:
    """``python -m fleet_emu.agents --robot r0 --run RUN --connect ENDPOINT --scenario FILE.json``."""
    node_main("agents", lambda a: AgentNode(a.scenario, a.run, a.robot), argv,
              lambda p: p.add_argument("--robot", required=True))
