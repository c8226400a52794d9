"""Thread CPU of one robot-tick of the brain on a 512 x 512 map, split by stage.

    python -m benchmarks.brain_step [--robots 16] [--ticks 60] [--cells 512] [--maps maze PATH ...] [--skip 1]
                                    [--shared]

The memory engine (:class:`fleet_emu.launch.memory.Fleet`: the real World, Channel and Brain objects, no Zenoh)
steps each map's fleet for ``--ticks`` ticks with ``benchmarks/scale.py``'s scenario (minpos with parallel
wavefronts, the wall radio, 10 % loss, sensor 8 cells, comm 20 cells, the map's most open start), and every
brain sums its own thread CPU (``time.thread_time``, robust to the machine's load) per stage of
``Brain.step`` (``Brain.cpu_ms``). One row per map, in ms per robot-tick (averaged over every robot-tick but
tick 0's, or the first ``--skip`` ticks'; the kernels are loaded first, as an agent process loads them before
its first tick):

- ``decide``: the allocator (``allocate``, wavefronts included);
- ``clusters``: frontier detection and clustering;
- ``merge``: writing the observation and teammates' map deltas into the belief;
- ``decode``: the radio messages' decode and validation, headers and payloads (``Brain.open``:
  each robot decodes its own copy, as over Zenoh, unless ``--shared``: the memory engine's
  one decode of a broadcast envelope that every teammate hears);
- ``nav``: the wavefront descent and unsticking;
- ``news``: the robot's own map delta, beacon and envelopes;
- ``other``: the rest of ``Brain.step`` (teammates' poses, map sync's bookkeeping and whole maps for teammates
  heard again, the problem, the command); ``outside``: everything but ``decide`` (the target is at most
  1 ms); ``step``: the whole of ``Brain.step``;
- ``rx codec``: what an agent process also does per tick before its brain runs (not in ``step``): reading its
  rx bundle from bytes (``core.codec.decode``), timed on the bundle netem would send it; without
  ``--shared`` the brain then hears those envelopes, as an agent process does.

The last column is the 1-minute load average at the end of the row. Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence
from typing import Any

from benchmarks import scale  # the maps, the start and the scenario
from benchmarks._common import REAL_MAP, FittedMap, fail, fitted_maps, machine, parser

PROG = "brain_step"

COLUMNS = ["decide", "clusters", "merge", "decode", "nav", "news", "other", "outside", "step", "rx codec"]


def fleet_for(m: FittedMap, robots: int, a: argparse.Namespace, shared: bool) -> Any:
    """The memory engine's fleet of ``robots`` on ``m`` with ``scale``'s scenario, reset; unless ``shared``, each
    brain decodes its own copy of what it hears (:func:`read_rx`), as over Zenoh."""
    from fleet_emu.launch.memory import Fleet

    fleet = Fleet(scale.scenario_for(m, robots, a))
    fleet.reset()
    if not shared:
        for brain in fleet.brains.values():
            brain.shared_inbox = False
    return fleet


def read_rx(dst: str, msgs: Sequence[Any]) -> tuple[tuple[Any, ...], float]:
    """``msgs`` as the agent process of ``dst`` reads them: its rx bundle encoded, then decoded into envelopes of
    its own; with the thread CPU of the decode, in seconds."""
    from fleet_emu.core.messages import RxBundle, decode

    data = RxBundle(src="netem", tick=0, seq=1, dst=dst, msgs=tuple(msgs)).encode()
    start = time.thread_time()
    bundle = decode(data, None, RxBundle)
    return bundle.msgs, time.thread_time() - start


def run(m: FittedMap, robots: int, a: argparse.Namespace) -> dict[str, float]:
    """One map's fleet stepped ``a.ticks`` ticks; ms of thread CPU per robot-tick by stage."""
    from fleet_emu.agents.brain import STAGES
    from fleet_emu.core.errors import FleetError
    from fleet_emu.core.kernels import warm_up
    from fleet_emu.core.malloc_tuning import collect_less

    warm_up()  # as an agent process does before its first tick: no kernel loads (or compiles) in a counted tick
    collect_less()  # and with an agent process's collector threshold (core/malloc_tuning.py)
    fleet = fleet_for(m, robots, a, a.shared)
    for _ in range(a.skip):  # tick 0 at least: the kernels warm_up leaves out (the allocator's) load then
        if not fleet.done:
            fleet.step()
    for brain in fleet.brains.values():
        brain.cpu_ms = dict.fromkeys(brain.cpu_ms, 0.0)
        brain.step_cpu_ms = 0.0
    rx_cpu = 0.0
    robot_ticks = 0
    while not fleet.done:
        for r in fleet.agents:  # the agent process's read of its rx bundle, which the brain does not count
            msgs, seconds = read_rx(r, fleet.rx.get(r, ()))
            rx_cpu += seconds
            if not a.shared:  # each robot hears its own copy, as over Zenoh (shared: one decode of a broadcast)
                fleet.rx[r] = msgs
        robot_ticks += len(fleet.agents)
        fleet.step()
    if not robot_ticks:
        raise FleetError("the run ended at tick 0: nothing to measure")
    brains = list(fleet.brains.values())
    per = {s: sum(b.cpu_ms[s] for b in brains) / robot_ticks for s in STAGES}
    step = sum(b.step_cpu_ms for b in brains) / robot_ticks
    return {"decide": per["decision"], "clusters": per["clusters"], "merge": per["merge"], "decode": per["decode"],
            "nav": per["navigation"], "news": per["news"], "other": step - sum(per.values()),
            "outside": step - per["decision"], "step": step, "rx codec": rx_cpu * 1000.0 / robot_ticks,
            "robot_ticks": robot_ticks}


def main(argv: list[str] | None = None) -> None:
    from fleet_emu.core.errors import FleetError

    p = parser("benchmarks.brain_step", __doc__)
    p.add_argument("--robots", type=int, default=16)
    p.add_argument("--ticks", type=int, default=60)
    p.add_argument("--cells", type=int, default=512)
    p.add_argument("--maps", nargs="+", default=["maze", REAL_MAP])
    p.add_argument("--sensor-cells", type=float, default=8.0)
    p.add_argument("--comm-cells", type=float, default=20.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--skip", type=int, default=1, help="ticks stepped first and not counted (default 1: tick 0)")
    p.add_argument("--shared", action="store_true",
                   help="decode as the memory engine does, once per broadcast for all its receivers")
    a = p.parse_args(argv)
    if a.robots < 1 or a.ticks < 2 or a.cells < 8 or not 1 <= a.skip < a.ticks:
        fail(PROG, "--robots must be at least 1, --ticks at least 2, --cells at least 8, --skip from 1 to --ticks - 1")
    print(f"# benchmarks/brain_step.py: {machine()}")
    print(f"# memory engine, minpos (parallel wavefronts), wall radio, loss 0.1, {a.robots} robots, {a.ticks} ticks, "
          f"sensor {a.sensor_cells:g} cells, comm {a.comm_cells:g} cells, seed {a.seed}; "
          f"thread CPU in ms per robot-tick after the first {a.skip} tick(s)"
          + ("; a broadcast decoded once for its receivers" if a.shared else ""))
    print(f"{'map':>10} " + " ".join(f"{c:>8}" for c in COLUMNS) + f" {'load1':>6}", flush=True)
    for m in fitted_maps(PROG, a.maps, a.cells, a.seed):
        t = time.monotonic()
        try:
            row = run(m, a.robots, a)
        except FleetError as exc:
            fail(PROG, f"map {m.name}: {str(exc).splitlines()[0]}")
        print(f"{m.label[:10]:>10} " + " ".join(f"{row[c]:>8.3f}" for c in COLUMNS)
              + f" {os.getloadavg()[0]:>6.2f}", flush=True)
        print(f"{m.name}: {row['robot_ticks']} robot-ticks in {time.monotonic() - t:.0f} s", file=sys.stderr,
              flush=True)


if __name__ == "__main__":
    main()
