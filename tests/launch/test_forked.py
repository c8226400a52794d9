"""The launcher's side of the fork server, without a router: exit codes reported, logs written, nothing left."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zenoh

from fleet_emu.core.bus import router_config, router_locators
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.cli import DEFAULT_SCENARIO as DEFAULT
from fleet_emu.launch.forked import NOT_STARTED, ForkServer, fork_server_enabled


def _gone(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return True
    return state == "Z"


@pytest.mark.slow  # a fork server for it; a failed robot by default
def test_a_node_that_fails_at_once_is_reported_with_its_code_and_log(tmp_path: Path) -> None:
    """A robot, and another node named by its module (``python -m fleet_emu.world ARGV`` in the fork)."""
    server = ForkServer(tmp_path / "forkserver.log", modules=("fleet_emu.world.node",))
    try:
        robot = server.spawn("r0", ["--robot", "r0"], tmp_path / "r0.log", "secret")  # no --run: usage error
        world = server.spawn("world", ["--run", "x"], tmp_path / "world.log", None, "fleet_emu.world")
        assert robot.pid > 0 and world.pid > 0
        assert robot.wait(60) == 2 and world.wait(60) == 2
        assert "the following arguments are required" in (tmp_path / "r0.log").read_text()
        log = (tmp_path / "world.log").read_text()
        assert log.startswith("usage: world ") and "the following arguments are required: --connect" in log, log
    finally:
        server.close()
    assert server.proc.returncode == 0
    assert _gone(server.pid) and _gone(robot.pid) and _gone(world.pid)


def _memory(pid: int) -> bytes:
    """Every readable private mapping of a process (its heap, anonymous memory, its stacks)."""
    chunks = []
    with open(f"/proc/{pid}/maps") as maps, open(f"/proc/{pid}/mem", "rb", buffering=0) as mem:
        for line in maps:
            fields = line.split()
            if "r" not in fields[1] or (len(fields) > 5 and fields[5].startswith("/")):
                continue  # files mapped from disk (the interpreter, libraries) hold nothing of the run
            start, end = (int(x, 16) for x in fields[0].split("-"))
            try:
                mem.seek(start)
                chunks.append(mem.read(end - start))
            except OSError:
                continue  # [vvar] and the like
    return b"".join(chunks)


def test_a_robots_credential_never_enters_the_fork_servers_memory(tmp_path: Path) -> None:
    """Attack: a robot forked later inherits the server's memory, so a credential that passed through it could
    be read there. It travels in a pipe handed to the robot; the request itself (its log path) is in there."""
    secret = '{"user": "r0", "password": "' + os.urandom(16).hex() + '"}'
    log = tmp_path / f"r0-{os.urandom(6).hex()}.log"
    server = ForkServer(tmp_path / "forkserver.log")
    try:
        robot = server.spawn("r0", ["--robot", "r0", "--auth-stdin"], log, secret)  # no --run: usage error
        assert robot.pid > 0 and robot.wait(60) == 2
        image = _memory(server.pid)
        assert str(log).encode() in image  # the scan sees what the server received
        assert secret.encode() not in image and secret.split('"')[-2].encode() not in image
    finally:
        server.close()


def test_a_killed_server_fails_what_it_had_not_forked(tmp_path: Path) -> None:
    server = ForkServer(tmp_path / "forkserver.log")
    os.killpg(server.pid, signal.SIGKILL)
    robot = server.spawn("r0", ["--robot", "r0"], tmp_path / "r0.log", None)
    assert robot.pid == NOT_STARTED and robot.returncode == NOT_STARTED
    server.close()
    assert _gone(server.pid)


@pytest.mark.slow  # fork server teardown: a killed robot by default
def test_closing_the_server_ends_the_robots_it_has_left(tmp_path: Path) -> None:
    scenario = tmp_path / "scenario.json"
    scenario.write_text(json.dumps(Scenario().to_dict()))
    with zenoh.open(router_config()) as router:  # a robot on a bus where no world ever says hello: it waits
        server = ForkServer(tmp_path / "forkserver.log", scenario)
        robot = server.spawn("r0", ["--robot", "r0", "--run", "x", "--connect", router_locators(router)[0],
                                    "--scenario", str(scenario)], tmp_path / "r0.log", None)
        with pytest.raises(subprocess.TimeoutExpired):
            robot.wait(3.0)  # it opened its own session in the forked process, and runs
        t0 = time.monotonic()
        server.close()
        assert robot.returncode == -signal.SIGTERM and time.monotonic() - t0 < 10
    assert _gone(server.pid) and _gone(robot.pid)
    assert "Traceback" not in (tmp_path / "r0.log").read_text()


@pytest.mark.parametrize("flag, env, expected", [(None, None, True), (None, "0", False), (None, "1", True),
                                                 (True, "0", True), (False, None, False)])
def test_the_switch(monkeypatch: pytest.MonkeyPatch, flag: bool | None, env: str | None, expected: bool) -> None:
    if env is None:
        monkeypatch.delenv("FLEET_FORK_SERVER", raising=False)
    else:
        monkeypatch.setenv("FLEET_FORK_SERVER", env)
    assert fork_server_enabled(flag) is expected


# Each scenario file in a child forked from one interpreter that has imported the code but loaded no kernel (the
# fork server's own start): the server's preload, then the robots' ticks; the specializations loaded after the
# preload, per file.
_NEW_SPECIALIZATIONS = """
import json, os, sys, traceback
import numba
from fleet_emu.agents import forkserver
from fleet_emu.core import cluster_kernels, kernels
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet

def signatures():
    return {f"{m.__name__}.{n}": set(map(str, f.signatures)) for m in (kernels, cluster_kernels)
            for n, f in vars(m).items() if isinstance(f, numba.core.registry.CPUDispatcher)}

def after_preload(path, ticks):
    forkserver.preload(path)
    before = signatures()
    fleet = Fleet(Scenario.from_json(path))
    fleet.reset()
    for _ in range(ticks):
        fleet.step()
    return {k: sorted(s - before.get(k, set())) for k, s in signatures().items() if s - before.get(k, set())}

assert not any(signatures().values())
found = {}
for path in sys.argv[2:]:
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(r)
        try:
            text = json.dumps(after_preload(path, int(sys.argv[1])))
        except BaseException:
            text = json.dumps({"error": traceback.format_exc()})
        with os.fdopen(w, "w") as f:
            f.write(text)
        os._exit(0)
    os.close(w)
    with os.fdopen(r) as f:
        found[path] = json.loads(f.read())
    os.waitpid(pid, 0)
print(json.dumps(found))
"""

ALLOCATORS = {"minpos-parallel": {"type": "minpos", "wavefront": "parallel"},
              "minpos-stop": {"type": "minpos", "wavefront": "stop"}, "greedy": {"type": "greedy"},
              "connectivity": {"type": "connectivity"}, "mhm": {"type": "mhm"}}


@pytest.fixture(scope="module")
def specializations(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, list[str]]]:
    """Per allocator of :data:`ALLOCATORS`, the kernel specializations its robots loaded after the server's
    preload, in 12 ticks of 4 robots on the default map (one interpreter, a fork per allocator)."""
    scenario = Scenario.load(DEFAULT).override(robots=4, max_ticks=12)
    paths = {}
    for name, allocator in ALLOCATORS.items():
        base = {"base": True} if allocator["type"] == "mhm" else {}  # a base-station planner needs its base
        paths[name] = tmp_path_factory.mktemp("forked") / f"{name}.json"
        paths[name].write_text(json.dumps({**scenario.to_dict(), "allocator": allocator, **base}))
    out = subprocess.run([sys.executable, "-c", _NEW_SPECIALIZATIONS, "12", *map(str, paths.values())],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    found = json.loads(out.stdout)
    return {name: found[str(path)] for name, path in paths.items()}


@pytest.mark.slow  # a fleet per allocator's kernels; forking once by default
@pytest.mark.parametrize("allocator", sorted(ALLOCATORS))
def test_the_fork_server_loads_every_kernel_specialization_a_robot_uses(
        specializations: dict[str, dict[str, list[str]]], allocator: str) -> None:
    """What the server preloads covers what robots call in their ticks: a kernel's specialization compiled
    after the fork (a read-only array is one of its own to numba) is compiled, or loaded from numba's cache,
    by every robot on its own; with an empty cache and 100 robots that stalled the first ticks.
    The robots' ticks run in one process (the memory engine), after the server's preload."""
    assert specializations[allocator] == {}
