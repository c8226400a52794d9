"""fleet_emu: multi-robot frontier exploration under realistic radio, one process per robot over Eclipse Zenoh.

The public API, for scripts and notebooks (the ``fleet`` CLI is built on it)::

    import fleet_emu as fe

    scenario = fe.Scenario.load("default").override(robots=3, allocator="greedy")  # a shipped scenario, by name
    result = fe.run(scenario, out="runs/greedy3")        # a real fleet: one process per robot, over Zenoh
    ticks, coverage = result.coverage_curve()
    run = fe.load_recording("runs/greedy3/run.mcap")     # the same fold as ``fleet report``
    fast = fe.Fleet(scenario).run(seed=4)                 # the same objects in memory: no Zenoh, same result

Names are imported on first use, so that a robot process (``python -m fleet_emu.agents``) loads only what it
needs.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import TYPE_CHECKING, Any

__all__ = [
    "__version__",
    # scenarios and runs
    "Scenario", "RadioConfig", "run", "Result", "Fleet",
    # recordings
    "load_recording",
    # allocators
    "Allocator", "Allocation", "AllocStatus", "Problem", "make_allocator",
    # errors
    "FleetError", "ConfigError", "MapError", "DecodeError", "ReportError", "RunError",
    # versions
    "SCHEMA_VERSION",
]

_LAZY = {
    "Scenario": "fleet_emu.core.scenario",
    "RadioConfig": "fleet_emu.core.radio",
    "Result": "fleet_emu.recording.result",
    "Fleet": "fleet_emu.launch.memory",
    "load_recording": "fleet_emu.recording",
    "Allocator": "fleet_emu.agents.allocators",
    "Allocation": "fleet_emu.agents.allocators",
    "AllocStatus": "fleet_emu.agents.allocators",
    "Problem": "fleet_emu.agents.allocators",
    "make_allocator": "fleet_emu.agents.allocators",
    "FleetError": "fleet_emu.core.errors",
    "ConfigError": "fleet_emu.core.errors",
    "MapError": "fleet_emu.core.errors",
    "DecodeError": "fleet_emu.core.errors",
    "ReportError": "fleet_emu.core.errors",
    "RunError": "fleet_emu.core.errors",
    "SCHEMA_VERSION": "fleet_emu.core.version",
    "__version__": "fleet_emu.core.version",
}

if TYPE_CHECKING:
    from fleet_emu.agents.allocators import Allocation, Allocator, AllocStatus, Problem, make_allocator
    from fleet_emu.core.errors import ConfigError, DecodeError, FleetError, MapError, ReportError, RunError
    from fleet_emu.core.radio import RadioConfig
    from fleet_emu.core.scenario import Scenario
    from fleet_emu.core.version import SCHEMA_VERSION, __version__
    from fleet_emu.launch.memory import Fleet
    from fleet_emu.recording import load_recording
    from fleet_emu.recording.result import Result


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'fleet_emu' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


def run(scenario: Scenario, out: str | Path | None = None, *, record: bool | None = None,
        in_process: bool = False, connect: str | None = None, run_id: str = "",
        grid_every: int | None = None, engine: str = "processes", realtime_hz: float | None = None,
        credentials: str | Path | None = None, tls_ca: str | Path | None = None, listen: str | None = None,
        tls_cert: str | Path | None = None, tls_key: str | Path | None = None,
        host_timeout: float | None = None, overwrite: bool = False, ros2: int | None = None) -> Result:
    """Run one scenario as a real fleet (world, netem and one process per robot over Zenoh; with
    ``in_process`` every node in this process, a session each) and return its :class:`Result`.

    Files are written only where asked: with ``out``, the run's directory gets ``result.json``,
    ``scenario.json``, ``map.npz``, the process logs and (unless ``record=False``) ``run.mcap``; without it,
    nothing is kept. Nothing is printed. Raises :class:`ConfigError` (or :class:`MapError`) on bad input before
    any process starts, and :class:`RunError` when a process of the fleet failed the run (the world, netem).
    A robot that failed does not raise: the run goes on without it and ``result["failed"]`` names it.
    ``engine="memory"`` steps the same objects in this process with no Zenoh (:class:`Fleet`): the same
    result for a seed, several times faster. ``realtime_hz`` runs the processes engine in real time: the
    world ticks that many times a second on the wall clock (not deterministic; the memory engine refuses it).
    The rest are ``fleet run``'s options of the same names: ``credentials`` and ``tls_ca`` with ``connect``
    (or ``credentials`` the hosts' users file of a scenario with ``[hosts]``); ``listen``, ``tls_cert`` and
    ``tls_key`` the embedded router's endpoint and TLS identity, e.g. for hosts on other machines;
    ``host_timeout`` the seconds to wait for them. An ``out`` that holds a run is refused (ConfigError) unless
    ``overwrite``, which removes that run's files first; one another run is writing is always refused.
    ``ros2`` (a ROS domain id) publishes the run as ROS 2 topics in rmw_zenoh's format on its router, as
    ``fleet run --ros2`` (the ``ros2`` extra; docs/guides/ros2.md), and prints its one ``ros2: ...`` line on
    stderr, which a viewer needs.
    """
    import dataclasses

    from fleet_emu.launch.engines import start_run
    from fleet_emu.launch.runner import RunOptions

    out_dir = Path(out) if out is not None else None
    if record and out_dir is None:
        from fleet_emu.core.errors import ConfigError

        raise ConfigError("record=True needs an output directory (out=...)")
    opts = RunOptions(out_dir=out_dir, in_process=in_process, record=out_dir is not None and record is not False,
                      connect=connect, run_id=run_id, grid_every=grid_every, realtime_hz=realtime_hz,
                      credentials=_path(credentials), tls_ca=_path(tls_ca), listen=listen,
                      tls_cert=_path(tls_cert), tls_key=_path(tls_key), overwrite=overwrite)
    if host_timeout is not None:  # else RunOptions' own default
        opts = dataclasses.replace(opts, host_timeout=host_timeout)
    if ros2 is not None:
        from fleet_emu.ros2.bridge import Ros2Options
        from fleet_emu.ros2.types import typestore

        typestore()  # the ros2 extra is installed, or one line saying so
        opts = dataclasses.replace(opts, **Ros2Options.new(ros2, authenticated=connect is None).run_options())
    return start_run(scenario, engine, opts)


def _path(value: str | Path | None) -> Path | None:
    return Path(value) if value is not None else None
