"""``fleet run`` and ``fe.run`` take one path from their options to a run (``launch/engines.py``): the same
:class:`RunOptions` reach the same function, and one list says what the memory engine refuses, each option named
as its user wrote it (the flag from the CLI, the keyword from Python)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest

import fleet_emu as fe
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.scenario import HostPlan, Scenario
from fleet_emu.core.setting_names import cli_spelling
from fleet_emu.launch import engines
from fleet_emu.launch.engines import BUS_OPTIONS, check_engine
from fleet_emu.launch.runner import RunOptions
from tests.harness.cli import run_cli

#: A value other than the default for each option only the processes engine takes.
GIVEN: dict[str, Any] = {"in_process": True, "connect": "tcp/127.0.0.1:7447", "credentials": Path("users"),
                         "tls_ca": Path("ca.pem"), "listen": "tcp/127.0.0.1:0", "tls_cert": Path("c.pem"),
                         "tls_key": Path("k.pem"), "host_timeout": 5.0, "fork_server": False,
                         "companions": (object(),)}


class _Started(Exception):
    """Raised by the stand-in for the run: what it was asked to start."""

    def __init__(self, scenario: Scenario, engine: str, opts: RunOptions) -> None:
        super().__init__(engine)
        self.scenario, self.engine, self.opts = scenario, engine, opts


def _caught(monkeypatch: pytest.MonkeyPatch) -> None:
    def start(scenario: Scenario, engine: str, opts: RunOptions) -> Any:
        check_engine(scenario, engine, opts)
        raise _Started(scenario, engine, opts)

    monkeypatch.setattr(engines, "start_run", start)


def test_fleet_run_and_fe_run_start_the_same_run(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    _caught(monkeypatch)
    with pytest.raises(_Started) as python:
        fe.run(Scenario().override(robots=2, seed=3), tmp_path, engine="memory", run_id="same", grid_every=4)
    with pytest.raises(_Started) as cli:
        run_cli(["run", "--robots", "2", "--seed", "3", "--engine", "memory", "--run-id", "same", "--grid-every",
                 "4", "--out", str(tmp_path), "--quiet"])
    a, b = python.value, cli.value
    assert (a.scenario, a.engine) == (b.scenario, b.engine) == (Scenario().override(robots=2, seed=3), "memory")
    fields = ("out_dir", "record", "run_id", "grid_every", "in_process", "connect", "realtime_hz", "overwrite")
    assert [getattr(a.opts, f) for f in fields] == [getattr(b.opts, f) for f in fields]
    assert a.opts.out_dir == tmp_path and a.opts.grid_every == 4 and a.opts.record


@pytest.mark.parametrize("field, flag", BUS_OPTIONS, ids=[f for f, _ in BUS_OPTIONS])
def test_the_memory_engine_refuses_each_bus_option_by_its_users_name(field: str, flag: str) -> None:
    assert set(GIVEN) == {f for f, _ in BUS_OPTIONS}  # the list and this test name the same options
    opts = dataclasses.replace(RunOptions(), **{field: GIVEN[field]})
    check_engine(Scenario(), "processes", opts)  # the processes engine takes it
    with pytest.raises(ConfigError) as python:
        check_engine(Scenario(), "memory", opts)
    with cli_spelling(), pytest.raises(ConfigError) as cli:
        check_engine(Scenario(), "memory", opts)
    keyword = flag if flag and not flag.startswith("--") else field
    assert str(python.value) == f"the memory engine runs without Zenoh nor processes: it takes no {keyword}"
    spelt = flag if flag.startswith("--") else "--" + keyword.replace("_", "-")
    assert str(cli.value) == f"--engine memory runs without Zenoh nor processes: it takes no {spelt}"


def test_real_time_hosts_a_bad_engine_and_a_bad_grid_rate_are_refused_once() -> None:
    with pytest.raises(ConfigError, match=r"^realtime_hz needs the processes engine: the memory engine is lockstep"):
        check_engine(Scenario(), "memory", RunOptions(realtime_hz=5.0))
    with pytest.raises(ConfigError, match=r"^the memory engine .* takes no \[hosts\] \(the scenario's; hosts=0 runs"):
        check_engine(Scenario(hosts=HostPlan(1)), "memory", RunOptions())
    with pytest.raises(ConfigError, match=r"^engine must be one of processes, memory \(got 'fast'\)"):
        fe.run(Scenario(), engine="fast")
    with pytest.raises(ConfigError, match=r"^grid_every must be a whole number of ticks, at least 1 \(got 0\)"):
        fe.run(Scenario(), engine="memory", grid_every=0)
    code, _, err = run_cli(["run", "--engine", "memory", "--grid-every", "0"])
    assert code == 2 and err == "fleet: error: --grid-every must be a whole number of ticks, at least 1 (got 0)\n"
