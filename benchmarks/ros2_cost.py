"""The cost of ``fleet run --ros2``: lockstep ticks per second of one seeded run (processes engine, office map)
without the bridge, with it and nobody watching, and with it watched by a viewer subscribed to every topic.

    python -m benchmarks.ros2_cost [--robots 16] [--ticks 150] [--repeat 1]

The viewer is a Zenoh session logged in as the run's read-only ``ros2`` user, in this (the launcher's) process:
it receives every publication (counted), so its cost lands on the launcher as a ROS 2 viewer's load on the
router would. Ticks per second are ``result.json``'s (the launcher's measure, first spawn to the end); the three
runs' deterministic results are compared (the bridge never changes a run), and the launcher process's CPU
seconds (user + system) are given: the bridge's work, less sensitive to a shared machine's load. Prints a table.
"""

from __future__ import annotations

import contextlib
import resource
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import zenoh

from benchmarks._common import parser
from fleet_emu.core.access import Credential
from fleet_emu.core.bus import client_config
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.runner import BusAccess, RunOptions, run_fleet
from fleet_emu.recording.result import deterministic
from fleet_emu.ros2.bridge import VIEWER, Ros2Options, grants

DOMAIN = 0


class Viewer:
    """A companion subscribed to ``<domain>/**`` as the viewer, counting what it receives."""

    def __init__(self, password: str) -> None:
        self.password = password
        self.received = 0
        self.lock = threading.Lock()

    @contextlib.contextmanager
    def __call__(self, access: BusAccess) -> Iterator[None]:
        session = zenoh.open(client_config(access.endpoint, Credential(VIEWER, self.password)))
        try:
            session.declare_subscriber(f"{DOMAIN}/**", self._count)
            yield
        finally:
            session.close()

    def _count(self, _sample: zenoh.Sample) -> None:
        with self.lock:
            self.received += 1


def one(scenario: Scenario, mode: str) -> tuple[dict[str, Any], int, float]:
    """One run in ``mode`` (plain, bridge, watched): its result, the messages the viewer received and the CPU
    seconds of this (the launcher's) process, where the bridge and the viewer run."""
    password = "benchmark-viewer"
    ros2 = Ros2Options(DOMAIN, password, lambda _line: None)
    viewer = Viewer(password)
    companions: tuple[Any, ...] = () if mode == "plain" else \
        (ros2.companion(),) if mode == "bridge" else (ros2.companion(), viewer)
    with tempfile.TemporaryDirectory() as tmp:
        opts = RunOptions(out_dir=Path(tmp) / "run", record=False, companions=companions,
                          grants=grants(DOMAIN) if companions else (),
                          grant_users={VIEWER: password} if companions else {})
        before = resource.getrusage(resource.RUSAGE_SELF)
        result = run_fleet(scenario, opts)
        after = resource.getrusage(resource.RUSAGE_SELF)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return result.data, viewer.received, cpu


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.ros2_cost", __doc__)
    p.add_argument("--robots", type=int, default=16)
    p.add_argument("--ticks", type=int, default=150)
    p.add_argument("--repeat", type=int, default=1)
    a = p.parse_args(argv)
    scenario = Scenario().override(map="office", robots=a.robots, seed=0, max_ticks=a.ticks, target_coverage=1.0)
    print(f"{'mode':>8} {'robots':>6} {'ticks':>6} {'ticks/s':>8} {'wall s':>7} {'launcher CPU s':>15} "
          f"{'viewer msgs':>12} {'same':>5}")
    first: dict[str, Any] | None = None
    for _ in range(a.repeat):
        for mode in ("plain", "bridge", "watched"):
            data, received, cpu = one(scenario, mode)
            same = deterministic(data) == first if first is not None else True
            first = first if first is not None else deterministic(data)
            print(f"{mode:>8} {a.robots:>6} {data['ticks']:>6} {data['ticks_per_second'] or 0:>8.1f} "
                  f"{data['wall_seconds']:>7.1f} {cpu:>15.2f} {received if mode == 'watched' else '-':>12} {same!s:>5}",
                  flush=True)


if __name__ == "__main__":
    main()
