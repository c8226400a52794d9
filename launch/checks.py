"""What can be wrong with a run's input, found before any process starts: the scenario and its map, the
machine's memory and file limits, the options (run id, hosts, real-time rate, TLS files, an external router),
the output directory; and each process's login. Split out of ``launch/runner.py``; ``fleet run``, ``fe.run``
and the memory engine share them."""

from __future__ import annotations

import contextlib
import secrets
import time
from pathlib import Path
from typing import TYPE_CHECKING

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.allocators.policy import pin_policy
from fleet_emu.agents.brain import allocator_config
from fleet_emu.core.access import LAUNCHER, Credential, fleet_nodes, make_credentials, read_users
from fleet_emu.core.bus import open_client, shm_enabled
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.grid import MapData
from fleet_emu.core.keys import RUN_ID, robot_ids
from fleet_emu.core.messages import MAX_REALTIME_HZ
from fleet_emu.core.scenario import Scenario
from fleet_emu.core.setting_names import option
from fleet_emu.launch import budget
from fleet_emu.launch.host_client import check_hosts, check_reliable, host_credentials, listen_endpoints
from fleet_emu.launch.liveness import check_run_id_free
from fleet_emu.world.build import base_cell, build_world
from fleet_emu.world.maps import load_map, map_shape

if TYPE_CHECKING:
    from fleet_emu.launch.runner import RunOptions

CONNECT_TIMEOUT = 5.0  # seconds ``--connect`` keeps trying an external router before giving up
MAX_HZ = MAX_REALTIME_HZ  # the fastest real-time rate accepted


def new_run_id() -> str:
    return time.strftime("%Y%m%d-%H%M%S") + "-" + secrets.token_hex(2)


def pinned(scenario: Scenario) -> Scenario:
    """``scenario`` with its policy file's sha256 among the allocator's parameters (:func:`pin_policy`: the file
    read once, here, before any robot starts; every robot verifies it), or as it is for another allocator."""
    alloc = scenario.allocator
    if not isinstance(alloc, dict):
        return scenario
    pin = pin_policy(alloc)
    return scenario if pin == alloc else scenario.override(allocator=pin)


def check(scenario: Scenario) -> MapData:
    """Everything that can be wrong with the user's input, found before any process starts; the true map,
    built once for the whole run."""
    scenario.validate()
    make_allocator(allocator_config(scenario))  # exactly what every agent will build; ConfigError if bad
    check_map_size(scenario)
    md = load_map(scenario.map, scenario.cell_size, scenario.seed, cell_size_given=scenario.cell_size_given)
    world = build_world(scenario, md)
    world.place()  # raises StartAreaError when the robots do not fit (no kernel runs: numba stays unloaded)
    base_cell(scenario, md, world)  # a ConfigError for a base cell off the map or on a wall
    return md


def check_map_size(scenario: Scenario) -> None:
    """The map's grid, sized from its extent or its image's header, against the memory budget before it is built:
    a map whose own part of the memory engine's estimate (the least of any engine's) does not fit is refused
    naming the map (``check_machine`` checks the run's own fleet once the grid is built)."""
    shape = map_shape(scenario.map, scenario.cell_size)
    if shape is None:
        return
    cells, available = shape[0] * shape[1], budget.available_mb()
    grid = (budget.estimate(1, cells, "memory", False, base=scenario.has_base)["total"]
            - budget.estimate(1, 1, "memory", False, base=scenario.has_base)["total"])
    if grid > available:  # the map alone does not fit: it is the cause (else check_machine names the fleet)
        budget.check_memory(scenario.robots, cells, "memory", False, False, available, base=scenario.has_base,
                            what=f"map {scenario.map} ({shape[0]} x {shape[1]} cells)")


def check_machine(scenario: Scenario, map_data: MapData, engine: str, fork_server: bool = False) -> None:
    """Whether the machine holds the run (``launch/budget.py``): its estimated memory against what is
    available, and (over Zenoh) the launcher's open-file limit, raised to its hard limit when needed."""
    budget.check_memory(scenario.robots, int(map_data.grid.size), engine, fork_server, shm_enabled(),
                        budget.available_mb(), base=scenario.has_base)
    if engine != "memory":
        budget.ensure_fds(scenario.robots)


def credentials(scenario: Scenario, opts: RunOptions) -> dict[str, Credential] | None:
    """Every process's login: fresh per-run passwords for the embedded router; with ``connect``, the users
    file of ``fleet router-config`` (None without one: the external router is then not authenticated)."""
    nodes = fleet_nodes(robot_ids(scenario.robots), scenario.has_base)
    ca = str(opts.tls_ca.absolute()) if opts.tls_ca is not None else None
    if opts.connect is None:
        hosts = host_credentials(opts.credentials, scenario.hosts) if scenario.hosts else {}
        return {n: Credential(n, p) for n, p in make_credentials(nodes).items()} | hosts
    if opts.credentials is None:
        return None
    users = read_users(opts.credentials)
    runs = sorted({u.rpartition(".")[0] for u in users if "." in u})  # logins of their own run ids only
    if runs and opts.run_id not in runs:
        raise ConfigError(f"--credentials {opts.credentials} holds the logins of run id {' '.join(runs)}: "
                          f"add --run-id {runs[0]}")
    login = {n: f"{opts.run_id}.{n}" if runs else n for n in nodes}
    missing = [n for n in nodes if login[n] not in users]
    if missing:
        raise ConfigError(f"--credentials {opts.credentials} has no user {login[missing[0]]!r}; make it with "
                          f"`fleet router-config --robots {scenario.robots}` or more robots")
    return {n: Credential(login[n], users[login[n]], ca) for n in nodes}


def check_options(opts: RunOptions, creds: dict[str, Credential] | None = None, hosts: int = 0) -> None:
    """The run's options that can be wrong before anything starts: the run id, the hosts' (``hosts``: the
    scenario's number of hosts), the real-time rate, the TLS CA file, and
    ``connect`` (its syntax, and a router answering there within :data:`CONNECT_TIMEOUT` and accepting the
    launcher's credential)."""
    if opts.run_id and not RUN_ID.fullmatch(opts.run_id):
        raise ConfigError(f"{option('run_id')} must be letters, digits, '_', '-' or '.' (not first), at most 100 "
                          f"(got {opts.run_id!r})")
    check_hosts(hosts, opts.in_process, opts.connect, opts.listen)
    if opts.connect is None:
        listen_endpoints(opts.listen, opts.tls_cert, opts.tls_key)
    elif opts.tls_cert is not None or opts.tls_key is not None:
        raise ConfigError("--tls-cert and --tls-key go with a tls/ or quic/ --listen (the embedded router's)")
    else:
        check_reliable("--connect", opts.connect)
    hz = opts.realtime_hz
    if hz is not None and (isinstance(hz, bool) or not isinstance(hz, int | float) or not 0 < hz <= MAX_HZ):
        raise ConfigError(f"{option('realtime_hz', flag='--realtime')} must be a number of ticks per second > 0 "
                          f"and <= {MAX_HZ:g} (got {hz!r})")
    if opts.tls_ca is not None and not opts.tls_ca.is_file():
        raise ConfigError(f"{option('tls_ca')} {opts.tls_ca}: no such file")
    if opts.connect is None:
        return
    session = open_client(opts.connect, creds[LAUNCHER] if creds else None, CONNECT_TIMEOUT,
                          example="tcp/127.0.0.1:7447", refused=" or it refused the credentials" if creds else "",
                          hint="" if creds else "; a router with authentication needs --credentials")
    with contextlib.closing(session):
        check_run_id_free(session, opts.run_id, opts.connect)


def make_out(out: Path) -> None:
    """Create ``out`` (and its missing parents) and check it is writable; a ConfigError, and no directory left
    behind, when it cannot be written."""
    from fleet_emu.launch.outdir import make_folder

    make_folder(out)


def check_logins(connect: str | None, credentials: Path | None, tls_ca: Path | None, hosts: bool) -> None:
    """A users file and a CA certificate are an external router's (or the users file the hosts' logins)."""
    if connect is None and (tls_ca or (credentials and not hosts)):
        raise ConfigError("--credentials and --tls-ca go with --connect (the embedded router makes its own)")
