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
from fleet_emu.core.node import NodeBase, node_main, undeclare
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
        self.brain = Brain(robot, allocator, generator(scenario.seed, robot), brain_config(scenario),
                           team=frozenset(robot_ids(scenario.robots)), on_drop=self.drop)
        self.ctx_world = Context(senders=frozenset({"world"}))

    def next_seq(self) -> int:
        """The robot's one counter, shared with its brain."""
        return self.brain.next_seq()

    async def run(self, session: zenoh.Session) -> None:
        keys = self.keys
        inbox = Inbox()
        handles = [
            inbox.subscribe(session, keys.obs(self.robot)),
            inbox.subscribe(session, keys.rx(self.robot)),
            inbox.subscribe(session, keys.stop),
        ]
        self.pub_cmd = publisher(session, keys.cmd(self.robot))
        self.pub_tx = publisher(session, keys.tx(self.robot))
        pub_report = publisher(session, keys.report(self.robot))
        self.pub_belief = publisher(session, keys.belief(self.robot)) if self.scenario.belief_every else None
        handles += [self.pub_cmd, self.pub_tx, pub_report, *([self.pub_belief] if self.pub_belief else [])]
        handles += self.declare_presence(session, inbox)
        try:
            tick = await self._lockstep(inbox)
            ms = np.array(self.brain.decision_ms or [0.0])
            pub_report.put(AgentReport(
                src=self.robot, tick=tick, seq=self.next_seq(), decisions=len(self.brain.decision_ms),
                decision_ms_mean=float(ms.mean()), decision_ms_p95=float(np.percentile(ms, 95)),
                dropped=self.dropped, peak_rss_kb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                decision_cpu_ms=self.brain.decision_cpu_ms, step_cpu_ms=self.brain.step_cpu_ms).encode())
            await asyncio.sleep(0.05)
        finally:
            undeclare(handles)

    async def _lockstep(self, inbox: Inbox) -> int:
        """Act on every tick whose observation and rx bundle have both come, until the stop; the next tick."""
        obs: dict[int, Observation] = {}
        rx: dict[int, RxBundle] = {}
        tick = 0
        while True:
            item = await inbox.get()
            if item is None:
                continue
            key, data, _ = item
            parsed = self.keys.parse(key)
            channel = parsed.channel if parsed is not None else None
            if channel == "stop":
                if self.decode(key, data, Stop) is not None:
                    return tick
            elif channel == "hello":
                self.answer_hello(key, data)
            elif channel == "obs":
                o = self.decode(key, data, Observation, self.ctx_world)
                if o is not None and o.robot == self.robot and o.tick >= tick:
                    obs[o.tick] = o
                elif o is not None:
                    self.drop(key, "observation for another robot or a past tick")
            elif channel == "rx":
                b = self.decode(key, data, RxBundle)  # loosely: the brain checks each envelope against the team
                if b is not None and b.dst == self.robot and b.tick >= tick:
                    rx[b.tick] = b
                elif b is not None:
                    self.drop(key, "rx bundle for another robot or a past tick")
            while tick in obs and tick in rx:
                self._act(obs.pop(tick), rx.pop(tick))
                tick += 1

    def _act(self, obs: Observation, bundle: RxBundle) -> None:
        """One tick: the brain's decision, then the tx bundle, the command and (every few ticks) the belief."""
        cmd, out = self.brain.step(obs, bundle.msgs)
        self.pub_tx.put(TxBundle(src=self.robot, tick=obs.tick, seq=self.next_seq(), msgs=out).encode())
        self.pub_cmd.put(cmd.encode())
        if self.pub_belief is not None and obs.tick % self.scenario.belief_every == 0 \
                and self.brain.belief is not None:
            self.pub_belief.put(BeliefSnapshot(src=self.robot, tick=obs.tick, seq=self.next_seq(),
                                               grid=self.brain.belief.grid).encode())


def main(argv: list[str] | None = None) -> None:
    """``python -m fleet_emu.agents --robot r0 --run RUN --connect ENDPOINT --scenario FILE.json``."""
    node_main("agents", lambda a: AgentNode(a.scenario, a.run, a.robot), argv,
              lambda p: p.add_argument("--robot", required=True))
