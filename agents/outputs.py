"""What a robot and the base station publish, built once for both engines: the node shells
(``agents/node.py``, ``agents/base_node.py``) put these messages on the bus and the memory engine
(``launch/memory.py``) hands them to its fold, so that a seed gives the same messages, field for field, in
either. The order in which they draw from the sender's one sequence counter is fixed here too: it is part of
the radio's bytes, hence of the run.

Pure but for what the callers measure and pass in (peak RSS, process and event-loop CPU): no Zenoh, no clock.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fleet_emu.agents.base import BaseStation
from fleet_emu.agents.brain import Brain
from fleet_emu.core.keys import BASE
from fleet_emu.core.messages import BaseReport, BeliefSnapshot, Envelope, RobotReport, TxBundle

# --- a robot ---------------------------------------------------------------------------------------------


def robot_outputs(brain: Brain, tick: int, out: Sequence[Envelope], belief_every: int
                  ) -> tuple[TxBundle, BeliefSnapshot | None]:
    """A robot's messages after its step of ``tick`` (besides the command, which the step returns): its tx
    bundle, then every ``belief_every`` ticks its belief snapshot. The snapshot's sequence number is drawn
    whether or not anybody records it, so that the counter (and so the radio's bytes) does not depend on it."""
    tx = TxBundle(src=brain.me, tick=tick, seq=brain.next_seq(), msgs=tuple(out))
    if not belief_every or tick % belief_every or brain.belief is None:
        return tx, None
    return tx, BeliefSnapshot(src=brain.me, tick=tick, seq=brain.next_seq(), grid=brain.belief.grid)


def first_cpu_ms(brain: Brain, process_ms: float, loop_ms: float) -> dict[str, float]:
    """The first step's CPU, taken right after it (:attr:`RobotReport.first_cpu_ms`): the process's and the
    event loop's (``process_ms``, ``loop_ms``: measured by the caller, 0 where not measured) and the brain's
    own sums so far."""
    return {"process": process_ms, "loop": loop_ms, "step": brain.step_cpu_ms, **brain.cpu_ms}


def robot_report(brain: Brain, tick: int, dropped: int, peak_rss_kb: int, *, process_cpu_ms: float = 0.0,
                 loop_cpu_ms: float = 0.0, first: dict[str, float] | None = None) -> RobotReport:
    """A robot's report when it stops at ``tick``: its decisions and their wall times, the messages it dropped,
    and its CPU (the brain's sums by stage; the process's and the event loop's since its first step, 0 where
    the caller does not measure them, as the memory engine, one process for every robot, does not)."""
    ms = np.array(brain.decision_ms or [0.0])
    return RobotReport(
        src=brain.me, tick=tick, seq=brain.next_seq(), decisions=len(brain.decision_ms),
        decision_ms_mean=float(ms.mean()), decision_ms_p95=float(np.percentile(ms, 95)), dropped=dropped,
        peak_rss_kb=peak_rss_kb, decision_cpu_ms=brain.decision_cpu_ms, step_cpu_ms=brain.step_cpu_ms,
        process_cpu_ms=process_cpu_ms, loop_cpu_ms=loop_cpu_ms, stage_cpu_ms=dict(brain.cpu_ms),
        first_cpu_ms=dict(first or {}))


# --- the base station ------------------------------------------------------------------------------------


def base_tx(station: BaseStation, tick: int, out: Sequence[Envelope]) -> TxBundle:
    """A planning base's tx bundle of ``tick``: its orders, sent even when empty."""
    return TxBundle(src=BASE, tick=tick, seq=station.next_seq(), msgs=tuple(out))


def base_report(station: BaseStation, tick: int, dropped: int, peak_rss_kb: int) -> BaseReport:
    """The base station's report when it stops at ``tick``: what its team map holds."""
    st = station
    return BaseReport(src=BASE, tick=tick, seq=st.next_seq(), cell=st.cell, known_cells=st.known_cells,
                      cells=int(st.belief.grid.size), merged=st.merged, ticks=st.ticks, dropped=dropped,
                      peak_rss_kb=peak_rss_kb)
