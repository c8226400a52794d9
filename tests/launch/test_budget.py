"""The memory a run needs against what the machine has: a pure estimate and its check."""

from __future__ import annotations

import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.launch.budget import MODEL, BudgetError, available_mb, check_memory, estimate, fds_needed

MAZE = 511 * 511  # benchmarks/scale.py's maze


def test_the_estimate_adds_up_and_grows_with_the_fleet_and_the_map() -> None:
    forked = estimate(80, MAZE, "processes", fork_server=True)
    assert forked["total"] == pytest.approx(sum(v for k, v in forked.items() if k != "total"))
    assert set(forked) == {"robots", "world", "netem", "launcher", "router", "fork server", "total"}
    # measured at 100 robots on this maze (scale.py, 2026-11-24, robots keeping their heap): agents 25 MB mean,
    # world 99, netem 157, the router 45, the launcher 104
    measured = 100 * 25 + 99 + 157 + 45 + 104
    assert measured <= estimate(100, MAZE)["total"] <= 2 * measured
    fresh = estimate(80, MAZE, "processes", fork_server=False)
    assert fresh["robots"] - forked["robots"] == pytest.approx(80 * (MODEL.agent_fresh - MODEL.agent_forked))
    assert estimate(160, MAZE)["total"] > forked["total"]
    assert estimate(80, 4 * MAZE)["total"] > forked["total"]
    assert estimate(80, MAZE, shm=True)["shared memory"] == 80 * MODEL.shm_per_robot
    memory = estimate(80, MAZE, "memory")
    assert set(memory) == {"process", "robots", "total"} and memory["total"] < forked["total"]
    assert estimate(80, MAZE, "in-process")["total"] > memory["total"]


def test_a_run_that_does_not_fit_is_refused_with_its_numbers() -> None:
    need = estimate(256, MAZE, "processes", fork_server=False)["total"]
    assert need > 20 * 1024  # 256 robots started afresh: more than 20 GB
    with pytest.raises(BudgetError) as exc:
        check_memory(256, MAZE, "processes", False, False, available_mb=16 * 1024)
    text = str(exc.value)
    assert text.startswith(f"256 robots (each started afresh) need about {need / 1024:.1f} GB of memory (robots ")
    assert "but 16.0 GB is available (MemAvailable, or FLEET_MEM_AVAILABLE_MB)" in text
    assert text.endswith("run fewer robots, or with the fork server") and "\n" not in text
    assert isinstance(exc.value, ConfigError)  # bad input: exit 2
    parts = check_memory(256, MAZE, "processes", True, False, available_mb=16 * 1024)  # forked, it fits
    assert parts["total"] < 16 * 1024
    with pytest.raises(BudgetError, match=r"^256 robots \(forked from the fork server\) .*run fewer robots$"):
        check_memory(256, MAZE, "processes", True, False, available_mb=1024)


def test_available_memory_comes_from_meminfo_or_the_environment() -> None:
    meminfo = "MemTotal:       24684096 kB\nMemFree:         1000 kB\nMemAvailable:   2097152 kB\n"
    assert available_mb({}, meminfo) == 2048
    assert available_mb({"FLEET_MEM_AVAILABLE_MB": "512"}, meminfo) == 512
    assert available_mb({}, "MemTotal: 1 kB\n") == float("inf")  # no MemAvailable: no check
    for bad in ("lots", "-1", "nan"):
        with pytest.raises(ConfigError, match="FLEET_MEM_AVAILABLE_MB must be a number of MB"):
            available_mb({"FLEET_MEM_AVAILABLE_MB": bad}, meminfo)


def test_file_descriptors_grow_with_the_fleet() -> None:
    # measured: 509 open in the launcher at 128 robots with Zenoh's shared memory on (a socket and a mapped
    # pool per robot's session)
    assert fds_needed(128) >= 509 and fds_needed(256) > fds_needed(128)


def test_a_base_station_is_one_process_more_on_the_processes_engine() -> None:
    without = estimate(8, MAZE, "processes")
    with_base = estimate(8, MAZE, "processes", base=True)
    assert "base" not in without and with_base["base"] > 80
    assert with_base["total"] == pytest.approx(without["total"] + with_base["base"])
    assert estimate(8, MAZE, "memory", base=True) == estimate(8, MAZE, "memory")  # one process anyway
