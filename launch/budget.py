"""What a run needs of the machine, checked before anything starts: memory against
``MemAvailable`` and file descriptors against ``RLIMIT_NOFILE``.

:func:`estimate` and :func:`check_memory` are pure: a model of each process's proportional set size (PSS:
shared pages divided among the processes mapping them, so the sum is what the run costs the machine) from the
fleet size, the map's cells, the engine and whether the robots are forked. The figures are measured
(``benchmarks/scale.py`` and ``benchmarks/agent_memory.py``, 2026-11-23, 2-core VM; docs/guides/large-fleets.md) and
rounded up; :data:`MODEL` says where each comes from. The estimate is a guard against a run that would swap or
be killed by the OOM killer halfway, not a measurement: ``FLEET_MEM_AVAILABLE_MB`` replaces what
``/proc/meminfo`` says (for a test, or to run past the check on purpose).
"""

from __future__ import annotations

import dataclasses
import os
import resource
from collections.abc import Mapping
from pathlib import Path

from fleet_emu.core.errors import ConfigError

MB = 2**20
MEM_ENV = "FLEET_MEM_AVAILABLE_MB"


class BudgetError(ConfigError):
    """The run does not fit the machine (one line naming the numbers)."""


@dataclasses.dataclass(frozen=True)
class MemoryModel:
    """PSS in MB of each process of a run; ``*_per_mcell`` grow with the map's cells (millions)."""

    # forked robot: 13 MB mean, 18 max at 80 robots, 512 x 512 maze (scale.py); 23-27 MB mean at 16-100 robots
    # once it keeps its heap (core/malloc_tuning.py, 2026-11-24), with agent_per_mcell's 6 MB of that map in it
    agent_forked: float = 22.0
    agent_fresh: float = 90.0  # started afresh: 81 MB mean, 83 max at 32 robots (scale.py, FLEET_FORK_SERVER=0)
    agent_per_mcell: float = 24.0  # belief (int8), wavefront distances and frontier masks over the map
    fork_server: float = 60.0  # the server's own share of the pages it holds for its robots
    world: float = 90.0  # 79-86 MB on the 512 x 512 maze, whatever the fleet
    world_per_mcell: float = 16.0
    base: float = 90.0  # the base station's process (a run with one): 82 MB on the maze, 4 robots, like the world's
    netem: float = 80.0  # 76 MB at 32 robots, 88 MB at 80 with Zenoh's shared memory off
    netem_per_robot: float = 0.5
    launcher: float = 100.0  # the launcher (with the router before it had its own process): 101 MB at 32 robots
    launcher_per_robot: float = 0.5
    router: float = 30.0  # the router's own process (processes engine): 26 MB at 32 robots
    shm_per_robot: float = 40.0  # FLEET_ZENOH_SHM=1: each session's 16 MB pool, mapped by netem and router
    engine: float = 250.0  # the memory engine's one process (imports, world, netem, the fold): 191 MB at 8 robots
    brain_per_robot: float = 1.0  # one Brain in the memory engine: 237 MB at 64 robots, 0.8 MB a robot more
    brain_per_mcell: float = 4.0  # its belief and what it keeps of the map


MODEL = MemoryModel()


def estimate(robots: int, cells: int, engine: str = "processes", fork_server: bool = True,
             shm: bool = False, model: MemoryModel = MODEL, base: bool = False) -> dict[str, float]:
    """The MB each part of a run needs (its keys name the parts; ``total`` their sum). ``engine``:
    ``processes``, ``in-process`` (every node in the launcher, each its own Zenoh session) or ``memory``;
    ``base``: the run has a base station (its own process on the processes engine)."""
    mcells = cells / 1e6
    brain_map = model.agent_per_mcell * mcells
    if engine == "processes":
        per_robot = (model.agent_forked if fork_server else model.agent_fresh) + brain_map
        parts = {
            "robots": robots * per_robot,
            "world": model.world + model.world_per_mcell * mcells,
            "netem": model.netem + model.netem_per_robot * robots,
            "launcher": model.launcher + model.launcher_per_robot * robots,
            "router": model.router,
        }
        if fork_server:
            parts["fork server"] = model.fork_server
        if base:
            parts["base"] = model.base + model.world_per_mcell * mcells
        if shm:
            parts["shared memory"] = model.shm_per_robot * robots
    else:
        parts = {"process": model.engine + model.world_per_mcell * mcells,
                 "robots": robots * (model.brain_per_robot + model.brain_per_mcell * mcells)}
        if engine == "in-process":
            parts["process"] += model.launcher + model.netem
            parts["robots"] += robots * (model.launcher_per_robot + model.netem_per_robot)
    return {**parts, "total": sum(parts.values())}


def check_memory(robots: int, cells: int, engine: str, fork_server: bool, shm: bool, available_mb: float,
                 model: MemoryModel = MODEL, base: bool = False, what: str = "") -> dict[str, float]:
    """:func:`estimate`'s parts when they fit ``available_mb``; a :class:`BudgetError` naming the numbers when
    they do not (and ``what``: the map, when its size is the cause)."""
    parts = estimate(robots, cells, engine, fork_server, shm, model, base)
    need = parts["total"]
    if need <= available_mb:
        return parts
    how = {"processes": "forked from the fork server" if fork_server else "each started afresh",
           "in-process": "in one process over Zenoh", "memory": "on the memory engine"}.get(engine, engine)
    split = ", ".join(f"{k} {_mb(v)}" for k, v in parts.items() if k != "total")
    hint = ", or with the fork server" if engine == "processes" and not fork_server else ""
    if what:
        raise BudgetError(f"{what} with {robots} robots needs about {_mb(need)} of memory ({split}) but "
                          f"{_mb(available_mb)} is available (MemAvailable, or {MEM_ENV}); use larger cells "
                          "(--cell-size) or a smaller map")
    raise BudgetError(f"{robots} robots ({how}) need about {_mb(need)} of memory ({split}) but {_mb(available_mb)} "
                      f"is available (MemAvailable, or {MEM_ENV}); run fewer robots{hint}")


def _mb(v: float) -> str:
    return f"{v / 1024:.1f} GB" if v >= 1024 else f"{v:.0f} MB"


def available_mb(env: Mapping[str, str] | None = None, meminfo: str | None = None) -> float:
    """``FLEET_MEM_AVAILABLE_MB`` when set (a bad value is a ConfigError), else ``MemAvailable`` of
    ``/proc/meminfo`` (infinite where there is none: the check is then skipped)."""
    env = os.environ if env is None else env
    text = env.get(MEM_ENV)
    if text is not None:
        try:
            value = float(text)
        except ValueError:
            value = -1.0
        if not value >= 0:
            raise ConfigError(f"{MEM_ENV} must be a number of MB, at least 0 (got {text!r})")
        return value
    try:
        meminfo = Path("/proc/meminfo").read_text() if meminfo is None else meminfo
    except OSError:
        return float("inf")
    for line in meminfo.splitlines():
        if line.startswith("MemAvailable:"):
            return int(line.split()[1]) / 1024
    return float("inf")


def fds_needed(robots: int) -> int:
    """File descriptors the launcher (with the embedded router) holds: per robot its session's socket, its log
    file and its standard input (about 2 measured with the fork server at 128 robots, 4 allowed), and a margin."""
    return 4 * robots + 128


def ensure_fds(robots: int) -> None:
    """Raise this process's soft ``RLIMIT_NOFILE`` up to its hard limit when the run needs more than the soft one
    (often 1024); a BudgetError when even the hard limit is too low."""
    need = fds_needed(robots)
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY or soft >= need:
        return
    if hard != resource.RLIM_INFINITY and hard < need:
        raise BudgetError(f"{robots} robots need about {need} open files in the launcher but its limit is {hard} "
                          f"(ulimit -Hn); raise it or run fewer robots")
    resource.setrlimit(resource.RLIMIT_NOFILE, (need if hard == resource.RLIM_INFINITY else hard, hard))
